"""``armgen verify``: the plan-and-verify pipeline of spec 60.

The code verified is a folder written by ``armgen gen`` (default ``./generated/<robot>/``,
``-o DIR`` elsewhere). Before anything is compiled, its ``manifest.json`` must name
the given robot file (sha256); a folder without a manifest, or generated from another robot
file, is an input error (exit 2) that names the folder and the ``armgen gen`` command to fix it.

Stages (each a function returning a :class:`Stage` with a table of rows):
1. fresh    — regenerate (with the manifest's options) into a temp dir; every file must match.
   Stale code is reported and never compiled or run: the later stages are shown as not run;
2. compile  — strict gcc flags, float and double, plus an ASan/UBSan driver run (the four
   builds side by side on the cores the load leaves free, while this process draws the
   callbacks stage's samples and evaluates the interpreter on them; a build of the same bytes
   is taken from the kernel store, its SHA-256 checked);
3. callbacks — each compiled function against the interpreter at N seeded samples
   (near-singular and near-limit included), per-precision bounds: the samples go through a
   batched C entry compiled into the library (one call per function) and through the
   interpreter's ``Function.map``;
4. replay   — rerun the plan's task with the C backend (the same planner code) and compare
   with the plan CSV sample by sample; then run the firmware stub (``firmware_stub/``) on the
   same task on the host — double with ASan/UBSan, and float — and compare it the same way;
5. target   — (``--target NAME``, a core of :data:`armgen.firmware.TARGETS`: cortex-m4,
   cortex-m7, cortex-m33, cortex-m0plus, rv32imf) the firmware cross-compiled for that core in the
   precision it computes natively (float; double on the Cortex-M7), run under
   QEMU on the core's board model (MPS2, RISC-V virt; docs/targets.md), compared with the plan
   (and with the host run of the same precision); fails naming the apt packages when the toolchain or QEMU is missing. Without
   ``--plan`` it plans the demo task of ``armgen firmware`` (:mod:`armgen.firmware.project`);
6. run      — (``--run CSV``, with ``--plan``) what a firmware run printed (the host demo of an
   ``armgen firmware`` project, or its Cortex-M4F image under QEMU) compared with the plan in the
   bounds of the run's precision (``# real_bytes`` of its summary).

A stage that compared nothing is never a PASS: it is a FAIL, or SKIPPED when the user did not
ask for it (replay without ``--plan``); skipped stages do not fail the run. Temporary build
folders are removed however the run ends.

A passed verdict of fresh, compile + callbacks (per precision) and replay is stored and reused
for the same inputs, which its key digests (:mod:`armgen.verification.reuse`; ``reuse=False``,
``--again``, redoes everything).

Bounds of the firmware comparisons and why: :mod:`armgen.verification.firmware_compare`.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import tempfile
from concurrent.futures import Future, ThreadPoolExecutor, as_completed
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterator

import numpy as np

from ..codegen.generate import GENERATED_DIR, CodegenConfig, generate
from ..codegen.toolchain import host_cc
from ..errors import ArmgenError, OptionError, PlanFileError, excerpt
from ..fileio import write_text_atomic
from ..planning.result import PlanResult, read_plan
from ..planning.tasks import run_task
from ..progress import progress
from ..robot import Robot, load_robot
from ..symbolic.model import ModelOptions, SymbolicModel
from .compare import ReferenceSamples, compare_model, reference_samples
from .. import firmware as fw
from ..firmware import bound as static_bound
from . import firmware_compare as fwcmp
from ..codegen.api_kernel import OPTIMISATION, KernelLibrary, Signature, folder_sources, kernel_library
from ..codegen.toolchain import compiler_identity
from ..planning.result import metadata_path
from . import reuse
from .harness import run_sanitized_program

# Replaying a plan through the double C backend performs the same operations as the symbolic
# run; libm may differ by an ulp per call, which 12 500 integration steps can amplify by at
# most ~1e4 × eps: 1e-9 rad (≈ 6e-8 deg) leaves a wide margin and still catches any real bug.
REPLAY_DOUBLE_BOUND_RAD = 1e-9
REPLAY_TASK_ERROR_BOUND_M = 1e-9


@dataclass
class Stage:
    """One stage's verdict and table. A stage with no rows checked nothing: unless it was
    skipped on purpose (``skipped``), that is a failure, whatever ``passed`` says."""

    name: str
    passed: bool
    columns: list[str]
    rows: list[list[Any]] = field(default_factory=list)
    message: str = ""
    skipped: bool = False
    reused: bool = False  # the verdict of the same inputs, verified before (armgen.verification.reuse)

    def __post_init__(self) -> None:
        if self.skipped:
            self.passed = True
        elif not self.rows:
            self.passed = False
            self.message = self.message or "nothing was checked"

    @property
    def verdict(self) -> str:
        return "SKIPPED" if self.skipped else ("PASS" if self.passed else "FAIL")

    def render(self) -> str:
        widths = [max(len(str(c)), *(len(_fmt(r[k])) for r in self.rows)) if self.rows else len(str(c))
                  for k, c in enumerate(self.columns)]
        lines = [f"== {self.name}: {self.verdict}" + (" (reused)" if self.reused else "")
                 + (f" — {self.message}" if self.message else "")]
        lines.append("  " + "  ".join(str(c).ljust(w) for c, w in zip(self.columns, widths)))
        for r in self.rows:
            lines.append("  " + "  ".join(_fmt(v).ljust(w) for v, w in zip(r, widths)))
        return "\n".join(lines)


def _fmt(value: Any) -> str:
    if isinstance(value, bool):
        return "pass" if value else "FAIL"
    if isinstance(value, float):
        return f"{value:.3g}"
    return str(value)


class GeneratedDirError(ArmgenError):
    """The folder given as generated code is not ``armgen gen`` output for this robot file."""

    exit_code = 2


@dataclass
class VerifyConfig:
    robot: Robot
    plan: Path | None = None
    samples: int = 10_000
    precisions: tuple[str, ...] = ("double", "float")
    target: str | None = None
    seed: int = 20261122
    generated: Path | None = None  # default ./generated/<robot>/
    run: Path | None = None  # a firmware run's printed CSV (host demo or QEMU) to compare with the plan
    robot_ref: str = ""  # how the user named the robot (for the fix in messages)
    reuse: bool = True  # take stored builds and passed verdicts of the same inputs (False: redo everything)

    @property
    def gen_dir(self) -> Path:
        return self.generated if self.generated is not None else GENERATED_DIR / self.robot.name

    @property
    def regenerate_command(self) -> str:
        return f"armgen gen {self.robot_ref or self.robot.source} --out {self.gen_dir}"


@dataclass(frozen=True)
class GeneratedCode:
    """What ``manifest.json`` says the folder holds."""

    prefix: str
    precision: str
    functions: tuple[str, ...]
    robot_file: str  # the robot file's name as recorded (provenance; the sha256 is what counts)


def read_manifest(config: VerifyConfig) -> GeneratedCode:
    """The folder's manifest, checked against the robot file; GeneratedDirError otherwise."""
    folder = config.gen_dir
    manifest_path = folder / "manifest.json"
    fix = f"generate it with `{config.regenerate_command}`, or point -o at a folder written by `armgen gen`"
    if not manifest_path.is_file():
        what = "does not exist" if not folder.exists() else "has no manifest.json (not written by `armgen gen`)"
        raise GeneratedDirError(f"{folder}: {what}; {fix}")
    try:
        manifest = json.loads(manifest_path.read_text(encoding="utf-8"))
        robot, options = manifest["robot"], manifest["options"]
        sha, prefix, precision = str(robot["sha256"]), str(options["prefix"]), str(options["precision"])
        functions = tuple(str(f) for f in options["functions"])
    except (OSError, UnicodeDecodeError, ValueError, KeyError, TypeError) as exc:
        raise GeneratedDirError(f"{manifest_path}: not a readable armgen manifest ({type(exc).__name__}: {exc}); "
                                f"regenerate with `{config.regenerate_command}`") from None
    if sha != config.robot.sha256:
        raise GeneratedDirError(
            f"{manifest_path}: generated from a robot file with sha256 {sha[:16]}… ({robot.get('file', '?')}), but "
            f"{config.robot.source} has sha256 {config.robot.sha256[:16]}…; the code is stale for this robot file — "
            f"regenerate with `{config.regenerate_command}` (or give the robot file it was generated from)")
    return GeneratedCode(prefix, precision, functions, str(robot.get("file", config.robot.source)))


