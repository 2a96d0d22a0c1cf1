#!/usr/bin/env python3
"""Dynamics benchmarks (issue 39's bar): measurements, not tests.

    python benchmarks/bench_dynamics.py [--robot iiwa14] [--out benchmarks/results/dynamics.json]

In one run:

1. Agreement with Pinocchio (``pin``: ``computeGeneralizedGravity``, ``rnea``, ``crba``,
   ``nonLinearEffects − gravity``) on every arm of example-robot-data that armgen reads with
   inertials (tests/test_dynamics.py's EXAMPLE_ARMS, Pinocchio set up as there), on Drake's
   iiwa14 (tests/data/iiwa14_drake_inertials.urdf) and on the bundled DH panda and iiwa14
   against their source URDFs (tests/test_bundled_inertials.py): SAMPLES seeded (q, q̇, q̈)
   each (q within the limits, |q̇| ≤ 2, |q̈| ≤ 10). Double: the largest relative error (largest
   entry error over the largest reference entry) of the CasADi functions (armgen's Python
   API, batched). Float: the generated C built with ``<P>_USE_FLOAT=1`` (gcc -O2, strict
   flags) called on the float-rounded inputs, against Pinocchio in double at those same
   inputs: the largest absolute error (N·m; kg·m² for M) and the same relative to the
   largest reference entry.
2. Cortex-M4F (``--robot``, a bundled 7-DOF arm with inertials): ``arm-none-eabi-gcc -Os``
   float, text bytes of each dynamic function (``.text.<prefix>_<fn>``, literal pools
   included; the header's shared sin/cos helper is not in it) and executed instructions per
   call under ``qemu-system-arm -M mps2-an386 -icount shift=0`` (bench_criteria.py's
   driver: 16 seeded input sets, a stub of the same signature subtracted), with newlib's
   ``sinf``/``cosf`` and with ``<P>_BOUNDED_TRIG=1``.
3. Host ns/call, in the same run: the generated C called from C (benchmarks/c/bench_dynamics.c,
   gcc -O2 strict flags, double and float, best of TIME_REPEATS × TIME_CALLS calls, inputs
   cycling through 256 sets), Pinocchio's C++ called from Python in a loop over 256 sets
   (its figure includes the Python-to-C++ call; the same figure less the "call floor", the
   time of ``isNormalized(model, q)``, a binding call with one q converted and next to no
   work, estimates its C++ alone), and armgen's batched NumPy API
   (``robot.rnea`` etc. on 1 000 samples at once, per sample); ratios Pinocchio / C.

A missing tool or peer skips its rows and the run exits 4; a measurement that fails exits 1
(bench_kinematics.py's EXIT_CODES). ``--quick``: 40 samples per URDF, 32 M4 calls per
function, 10 000 host calls once, one Python timing pass; its figures are a smoke run's.
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
for path in (str(REPO), str(HERE)):
    if path not in sys.path:
        sys.path.insert(0, path)

import bench_kinematics  # noqa: E402
from bench_criteria import QUICK_ARM_NCALLS, arm_object_with, m4_instructions  # noqa: E402
from bench_kinematics import Report, Skip, bar_note, finish, run, tool, use_quick_counts  # noqa: E402
from armgen.codegen.compiled import CompiledModel, build_library  # noqa: E402
from armgen.codegen.generate import CodegenConfig, generate, write  # noqa: E402
from armgen.codegen.toolchain import STRICT_FLAGS  # noqa: E402
from armgen.robot import Robot, load_robot  # noqa: E402
from armgen.symbolic.dynamics import DYNAMIC_FUNCTIONS  # noqa: E402
from armgen.symbolic.model import SymbolicModel  # noqa: E402

# Issue 39's goals for a 7-DOF arm on the Cortex-M4F (instructions per call); reported, never asserted.
BARS = {"gravity": 2_500, "rnea": 8_000}
SAMPLES = 1_000
QUICK_SAMPLES = 40
SEED = 20261128
ARM_NCALLS = 512  # per function and timing loop, a multiple of bench_criteria's 16 input sets
PYTHON_MIN_SECONDS = 0.5  # each Pinocchio / NumPy timing runs at least this long (best of PYTHON_REPEATS)
PYTHON_REPEATS = 3
BATCH = 1_000  # samples per call of armgen's batched NumPy API
DRIVER = HERE / "c" / "bench_dynamics.c"
MINIMUM_URDFS = 10  # the issue's bar: at least ten foreign URDFs with inertials


def _tests_module(name: str):
    """tests/<name>.py (the Pinocchio reference set-up shared with the tests)."""
    if importlib.util.find_spec("pinocchio") is None:
        raise Skip("skipped: Pinocchio not installed (pip install pin example-robot-data)")
    tests = str(REPO / "tests")
    if tests not in sys.path:
        sys.path.insert(0, tests)
    return __import__(name)


class _Peer:
    """Pinocchio's four functions of one robot, in armgen's joint order (a callable of q, q̇, q̈)."""

    def __init__(self, model, configuration=lambda q: q, rate=lambda v: v, columns=None):
        import pinocchio as pin

        self.pin, self.model, self.data = pin, model, model.createData()
        self.configuration, self.rate = configuration, rate
        self.columns = columns if columns is not None else slice(None)

    def __call__(self, q, dq, ddq) -> dict[str, np.ndarray]:
        pin, model, data, v = self.pin, self.model, self.data, self.columns
        qp, vp, ap = self.configuration(q), self.rate(dq), self.rate(ddq)
        gravity = pin.computeGeneralizedGravity(model, data, qp)[v].copy()
        mass = pin.crba(model, data, qp)
        mass = np.triu(mass) + np.triu(mass, 1).T  # crba fills the upper triangle
        return {"gravity": gravity, "rnea": pin.rnea(model, data, qp, vp, ap)[v].copy(),
                "mass_matrix": mass[np.ix_(v, v)] if isinstance(v, list) else mass,
                "coriolis": pin.nonLinearEffects(model, data, qp, vp)[v].copy() - gravity}


def test_set() -> list[tuple[str, Robot, _Peer]]:
    """(label, armgen robot, Pinocchio) of every robot compared: the foreign URDFs, then the
    bundled DH arms against their source URDFs."""
    import pinocchio as pin

    dynamics, bundled = _tests_module("test_dynamics"), _tests_module("test_bundled_inertials")
    root = _tests_module("test_urdf")._example_robot_data_dir()
    robots = []
    for relative, base, tip in dynamics.EXAMPLE_ARMS:
        robot = Robot.from_urdf(root / relative, base_link=base, tip_link=tip)
        reference = dynamics._Pinocchio(pin.buildModelFromUrdf(str(root / relative)), robot)
        robots.append((relative.split("/")[-1].removesuffix(".urdf"), robot,
                       _Peer(reference.model, reference.configuration, reference.rate, reference.v)))
    drake = Robot.from_urdf(bundled.IIWA14_URDF)
    robots.append(("iiwa14 (Drake)", drake, _Peer(pin.buildModelFromUrdf(str(bundled.IIWA14_URDF)))))
    for name in ("panda", "iiwa14"):
        robots.append((f"{name} (bundled DH vs its source URDF)", load_robot(name), _Peer(bundled.source_model(name))))
    return robots


def _inputs(robot: Robot, count: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(SEED)
    q = rng.uniform(robot.qmin, robot.qmax, (count, robot.n))
    return q, rng.uniform(-2.0, 2.0, (count, robot.n)), rng.uniform(-10.0, 10.0, (count, robot.n))


def _reference(peer: _Peer, q, dq, ddq) -> dict[str, np.ndarray]:
    rows = [peer(q[k], dq[k], ddq[k]) for k in range(len(q))]
    return {name: np.array([row[name] for row in rows]) for name in DYNAMIC_FUNCTIONS}


def _float_c(robot: Robot, work: Path) -> dict[str, object]:
    """The robot's dynamic functions generated and built in float, with batched entries."""
    code = generate(CodegenConfig(robot, functions=DYNAMIC_FUNCTIONS))
    gen_dir = work / code.prefix
    write(code, gen_dir)
    functions = {name: robot.symbolic.function(name) for name in DYNAMIC_FUNCTIONS}
    library = build_library(gen_dir, code.prefix, "float", gen_dir, batch=functions)
    return CompiledModel(library, code.prefix, functions, "float").raw


