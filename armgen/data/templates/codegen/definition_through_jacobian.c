/* $function: $ops; calls ${p}_jacobian and ${p}_$twin */
$signature {
$body
}