def stage_fresh(config: VerifyConfig, work: Path, found: GeneratedCode | None = None) -> Stage:
    """Regenerate with the manifest's options; every file in the folder must be identical."""
    found = found or read_manifest(config)
    # Same bytes (sha256 checked), so only the recorded file name may differ: keep the recorded one.
    robot = dataclasses.replace(config.robot, source=found.robot_file)
    code = generate(CodegenConfig(robot, found.precision, found.prefix, found.functions))
    rows = []
    for name, text in sorted(code.files.items()):
        path = config.gen_dir / name
        same = path.is_file() and path.read_text(encoding="utf-8") == text
        rows.append([name, "missing" if not path.is_file() else ("identical" if same else "stale"), same])
    passed = all(r[2] for r in rows)
    msg = "" if passed else f"stale code is never compiled or run; regenerate with `{config.regenerate_command}`"
    return Stage("fresh", passed, ["file", "state", "ok"], rows, msg)


Build = tuple[str, str, Callable[[], Any]]  # (precision, what, action)


def compile_builds(config: VerifyConfig, work: Path, functions, found: GeneratedCode | None = None) -> list[Build]:
    """The compile stage's builds per precision: the kernel library of the folder's C (the
    extension module the callbacks stage calls, with the strict flags; its double build is the
    robot's API kernel when the folder holds armgen gen's default output) and the ASan/UBSan
    driver run; each action returns (library or output, whether it was built now rather than
    taken from the kernel store)."""
    gen_dir = config.gen_dir
    prefix = (found or read_manifest(config)).prefix
    host_cc()  # a missing compiler is a missing tool (exit 4), not a verification failure
    signatures = {name: Signature.of(f) for name, f in functions.items()}
    sources = folder_sources(gen_dir, prefix)  # read once for both precisions
    return [(precision, what, action) for precision in config.precisions for what, action in (
        (f"strict {OPTIMISATION} kernel library",
         lambda p=precision: kernel_library(sources, prefix, p, signatures, not config.reuse)),
        ("ASan/UBSan driver",
         lambda p=precision: run_sanitized_program(gen_dir, prefix, functions, p, not config.reuse)))]


