/*
 * Fast single-precision sinf/cosf for the Cortex-M4F firmware, linked in front of newlib's
 * with `-Wl,--wrap=sinf -Wl,--wrap=cosf`: every call the generated kinematics and the
 * controller make goes to __wrap_sinf/__wrap_cosf, which handle |x| <= FW_TRIG_FAST_MAX
 * themselves and pass anything else (large, inf, NaN) to newlib (__real_sinf/__real_cosf).
 *
 * Why: newlib's sinf/cosf reduce every |x| > pi/4 through __ieee754_rem_pio2f (arbitrary
 * range, ~100 instructions); joint angles never leave a few radians, so a Cody-Waite
 * reduction by pi/2 in three parts (the first two with 12 significant bits, so k * part is
 * exact) and the Cephes minimax polynomials on [-pi/4, pi/4] do the same job in ~30
 * instructions. Accuracy on [-FW_TRIG_FAST_MAX, FW_TRIG_FAST_MAX]: within 2 ulp of the exact
 * value (measured 1.6 ulp, 9.3e-8 absolute; tests/test_firmware.py checks it against double
 * sin/cos on 2e6 points); newlib's own sinf/cosf are within 1 ulp.
 *
 * Build with -DFW_FASTMATH_SELFTEST to compile the functions without the wrap (host tests).
 */
#include <math.h>
#include <stdint.h>

#define FW_TRIG_FAST_MAX 8.0f /* covers joint angles (|q| <= 2.5 pi) and path angles [0, 2 pi] */
#define FW_SIN_TINY 2.44140625e-4f /* 2^-12: sin x = x to within half an ulp below */

#ifdef FW_FASTMATH_SELFTEST
#define FW_SIN fw_fast_sinf
#define FW_COS fw_fast_cosf
#define REAL_SIN sinf
#define REAL_COS cosf
float fw_fast_sinf(float x);
float fw_fast_cosf(float x);
#else
#define FW_SIN __wrap_sinf
#define FW_COS __wrap_cosf
#define REAL_SIN __real_sinf
#define REAL_COS __real_cosf
float __real_sinf(float x);
float __real_cosf(float x);
float __wrap_sinf(float x);
float __wrap_cosf(float x);
#endif

static const float TWO_OVER_PI = 0.636619746685028076171875f;
static const float PIO2_1 = 1.5703125f;                    /* pi/2 = PIO2_1 + PIO2_2 + PIO2_3 */
static const float PIO2_2 = 4.837512969970703125e-4f;
static const float PIO2_3 = 7.549790126404332e-8f;

/* x = j pi/2 + r, |r| <= pi/4 (+ rounding); returns j */
static int32_t reduce(float x, float *r) {
  float y = x * TWO_OVER_PI;
  int32_t j = (int32_t)(y + (y >= 0.0f ? 0.5f : -0.5f));
  float fj = (float)j;
  *r = ((x - fj * PIO2_1) - fj * PIO2_2) - fj * PIO2_3;
  return j;
}

static float sin_poly(float r) { /* Cephes sinf, |r| <= pi/4 */
  float z = r * r;
  return r + r * z * (-1.6666654611e-1f + z * (8.3321608736e-3f + z * -1.9515295891e-4f));
}

static float cos_poly(float r) { /* Cephes cosf, |r| <= pi/4 */
  float z = r * r;
  return 1.0f - 0.5f * z + z * z * (4.166664568298827e-2f + z * (-1.388731625493765e-3f + z * 2.443315711809948e-5f));
}

float FW_SIN(float x) {
  float r;
  if (!(fabsf(x) <= FW_TRIG_FAST_MAX)) {
    return REAL_SIN(x);
  }
  if (fabsf(x) < FW_SIN_TINY) {
    return x; /* keeps the sign of -0 */
  }
  switch ((uint32_t)reduce(x, &r) & 3u) {
    case 0u: return sin_poly(r);
    case 1u: return cos_poly(r);
    case 2u: return -sin_poly(r);
    default: return -cos_poly(r);
  }
}

float FW_COS(float x) {
  float r;
  if (!(fabsf(x) <= FW_TRIG_FAST_MAX)) {
    return REAL_COS(x);
  }
  switch ((uint32_t)reduce(x, &r) & 3u) {
    case 0u: return cos_poly(r);
    case 1u: return -sin_poly(r);
    case 2u: return -cos_poly(r);
    default: return sin_poly(r);
  }
}
