/* Lean math (no library calls where the FPU or a comparison does the job). */
static inline ${p}_real ${p}_fmin(${p}_real a, ${p}_real b) { return ((a < b) || (b != b)) ? a : b; }
static inline ${p}_real ${p}_fmax(${p}_real a, ${p}_real b) { return ((a > b) || (b != b)) ? a : b; }
static inline ${p}_real ${p}_sqrt(${p}_real x) {
#if ${P}_USE_FLOAT && defined(__GNUC__) && defined(__ARM_FP) && ((__ARM_FP & 4) != 0)
  ${p}_real r;
  __asm__("vsqrt.f32 %0, %1" : "=t"(r) : "t"(x));
  return r;
#elif ${P}_USE_FLOAT
  return sqrtf(x);
#else
  return sqrt(x);
#endif
}