# The compile row's detail: where the build came from.
BUILT_NOW = "built"
FROM_STORE = "stored build of the same bytes (SHA-256 checked)"


def compile_stage(builds: list[Build], futures: list[Future]) -> tuple[Stage, dict[str, KernelLibrary]]:
    """The compile stage's verdict from its finished builds (rows in the builds' order)."""
    rows, libraries = [], {}
    passed = True
    for (precision, what, _), future in zip(builds, futures):
        try:
            out, built = future.result()
        except ArmgenError as exc:
            passed = False
            rows.append([precision, what, False, str(exc).splitlines()[0]])
            continue
        if isinstance(out, KernelLibrary):
            libraries[precision] = out
        rows.append([precision, what, True, BUILT_NOW if built else FROM_STORE])
    return Stage("compile", passed, ["precision", "build", "ok", "detail"], rows), libraries


def free_cores() -> int:
    """Cores no process is using now (this machine's, less the last minute's load), at least 1:
    the builds run side by side only on these."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    return max(1, int(cores - os.getloadavg()[0]))


def compile_and_prepare(config: VerifyConfig, work: Path, functions, found: GeneratedCode | None = None
                        ) -> tuple[Stage, dict[str, KernelLibrary], dict[str, dict[str, ReferenceSamples]]]:
    """The compile stage, its builds in parallel (compilers are processes), and meanwhile, on
    this thread, the callbacks stage's seeded inputs and interpreter outputs per precision."""
    builds = compile_builds(config, work, functions, found)
    total = len(builds) + len(config.precisions) * len(functions)
    with progress(total, "compile, and reference samples meanwhile") as bar, \
            ThreadPoolExecutor(max_workers=free_cores()) as pool:
        futures = [pool.submit(action) for _, _, action in builds]
        prepared = {precision: reference_samples(functions, config.robot, config.samples, config.seed, precision,
                                                 lambda: bar.update(1)) for precision in config.precisions}
        for _ in as_completed(futures):
            bar.update(1)
    stage, libraries = compile_stage(builds, futures)
    return stage, libraries, prepared


