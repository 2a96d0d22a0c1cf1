"""Error types. Every user-facing failure is an ArmgenError with a message that names
the file, the field and the fix; the CLI maps the class to an exit code."""


class ArmgenError(Exception):
    """Base class of all expected (user-facing) failures."""

    exit_code = 1


class RobotFileError(ArmgenError):
    """A robot description is malformed (missing field, wrong type, NaN, bad limits...)."""

    exit_code = 2


class TaskFileError(ArmgenError):
    """A task file is malformed or asks for something impossible."""

    exit_code = 2


class PlanningError(ArmgenError):
    """A plan cannot be completed (unreachable target, start outside limits, infeasible timing)."""

    exit_code = 3


class ToolchainError(ArmgenError):
    """A required external tool (compiler, emulator) is missing or failed."""

    exit_code = 4


class VerificationError(ArmgenError):
    """A verification stage failed."""

    exit_code = 5


class OutputError(ArmgenError):
    """An output cannot be written (the name is a directory, a read-only folder, a full disk)."""

    exit_code = 4


class PlanFileError(ArmgenError):
    """A plan CSV or its plan.json is malformed."""

    exit_code = 2


class OptionError(ArmgenError):
    """A command-line option has an invalid value (e.g. a C prefix that is a keyword)."""

    exit_code = 2
