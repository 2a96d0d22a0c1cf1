"""The static worst-case bounds of a firmware project (``armgen firmware --bound TARGET``, issue
42; ``armgen firmware-task --bound TARGET`` writes them beside the task files, :data:`BOUNDS_FILE`): the project's own generated code and task built for a core of targets.TARGETS as armgen's
verify builds it (FirmwareBuilder, target_variant), and armgen.firmware.bound's count of each
generated function in that image and of a running tick of the task's mode, with the cycle
bound where the core has a cycle model. The result goes into the project's manifest
(``"bounds"``) and a table of its README; docs/targets.md, "Static bound", states the
assumptions.
"""

from __future__ import annotations

import dataclasses
import inspect
import json
import tempfile
from pathlib import Path
from typing import Any

from ..codegen.generate import GENERATED_DIR
from ..codegen.toolchain import find_tool
from ..fileio import write_text_atomic
from ..errors import OptionError
from ..robot import Robot
from . import bound
from .builder import FirmwareBuilder, target_variant
from .configuration import FirmwareTask, write_task_files
from .targets import TARGETS, Target

BOUNDS_FILE = "bounds.json"  # `armgen firmware-task --bound`'s: the manifest's "bounds" list

# The cycle models of bound.py, per core, each with the assumption that tells them apart; the
# Cortex-M4F's at no flash wait state (SRAM, or a flash accelerator that always hits) and at 5
# (an STM32F4 at 168 MHz with nothing cached).
CYCLE_MODELS = {
    "cortex-m4": (("0 flash wait states", bound.CortexM4Cycles(0)),
                  ("5 flash wait states", bound.CortexM4Cycles(5))),
    "cortex-m0plus": (("zero-wait-state memory", bound.CortexM0PlusCycles()),),
}

# What every bound assumes of the C library (bound.py: LIBRARY_LOOPS, HUGE_ARGUMENT_REDUCTION).
LIBRARY_ASSUMPTIONS = (
    *(f"`{name}`: at most {turns} turns ({why})" for name, (turns, why) in bound.LIBRARY_LOOPS.items()),
    f"{', '.join('`' + n + '`' for n in bound.HUGE_ARGUMENT_REDUCTION)} (sin/cos of a huge argument) is not on any path: no argument of "
    "the controller's and the generated code's sin/cos is that large (joint angles within their limits, the time "
    "law's phases)",
)


def bound_targets(values: list[str] | tuple[str, ...]) -> list[str]:
    """The cores of ``--bound`` (repeated or comma lists), in order, each once; an unknown name
    is an OptionError naming the choices."""
    names = [name.strip() for value in values for name in value.split(",") if name.strip()]
    unknown = [name for name in names if name not in TARGETS]
    if unknown:
        raise OptionError(f"--bound {unknown[0]}: not a target; give one of {', '.join(TARGETS)}")
    return list(dict.fromkeys(names))


def require_bound_tools(target: Target) -> None:
    """The cross compiler and the binutils the bound reads the image with, or a ToolchainError
    (exit 4) naming the packages to install."""
    hint = (f"--bound {target.name} builds the project for that core: install its cross toolchain "
            f"(apt-get install -y {' '.join(p for p in target.apt_packages if not p.startswith('qemu'))}) "
            "or leave --bound out (nothing was written)")
    tools = target.compiler.removesuffix("gcc")
    for tool in (target.compiler, f"{tools}objdump", f"{tools}addr2line"):
        find_tool(tool, hint)


def _assumptions(model) -> str:
    """A cycle model's stated assumptions: its docstring, one paragraph."""
    return " ".join(inspect.cleandoc(type(model).__doc__ or "").split())