def stage_callbacks(config: VerifyConfig, libraries: dict[str, KernelLibrary], functions,
                    prepared: dict[str, dict[str, ReferenceSamples]] | None = None) -> Stage:
    """Every compiled function against the symbolic one at ``config.samples`` seeded inputs,
    per precision, evaluated in batches (one C call per function); ``prepared`` are the
    reference samples of :func:`compile_and_prepare` (else drawn here)."""
    rows, passed = [], True
    with progress(len(libraries) * len(functions), "callbacks") as bar:
        for precision, library in libraries.items():
            for r in compare_model(library, functions, config.robot, config.samples, config.seed,
                                   lambda: bar.update(1), (prepared or {}).get(precision)):
                rows.append([r.name, precision, r.samples, r.max_error, r.bound, r.passed])
                passed &= r.passed
    return Stage("callbacks", passed, ["function", "precision", "samples", "max error", "bound", "ok"], rows,
                 "" if rows else "nothing compared: no library was built")


def _angle_columns(plan, robot: Robot) -> list[str]:
    """Joint columns: q<i>_rad (resolved rate), theta_<joint>_rad (ptp), or each joint's by name
    (snake: feed_m, a1_rad, …)."""
    if plan.metadata.get("planner") == "snake":
        return [c for c in map(fw.sample_column, robot.joints) if c in plan.columns]
    return [c for c in plan.columns if (c.startswith("q") or c.startswith("theta_")) and c.endswith("_rad")]


@contextlib.contextmanager
def _work_dir(work: Path | None, prefix: str) -> Iterator[Path]:
    """``work`` when given, else a temporary folder removed when the block ends."""
    if work is not None:
        yield work
        return
    with tempfile.TemporaryDirectory(prefix=prefix) as tmp:
        yield Path(tmp)


def _firmware_gen_dir(config: VerifyConfig) -> Path | None:
    """The user's generated folder when the controller's binding (prefix = robot name) fits it;
    otherwise the builder generates its own copy."""
    manifest = config.gen_dir / "manifest.json"
    if manifest.is_file() and (config.gen_dir / f"{fw.robot_prefix(config.robot)}.h").is_file():
        return config.gen_dir.resolve()  # the compilers run in their own folders
    return None


def _firmware_builder(config: VerifyConfig, work: Path, builder: fw.FirmwareBuilder | None) -> fw.FirmwareBuilder:
    if builder is not None:
        return builder
    return fw.FirmwareBuilder(config.robot, work / "firmware", _firmware_gen_dir(config))


def load_plan(path: Path) -> PlanResult:
    """The plan, or a PlanFileError (exit 2) naming the file: never a traceback."""
    try:
        return read_plan(path)
    except PlanFileError:
        raise
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise PlanFileError(f"{path}: not a plan written by `armgen plan` ({exc}); give its CSV and plan.json") from None


def _firmware_task(config: VerifyConfig, plan, label: str) -> tuple[fw.FirmwareTask | None, list[Any]]:
    """The plan as a controller task, or the failing row that says why it cannot be one."""
    reason = fw.refusal(plan)
    if reason is None:
        try:
            task = fw.task_from_plan(plan, str(config.plan), config.robot)
        except ArmgenError as exc:
            reason = str(exc).splitlines()[0]
        else:
            if task.robot.sha256 != config.robot.sha256:
                reason = f"the plan is for robot '{task.robot.name}', not '{config.robot.name}'"
            else:
                return task, []
    return None, [label, "plan accepted", reason, "a plan the controller can run", False]


