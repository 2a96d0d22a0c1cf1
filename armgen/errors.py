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


class RobotMismatchError(ArmgenError):
    """A task or plan for another robot than the one given (e.g. the robot a firmware is built
    for): nothing of it can run on that robot."""

    exit_code = 5


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


class Interrupted(ArmgenError):
    """The user interrupted a long command (Ctrl-C); the message says what was kept."""

    exit_code = 130


class PlanFileError(ArmgenError):
    """A plan CSV or its plan.json is malformed."""

    exit_code = 2


class OptionError(ArmgenError):
    """A command-line option has an invalid value (e.g. a C prefix that is a keyword)."""

    exit_code = 2


# An error message quotes at most this much of an offending value (a name, a path, a cell):
# enough to find it, never a megabyte of it.
EXCERPT_CHARS = 60


def excerpt(value: object, limit: int = EXCERPT_CHARS) -> str:
    """``value`` (its text, else its repr) cut to ``limit`` characters, saying how long it was."""
    text = value if isinstance(value, str) else repr(value)
    return text if len(text) <= limit else f"{text[:limit]}… ({len(text)} characters)"