def agreement(rep: Report, samples: int, work: Path) -> None:
    robots = test_set()
    foreign = [label for label, _, _ in robots if "bundled" not in label]
    print(f"  {len(foreign)} foreign URDFs with inertials (bar >= {MINIMUM_URDFS}) + the 2 bundled DH arms, "
          f"{samples} samples each")
    print(f"  {'robot (joints)':<44} {'double: max relative error':^44} | {'float C: max abs error (relative)':^60}")
    print(f"  {'':<44} {'gravity':>10} {'rnea':>10} {'M':>10} {'coriolis':>10} | {'gravity':>19} {'rnea':>19} "
          f"{'M':>19}")
    figures = {}
    for label, robot, peer in robots:
        q, dq, ddq = _inputs(robot, samples)
        expected = _reference(peer, q, dq, ddq)
        ours = {"gravity": robot.gravity_torques(q), "rnea": robot.rnea(q, dq, ddq),
                "mass_matrix": robot.mass_matrix(q), "coriolis": robot.coriolis(q, dq)}
        double = {name: _worst_relative(ours[name], expected[name]) for name in DYNAMIC_FUNCTIONS}
        # float: the C's inputs are floats, so the reference is taken at the float-rounded inputs
        q32, dq32, ddq32 = (np.asarray(a, dtype=np.float32).astype(float) for a in (q, dq, ddq))
        at_float = _reference(peer, q32, dq32, ddq32)
        compiled = _float_c(robot, work / f"float_{len(figures)}")
        c_out = {"gravity": compiled["gravity"].batch([q32])[0][..., 0],
                 "rnea": compiled["rnea"].batch([q32, dq32, ddq32])[0][..., 0],
                 "mass_matrix": compiled["mass_matrix"].batch([q32])[0],
                 "coriolis": compiled["coriolis"].batch([q32, dq32])[0][..., 0]}
        absolute = {name: float(np.abs(c_out[name] - at_float[name]).max()) for name in DYNAMIC_FUNCTIONS}
        relative = {name: _worst_relative(c_out[name], at_float[name]) for name in DYNAMIC_FUNCTIONS}
        figures[label] = {"joints": robot.n, "samples": samples, "double_max_relative": double,
                          "float_c_max_abs": absolute, "float_c_max_relative": relative}
        print(f"  {label + f' ({robot.n})':<44} " + " ".join(f"{double[k]:>10.1e}" for k in DYNAMIC_FUNCTIONS)
              + " | " + " ".join(f"{absolute[k]:>8.1e} ({relative[k]:>7.1e})" for k in DYNAMIC_FUNCTIONS[:3]),
              flush=True)
    worst_double = max(max(f["double_max_relative"].values()) for f in figures.values())
    worst_float = {name: max(f["float_c_max_relative"][name] for f in figures.values()) for name in DYNAMIC_FUNCTIONS}
    rep.data["agreement"] = figures
    rep.row("foreign URDFs with inertials", len(foreign), "", f"bar >= {MINIMUM_URDFS}: "
            f"{'meets' if len(foreign) >= MINIMUM_URDFS else 'BELOW'}; " + ", ".join(foreign))
    rep.row("double vs Pinocchio, max relative error", worst_double, "", f"all robots and functions, {samples} samples")
    rep.row("float C vs Pinocchio, max relative error", max(worst_float.values()), "",
            ", ".join(f"{k} {v:.1e}" for k, v in worst_float.items()))


