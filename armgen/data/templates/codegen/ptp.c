#include "${p}_ptp.h"

#include <stddef.h>

${p}_ptp_status ${p}_ptp_eval(const ${p}_real coeffs[], const ${p}_real knots[], int nseg, ${p}_real t,
    ${p}_real out[3]) {
  int lo, hi;
  const ${p}_real *a;
  ${p}_real tau;
  if (coeffs == NULL || knots == NULL || out == NULL || nseg < 1 || t != t) {
    return ${P}_PTP_BAD_ARGS;
  }
  if (t < knots[0]) {
    return ${P}_PTP_BEFORE_START;
  }
  if (t > knots[nseg]) {
    return ${P}_PTP_AFTER_END;
  }
  /* largest lo in [0, nseg - 1] with knots[lo] <= t */
  lo = 0;
  hi = nseg;
  while (hi - lo > 1) {
    int mid = lo + (hi - lo) / 2;
    if (knots[mid] <= t) {
      lo = mid;
    } else {
      hi = mid;
    }
  }
  if (!(knots[lo] < knots[lo + 1]) || !(knots[lo] <= t)) {
    return ${P}_PTP_BAD_KNOTS;
  }
  a = coeffs + ${P}_PTP_NCOEF * lo;
  tau = t - knots[lo];
  out[0] = a[0] + tau * (a[1] + tau * (a[2] + tau * (a[3] + tau * (a[4] + tau * a[5]))));
  out[1] = a[1] + tau * (${P}_LIT(2.0) * a[2] + tau * (${P}_LIT(3.0) * a[3]
      + tau * (${P}_LIT(4.0) * a[4] + tau * (${P}_LIT(5.0) * a[5]))));
  out[2] = ${P}_LIT(2.0) * a[2] + tau * (${P}_LIT(6.0) * a[3] + tau * (${P}_LIT(12.0) * a[4]
      + tau * (${P}_LIT(20.0) * a[5])));
  return ${P}_PTP_OK;
}
