"""The firmware's error: a task the controller cannot run, or a firmware run that failed."""

from __future__ import annotations

from ..errors import ArmgenError


class FirmwareError(ArmgenError):
    """A task the controller cannot run, or a firmware run that failed."""

    exit_code = 5

