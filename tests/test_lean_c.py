"""Generated C beyond the interpreter comparison (issues 11, 12): the bounded-range sin/cos
against libm in ulp, the status contract and finiteness under a fuzz of extreme inputs
(ASan/UBSan), --prefix and stamp hygiene."""

import subprocess

import numpy as np
import pytest

from armgen.codegen.generate import (BOUNDED_ATAN2_ULP, BOUNDED_TRIG_RANGE, BOUNDED_TRIG_ULP, CodegenConfig, generate,
                                    write)
from armgen.codegen.stamp import comment_safe
from armgen.codegen.toolchain import STRICT_FLAGS
from armgen.errors import ArmgenError

from armgen.robot import load_robot, parse_robot, resolve_robot_path
from armgen.codegen.c_emitter import carried_entries, read_entries
from armgen.symbolic.model import STEP_FUNCTIONS, SymbolicModel

from conftest import require_tool

TRIG_SAMPLES = 2_000_001
FUZZ_TRIALS = 400  # per function and precision
# "Moderate" finite inputs (|x| ≤ 1e3, q within 1 rad of the limits): every output must be
# finite and every status OK; 1e3 keeps products of a few inputs far from float overflow.
MODERATE = 1e3

TRIG_HARNESS = r"""
#include <stdio.h>
#include <stdlib.h>
#include "{p}.c"
int main(int argc, char **argv) {{
  long n = atol(argv[1]), i;
  double range = atof(argv[2]);
  for (i = 0; i < n; ++i) {{
    float out[3];
    out[0] = (float)(-range + 2.0 * range * (double)i / (double)(n - 1));
    out[1] = {p}_sin_bounded(out[0]);
    out[2] = {p}_cos_bounded(out[0]);
    (void)fwrite(out, sizeof out, 1, stdout);
  }}
  return 0;
}}
"""


def test_bounded_trig_error_in_ulp(tmp_path):
    """|sin_bounded(x) − sin(x)| ≤ BOUNDED_TRIG_ULP ulp of the float result (x the float input,
    sin in double) over |x| ≤ BOUNDED_TRIG_RANGE; results below ½ in magnitude are measured in
    ulp(½) (absolute error 6e-8), since near a zero of sin the reduction's absolute error dominates."""
    require_tool("gcc")
    code = generate(CodegenConfig(load_robot("planar3"), precision="float"))
    write(code, tmp_path)
    (tmp_path / "h.c").write_text(TRIG_HARNESS.format(p="planar3"))
    exe = tmp_path / "h"
    subprocess.run(["gcc", "-std=c99", "-O2", "-DPLANAR3_BOUNDED_TRIG=1", f"-I{tmp_path}", str(tmp_path / "h.c"),
                    "-o", str(exe), "-lm"], check=True)
    raw = subprocess.run([str(exe), str(TRIG_SAMPLES), str(BOUNDED_TRIG_RANGE)], check=True, capture_output=True).stdout
    a = np.frombuffer(raw, dtype=np.float32).reshape(-1, 3).astype(float)
    for k, ref_fun in ((1, np.sin), (2, np.cos)):
        ref = ref_fun(a[:, 0])
        ulp = np.spacing(np.maximum(np.abs(ref), 0.5).astype(np.float32)).astype(float)
        assert (np.abs(a[:, k] - ref) / ulp).max() <= BOUNDED_TRIG_ULP


ATAN2_HARNESS = r"""
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include "{p}.c"
/* argv: n; stdin: n (y, x) float pairs; stdout: n atan2_bounded results */
int main(int argc, char **argv) {{
  long n = atol(argv[1]), i;
  for (i = 0; i < n; ++i) {{
    float yx[2], r;
    if (fread(yx, sizeof yx, 1, stdin) != 1) return 3;
    r = {p}_atan2_bounded(yx[0], yx[1]);
    (void)fwrite(&r, sizeof r, 1, stdout);
  }}
  return 0;
}}
"""
# (y, x) pairs per quadrant draw; the angles below this are measured in its ulp (absolute 1e-10).
ATAN2_SAMPLES = 400_000
ATAN2_SMALL = 2.0 ** -10