def firmware_replay_rows(config: VerifyConfig, plan, work: Path | None = None,
                         builder: fw.FirmwareBuilder | None = None) -> tuple[list[list[Any]], bool]:
    """Host firmware runs of the plan's task (double with ASan/UBSan, float), compared with the plan."""
    task, refused = _firmware_task(config, plan, "host firmware")
    if task is None:
        return [refused], False
    with _work_dir(work, "armgen-firmware-") as base:
        return _host_firmware_rows(config, plan, task, _firmware_builder(config, base, builder))


def _host_firmware_rows(config: VerifyConfig, plan, task: fw.FirmwareTask,
                        builder: fw.FirmwareBuilder) -> tuple[list[list[Any]], bool]:
    rows, passed = [], True
    for precision in config.precisions:
        sanitize = precision == "double"
        label = f"host firmware, {precision}" + (", ASan/UBSan" if sanitize else "")
        variant = fw.Variant("host", precision, sanitize=sanitize, opt="-O1" if sanitize else "-O2")
        try:
            run = fw.run_host(builder.executable(variant, task, f"replay_{precision}"))
        except ArmgenError as exc:
            rows.append([label, "build and run", str(exc).splitlines()[0], "exit 0, clean", False])
            passed = False
            continue
        cmp = fwcmp.compare_with_plan(plan, run, task, precision, label)
        rows += cmp.rows
        passed &= cmp.passed
    return rows, passed


def stage_replay(config: VerifyConfig, work: Path | None = None,
                 builder: fw.FirmwareBuilder | None = None) -> Stage:
    if config.plan is None:
        return Stage("replay", True, ["source"], [], "no --plan given", skipped=True)
    plan = load_plan(config.plan)
    task = plan.metadata.get("task")
    if not task:
        raise ArmgenError(f"{config.plan}: no task in its plan.json; replay needs the JSON sidecar written by `armgen plan`")
    columns = ["run", "quantity", "value", "bound", "ok"]
    replay = run_task(task, str(config.plan), plan.metadata.get("task_sha256", ""), "c")
    q_cols = _angle_columns(plan, config.robot)
    rows, passed = [], True
    if replay.data.shape != plan.data.shape:
        return Stage("replay", False, ["source"], [], f"sample count differs: plan {plan.data.shape}, replay {replay.data.shape}")
    dq = max((float(np.max(np.abs(replay.column(c) - plan.column(c)))) for c in q_cols), default=0.0)
    ok = dq <= REPLAY_DOUBLE_BOUND_RAD
    rows.append(["planner, C backend via casadi.Callback", "max |Δq| [rad]", dq, REPLAY_DOUBLE_BOUND_RAD, ok])
    passed &= ok
    if "pos_err_m" in plan.columns:
        de = float(np.max(np.abs(replay.column("pos_err_m") - plan.column("pos_err_m"))))
        ok = de <= REPLAY_TASK_ERROR_BOUND_M
        rows.append(["planner, C backend via casadi.Callback", "max |Δ task error| [m]", de, REPLAY_TASK_ERROR_BOUND_M, ok])
        passed &= ok
    fw_rows, fw_passed = firmware_replay_rows(config, plan, work, builder)
    rows += fw_rows
    passed &= fw_passed
    failed = sorted({r[0] for r in rows if r[-1] is False})
    message = "" if passed else "differs from the plan: " + "; ".join(failed)
    return Stage("replay", passed, columns, rows, message)


def _default_target_plan(config: VerifyConfig, work: Path) -> Path:
    """Without --plan: the demo task of ``armgen firmware`` (a short line from the robot's q0,
    its first named configuration, or mid-range), planned with the symbolic backend."""
    from ..planning.result import write_plan
    from ..firmware.project import plan_demo

    ref = config.robot_ref
    if not ref:  # a bundled robot by name, else its file
        try:
            ref = config.robot.name if load_robot(config.robot.name).sha256 == config.robot.sha256 else config.robot.source
        except ArmgenError:
            ref = config.robot.source
    _, result, _ = plan_demo(config.robot, ref, "target smoke task")
    path = work / "target_plan.csv"
    write_plan(result, path)
    return path


