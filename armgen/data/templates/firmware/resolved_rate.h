$common
    .rr = {
$path
        .method = $method,
        .rho_R = $rho_R, .T_smo_R = $T_smo_R,
        .rho_L = $rho_L, .theta_s = $theta_s,
        .T_smo_L = $T_smo_L, .T_sum_L = $T_sum_L,
        .gamma_R_ramp = $gamma_R_ramp,
        .clik_gain = $clik_gain,
        .damping = CTRL_LIT(0.0),
        .task_rows = $task_rows,
    },
