$common
    .rr = {
$path
        .clik_gain = $clik_gain,
        .task_rows = $task_rows,
    },
    .ft = {
        .method = $method,
        .index = $index,
        .K = $K, .b = $b,
        .rule = $rule,
        .v_band = $v_band, .omega_floor = $omega_floor, .delta = $delta,
        .a = $a,
        .epsilon = $epsilon, .lambda_max = $lambda_max,
    },
