$common
    .pb = {
        .nseg = $nseg,
        .n_ticks = $n_ticks,
        .knots = $knots,
        .active = $active,
        .coeffs = {
$coeffs
        },
    },