def test_bounded_atan2_error_in_ulp(tmp_path):
    """|atan2_bounded(y, x) − atan2(y, x)| ≤ BOUNDED_ATAN2_ULP ulp of the float result (the float
    inputs, atan2 in double, NumPy's) over angles all around the circle and magnitudes from 1e-6
    to 1e6; (0, 0) gives 0 and NaN or inf in give NaN."""
    require_tool("gcc")
    code = generate(CodegenConfig(load_robot("planar3"), precision="float"))
    write(code, tmp_path)
    (tmp_path / "h.c").write_text(ATAN2_HARNESS.format(p="planar3"))
    exe = tmp_path / "h"
    subprocess.run(["gcc", "-std=c99", "-O2", "-DPLANAR3_BOUNDED_TRIG=1", f"-I{tmp_path}", str(tmp_path / "h.c"),
                    "-o", str(exe), "-lm"], check=True)
    rng = np.random.default_rng(3)
    angle = rng.uniform(-np.pi, np.pi, ATAN2_SAMPLES)
    radius = 10.0 ** rng.uniform(-6, 6, ATAN2_SAMPLES)
    special = [(0.0, 0.0), (np.nan, 1.0), (1.0, np.nan), (np.inf, 1.0), (1.0, -np.inf), (0.0, -1.0), (1.0, 0.0),
               (-1.0, 0.0), (1e-30, 1.0)]
    yx = np.concatenate([np.stack([radius * np.sin(angle), radius * np.cos(angle)], axis=1),
                         np.array(special)]).astype(np.float32)
    raw = subprocess.run([str(exe), str(len(yx))], input=yx.tobytes(), check=True, capture_output=True).stdout
    got = np.frombuffer(raw, dtype=np.float32).astype(float)
    ref = np.arctan2(yx[:, 0].astype(float), yx[:, 1].astype(float))
    finite = np.all(np.isfinite(yx), axis=1)
    ulp = np.spacing(np.maximum(np.abs(ref), ATAN2_SMALL).astype(np.float32)).astype(float)
    assert (np.abs(got - ref)[finite] / ulp[finite]).max() <= BOUNDED_ATAN2_ULP
    assert got[len(radius)] == 0.0 and np.all(np.isnan(got[~finite]))


FLOOR_HARNESS = r"""
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include "{p}.c"
/* argv: n; stdin: n floats; stdout: n (floorf, {p}_floorf) pairs */
int main(int argc, char **argv) {{
  long n = atol(argv[1]), i;
  for (i = 0; i < n; ++i) {{
    float x, out[2];
    if (fread(&x, sizeof x, 1, stdin) != 1) return 3;
    out[0] = floorf(x);
    out[1] = {p}_floorf(x);
    (void)fwrite(out, sizeof out, 1, stdout);
  }}
  return 0;
}}
"""


def test_float_floor_is_libm_floor_to_the_bit(tmp_path):
    """<p>_floorf (the float build's floor, no library call) equals libm's floorf bit for bit:
    fractions of either sign, integers, the 2^22…2^24 edges where floats stop having
    fractions, ±0, tiny values, ±inf and NaN."""
    require_tool("gcc")
    code = generate(CodegenConfig(load_robot("planar3"), precision="float"))
    write(code, tmp_path)
    (tmp_path / "h.c").write_text(FLOOR_HARNESS.format(p="planar3"))
    exe = tmp_path / "h"
    subprocess.run(["gcc", "-std=c99", "-O2", f"-I{tmp_path}", str(tmp_path / "h.c"), "-o", str(exe), "-lm"],
                   check=True)
    rng = np.random.default_rng(13)
    edges = [2.0 ** 22, 2.0 ** 23, 2.0 ** 24]
    values = np.concatenate([rng.uniform(-50, 50, 100_000), 10.0 ** rng.uniform(-30, 30, 20_000) * rng.choice([-1, 1], 20_000),
                             np.arange(-20, 20, 0.25), [e + d for e in edges for d in (-1.5, -0.5, 0.0, 0.5, 1.0)],
                             [-e - d for e in edges for d in (-1.5, -0.5, 0.0, 0.5, 1.0)],
                             [0.0, -0.0, 1e-45, -1e-45, np.inf, -np.inf, np.nan]]).astype(np.float32)
    raw = subprocess.run([str(exe), str(len(values))], input=values.tobytes(), check=True, capture_output=True).stdout
    libm, ours = np.frombuffer(raw, dtype=np.float32).reshape(-1, 2).T
    assert np.array_equal(libm.view(np.uint32)[~np.isnan(libm)], ours.view(np.uint32)[~np.isnan(libm)])
    assert np.array_equal(np.isnan(libm), np.isnan(ours))


