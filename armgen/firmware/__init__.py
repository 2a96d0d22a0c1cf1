"""The firmware: the controller stub (``armgen/data/firmware_stub/``) driven from Python, one
concept per module —

- :mod:`.tasks`: a task or a plan turned into the controller's C configuration by its planner's
  adapter (:mod:`.adapters`), on :mod:`.configuration`'s shared fields and the C templates;
- :mod:`.sources`: the stub's sources and the robot's generated functions it calls;
- :mod:`.builder`: the host and cross builds; :mod:`.targets`: the cores (flags, QEMU machine);
- :mod:`.runners` and :mod:`.output`: running a build and parsing what it printed;
- :mod:`.project`: the self-contained project ``armgen firmware`` writes.

``armgen.verification`` compares the runs with the plans (:mod:`armgen.verification.firmware_compare`).
"""

from .builder import APT_PACKAGES, ARM_VARIANT, FirmwareBuilder, Variant, arm_tools, target_tools, target_variant
from .configuration import MAX_SEGMENTS, FirmwareTask, sample_column, schedule_lock, write_task_files
from .errors import FirmwareError
from .output import FAULT_NAMES, FAULT_STATE, STATE_NAMES, FirmwareRun, instructions_per_tick, parse_output
from .runners import QEMU_ICOUNT, QEMU_MACHINE, run_host, run_qemu
from .sources import FIRMWARE_DIR, FIRMWARE_FUNCTIONS, OPTIONAL_FUNCTIONS, robot_prefix
from .targets import TARGETS, Target
from .tasks import refusal, task_from_dict, task_from_file, task_from_plan

__all__ = ["APT_PACKAGES", "ARM_VARIANT", "FAULT_NAMES", "FAULT_STATE", "FIRMWARE_DIR", "FIRMWARE_FUNCTIONS",
           "MAX_SEGMENTS", "OPTIONAL_FUNCTIONS", "QEMU_ICOUNT", "QEMU_MACHINE", "STATE_NAMES", "TARGETS", "FirmwareBuilder",
           "FirmwareError", "FirmwareRun", "FirmwareTask", "Target", "Variant", "arm_tools",
           "instructions_per_tick", "parse_output", "refusal", "robot_prefix", "run_host", "run_qemu", "sample_column",
           "schedule_lock", "target_tools", "target_variant", "task_from_dict", "task_from_file", "task_from_plan", "write_task_files"]
