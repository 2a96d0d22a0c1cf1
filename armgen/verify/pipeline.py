"""``armgen verify``: the plan-and-verify pipeline of spec 60.

Stages (each a function returning a :class:`Stage` with a table of rows):
1. fresh    — regenerate into a temp dir; the checked-in ``generated/<robot>/`` must match;
2. compile  — strict gcc flags, float and double, plus an ASan/UBSan driver run;
3. callbacks — each compiled function as a ``casadi.Callback`` against the interpreter at N
   seeded samples (near-singular and near-limit included), per-precision bounds;
4. replay   — rerun the plan's task with the C backend (the same planner code) and compare
   with the plan CSV sample by sample; the firmware stub's host run when it is built;
5. target   — (``--target cortex-m4``) the firmware on an emulated Cortex-M4F, if available.
"""

from __future__ import annotations

import json
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..codegen.generate import REPO_GENERATED_DIR, CodegenConfig, generate, write
from ..errors import ArmgenError
from ..fileio import write_text_atomic
from ..planning.result import read_plan
from ..planning.tasks import run_task
from ..robot import Robot, load_robot
from ..symbolic.model import SymbolicModel
from .compare import compare_model
from .compiled import CompiledModel, build_library
from .harness import run_sanitized

# Replaying a plan through the double C backend performs the same operations as the symbolic
# run; libm may differ by an ulp per call, which 12 500 integration steps can amplify by at
# most ~1e4 × eps: 1e-9 rad (≈ 6e-8 deg) leaves a wide margin and still catches any real bug.
REPLAY_DOUBLE_BOUND_RAD = 1e-9
REPLAY_TASK_ERROR_BOUND_M = 1e-9


@dataclass
class Stage:
    name: str
    passed: bool
    columns: list[str]
    rows: list[list[Any]] = field(default_factory=list)
    message: str = ""

    def render(self) -> str:
        widths = [max(len(str(c)), *(len(_fmt(r[k])) for r in self.rows)) if self.rows else len(str(c))
                  for k, c in enumerate(self.columns)]
        lines = [f"== {self.name}: {'PASS' if self.passed else 'FAIL'}" + (f" — {self.message}" if self.message else "")]
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


@dataclass
class VerifyConfig:
    robot: Robot
    plan: Path | None = None
    samples: int = 10_000
    precisions: tuple[str, ...] = ("double", "float")
    target: str | None = None
    seed: int = 20261122


def stage_fresh(config: VerifyConfig, work: Path) -> Stage:
    code = generate(CodegenConfig(config.robot))
    fresh_dir = work / "fresh"
    write(code, fresh_dir)
    checked_in = REPO_GENERATED_DIR / config.robot.name
    rows = []
    for name, text in sorted(code.files.items()):
        path = checked_in / name
        same = path.is_file() and path.read_text(encoding="utf-8") == text
        rows.append([name, "missing" if not path.is_file() else ("identical" if same else "stale"), same])
    passed = all(r[2] for r in rows)
    msg = "" if passed else f"update with `armgen gen {config.robot.name}` and commit generated/{config.robot.name}/"
    return Stage("fresh", passed, ["file", "state", "ok"], rows, msg)


def stage_compile(config: VerifyConfig, work: Path, functions) -> tuple[Stage, dict[str, Path]]:
    gen_dir = REPO_GENERATED_DIR / config.robot.name
    prefix = config.robot.name
    rows, libraries = [], {}
    passed = True
    for precision in config.precisions:
        for what, action in (("strict -O2 shared library", lambda p=precision: build_library(gen_dir, prefix, p, work)),
                             ("ASan/UBSan driver", lambda p=precision: run_sanitized(gen_dir, prefix, functions, p))):
            try:
                out = action()
                if isinstance(out, Path):
                    libraries[precision] = out
                rows.append([precision, what, True, ""])
            except ArmgenError as exc:
                passed = False
                rows.append([precision, what, False, str(exc).splitlines()[0]])
    return Stage("compile", passed, ["precision", "build", "ok", "detail"], rows), libraries


