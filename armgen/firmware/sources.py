"""The firmware stub's sources (``armgen/data/firmware_stub/``) and the generated functions of
a robot that the controller calls, extracted byte for byte from ``generated/<robot>/<robot>.c``."""

from __future__ import annotations

import re
from importlib import resources
from pathlib import Path
from typing import Sequence

from ..robot import Robot

FIRMWARE_DIR = Path(str(resources.files("armgen.data") / "firmware_stub"))
ARM_DIR = FIRMWARE_DIR / "arm"
PTP_PREFIX = "fw"  # fw_ptp_eval, fw_real: must not clash with the robot prefix


def robot_prefix(robot: Robot) -> str:
    return re.sub(r"[^0-9a-zA-Z_]", "_", robot.name).lower()


# The generated functions the controller calls: always, and per optional feature (a robot whose
# generated code lacks them gets a firmware without it: -DCTRL_HAS_<FEATURE>=0). The steps take
# the J of the tick's fk_jacobian (their *_from_jacobian twins); DYNAMICS (a robot with
# inertials) is each command's feed-forward torque and the TORQUE fault; COLLISION (a robot with
# capsules) the clearance check and the collision criterion of a task with [collision] (the task's
# task_params.h binds them to its obstacles: a task without links neither).
FIRMWARE_FUNCTIONS = ("fk_jacobian", "zghal", "repetitive", "step_gpm_from_jacobian")
OPTIONAL_FUNCTIONS = {"FAULT_TOLERANT": ("ft_index_from_jacobian", "wln_weights", "step_fault_from_jacobian"),
                      "WEIGHTED_GPM": ("step_wgpm_from_jacobian",),
                      "MOVE_TO": ("ik",),
                      "DYNAMICS": ("gravity", "rnea"),
                      "COLLISION": ("collision_distances", "collision_criterion")}


def available_modes(source: str, prefix: str) -> tuple[str, ...]:
    """The optional controller features whose generated functions the robot's source defines."""
    return tuple(mode for mode, names in OPTIONAL_FUNCTIONS.items()
                 if all(re.search(rf"^(?:void|{prefix}_status) {prefix}_{n}\(", source, re.M) for n in names))


def firmware_functions(source: str, prefix: str) -> tuple[str, ...]:
    """Every generated function the firmware of this robot calls."""
    return FIRMWARE_FUNCTIONS + tuple(n for mode in available_modes(source, prefix) for n in OPTIONAL_FUNCTIONS[mode])


def extract_functions(source: str, prefix: str, names: Sequence[str] = FIRMWARE_FUNCTIONS) -> str | None:
    """The generated source reduced to the named functions: its preamble and includes, then
    each definition byte for byte. None when the file does not have the generator's layout
    (``/* name: ops */`` above each definition) or lacks a function.

    The firmware needs a few of the robot's functions; compiling only those keeps the builds
    fast (the whole generated file of modular8 is > 40 000 lines)."""
    pattern = re.compile(rf"^/\* (\w+): [^\n]*\*/\n(?:void|{prefix}_status) {prefix}_(\w+)\(", re.M)
    matches = list(pattern.finditer(source))
    if not matches or any(m.group(1) != m.group(2) for m in matches):
        return None
    blocks = {m.group(1): source[m.start():(nxt.start() if nxt is not None else len(source))]
              for m, nxt in zip(matches, [*matches[1:], None])}
    if not all(n in blocks for n in names):
        return None
    # and the loop functions (symbolic.loops) that those call
    names = [*names, *(m for m in blocks if m not in names and any(f" {prefix}_{m}(" in blocks[n] for n in names))]
    note = (f"/* The definitions of {', '.join(names)} from {prefix}.c, byte for byte\n"
            " * (extracted by armgen.firmware for the firmware build). */\n")
    body = "".join(blocks[n].rstrip("\n") + "\n\n" for n in names)
    return source[:matches[0].start()] + note + "\n" + body