def stage_target(config: VerifyConfig, work: Path, builder: fw.FirmwareBuilder | None = None) -> Stage:
    """The firmware on an emulated core (fw.TARGETS; in the precision its FPU computes
    natively): build, run under QEMU, compare with the plan and with the host run of the
    same precision."""
    columns = ["run", "quantity", "value", "bound", "ok"]
    if config.target not in fw.TARGETS:
        return Stage("target", False, columns, [[config.target, "target", "unknown", ", ".join(fw.TARGETS), False]],
                     f"unknown target {excerpt(repr(config.target))}")
    target = fw.TARGETS[config.target]
    label = target.description
    try:
        fw.target_tools(target.name)
    except ArmgenError as exc:
        return Stage("target", False, columns, [[label, "toolchain", str(exc), "installed", False]],
                     f"the {target.name} toolchain or QEMU is missing; apt-get install -y {' '.join(target.apt_packages)}")
    try:
        plan_path = config.plan if config.plan is not None else _default_target_plan(config, work)
    except ArmgenError as exc:
        return Stage("target", False, columns, [[label, "smoke-test plan", str(exc).splitlines()[0], "planned", False]],
                     "no --plan given and the default smoke-test line could not be planned; pass --plan")
    plan = load_plan(Path(plan_path))
    target_config = dataclasses.replace(config, plan=Path(plan_path))
    task, refused = _firmware_task(target_config, plan, label)
    if task is None:
        return Stage("target", False, columns, [refused], "the controller cannot run this plan")
    builder = _firmware_builder(config, work, builder)
    rows, passed = [], True
    try:
        elf = builder.executable(fw.target_variant(target.name), task, "target")
        run = fw.run_qemu(elf, target=target.name)
    except ArmgenError as exc:
        return Stage("target", False, columns, [[label, "build and run", str(exc).splitlines()[0], "exit 0", False]],
                     f"the {target.name} build or the QEMU run failed")
    cmp = fwcmp.compare_with_plan(plan, run, task, target.precision, label)
    rows += cmp.rows
    passed &= cmp.passed
    try:  # the same task on the host in the same precision: how much of the difference is the target's
        host = fw.run_host(builder.executable(fw.Variant("host", target.precision), task,
                                              f"target_host_{target.precision}"))
        n = task.robot.n
        ticks = sorted(set(run.by_tick()) & set(host.by_tick()))
        a, b = run.by_tick(), host.by_tick()
        d = max((float(np.max(np.abs(a[k][2:2 + n] - b[k][2:2 + n]))) for k in ticks), default=0.0)
        bound = fwcmp.bounds_for(target.precision, task.mode)[0]
        rows.append([f"{config.target} vs host firmware, {target.precision}", "max |Δq| [rad]", d, bound, d <= bound])
        passed &= d <= bound
    except ArmgenError as exc:
        rows.append([f"host firmware, {target.precision}", "build and run", str(exc).splitlines()[0], "exit 0", False])
        passed = False
    ipt = fw.instructions_per_tick(run)
    rows.append([label, "instructions per tick, mean / max", f"{ipt['mean']:.0f} / {ipt['max']:.0f}",
                 "(informative)", True])
    rows.append([label, "peak stack [bytes]", run.summary.get("stack_peak_bytes", "?"), "(informative)", True])
    try:  # the static worst case (armgen.firmware.bound): no measured tick may exceed it
        static = static_bound.tick_bound(target, elf, builder.cflags(fw.target_variant(target.name)), builder.prefix,
                                  task.mode, task.header).instructions
        holds = static + ipt["resolution"] >= ipt["max"]  # a tick is measured to one timer count
        rows.append([label, "static bound per tick [instructions], bound / max", f"{static} ({static / ipt['max']:.2f})",
                     ">= max", holds])
        passed &= holds
    except (ArmgenError, OSError) as exc:  # a mode without a tick bound (docs/targets.md), no objdump
        rows.append([label, "static bound per tick", str(exc).splitlines()[0], "(informative)", True])
    message = "" if passed else f"the {target.name} run differs from the plan: see the rows marked FAIL"
    return Stage("target", passed, columns, rows, message)