def stage_callbacks(config: VerifyConfig, libraries: dict[str, Path], functions) -> Stage:
    rows, passed = [], True
    for precision, library in libraries.items():
        compiled = CompiledModel(library, config.robot.name, functions, precision)
        for r in compare_model(compiled, functions, config.robot, config.samples, config.seed):
            rows.append([r.name, precision, r.samples, r.max_error, r.bound, r.passed])
            passed &= r.passed
    return Stage("callbacks", passed, ["function", "precision", "samples", "max error", "bound", "ok"], rows)


def stage_replay(config: VerifyConfig) -> Stage:
    if config.plan is None:
        return Stage("replay", True, ["source"], [], "skipped: no --plan given")
    plan = read_plan(config.plan)
    task = plan.metadata.get("task")
    if not task:
        raise ArmgenError(f"{config.plan}: no task in its plan.json; replay needs the JSON sidecar written by `armgen plan`")
    replay = run_task(json.loads(json.dumps(task)), str(config.plan), plan.metadata.get("task_sha256", ""), "c")
    q_cols = [c for c in plan.columns if c.startswith("q") and c.endswith("_rad")]
    rows, passed = [], True
    if replay.data.shape != plan.data.shape:
        return Stage("replay", False, ["source"], [], f"sample count differs: plan {plan.data.shape}, replay {replay.data.shape}")
    dq = max(float(np.max(np.abs(replay.column(c) - plan.column(c)))) for c in q_cols)
    ok = dq <= REPLAY_DOUBLE_BOUND_RAD
    rows.append(["planner, C backend via casadi.Callback", "max |Δq| [rad]", dq, REPLAY_DOUBLE_BOUND_RAD, ok])
    passed &= ok
    if "pos_err_m" in plan.columns:
        de = float(np.max(np.abs(replay.column("pos_err_m") - plan.column("pos_err_m"))))
        ok = de <= REPLAY_TASK_ERROR_BOUND_M
        rows.append(["planner, C backend via casadi.Callback", "max |Δ task error| [m]", de, REPLAY_TASK_ERROR_BOUND_M, ok])
        passed &= ok
    return Stage("replay", passed, ["run", "quantity", "value", "bound", "ok"], rows)


def run_pipeline(config: VerifyConfig, report_path: Path | None = None,
                 echo: Callable[[str], None] = print) -> list[Stage]:
    functions = SymbolicModel(config.robot).functions()
    stages: list[Stage] = []
    with tempfile.TemporaryDirectory(prefix="armgen-verify-") as tmp:
        work = Path(tmp)
        stages.append(stage_fresh(config, work))
        echo(stages[-1].render())
        compile_stage, libraries = stage_compile(config, work, functions)
        stages.append(compile_stage)
        echo(compile_stage.render())
        stages.append(stage_callbacks(config, libraries, functions))
        echo(stages[-1].render())
        stages.append(stage_replay(config))
        echo(stages[-1].render())
        if config.target is not None:
            stages.append(Stage("target", False, ["target"], [[config.target]],
                                "the Cortex-M firmware run is not available in this version"))
            echo(stages[-1].render())
    if report_path is not None:
        report = {"robot": config.robot.name, "passed": all(s.passed for s in stages),
                  "stages": [{"name": s.name, "passed": s.passed, "message": s.message, "columns": s.columns,
                              "rows": s.rows} for s in stages]}
        write_text_atomic(report_path, json.dumps(report, indent=2, default=float) + "\n")
    return stages


def verify(robot: str, plan: str | None = None, samples: int = 10_000, precision: str | None = None,
           target: str | None = None, report: str | None = None, echo: Callable[[str], None] = print) -> bool:
    precisions = (precision,) if precision else ("double", "float")
    config = VerifyConfig(load_robot(robot), Path(plan) if plan else None, samples, precisions, target)
    stages = run_pipeline(config, Path(report) if report else None, echo)
    return all(s.passed for s in stages)
