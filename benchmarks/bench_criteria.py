#!/usr/bin/env python3
"""Criteria benchmarks of the generated C (issue 12): measurements, not tests.

    python benchmarks/bench_criteria.py [--robot modular8] [--previous 85a2322] [--out benchmarks/results/criteria.json]

In one run, for the current generator and for the previous C (the checked-in
``generated/<robot>/`` at the ``--previous`` commit, read with ``git show``: the Cauchy–Binet
construction of the manipulability family, before issue 12), built and measured the same way:

1. Cortex-M4F, ``arm-none-eabi-gcc -Os`` float: text bytes per function (``.text.<prefix>_<fn>``
   with ``-ffunction-sections``) and in total, and executed instructions per call of every
   function under ``qemu-system-arm -M mps2-an386 -icount shift=0`` (SysTick on the CPU clock,
   calibrated in the same run; the bench_kinematics method). Each function is called through a
   volatile pointer from a wrapper that reads one of 16 seeded input sets
   (``armgen.verification.samples.function_inputs``, the inputs of the compiled-vs-interpreter
   comparison); the same wrapper calling a stub of the same signature is subtracted, and the
   stub's own instructions (``bx lr``, plus ``movs r0, #0`` for a status) added back. The
   current code is measured with newlib's ``sinf``/``cosf`` and with ``<P>_BOUNDED_TRIG=1``.
2. x86-64 gcc -O2 float, callgrind: ``fk_jacobian`` against CasADi's C of the same geometric
   Jacobian (CasADi's CodeGenerator on ``SymbolicModel(robot).function('fk_jacobian')``,
   ``casadi_real=float``, sin/cos mapped to ``sinf``/``cosf``).
3. snake12 (25 DOF), every function: generation time, host ``gcc -O2 -c`` time (double and
   float), M4 text in total.
4. Op counts (``flops`` of the emitted code) of every function for spatial test chains of
   n = 6…40 joints and the fitted growth exponent (least squares of log flops on log n over
   n ≥ 12).

The previous figures of rows the old code cannot give (snake12 had none of the criteria; the
old exponent) are the issue's, marked "(issue)". Bars (reported, never asserted) are in BARS.

``--quick`` (seconds): the current code only (no previous build, so no git history needed),
the M4 in its bounded-trig build, small call counts, snake12 generated but not compiled,
chains up to n = 16. The exit status is bench_kinematics.py's: 1 when a measurement failed, 4 when a tool is
missing.
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import casadi as ca
import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
for path in (str(REPO), str(HERE)):
    if path not in sys.path:
        sys.path.insert(0, path)

from bench_kinematics import (FIRMWARE, QEMU_BASE, Report, Skip, arm_flags, arm_object, bar_note,  # noqa: E402
                              build_host_driver, callgrind_instr, finish, run, tool, use_quick_counts)
from armgen.codegen.generate import CodegenConfig, generate, write  # noqa: E402
from armgen.codegen.toolchain import STRICT_FLAGS  # noqa: E402
from armgen.robot import load_robot, parse_robot  # noqa: E402
from armgen.symbolic.model import SymbolicModel  # noqa: E402
from armgen.verification.samples import function_inputs, joint_samples  # noqa: E402

PREVIOUS_REV = "85a2322"  # main before issue 12: the Cauchy–Binet criteria
# Issue 12's bars (modular8 unless named); reported against, never asserted.
BARS = {
    "m4_text_total": 100 * 1024,
    "m4_instr": {"step_wgpm": 10_000, "ft_index": 6_000, "step_fault": 6_000, "manipulability": 3_500,
                 "joint_manipulability": 5_000, "fk_jacobian": 1_000},
    "x86_float_fkj_over_casadi": 0.8,
    "snake12_gen_seconds": 10.0,
    "snake12_compile_seconds": 30.0,
}
# Figures the old code cannot give in this run (issue 12's text).
ISSUE_PREVIOUS = {"snake12": "criteria not generated (n >= 14)", "exponent": "about 6"}
INPUT_SETS = 16  # seeded input sets per function, cycled by the timing loop
ARM_NCALLS = 512  # calls per function and timing loop (a multiple of INPUT_SETS)
CHAIN_DOFS = (6, 8, 10, 12, 16, 20, 25, 30, 40)
FIT_FROM_DOF = 12
QUICK_ARM_NCALLS = 32  # --quick: two cycles of the input sets
QUICK_CHAIN_DOFS = (6, 12, 16)  # --quick: two points from FIT_FROM_DOF on, for the fit
HOST_OPT = "-O2"
SECTIONS = ("cortex_m4f", "x86", "snake12", "growth")


def chain_toml(dof: int) -> str:
    """A spatial test chain (as tests/test_criteria_scaling.py): alternating ±90° twists, 80 mm links."""
    joints = "\n".join(
        f'[[joints]]\nname = "j{i}"\ntype = "revolute"\na = 80\nd = {0 if i % 2 else 40}\n'
        f"alpha = {90 if i % 2 else -90}\noffset = 0\nqlim = [-150, 150]\n" for i in range(dof))
    return (f'name = "chain{dof}"\nconvention = "standard"\n[units]\nlength = "mm"\nangle = "deg"\n'
            f"{joints}")


def previous_code(rev: str, name: str, out: Path) -> Path:
    """generated/<name>/ at ``rev`` (git show), or Skip."""
    tool("git")
    out.mkdir(parents=True)
    for suffix in (".c", ".h"):
        proc = subprocess.run(["git", "-C", str(REPO), "show", f"{rev}:generated/{name}/{name}{suffix}"],
                              capture_output=True)
        if proc.returncode != 0:
            raise Skip(f"skipped: git show {rev}:generated/{name}/{name}{suffix} failed (not a git checkout?)")
        (out / f"{name}{suffix}").write_bytes(proc.stdout)
    return out


def _c_literal(value: float) -> str:
    return f"{float(np.float32(value))!r}f"


def return_types(header: str, prefix: str, names: list[str]) -> dict[str, str]:
    """Each function's C return type, as its prototype in the generated header declares it."""
    types = {}
    for name in names:
        match = re.search(rf"^(\w+) {prefix}_{name}\(", header, re.M)
        if match is None:
            raise RuntimeError(f"no prototype of {prefix}_{name} in the generated header")
        types[name] = match.group(1)
    return types


