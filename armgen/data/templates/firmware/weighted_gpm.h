$common
    .rr = {
$path
        .clik_gain = $clik_gain,
        .task_rows = $task_rows,
    },
    .wg = {
        .band = $band, .t_rmax = $t_rmax, .delta = $delta,
        .epsilon = $epsilon, .rho_max = $rho_max,
        .ramp_time = $ramp_time, .ramp_out = $ramp_out,
        .H_lo = $H_lo, .H_hi = $H_hi,
        .k_hi = $k_hi, .k_lo = $k_lo,
        .u_th = $u_th, .u_band = $u_band,
    },
