#if ${P}_USE_FLOAT
#define $count $float_count
#else
#define $count $double_count
#endif
$signature;