# draw()'s kind of an input: 1 a joint angle (near its limits), 2 a lock mask (0/1 by its
# documented domain), 0 anything else
DRAW_KIND = {"q": 1, "mask": 2}


def _fuzz_harness(model: SymbolicModel, p: str) -> str:
    """C that calls every generated function FUZZ_TRIALS times with inputs drawn from normal
    values and extremes (NaN, ±inf, ±1e30, denormals, 0, q exactly at a limit, q = 0) and
    counts contract violations per function."""
    robot = model.robot
    lines = [f'#include "{p}.h"', "#include <stdio.h>", "#include <math.h>",
             f"static const {p}_real qmin[{robot.n}] = {{{', '.join(repr(float(v)) for v in robot.qmin)}}};",
             f"static const {p}_real qmax[{robot.n}] = {{{', '.join(repr(float(v)) for v in robot.qmax)}}};",
             "static unsigned long state = 12345u;",
             "static double uniform(void) { state = state * 6364136223846793005ul + 1442695040888963407ul;"
             " return (double)((state >> 11) & 0xFFFFFFFFFul) / 68719476736.0; }",
             f"static {p}_real draw(int is_q, int k, int *extreme) {{",
             "  double u = uniform();",
             "  int pick = (int)(uniform() * 12.0);",
             "  if (u < 0.7) {",
             f"    if (is_q == 1) return ({p}_real)(qmin[k] - 0.5 + (qmax[k] - qmin[k] + 1.0) * uniform());",
             f"    if (is_q == 2) return ({p}_real)((uniform() < 0.8) ? 1.0 : 0.0);",
             f"    return ({p}_real)(uniform() * 2.0 - 0.5);",
             "  }",
             "  switch (pick) {",
             f"  case 0: *extreme = 1; return ({p}_real)NAN;",
             f"  case 1: *extreme = 1; return ({p}_real)INFINITY;",
             f"  case 2: *extreme = 1; return -({p}_real)INFINITY;",
             f"  case 3: *extreme = 1; return ({p}_real)1e30;",
             f"  case 4: *extreme = 1; return -({p}_real)1e30;",
             f"  case 5: return ({p}_real)1e-41;",
             f"  case 6: return ({p}_real)0.0;",
             f"  case 7: return (is_q == 1) ? qmin[k] : ({p}_real)1.0;",
             f"  case 8: return (is_q == 1) ? qmax[k] : ({p}_real)0.5;",
             f"  case 9: return ({p}_real)-1e-41;",
             f"  default: return is_q ? ({p}_real)0.0 : ({p}_real)0.1;",
             "  }", "}",
             f"static int all_finite(const {p}_real *x, int n) {{ int k; for (k = 0; k < n; ++k) "
             "{ if (!isfinite(x[k])) return 0; } return 1; }",
             "int main(void) {", "  int t, k, bad = 0, extreme;"]
    for name, func in model.functions().items():
        ins = [(func.name_in(k), func.sparsity_in(k).numel()) for k in range(func.n_in())]
        outs = [(func.name_out(k), func.sparsity_out(k).numel()) for k in range(func.n_out())]
        lines.append("  {")
        for nm, size in ins + outs:
            lines.append(f"    {p}_real {nm}_[{size}];")
        lines.append(f"    for (t = 0; t < {FUZZ_TRIALS}; ++t) {{")
        lines.append("      int in_ok = 1, out_ok = 1, moderate = 1, status = 0;")
        lines.append("      extreme = 0;")
        for index, (nm, size) in enumerate(ins):
            lines.append(f"      for (k = 0; k < {size}; ++k) {{ {nm}_[k] = draw({DRAW_KIND.get(nm, 0)}, k, &extreme); }}")
            if nm == "q":  # a step's status covers all of q, also angles J does not depend on
                lines.append(f"      in_ok = in_ok && all_finite({nm}_, {size});")
            else:  # an entry the function does not read (J's robot-constant ones) cannot matter
                for e in sorted(read_entries(func, index)):
                    lines.append(f"      in_ok = in_ok && isfinite({nm}_[{e}]);")
        lines.append("      moderate = in_ok && !extreme;")
        for nm, size in outs:
            lines.append(f"      for (k = 0; k < {size}; ++k) {{ {nm}_[k] = ({p}_real)-7.0; }}")
        args = [f"{nm}_[0]" if size == 1 else f"{nm}_" for nm, size in ins] + [f"{nm}_" for nm, _ in outs]
        call = f"{p}_{name}({', '.join(args)})"
        lines.append(f"      status = (int){call};" if name in STEP_FUNCTIONS else f"      {call};")
        for nm, size in outs:
            lines.append(f"      out_ok = out_ok && all_finite({nm}_, {size});")
        if name in STEP_FUNCTIONS:
            lines.append(f'      if ((status == 0) != (in_ok && out_ok)) {{ ++bad; printf("{name} status %d in_ok %d out_ok %d\\n", status, in_ok, out_ok); }}')
        lines.append(f'      if (moderate && (!out_ok || status != 0)) {{ ++bad; printf("{name} non-finite at moderate inputs\\n"); }}')
        lines.append("    }")
        carried = sorted(carried_entries(func)) if name in STEP_FUNCTIONS else []
        if carried:
            # one non-finite entry at a time, every other input moderate: the status does not
            # scan the entries whose NaN/inf the arithmetic carries to an output, so it must
            # say NONFINITE through the outputs
            lines.append("    for (t = 0; t < 8; ++t) {")
            for nm, size in ins:
                lines.append(f"      for (k = 0; k < {size}; ++k) {{ do {{ extreme = 0; {nm}_[k] = "
                             f"draw({DRAW_KIND.get(nm, 0)}, k, &extreme); }} while (extreme || !isfinite({nm}_[k])); }}")
            lines.append(f"      static const int which[{len(carried)}] = {{{', '.join(str(i) for i, _ in carried)}}};")
            lines.append(f"      static const int entry[{len(carried)}] = {{{', '.join(str(e) for _, e in carried)}}};")
            lines.append(f"      {p}_real *const inputs[{len(ins)}] = {{{', '.join(f'{nm}_' for nm, _ in ins)}}};")
            lines.append(f"      const {p}_real bad_values[3] = {{({p}_real)NAN, ({p}_real)INFINITY, -({p}_real)INFINITY}};")
            lines.append("      int e, v;")
            lines.append(f"      for (e = 0; e < {len(carried)}; ++e) {{")
            lines.append("        for (v = 0; v < 3; ++v) {")
            lines.append(f"          {p}_real keep = inputs[which[e]][entry[e]];")
            lines.append("          inputs[which[e]][entry[e]] = bad_values[v];")
            lines.append(f'          if ((int){call} == 0) {{ ++bad; printf("{name} OK with input %d[%d] = %g\\n", which[e], entry[e], (double)bad_values[v]); }}')
            lines.append("          inputs[which[e]][entry[e]] = keep;")
            lines.append("        }")
            lines.append("      }")
            lines.append("    }")
        lines.append("  }")
    lines += ['  printf("violations %d\\n", bad);', "  return bad != 0;", "}"]
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("name", ["planar3", "modular8"])
@pytest.mark.parametrize("precision", ["double", "float"])
def test_fuzz_extreme_inputs_status_contract(name, precision, tmp_path):
    """Every function: with moderate finite inputs (q anywhere within 1 rad of the limits,
    exactly at them, the singular q = 0, denormals) all outputs are finite and steps return OK;
    with any NaN/inf/1e30 input a step returns OK only if every input and output is finite —
    and NONFINITE whenever one it reads is not (J's robot-constant entries are not read). The
    status does not scan the input entries whose NaN/inf the arithmetic carries to an output
    (generate._status_check), so each of those gets NaN, +inf and −inf in turn with every
    other input moderate, and the step must still say NONFINITE. Under ASan/UBSan."""
    require_tool("gcc")
    model = SymbolicModel(load_robot(name))
    code = generate(CodegenConfig(model.robot, precision=precision))
    write(code, tmp_path)
    (tmp_path / "fuzz.c").write_text(_fuzz_harness(model, code.prefix))
    exe = tmp_path / "fuzz"
    flags = [f for f in STRICT_FLAGS if f not in ("-Wdouble-promotion", "-Wfloat-conversion")]
    subprocess.run(["gcc", *flags, "-O1", "-g", "-fsanitize=address,undefined", "-fno-sanitize-recover=all",
                    f"-I{tmp_path}", str(tmp_path / "fuzz.c"), str(tmp_path / f"{code.prefix}.c"), "-o", str(exe),
                    "-lm"], check=True, capture_output=True, text=True)
    run = subprocess.run([str(exe)], capture_output=True, text=True)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    assert "violations 0" in run.stdout