def _worst_relative(ours: np.ndarray, reference: np.ndarray) -> float:
    """Per sample, the largest entry error over the largest reference entry; the worst sample."""
    axes = tuple(range(1, reference.ndim))
    scale = np.maximum(np.abs(reference).max(axis=axes), np.finfo(float).tiny)
    return float((np.abs(ours - reference).max(axis=axes) / scale).max())


def cortex_m4(rep: Report, robot: Robot, work: Path, quick: bool) -> None:
    code = generate(CodegenConfig(robot, functions=DYNAMIC_FUNCTIONS))
    prefix, gen_dir = code.prefix, work / "m4_gen"
    write(code, gen_dir)
    model = SymbolicModel(robot)
    names = list(DYNAMIC_FUNCTIONS)
    figures = {}
    for label, defines in (("newlib sinf/cosf", ()), ("bounded trig", (f"{prefix.upper()}_BOUNDED_TRIG=1",))):
        sub = work / f"m4_{'bounded' if defines else 'plain'}"
        sub.mkdir()
        info = arm_object_with(sub, gen_dir, prefix, defines)
        obj = info.pop("object")
        if info["aeabi_double"]:
            raise RuntimeError(f"soft double in the M4 object: {info['aeabi_double']}")
        instr = m4_instructions(sub, obj.parent if defines else gen_dir, model, prefix, names, obj, defines,
                                QUICK_ARM_NCALLS if quick else ARM_NCALLS)
        figures[label] = {"text": {n: info["text_bytes"][n] for n in names}, "instr": instr,
                          "undefined": info["undefined"]}
    rep.data["cortex_m4f"] = {"robot": robot.name, "dof": robot.n, "builds": figures,
                              "ops": {e.name: e.op_counts for e in code.emitted}}
    plain, bounded = figures["newlib sinf/cosf"], figures["bounded trig"]
    print(f"  {robot.name} ({robot.n} DOF)   {'flash B':>8} {'bounded':>8} {'instr/call':>11} {'bounded':>8}  goal")
    for name in names:
        best = min(plain["instr"][name], bounded["instr"][name])
        note = bar_note(best, BARS[name]) if name in BARS else ""
        print(f"  {name:<22} {plain['text'][name]:>8} {bounded['text'][name]:>8} {plain['instr'][name]:>11.0f} "
              f"{bounded['instr'][name]:>8.0f}  {note}")
        rep.rows.append((f"M4 {name}", f"{plain['text'][name]} B / {best:.0f} instr", "", note))
    rep.row("M4 undefined symbols (newlib / bounded trig)", "", "",
            f"{' '.join(plain['undefined'])} / {' '.join(bounded['undefined']) or 'none'}")


