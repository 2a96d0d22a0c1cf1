#ifndef ${P}_PTP_H
#define ${P}_PTP_H

#ifdef __cplusplus
extern "C" {
#endif

/* The one precision switch: ${P}_USE_FLOAT 1 is true single precision (f literals, no
 * promotion to double); 0 is double. The generator's default is below; -D${P}_USE_FLOAT=...
 * overrides it. */
#ifndef ${P}_USE_FLOAT
#define ${P}_USE_FLOAT $float_default
#endif
#if ${P}_USE_FLOAT
typedef float ${p}_real;
#define ${P}_LIT(x) x##f
#else
typedef double ${p}_real;
#define ${P}_LIT(x) x
#endif

/* Coefficients per segment: a0..a5 of theta(tau) = sum_j a_j tau^j (lower degrees zero). */
#define ${P}_PTP_NCOEF 6

/* Result of ${p}_ptp_eval. On anything but ${P}_PTP_OK, out[] is left unchanged. */
typedef enum {
  ${P}_PTP_OK = 0,           /* out[] holds theta, omega, eps at t */
  ${P}_PTP_BAD_ARGS = 1,     /* a NULL pointer, nseg < 1, or t is NaN */
  ${P}_PTP_BEFORE_START = 2, /* t < knots[0] */
  ${P}_PTP_AFTER_END = 3,    /* t > knots[nseg] */
  ${P}_PTP_BAD_KNOTS = 4     /* the knots of the segment holding t are not increasing (or NaN) */
} ${p}_ptp_status;

/* Evaluate a piecewise polynomial joint trajectory at time t.
 *   coeffs: nseg * ${P}_PTP_NCOEF reals, segment k at coeffs[${P}_PTP_NCOEF * k + j] = a_j
 *           (units: rad and s, as in the plan metadata);
 *   knots:  nseg + 1 strictly increasing knot times in s; segment k spans [knots[k], knots[k+1]];
 *   t:      time in s, knots[0] <= t <= knots[nseg]; at an inner knot the later segment is used;
 *   out:    out[0] = theta (rad), out[1] = omega (rad/s), out[2] = eps (rad/s^2).
 * Finds the segment by bisection (O(log nseg)), evaluates by Horner's rule. No heap, no
 * globals, reentrant; nseg must not exceed INT_MAX / ${P}_PTP_NCOEF. */
${p}_ptp_status ${p}_ptp_eval(const ${p}_real coeffs[], const ${p}_real knots[], int nseg, ${p}_real t,
    ${p}_real out[3]);

#ifdef __cplusplus
}
#endif

#endif /* ${P}_PTP_H */
