            [$joint] = $coefficients,