def host(rep: Report, robot: Robot, work: Path, quick: bool) -> None:
    gcc = tool("gcc")
    code = generate(CodegenConfig(robot, functions=DYNAMIC_FUNCTIONS))
    prefix, gen_dir = code.prefix, work / "host_gen"
    write(code, gen_dir)
    ours: dict[str, dict[str, float]] = {}
    for precision, flag in (("double", 0), ("float", 1)):
        exe = work / f"bench_dynamics_{precision}"
        run([gcc, *STRICT_FLAGS, bench_kinematics.HOST_OPT, "-I", gen_dir, f"-D{prefix.upper()}_USE_FLOAT={flag}",
             "-c", gen_dir / f"{prefix}.c", "-o", work / f"{prefix}_{precision}.o"], f"compiling {prefix}.c")
        run([gcc, *STRICT_FLAGS, bench_kinematics.HOST_OPT, "-I", gen_dir, f"-D{prefix.upper()}_USE_FLOAT={flag}",
             f"-DBENCH_HEADER=\"{prefix}.h\"", f"-DBENCH_PREFIX={prefix}", f"-DBENCH_NDOF={robot.n}",
             DRIVER, work / f"{prefix}_{precision}.o", "-o", exe, "-lm"], "building the dynamics driver")
        ours[precision] = {}
        for name in DYNAMIC_FUNCTIONS:
            out = run([exe, "time", name, bench_kinematics.TIME_CALLS, bench_kinematics.TIME_REPEATS],
                      f"timing {name}", timeout=300)
            ours[precision][name] = float(out.split()[1])
    peer = _pinocchio_timings(robot, quick)
    batched = _batched_timings(robot, quick)
    rep.data["host"] = {"robot": robot.name, "c_ns_per_call": ours, "pinocchio_python_ns_per_call": peer,
                        "armgen_numpy_batched_ns_per_sample": batched,
                        "time_calls": bench_kinematics.TIME_CALLS, "time_repeats": bench_kinematics.TIME_REPEATS}
    floor = peer["call floor"]
    print(f"  {robot.name}, ns/call   {'C double':>9} {'C float':>9} {'Pinocchio (Python)':>19} {'ratio':>7} "
          f"{'less floor':>11} {'ratio':>7} {'armgen batched':>15}")
    for name in DYNAMIC_FUNCTIONS:
        ratio, net = peer[name] / ours["double"][name], peer[name] - floor
        print(f"  {name:<18} {ours['double'][name]:>9.1f} {ours['float'][name]:>9.1f} {peer[name]:>19.1f} "
              f"{ratio:>6.1f}x {net:>11.1f} {net / ours['double'][name]:>6.1f}x {batched[name]:>15.1f}")
        rep.rows.append((f"host {name} ns/call", f"C {ours['double'][name]:.0f} / Pinocchio {peer[name]:.0f}", "ns",
                         f"Pinocchio (Python) / C double {ratio:.1f}x; "
                         f"less the call floor {net / ours['double'][name]:.1f}x"))
    print(f"  Pinocchio's call floor (isNormalized(model, q): the Python-to-C++ call alone) {floor:.0f} ns; "
          "its coriolis is nonLinearEffects (c + g); ratios are Pinocchio / C double")