def arm_driver(model: SymbolicModel, prefix: str, names: list[str], returns: dict[str, str], ncalls: int) -> str:
    """Timing firmware: per function a wrapper reading one of INPUT_SETS input sets and calling
    through a volatile pointer that is either the function or a stub of the same signature
    (``returns``: the return types of the header's prototypes)."""
    P = prefix.upper()
    functions = model.functions()
    lines = ["#include <stdint.h>", f'#include "{prefix}.h"', '#include "semihost.h"',
             "#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)",
             "#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)",
             "#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)",
             "#define SYST_MASK 0xFFFFFFu", f"typedef {prefix}_real real_t;",
             f"static real_t out_buf[{max(functions[n].size1_out(k) * functions[n].size2_out(k) for n in names for k in range(functions[n].n_out()))}];",
             "volatile real_t bench_sink;", "typedef void (*wrapper_fn)(uint32_t set);"]
    q_all, _ = joint_samples(model.robot, INPUT_SETS, 1212)
    for index, name in enumerate(names):
        func = functions[name]
        rng = np.random.default_rng([1212, index])
        calls = [function_inputs(func, model.robot, q, rng, "float") for q in q_all]
        params, args = [], []
        for k in range(func.n_in()):
            numel = func.sparsity_in(k).numel()
            if numel == 1:
                values = ", ".join(_c_literal(c[k]) for c in calls)
                lines.append(f"static const real_t in_{name}_{k}[{INPUT_SETS}] = {{{values}}};")
                params.append("real_t")
                args.append(f"in_{name}_{k}[set]")
            else:
                rows = ", ".join("{" + ", ".join(_c_literal(v) for v in np.ravel(c[k], order="F")) + "}" for c in calls)
                lines.append(f"static const real_t in_{name}_{k}[{INPUT_SETS}][{numel}] = {{{rows}}};")
                params.append("const real_t *")
                args.append(f"in_{name}_{k}[set]")
        for k in range(func.n_out()):
            params.append("real_t *")
            args.append("out_buf")
        ret = returns[name]
        stub_params = ", ".join(f"{t} a{i}" for i, t in enumerate(params))
        stub_body = " ".join(f"(void)a{i};" for i in range(len(params)))
        stub_ret = f" return {P}_OK;" if ret != "void" else ""
        lines += [f"typedef {ret} (*sig_{name})({', '.join(params)});",
                  f"__attribute__((noinline)) static {ret} stub_{name}({stub_params}) {{ {stub_body}{stub_ret} }}",
                  f"static sig_{name} volatile ptr_{name};",
                  f"__attribute__((noinline)) static void call_{name}(uint32_t set) {{ "
                  f"(void)ptr_{name}({', '.join(args)}); }}"]
    lines += ["static wrapper_fn volatile selected;",
              "__attribute__((noinline)) static uint32_t timed_loop(uint32_t ncalls) {",
              "  wrapper_fn fn = selected; uint32_t i, t0, t1;",
              "  t0 = SYST_CVR;",
              f"  for (i = 0; i < ncalls; ++i) {{ fn(i & {INPUT_SETS - 1}u); }}",
              "  t1 = SYST_CVR;", "  return (t0 - t1) & SYST_MASK;", "}",
              "__attribute__((noinline)) static uint32_t timed_calib(uint32_t iterations) {",
              "  uint32_t t0, t1;", "  t0 = SYST_CVR;",
              '  __asm__ volatile("1: subs %0, %0, #1\\n\\tbne 1b" : "+r"(iterations)::"cc");',
              "  t1 = SYST_CVR;", "  return (t0 - t1) & SYST_MASK;", "}",
              "int main(void) {", "  uint32_t small, large;",
              "  SYST_RVR = SYST_MASK; SYST_CVR = 0u; SYST_CSR = 5u;",
              "  small = timed_calib(1000u); large = timed_calib(101000u);",
              '  sh_put_kv("calib_insns", 2u * 100000u); sh_put_kv("calib_ticks", large - small);',
              f'  sh_put_kv("ncalls", {ncalls}u);']
    for index, name in enumerate(names):
        lines += [f"  selected = call_{name};",
                  f"  ptr_{name} = stub_{name}; sh_put_kv(\"stub_{index}\", timed_loop({ncalls}u));",
                  f"  ptr_{name} = {prefix}_{name}; sh_put_kv(\"fn_{index}\", timed_loop({ncalls}u));"]
    lines += ["  bench_sink = out_buf[0];", '  sh_puts("done\\n");', "  return 0;", "}"]
    return "\n".join(lines) + "\n"