def stage_run(config: VerifyConfig) -> Stage:
    """A firmware run the user made (``--run``: what the host demo or the Cortex-M4F image
    printed) compared with the plan, with the bounds of its precision."""
    columns = ["run", "quantity", "value", "bound", "ok"]
    if config.plan is None or config.run is None:
        raise OptionError("--run needs --plan: the plan the firmware ran (e.g. demo/plan.csv of `armgen firmware`)")
    plan = load_plan(config.plan)
    try:
        run = fw.parse_output(config.run.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError, ArmgenError) as exc:
        raise PlanFileError(f"{config.run}: not the output of an armgen firmware run ({str(exc).splitlines()[0]}); "
                            "give what the demo program or the QEMU run printed") from None
    # The runners print sizeof(ctrl_real); the Cortex-M4F image is float.
    precision = "double" if run.summary.get("real_bytes") == "8" else "float"
    label = f"{config.run.name} ({precision})"
    task, refused = _firmware_task(config, plan, label)
    if task is None:
        return Stage("run", False, columns, [refused], "the controller cannot run this plan")
    cmp = fwcmp.compare_with_plan(plan, run, task, precision, label)
    return Stage("run", cmp.passed, columns, cmp.rows, "" if cmp.passed else f"{config.run} differs from the plan")


STAGES = ("fresh", "compile", "callbacks", "replay")


def _not_run(name: str, reason: str) -> Stage:
    return Stage(name, False, ["reason"], [[reason]], "not run: " + reason)


def run_pipeline(config: VerifyConfig, report_path: Path | None = None,
                 echo: Callable[[str], None] = print) -> list[Stage]:
    found = read_manifest(config)
    stages: list[Stage] = []

    def add(stage: Stage) -> Stage:
        stages.append(stage)
        echo(stage.render())
        return stage

    with tempfile.TemporaryDirectory(prefix="armgen-verify-") as tmp:
        work = Path(tmp)
        with progress(1, "fresh (regenerating)") as bar:
            fresh = reused_fresh(config, work, found)
            bar.update(1)
        if not add(fresh).passed:
            stale = f"the code in {config.gen_dir} is stale; stale code is never compiled or run"
            for name in STAGES[1:] + (("target",) if config.target else ()) + (("run",) if config.run else ()):
                add(_not_run(name, stale))
        else:
            inputs = _verified_inputs(config, found, [row[0] for row in fresh.rows])
            for stage in verify_c(config, work, found, inputs):
                add(stage)
            builder = (fw.FirmwareBuilder(config.robot, work / "firmware", _firmware_gen_dir(config))
                       if (config.plan or config.target) else None)
            add(reused_replay(config, work, builder, inputs))
            if config.target is not None:
                add(stage_target(config, work, builder))
            if config.run is not None:
                add(stage_run(config))
    if report_path is not None:
        report = {"robot": config.robot.name, "generated": str(config.gen_dir), "passed": passed(stages),
                  "stages": [{"name": s.name, "verdict": s.verdict, "passed": s.passed, "skipped": s.skipped,
                              "reused": s.reused, "message": s.message, "columns": s.columns, "rows": s.rows}
                             for s in stages]}
        write_text_atomic(report_path, json.dumps(report, indent=2, default=float) + "\n")
    return stages


def _verified_inputs(config: VerifyConfig, found: GeneratedCode, files: list[str]) -> tuple:
    """What every verdict of this run depends on besides its own options: armgen, the compiler,
    the robot file and the bytes of the generated files (the fresh stage's, all identical to
    what armgen generates)."""
    return (reuse.armgen_fingerprint(), compiler_identity(), config.robot.sha256, found.prefix, found.functions,
            reuse.file_digests(config.gen_dir, files))


