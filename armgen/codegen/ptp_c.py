"""C99 evaluator for the PTP planner's segment polynomials (spec 40, "Outputs").

The firmware stores, per joint, the knot times ``t_0 < … < t_n`` and six coefficients per
segment (``a_0 … a_5`` of ``θ(τ) = Σ a_j τ^j``, ``τ = t − t_k``, exactly as in the plan's
metadata ``segments.coefficients``) and calls ``<prefix>_ptp_eval`` to play the plan back:
θ, ω, ε at time ``t`` by Horner's rule. No heap, no globals, no math library.

Output is deterministic: ``<prefix>_ptp.h`` and ``<prefix>_ptp.c`` (their C text in
``armgen/data/templates/codegen/ptp.h`` and ``ptp.c``), stamped with the preamble of
:mod:`armgen.codegen.stamp`. Precision: ``<P>_USE_FLOAT`` 1 is true single precision
(``f`` literals, no promotion), 0 is double; the generator's ``precision`` only sets the
default, ``-D<P>_USE_FLOAT=…`` overrides it.
"""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

from ..data import render_template
from ..errors import ArmgenError, excerpt
from ..fileio import write_text_atomic
from .stamp import c_file, c_preamble

PRECISIONS = ("double", "float")
SOURCE_NAME = "armgen/codegen/ptp_c.py"

def render_ptp_evaluator(prefix: str = "armgen", precision: str = "double") -> dict[str, str]:
    """The evaluator's files as ``{name: text}`` (nothing is written)."""
    if precision not in PRECISIONS:
        raise ArmgenError(f"precision {excerpt(repr(precision))}: choose one of {', '.join(PRECISIONS)}")
    if not re.fullmatch(r"[a-z_][a-z0-9_]*", prefix):
        raise ArmgenError(f"prefix {excerpt(repr(prefix))}: use a C identifier in lower case (letters, digits, _; not starting with a digit)")
    header = render_template("codegen/ptp.h", p=prefix, P=prefix.upper(), float_default=1 if precision == "float" else 0)
    source = render_template("codegen/ptp.c", p=prefix, P=prefix.upper())
    # the stamp's digest: of the two files' texts after the preamble, each with its last line break
    digest = hashlib.sha256((header + "\n" + source + "\n").encode()).hexdigest()
    preamble = c_preamble(SOURCE_NAME, digest, "armgen PTP segment-polynomial evaluator (theta, omega, eps from coefficients)",
                          regenerate="armgen gen-ptp")
    return {f"{prefix}_ptp.h": c_file(preamble, header), f"{prefix}_ptp.c": c_file(preamble, source)}


def generate_ptp_evaluator(out_dir: str | Path, prefix: str = "armgen", precision: str = "double") -> list[Path]:
    """Write ``<prefix>_ptp.h`` and ``<prefix>_ptp.c`` into ``out_dir``; returns their paths."""
    out_dir = Path(out_dir)
    paths = []
    for name, text in render_ptp_evaluator(prefix, precision).items():
        path = out_dir / name
        write_text_atomic(path, text)
        paths.append(path)
    return paths