def _best_ns(call, inputs: list[tuple], quick: bool) -> float:
    """ns per call of ``call(*inputs[i])`` cycling through the inputs, best of PYTHON_REPEATS
    passes of at least PYTHON_MIN_SECONDS (one short pass with --quick)."""
    repeats, seconds = (1, 0.05) if quick else (PYTHON_REPEATS, PYTHON_MIN_SECONDS)
    for args in inputs[:20]:  # warm-up
        call(*args)
    best = float("inf")
    for _ in range(repeats):
        calls, t0 = 0, time.perf_counter()
        while time.perf_counter() - t0 < seconds:
            for args in inputs:
                call(*args)
            calls += len(inputs)
        best = min(best, (time.perf_counter() - t0) / calls * 1e9)
    return best


def _pinocchio_timings(robot: Robot, quick: bool) -> dict[str, float]:
    import pinocchio as pin

    model = _tests_module("test_bundled_inertials").source_model(robot.name)
    data = model.createData()
    q, dq, ddq = _inputs(robot, 256)
    sets = list(zip(q, dq, ddq))
    return {"gravity": _best_ns(lambda a, b, c: pin.computeGeneralizedGravity(model, data, a), sets, quick),
            "rnea": _best_ns(lambda a, b, c: pin.rnea(model, data, a, b, c), sets, quick),
            "mass_matrix": _best_ns(lambda a, b, c: pin.crba(model, data, a), sets, quick),
            "coriolis": _best_ns(lambda a, b, c: pin.nonLinearEffects(model, data, a, b), sets, quick),
            # the floor of such a call: Python to C++ with one q converted, next to no work
            "call floor": _best_ns(lambda a, b, c: pin.isNormalized(model, a), sets, quick)}


def _batched_timings(robot: Robot, quick: bool) -> dict[str, float]:
    q, dq, ddq = _inputs(robot, BATCH)
    calls = {"gravity": lambda: robot.gravity_torques(q), "rnea": lambda: robot.rnea(q, dq, ddq),
             "mass_matrix": lambda: robot.mass_matrix(q), "coriolis": lambda: robot.coriolis(q, dq)}
    return {name: _best_ns(call, [()], quick) / BATCH for name, call in calls.items()}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--robot", default="iiwa14", help="bundled 7-DOF arm with inertials for sections 2 and 3 "
                    "(iiwa14 or panda; default iiwa14)")
    ap.add_argument("--out", default=None, help="JSON results file (default benchmarks/results/dynamics.json; "
                    "none with --quick)")
    ap.add_argument("--keep", action="store_true", help="keep the build directory and print its path")
    ap.add_argument("--quick", action="store_true", help="small counts, in seconds (a smoke run, see the docstring)")
    args = ap.parse_args(argv)
    if args.quick:
        use_quick_counts()
    elif args.out is None:
        args.out = str(HERE / "results" / "dynamics.json")
    started = time.perf_counter()
    rep = Report()
    work = Path(tempfile.mkdtemp(prefix="armgen_bench_dyn_"))
    robot = load_robot(args.robot)
    rep.data["meta"] = {"robot": robot.name, "dof": robot.n, "bars": BARS, "seed": SEED,
                        "samples": QUICK_SAMPLES if args.quick else SAMPLES}
    print(f"armgen dynamics benchmark: robot {robot.name} ({robot.n} DOF), build dir {work}")
    rep.section("agreement", "1. Agreement with Pinocchio (double: CasADi; float: the generated C):",
                lambda: agreement(rep, QUICK_SAMPLES if args.quick else SAMPLES, work))
    rep.section("cortex_m4f", "2. Cortex-M4F -Os float, flash and executed instructions per call (QEMU -icount):",
                lambda: cortex_m4(rep, robot, work, args.quick))
    rep.section("host", "3. Host ns/call: generated C from C vs Pinocchio's C++ from Python:",
                lambda: host(rep, robot, work, args.quick))
    return finish(rep, args, work, started)


if __name__ == "__main__":
    sys.exit(main())
