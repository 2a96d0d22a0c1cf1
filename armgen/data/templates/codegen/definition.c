/* $function: $ops */
$signature {
$body
}
