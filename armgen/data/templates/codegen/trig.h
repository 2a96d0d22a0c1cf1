#if defined(__GNUC__)
#define ${P}_TRIG_INLINE static inline __attribute__((always_inline))
#else
#define ${P}_TRIG_INLINE static inline
#endif
#if ${P}_USE_FLOAT && ${P}_BOUNDED_TRIG
/* sin and cos of x without a branch, always inlined (gcc/clang) into the sin/cos table loop,
 * also at -Os: x = k pi/2 + r,
 * |r| <= pi/4, the polynomials of r, then the rotation by j pi/2 (j = k mod 4 in -2..2) as
 * exact factors a = cos(j pi/2), b = sin(j pi/2) in {-1, 0, 1}, so that a loop over angles
 * runs four lanes wide where the compiler vectorises (x86 SSE). |x| beyond $trig_range rad is
 * outside the documented range; NaN/inf give NaN. */
${P}_TRIG_INLINE void ${p}_sincos_bounded(float x, float *s, float *c) {
  const float shifter = 12582912.0f; /* 1.5 * 2^23: adding it rounds to an integer */
  float k = (x * 0.636619772367581343f + shifter) - shifter;
  float r = ((x - k * 1.5703125f) - k * 4.837512969970703125e-4f) - k * 7.54978995489188216e-8f;
  float z = r * r;
  float sp = r + r * z * ((-1.9515295891e-4f * z + 8.3321608736e-3f) * z - 1.6666654611e-1f);
  float cp = 1.0f - 0.5f * z + z * z * ((2.443315711809948e-5f * z - 1.388731625493765e-3f) * z + 4.166664568298827e-2f);
  float j = k - 4.0f * ((k * 0.25f + shifter) - shifter);
  float aj = fabsf(j);
  float odd = aj * (2.0f - aj);                         /* 1 for j = +-1, else 0 */
  float a = (1.0f - odd) * (1.0f - aj * (aj - 1.0f));   /* 1, 0, -1 for |j| = 0, 1, 2 */
  float b = j * odd;
  *s = a * sp + b * cp;
  *c = a * cp - b * sp;
}
/* A sin or cos outside the table (a solver's computed angle, the IK's seed and restarts): both
 * through one body, which -Os keeps out of line (inlined, each of the IK's took ~170 B of flash,
 * and separate sin and cos bodies ~240 B each). */
static inline float ${p}_sincos_pick(float x, int want_cos) {
  float s, c;
  ${p}_sincos_bounded(x, &s, &c);
  return (want_cos != 0) ? c : s;
}
static inline float ${p}_sin_bounded(float x) { return ${p}_sincos_pick(x, 0); }
static inline float ${p}_cos_bounded(float x) { return ${p}_sincos_pick(x, 1); }
/* atan2(y, x) without a library call (newlib's atan2f costs a call and its branches in a step
 * with a time budget, the IK's; the compiler's choice to inline or call: a call at -Os, ~10
 * instructions against ~120 B of flash per inlined copy): t = min(|x|, |y|)/max(|x|, |y|) in [0, 1], reduced above
 * tan(pi/8) by u = (t - 1)/(t + 1) (+ pi/4), Cephes' atanf polynomial of u, then the octant
 * and the quadrant by selects. Error <= $atan2_ulp ulp (tested); atan2(+-0, +-0) is 0 (libm: +-0
 * or +-pi); NaN or inf in give NaN. */
static inline float ${p}_atan2_bounded(float y, float x) {
  float ax = fabsf(x), ay = fabsf(y);
  float hi = (ay > ax) ? ay : ax;
  float lo = (ay > ax) ? ax : ay;
  float t = lo / ((hi > 0.0f) ? hi : 1.0f);
  float u = (t > 0.41421356237f) ? ((t - 1.0f) / (t + 1.0f)) : t;
  float z = u * u;
  float r = ((((8.05374449538e-2f * z) - 1.38776856032e-1f) * z + 1.99777106478e-1f) * z - 3.33329491539e-1f) * z * u + u;
  r = (t > 0.41421356237f) ? (r + 0.785398163397f) : r;
  r = (ay > ax) ? (1.57079632679f - r) : r;
  r = (x < 0.0f) ? (3.14159265359f - r) : r;
  r = (y < 0.0f) ? (-r) : r;
  return r + 0.0f * (x + y); /* x + y is NaN or inf for a NaN or inf input: the product NaN */
}
#endif
/* The sin and cos of a function's n angles, in one loop before its straight-line code (the
 * generated kinematics call it): branch-free bodies, so the loop vectorises where it can. */
${P}_TRIG_INLINE void ${p}_sincos_table(const ${p}_real *angle, ${p}_real *s, ${p}_real *c, int n) {
  int i;
  for (i = 0; i < n; ++i) {
#if ${P}_USE_FLOAT && ${P}_BOUNDED_TRIG
    ${p}_sincos_bounded(angle[i], &s[i], &c[i]);
#else
    s[i] = ${P}_SIN(angle[i]);
    c[i] = ${P}_COS(angle[i]);
#endif
  }
}