def reused_fresh(config: VerifyConfig, work: Path, found: GeneratedCode) -> Stage:
    """The fresh stage, or its stored verdict: regenerating is a function of armgen, the robot
    file and the manifest's options, so a folder whose files have the bytes that were found
    identical to armgen's output before (same armgen, robot file and options) is so again."""
    listing = sorted(f.name for f in config.gen_dir.iterdir() if f.is_file())
    key = reuse.content_key("fresh", reuse.armgen_fingerprint(), config.robot.sha256, dataclasses.astuple(found),
                            reuse.file_digests(config.gen_dir, listing))
    record = reuse.read_verdict("fresh", key) if config.reuse else None
    if record is not None:
        return Stage("fresh", True, ["file", "state", "ok"], record["rows"],
                     f"reused: these bytes were found identical to armgen's output {reuse.when(record)}", reused=True)
    stage = stage_fresh(config, work, found)
    if stage.passed:
        reuse.write_verdict("fresh", key, {"rows": stage.rows})
    return stage


def verify_c(config: VerifyConfig, work: Path, found: GeneratedCode, inputs: tuple) -> list[Stage]:
    """The compile and callbacks stages, per precision: a precision whose verdict on the same
    inputs (and samples, seed) is stored passed is not redone (:mod:`armgen.verification.reuse`);
    the others are built (or their builds taken from the store) and compared now, and their
    verdict stored when they pass (the CasADi functions are built only then)."""
    keys = {p: reuse.content_key("c", inputs, config.samples, config.seed, p) for p in config.precisions}
    records = {p: reuse.read_verdict("c", keys[p]) if config.reuse else None for p in config.precisions}
    todo = tuple(p for p in config.precisions if records[p] is None)
    if todo:
        again = dataclasses.replace(config, precisions=todo)
        functions = SymbolicModel(config.robot, ModelOptions(found.functions)).functions()
        compiled, libraries, prepared = compile_and_prepare(again, work, functions, found)
        callbacks = stage_callbacks(again, libraries, functions, prepared)
        for p in todo:
            mine = {"compile": [r for r in compiled.rows if r[0] == p], "callbacks": [r for r in callbacks.rows if r[1] == p]}
            if compiled.passed and callbacks.passed:
                reuse.write_verdict("c", keys[p], mine)
            records[p] = mine
    compile_rows = [r for p in config.precisions for r in records[p]["compile"]]
    callback_rows = [r for p in config.precisions for r in records[p]["callbacks"]]
    reused = [p for p in config.precisions if p not in todo]
    note = (f"{', '.join(reused)}: reused, verified {reuse.when(records[reused[0]])} on the same code, armgen, "
            "compiler and options" if reused else "")
    if todo:
        return [dataclasses.replace(compiled, rows=compile_rows, message=_joined(compiled.message, note)),
                dataclasses.replace(callbacks, rows=callback_rows, message=_joined(callbacks.message, note))]
    return [Stage("compile", True, ["precision", "build", "ok", "detail"], compile_rows, note, reused=True),
            Stage("callbacks", True, ["function", "precision", "samples", "max error", "bound", "ok"], callback_rows,
                  note, reused=True)]


def _joined(*messages: str) -> str:
    return "; ".join(m for m in messages if m)


def reused_replay(config: VerifyConfig, work: Path, builder: fw.FirmwareBuilder | None, inputs: tuple) -> Stage:
    """The replay stage, or its stored verdict on the same inputs, plan (its CSV's and plan.json's
    bytes) and precisions; a passed replay is stored."""
    if config.plan is None:
        return stage_replay(config, work, builder)
    try:
        plan_files = tuple(reuse.file_digests(Path(), [str(config.plan), str(metadata_path(config.plan))]))
    except OSError:
        return stage_replay(config, work, builder)  # (it names what is missing)
    key = reuse.content_key("replay", inputs, config.precisions, [digest for _, digest in plan_files])
    record = reuse.read_verdict("replay", key) if config.reuse else None
    if record is not None:
        return Stage("replay", True, ["run", "quantity", "value", "bound", "ok"], record["rows"],
                     f"reused, verified {reuse.when(record)} on the same plan, code, armgen, compiler and options",
                     reused=True)
    stage = stage_replay(config, work, builder)
    if stage.passed:
        reuse.write_verdict("replay", key, {"rows": stage.rows})
    return stage


def passed(stages: list[Stage]) -> bool:
    """The run passes when no stage failed and at least one compared something."""
    return all(s.passed for s in stages) and any(not s.skipped for s in stages)