@pytest.mark.parametrize("prefix", ["math", "sin", "int", "_", "_Arm", "__x", "while", "stdio"])
def test_prefix_rejects_keywords_reserved_and_library_names(prefix):
    with pytest.raises(ArmgenError, match="--prefix"):
        generate(CodegenConfig(load_robot("planar3"), prefix=prefix))


def test_user_text_in_comments_is_sanitised():
    hostile = "x */ int injected = 42; /*\n??/"
    safe = comment_safe(hostile)
    assert "*" not in safe and "\n" not in safe and "?" not in safe
    text = resolve_robot_path("planar3").read_text()
    robot = parse_robot(text, "evil */ int x; /*.toml")
    code = generate(CodegenConfig(robot))
    for text in (code.files["planar3.h"], code.files["planar3.c"]):
        assert "int x;" not in text


def test_zghal_is_finite_exactly_at_and_beyond_the_limits():
    m = SymbolicModel(load_robot("modular8"))
    f = m.function("zghal")
    for q in (m.robot.qmin, m.robot.qmax, m.robot.qmax + 1.0, m.robot.qmin - 1.0):
        h, g = f(q)
        assert np.isfinite(float(h)) and np.all(np.isfinite(np.array(g)))


def test_header_refuses_fast_math(tmp_path):
    """-ffast-math would fold the status probe's x * 0 to 0 and the NaN tests to false: the
    generated header stops such a build with a message instead."""
    require_tool("gcc")
    code = generate(CodegenConfig(load_robot("planar3")))
    write(code, tmp_path)
    (tmp_path / "use.c").write_text('#include "planar3.h"\nint main(void) { return 0; }\n')
    for flag in ("-ffast-math", "-ffinite-math-only"):
        proc = subprocess.run(["gcc", *STRICT_FLAGS, flag, "-I", str(tmp_path), "-c", str(tmp_path / "use.c"), "-o",
                               str(tmp_path / "use.o")], capture_output=True, text=True)
        assert proc.returncode != 0 and "needs IEEE 754 semantics" in proc.stderr, (flag, proc.stderr)
    subprocess.run(["gcc", *STRICT_FLAGS, "-I", str(tmp_path), "-c", str(tmp_path / "use.c"), "-o",
                    str(tmp_path / "use.o")], check=True)

