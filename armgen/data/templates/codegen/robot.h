#ifndef ${P}_H
#define ${P}_H

#ifdef __cplusplus
extern "C" {
#endif

#define ${P}_NDOF $ndof  /* joints */
#define ${P}_NTASK $ntask  /* task-space rows used by criteria and steps */
#define ${P}_ROBOT_SHA256 "$robot_sha256"

/* The status probes (x * 0 is NaN only for NaN/inf), fmin/fmax and the Sturm counts rely on
 * IEEE 754 arithmetic, which -ffast-math / -ffinite-math-only give up. */
#if defined(__FAST_MATH__) || (defined(__FINITE_MATH_ONLY__) && (__FINITE_MATH_ONLY__ != 0))
#error "${p}.h needs IEEE 754 semantics: compile without -ffast-math and -ffinite-math-only"
#endif

/* The one precision switch: ${P}_USE_FLOAT 1 is true single precision (sinf, f literals,
 * no promotion); 0 is double. The generator's default is below; -D${P}_USE_FLOAT=… overrides. */
#ifndef ${P}_USE_FLOAT
#define ${P}_USE_FLOAT $float_default
#endif
/* ${P}_BOUNDED_TRIG 1 (float only): sin/cos by the generated bounded-range polynomials
 * (${p}_sin_bounded/${p}_cos_bounded below: error <= $trig_ulp ulp for |x| <= $trig_range rad,
 * tested; NaN/inf in give NaN out) instead of newlib's sinf/cosf, and atan2 by ${p}_atan2_bounded
 * (<= $atan2_ulp ulp) instead of atan2f. Default 0. */
#ifndef ${P}_BOUNDED_TRIG
#define ${P}_BOUNDED_TRIG 0
#endif
#if ${P}_USE_FLOAT
typedef float ${p}_real;
#define ${P}_LIT(x) x##f
$float_math_macros
#if ${P}_BOUNDED_TRIG
$bounded_trig_macros
#else
$libm_trig_macros
#endif
#else
typedef double ${p}_real;
#define ${P}_LIT(x) x
$double_math_macros
#endif

#include <math.h>

$speed_limits

$lean_math

/* Result of the functions that can fail. */
typedef enum {
  ${P}_OK = 0,             /* output is finite */
  ${P}_NONFINITE = 1,      /* output holds NaN/inf: a non-finite input, or an overflow */
  ${P}_NOT_CONVERGED = 2,  /* ${p}_ik only: no q within the tolerances; the outputs hold the closest reached */
  ${P}_BAD_TARGET = 3      /* ${p}_ik only: T_target is not a pose (${p}_is_pose); no step taken */
} ${p}_status;
$pose_check
/* Matrices are column-major: element (r, c) of an R x C matrix M is M[r + R*c].
 * Scalar inputs are passed by value, scalar outputs by pointer. Outputs must not overlap
 * inputs. No heap, no globals, reentrant; locals are the WORK_REALS scalars listed. */

$prototypes

#ifdef __cplusplus
}
#endif

#endif /* ${P}_H */