def m4_instructions(work: Path, gen_dir: Path, model: SymbolicModel, prefix: str, names: list[str], obj: Path,
                    defines: tuple[str, ...] = (), ncalls: int = ARM_NCALLS) -> dict[str, float]:
    gcc = tool("arm-none-eabi-gcc")
    tool("qemu-system-arm")
    tag = "_".join(d.split("=")[0].lower() for d in defines) or "plain"
    drv = work / f"drv_{prefix}_{tag}.c"
    returns = return_types((gen_dir / f"{prefix}.h").read_text(), prefix, names)
    drv.write_text(arm_driver(model, prefix, names, returns, ncalls))
    elf = work / f"crit_{prefix}_{tag}.elf"
    # the driver casts nothing and calls by exact prototypes: strict flags but the unused-function rule
    run([gcc, *arm_flags(prefix), *[f"-D{d}" for d in defines], "-Wno-unused-function", "-I", gen_dir, "-I", FIRMWARE,
         "-nostartfiles", "--specs=nano.specs", "-T", FIRMWARE / "mps2_an386.ld", "-Wl,--gc-sections",
         FIRMWARE / "startup.c", FIRMWARE / "semihost.c", drv, obj, "-lm", "-o", elf], "linking the criteria firmware")
    out = run([tool("qemu-system-arm"), *QEMU_BASE, "-kernel", elf], "qemu-system-arm", timeout=600, stderr_too=True)
    if "done" not in out:
        raise RuntimeError(f"firmware did not finish:\n{out[-2000:]}")
    kv = {m.group(1): int(m.group(2)) for m in re.finditer(r"^(\w+) (\d+)\s*$", out, re.M)}
    ipt = kv["calib_insns"] / kv["calib_ticks"]
    result = {}
    for index, name in enumerate(names):
        stub_own = 1 if returns[name] == "void" else 2  # bx lr, after movs r0, #0 for a status
        result[name] = (kv[f"fn_{index}"] - kv[f"stub_{index}"]) * ipt / kv["ncalls"] + stub_own
    return result


