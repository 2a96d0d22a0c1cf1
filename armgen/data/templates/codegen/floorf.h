#if ${P}_USE_FLOAT
/* floor(x) by a conversion to an integer (exact: |x| >= 2^23 is already integral, and NaN,
 * inf and -0 are their own floor): no library call, whose spills cost more on a Cortex-M4F. */
static inline float ${p}_floorf(float x) {
  float r = x;
  if ((fabsf(x) < 8388608.0f) && (x != 0.0f)) {
    const float t = (float)(long)x;
    if (t > x) {
      r = t - 1.0f;
    } else {
      r = t;
    }
  }
  return r;
}
#endif