def project_bounds(target: Target, robot: Robot, gen_dir: Path, task: FirmwareTask) -> dict[str, Any]:
    """The bounds of the project whose generated code is ``gen_dir`` running ``task``, built for
    ``target`` in a temporary folder: {"target", "mode", "functions": {name: {"instructions",
    "cycles": {model: n}}}, "tick": {...}, "cycle_models": {model: assumptions},
    "library_assumptions": [...]}."""
    require_bound_tools(target)
    with tempfile.TemporaryDirectory(prefix="armgen-bound-") as work:
        builder = FirmwareBuilder(robot, work, gen_dir)
        variant = dataclasses.replace(target_variant(target.name), print_rows=False)
        elf = builder.executable(variant, task, "bound")
        flags = builder.cflags(variant)
        models = CYCLE_MODELS.get(target.name, ())
        analyzers = [("instructions", bound.analyzer(target, elf, flags))]
        analyzers += [(name, bound.analyzer(target, elf, flags, block_cost=model)) for name, model in models]
        names = bound.generated_functions(analyzers[0][1], builder.prefix, Path(gen_dir) / f"{builder.prefix}.h")
        mode = task.mode.upper()
        avoid = bound.tick_avoid(builder.prefix, mode, "CTRL_PATH_PROGRAM" in task.header)
        for _, a in analyzers:  # as bound.tick_bound: PLAYBACK's bisection, a program's searches
            bound.set_tick_ranges(a, mode, task.header)

        def entry(function: str, avoided: tuple[str, ...] = ()) -> dict[str, Any]:
            counts = {name: a.bound(function, avoided).instructions for name, a in analyzers}
            row: dict[str, Any] = {"instructions": counts.pop("instructions")}
            if counts:
                row["cycles"] = counts
            return row

        tick = entry("ctrl_tick", avoid)
        return {"target": target.name, "precision": target.precision, "mode": mode,
                "functions": {name: entry(name) for name in names}, "tick": tick,
                "cycle_models": {name: _assumptions(model) for name, model in models},
                "library_assumptions": list(LIBRARY_ASSUMPTIONS)}


def readme_table(bounds: list[dict[str, Any]]) -> str:
    """The README's table of ``bounds`` (one per core), with the cycle models' assumptions."""
    lines = ["Static worst-case bounds of this project, computed by `armgen firmware --bound` (instructions; "
                 "cycles where the core has a cycle model):", ""]
    for b in bounds:
        models = list(b["cycle_models"])
        lines += [f"**{b['target']}** ({b['precision']}):", "",
                  "| function | instructions |" + "".join(f" cycles, {m} |" for m in models),
                  "|---|---:|" + "---:|" * len(models)]
        rows = [(f"`ctrl_tick` ({b['mode']} mode, running)", b["tick"])]
        rows += [(f"`{name}`", row) for name, row in b["functions"].items()]
        for label, row in rows:
            lines.append(f"| {label} | {row['instructions']} |"
                         + "".join(f" {row['cycles'][m]} |" for m in models))
        lines.append("")
        texts: dict[str, list[str]] = {}  # one model's assumptions at several settings: stated once
        for m, text in b["cycle_models"].items():
            texts.setdefault(text.replace("``", "`"), []).append(m)
        lines += [f"- cycles, {' / '.join(ms)}: {text}" for text, ms in texts.items()]
        if texts:
            lines.append("")
    lines += ["Library assumptions:", ""] + [f"- {a}" for a in LIBRARY_ASSUMPTIONS]
    return "\n".join(lines) + "\n"


def write_task_files_with_bounds(task: FirmwareTask, out_dir: str | Path, gen_dir: str | Path | None,
                                 bound: list[str] | tuple[str, ...]) -> list[Path]:
    """configuration.write_task_files, and with cores in ``bound`` (as ``--bound``) the bounds
    of the task's build for each (:func:`project_bounds`) in :data:`BOUNDS_FILE`: toolchains
    checked and bounds computed before any file is written."""
    targets = [TARGETS[name] for name in bound_targets(bound)]
    for target in targets:
        require_bound_tools(target)
    generated = Path(gen_dir) if gen_dir is not None else GENERATED_DIR / task.robot.name
    bounds = [project_bounds(target, task.robot, generated, task) for target in targets]
    paths = write_task_files(task, out_dir, gen_dir)
    if bounds:
        path = Path(out_dir) / BOUNDS_FILE
        write_text_atomic(path, json.dumps(bounds, indent=1) + "\n")
        paths.append(path)
    return paths
