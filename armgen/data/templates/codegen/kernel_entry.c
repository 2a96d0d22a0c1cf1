void $symbol(const k_real *x, k_real *y);
void $symbol(const k_real *x, k_real *y) {
$body
}