def arm_object_with(work: Path, gen_dir: Path, prefix: str, defines: tuple[str, ...]) -> dict:
    """arm_object (bench_kinematics) for a build with extra -D options."""
    if not defines:
        return arm_object(work, gen_dir, prefix)
    sub = work / ("obj_" + "_".join(d.split("=")[0].lower() for d in defines))
    sub.mkdir(exist_ok=True)
    patched = sub / f"{prefix}.c"
    patched.write_text("".join(f"#define {d.replace('=', ' ')}\n" for d in defines) + (gen_dir / f"{prefix}.c").read_text())
    shutil.copy(gen_dir / f"{prefix}.h", sub / f"{prefix}.h")
    return arm_object(sub, sub, prefix)


def fit_exponent(dofs: list[int], values: list[float]) -> float:
    pairs = [(d, v) for d, v in zip(dofs, values) if d >= FIT_FROM_DOF and v > 0]
    x = np.log([d for d, _ in pairs])
    y = np.log([v for _, v in pairs])
    return float(np.polyfit(x, y, 1)[0])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--robot", default="modular8", help="bundled robot (default modular8)")
    ap.add_argument("--previous", default=PREVIOUS_REV, help="git revision of the previous generated C")
    ap.add_argument("--out", default=None, help="JSON results file (default benchmarks/results/criteria.json; "
                    "none with --quick)")
    ap.add_argument("--keep", action="store_true", help="keep the build directory and print its path")
    ap.add_argument("--only", action="append", choices=SECTIONS,
                    help="run only this section (repeatable; default: all)")
    ap.add_argument("--quick", action="store_true",
                    help="the current code only, small counts, in seconds (a smoke run, see the docstring)")
    args = ap.parse_args(argv)
    if args.quick:
        use_quick_counts()
    elif args.out is None:
        args.out = str(HERE / "results" / "criteria.json")
    started = time.perf_counter()
    rep = Report(set(args.only) if args.only else None)
    work = Path(tempfile.mkdtemp(prefix="armgen_bench_crit_"))
    robot = load_robot(args.robot)
    model = SymbolicModel(robot)
    code = generate(CodegenConfig(robot))
    prefix = code.prefix
    names = [em.name for em in code.emitted]
    gen_now = work / "now"
    write(code, gen_now)
    rep.data["meta"] = {"robot": robot.name, "dof": robot.n, "previous": args.previous, "bars": BARS,
                        "arm_flags": arm_flags(prefix), "casadi": ca.__version__}
    print(f"armgen criteria benchmark: robot {robot.name} ({robot.n} DOF), previous = {args.previous}, "
          f"build dir {work}")

    def cortex_m4():
        bounded = (f"{prefix.upper()}_BOUNDED_TRIG=1",)
        if args.quick:
            builds = {"now+bounded": (gen_now, bounded)}
        else:
            builds = {"previous": (previous_code(args.previous, prefix, work / "prev"), ()), "now": (gen_now, ()),
                      "now+bounded": (gen_now, bounded)}
        figures: dict[str, dict] = {}
        for label, (gen_dir, defines) in builds.items():
            sub = work / f"m4_{label.replace('+', '_')}"
            sub.mkdir()
            info = arm_object_with(sub, gen_dir, prefix, defines)
            obj = info.pop("object")
            header = (gen_dir / f"{prefix}.h").read_text()
            present = [n for n in names if f" {prefix}_{n}(" in header]  # the previous C has no twins
            figures[label] = {"text": info["text_bytes"], "text_total": info["text_total"],
                              "undefined": info["undefined"], "aeabi_double": info["aeabi_double"],
                              "instr": m4_instructions(sub, obj.parent if defines else gen_dir, model, prefix,
                                                       present, obj, defines,
                                                       QUICK_ARM_NCALLS if args.quick else ARM_NCALLS)}
        rep.data["cortex_m4f"] = figures
        fast = figures["now+bounded"]
        prev, now = figures.get("previous", {}), figures.get("now", fast)
        print(f"  {'function':<22} {'text prev':>10} {'text now':>9} {'ratio':>6}   {'instr prev':>10} "
              f"{'instr now':>9} {'bounded':>8} {'ratio':>6}  bar")
        for name in names:
            tp, tn = prev.get("text", {}).get(name), now["text"].get(name)
            ip, i_now, ib = prev.get("instr", {}).get(name), now["instr"][name], fast["instr"][name]
            ip_text = "-" if ip is None else str(round(ip))
            bar = BARS["m4_instr"].get(name)
            best = min(i_now, ib)
            note = bar_note(best, bar) if bar else ""
            print(f"  {name:<22} {tp if tp is not None else '-':>10} {tn:>9} "
                  f"{(tn / tp if tp else float('nan')):>6.2f}   {ip_text:>10} {i_now:>9.0f} "
                  f"{ib:>8.0f} {(best / ip if ip else float('nan')):>6.2f}  {note}")
            rep.rows.append((f"M4 {name}", f"{tn} B / {best:.0f} instr", "", f"previous {tp} B / {ip} instr; {note}"))
        prev_total = prev.get("text_total")
        print(f"  {'whole file':<22} {prev_total if prev_total else '-':>10} {now['text_total']:>9} "
              f"{(now['text_total'] / prev_total if prev_total else float('nan')):>6.2f}   bounded-trig text "
              f"{fast['text_total']}  {bar_note(now['text_total'], BARS['m4_text_total'])}")
        rep.row("M4 undefined symbols now (plain / bounded trig)", "", "",
                f"{' '.join(now['undefined'])} / {' '.join(fast['undefined']) or 'none'}")
        if prev:
            rep.row("M4 undefined symbols previous", "", "", " ".join(prev["undefined"]))

    rep.section("cortex_m4f", "1. Cortex-M4F -Os float, per function (previous C vs now; instr/call):", cortex_m4)

    def x86():
        tool("gcc")
        P = prefix.upper()
        ours = build_host_driver(work, "x86_ours_float", [gen_now / f"{prefix}.c"], f"{prefix}.h",
                                 f"{prefix}_fk_jacobian", f"{prefix}_real", f"{P}_NDOF", [f"{P}_USE_FLOAT=1"], gen_now)
        ours_bt = build_host_driver(work, "x86_ours_float_bt", [gen_now / f"{prefix}.c"], f"{prefix}.h",
                                    f"{prefix}_fk_jacobian", f"{prefix}_real", f"{P}_NDOF",
                                    [f"{P}_USE_FLOAT=1", f"{P}_BOUNDED_TRIG=1"], gen_now)
        cg_dir = work / "casadi_float"
        cg_dir.mkdir()
        gen = ca.CodeGenerator("fkj_casadi.c", {"with_header": True, "casadi_real": "float"})
        f = model.function("fk_jacobian")
        gen.add(f)
        gen.generate(str(cg_dir) + "/")
        (cg_dir / "fkj_adapter.h").write_text("#ifndef FKJ_ADAPTER_H\n#define FKJ_ADAPTER_H\n"
                                              "void casadi_fkj_call(const float *q, float *T, float *J);\n#endif\n")
        (cg_dir / "fkj_adapter.c").write_text(f"""#include "fkj_adapter.h"
#include "fkj_casadi.h"
void casadi_fkj_call(const float *q, float *T, float *J) {{
  static casadi_real w[{max(f.sz_w(), 1)}];
  static casadi_int iw[{max(f.sz_iw(), 1)}];
  const casadi_real *arg[{max(f.sz_arg(), 1)}];
  casadi_real *res[{max(f.sz_res(), 2)}];
  arg[0] = q; res[0] = T; res[1] = J;
  (void)fk_jacobian(arg, res, iw, w, 0);
}}
""")
        src = cg_dir / "fkj_casadi.c"
        src.write_text(src.read_text().replace("#include <math.h>", "#include <math.h>\n#define sin sinf\n#define cos cosf"))
        base = build_host_driver(work, "x86_casadi_float", [cg_dir / "fkj_adapter.c"], "fkj_adapter.h",
                                 "casadi_fkj_call", "float", str(model.n), [], cg_dir, relaxed=[src])
        figures = {"ours": callgrind_instr(ours, f"{prefix}_fk_jacobian", work)["instr_per_call"],
                   "ours_bounded_trig": callgrind_instr(ours_bt, f"{prefix}_fk_jacobian", work)["instr_per_call"],
                   "casadi": callgrind_instr(base, "casadi_fkj_call", work)["instr_per_call"]}
        rep.data["x86_float_fk_jacobian"] = figures
        rep.row("x86 -O2 float fk_jacobian, ours (sinf/cosf)", f"{figures['ours']:.1f}", "instr/call",
                f"{figures['ours'] / figures['casadi']:.2f}x CasADi; "
                + bar_note(figures["ours"] / figures["casadi"], BARS["x86_float_fkj_over_casadi"]))
        rep.row("x86 -O2 float fk_jacobian, ours (bounded trig)", f"{figures['ours_bounded_trig']:.1f}", "instr/call",
                f"{figures['ours_bounded_trig'] / figures['casadi']:.2f}x CasADi; "
                + bar_note(figures["ours_bounded_trig"] / figures["casadi"], BARS["x86_float_fkj_over_casadi"]))
        rep.row("x86 -O2 float CasADi C of the same fk_jacobian", f"{figures['casadi']:.1f}", "instr/call",
                "casadi_real=float, sinf/cosf; issue: today 929 (ours) vs 942")

    rep.section("x86", "2. x86-64 gcc -O2 float, callgrind, fk_jacobian vs CasADi's C:", x86)

    def snake12():
        t0 = time.perf_counter()
        snake = generate(CodegenConfig(load_robot("snake12")))
        gen_s = time.perf_counter() - t0
        out = work / "snake12"
        write(snake, out)
        rep.row("snake12 generation, all functions", f"{gen_s:.2f}", "s",
                f"{len(snake.emitted)} functions; previous: {ISSUE_PREVIOUS['snake12']} (issue); "
                + bar_note(gen_s, BARS["snake12_gen_seconds"]))
        if args.quick:  # its compiles take a minute
            rep.data["snake12"] = {"generation_seconds": gen_s}
            return
        compile_s = {}
        for precision, flag in (("double", 0), ("float", 1)):
            t0 = time.perf_counter()
            run([tool("gcc"), *STRICT_FLAGS, HOST_OPT, f"-DSNAKE12_USE_FLOAT={flag}", "-c", out / "snake12.c",
                 "-o", work / f"snake12_{precision}.o"], "gcc snake12")
            compile_s[precision] = time.perf_counter() - t0
            rep.row(f"snake12 host compile gcc {HOST_OPT} {precision}", f"{compile_s[precision]:.2f}", "s",
                    bar_note(compile_s[precision], BARS["snake12_compile_seconds"]))
        info = arm_object(work, out, "snake12")
        rep.row("snake12 M4 -Os float text, all functions", str(info["text_total"]), "bytes",
                ", ".join(f"{k} {v}" for k, v in info["text_bytes"].items()))
        rep.data["snake12"] = {"generation_seconds": gen_s, "compile_seconds": compile_s,
                               "m4_text": info["text_bytes"], "m4_text_total": info["text_total"]}

    rep.section("snake12", "3. snake12 (25 DOF), every function:", snake12)

    def growth():
        flops: dict[str, list[int]] = {}
        dofs = QUICK_CHAIN_DOFS if args.quick else CHAIN_DOFS
        for dof in dofs:
            chain = generate(CodegenConfig(parse_robot(chain_toml(dof), f"chain{dof}.toml")))
            for em in chain.emitted:
                flops.setdefault(em.name, []).append(em.flops)
        exponents = {name: fit_exponent(list(dofs), values) for name, values in flops.items()}
        rep.data["growth"] = {"dofs": list(dofs), "flops": flops, "exponent_fit_from": FIT_FROM_DOF,
                              "exponents": exponents}
        print(f"  {'function':<22} " + " ".join(f"{'n=' + str(d):>8}" for d in dofs) + "  exponent")
        for name, values in flops.items():
            print(f"  {name:<22} " + " ".join(f"{v:>8}" for v in values) + f"  {exponents[name]:.2f}")
        rep.rows.append(("growth exponents", json.dumps({k: round(v, 2) for k, v in exponents.items()}), "",
                         f"previous: {ISSUE_PREVIOUS['exponent']} (issue)"))
        print(f"  previous exponent of the manipulability family: {ISSUE_PREVIOUS['exponent']} (issue)")

    rep.section("growth", f"4. Op counts of the emitted code, spatial chains, exponent fitted over n >= {FIT_FROM_DOF}:",
                growth)
    return finish(rep, args, work, started)


if __name__ == "__main__":
    sys.exit(main())
