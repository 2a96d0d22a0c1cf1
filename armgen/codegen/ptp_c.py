"""C99 evaluator for the PTP planner's segment polynomials (spec 40, "Outputs").

The firmware stores, per joint, the knot times ``t_0 < … < t_n`` and six coefficients per
segment (``a_0 … a_5`` of ``θ(τ) = Σ a_j τ^j``, ``τ = t − t_k``, exactly as in the plan's
metadata ``segments.coefficients``) and calls ``<prefix>_ptp_eval`` to play the plan back:
θ, ω, ε at time ``t`` by Horner's rule. No heap, no globals, no math library.

Output is deterministic: ``<prefix>_ptp.h`` and ``<prefix>_ptp.c``, stamped with the preamble
of :mod:`armgen.codegen.stamp`. Precision: ``<P>_USE_FLOAT`` 1 is true single precision
(``f`` literals, no promotion), 0 is double; the generator's ``precision`` only sets the
default, ``-D<P>_USE_FLOAT=…`` overrides it.
"""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

from ..errors import ArmgenError, excerpt
from ..fileio import write_text_atomic
from .stamp import c_preamble

PRECISIONS = ("double", "float")
SOURCE_NAME = "armgen/codegen/ptp_c.py"

_HEADER = """#ifndef {P}_PTP_H
#define {P}_PTP_H

#ifdef __cplusplus
extern "C" {{
#endif

/* The one precision switch: {P}_USE_FLOAT 1 is true single precision (f literals, no
 * promotion to double); 0 is double. The generator's default is below; -D{P}_USE_FLOAT=...
 * overrides it. */
#ifndef {P}_USE_FLOAT
#define {P}_USE_FLOAT {float_default}
#endif
#if {P}_USE_FLOAT
typedef float {p}_real;
#define {P}_LIT(x) x##f
#else
typedef double {p}_real;
#define {P}_LIT(x) x
#endif

/* Coefficients per segment: a0..a5 of theta(tau) = sum_j a_j tau^j (lower degrees zero). */
#define {P}_PTP_NCOEF 6

/* Result of {p}_ptp_eval. On anything but {P}_PTP_OK, out[] is left unchanged. */
typedef enum {{
  {P}_PTP_OK = 0,           /* out[] holds theta, omega, eps at t */
  {P}_PTP_BAD_ARGS = 1,     /* a NULL pointer, nseg < 1, or t is NaN */
  {P}_PTP_BEFORE_START = 2, /* t < knots[0] */
  {P}_PTP_AFTER_END = 3,    /* t > knots[nseg] */
  {P}_PTP_BAD_KNOTS = 4     /* the knots of the segment holding t are not increasing (or NaN) */
}} {p}_ptp_status;

/* Evaluate a piecewise polynomial joint trajectory at time t.
 *   coeffs: nseg * {P}_PTP_NCOEF reals, segment k at coeffs[{P}_PTP_NCOEF * k + j] = a_j
 *           (units: rad and s, as in the plan metadata);
 *   knots:  nseg + 1 strictly increasing knot times in s; segment k spans [knots[k], knots[k+1]];
 *   t:      time in s, knots[0] <= t <= knots[nseg]; at an inner knot the later segment is used;
 *   out:    out[0] = theta (rad), out[1] = omega (rad/s), out[2] = eps (rad/s^2).
 * Finds the segment by bisection (O(log nseg)), evaluates by Horner's rule. No heap, no
 * globals, reentrant; nseg must not exceed INT_MAX / {P}_PTP_NCOEF. */
{p}_ptp_status {p}_ptp_eval(const {p}_real coeffs[], const {p}_real knots[], int nseg, {p}_real t,
    {p}_real out[3]);

#ifdef __cplusplus
}}
#endif

#endif /* {P}_PTP_H */
"""

_SOURCE = """#include "{p}_ptp.h"

#include <stddef.h>

{p}_ptp_status {p}_ptp_eval(const {p}_real coeffs[], const {p}_real knots[], int nseg, {p}_real t,
    {p}_real out[3]) {{
  int lo, hi;
  const {p}_real *a;
  {p}_real tau;
  if (coeffs == NULL || knots == NULL || out == NULL || nseg < 1 || t != t) {{
    return {P}_PTP_BAD_ARGS;
  }}
  if (t < knots[0]) {{
    return {P}_PTP_BEFORE_START;
  }}
  if (t > knots[nseg]) {{
    return {P}_PTP_AFTER_END;
  }}
  /* largest lo in [0, nseg - 1] with knots[lo] <= t */
  lo = 0;
  hi = nseg;
  while (hi - lo > 1) {{
    int mid = lo + (hi - lo) / 2;
    if (knots[mid] <= t) {{
      lo = mid;
    }} else {{
      hi = mid;
    }}
  }}
  if (!(knots[lo] < knots[lo + 1]) || !(knots[lo] <= t)) {{
    return {P}_PTP_BAD_KNOTS;
  }}
  a = coeffs + {P}_PTP_NCOEF * lo;
  tau = t - knots[lo];
  out[0] = a[0] + tau * (a[1] + tau * (a[2] + tau * (a[3] + tau * (a[4] + tau * a[5]))));
  out[1] = a[1] + tau * ({P}_LIT(2.0) * a[2] + tau * ({P}_LIT(3.0) * a[3]
      + tau * ({P}_LIT(4.0) * a[4] + tau * ({P}_LIT(5.0) * a[5]))));
  out[2] = {P}_LIT(2.0) * a[2] + tau * ({P}_LIT(6.0) * a[3] + tau * ({P}_LIT(12.0) * a[4]
      + tau * ({P}_LIT(20.0) * a[5])));
  return {P}_PTP_OK;
}}
"""


def render_ptp_evaluator(prefix: str = "armgen", precision: str = "double") -> dict[str, str]:
    """The evaluator's files as ``{name: text}`` (nothing is written)."""
    if precision not in PRECISIONS:
        raise ArmgenError(f"precision {excerpt(repr(precision))}: choose one of {', '.join(PRECISIONS)}")
    if not re.fullmatch(r"[a-z_][a-z0-9_]*", prefix):
        raise ArmgenError(f"prefix {excerpt(repr(prefix))}: use a C identifier in lower case (letters, digits, _; not starting with a digit)")
    fmt = {"p": prefix, "P": prefix.upper(), "float_default": 1 if precision == "float" else 0}
    header, source = _HEADER.format(**fmt), _SOURCE.format(**fmt)
    digest = hashlib.sha256((header + source).encode()).hexdigest()
    preamble = c_preamble(SOURCE_NAME, digest, "armgen PTP segment-polynomial evaluator (theta, omega, eps from coefficients)",
                          regenerate="armgen gen-ptp")
    return {f"{prefix}_ptp.h": f"{preamble}\n{header}", f"{prefix}_ptp.c": f"{preamble}\n{source}"}


def generate_ptp_evaluator(out_dir: str | Path, prefix: str = "armgen", precision: str = "double") -> list[Path]:
    """Write ``<prefix>_ptp.h`` and ``<prefix>_ptp.c`` into ``out_dir``; returns their paths."""
    out_dir = Path(out_dir)
    paths = []
    for name, text in render_ptp_evaluator(prefix, precision).items():
        path = out_dir / name
        write_text_atomic(path, text)
        paths.append(path)
    return paths
