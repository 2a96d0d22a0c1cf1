#if ${P}_USE_FLOAT && defined(__GNUC__) && !defined(__clang__)  /* fused multiply-adds in this loop (float: one rounding instead of two) */
#pragma GCC push_options
#pragma GCC optimize("fp-contract=fast")
#endif
$definition
#if ${P}_USE_FLOAT && defined(__GNUC__) && !defined(__clang__)
#pragma GCC pop_options
#endif
