    .feedforward = $feedforward,
    .tau_max = $tau_max,
