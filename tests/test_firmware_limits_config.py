"""`armgen firmware` refuses, when it writes the project, the speed and acceleration limits the
controller's ``ctrl_init`` would refuse at run time (BAD_CONFIG) (issue 37 item 11)."""

from __future__ import annotations

import math
import re
import tempfile
from pathlib import Path

import pytest

from armgen.errors import RobotFileError
from armgen.firmware import configuration
from armgen.robot import load_robot

REPO = Path(__file__).resolve().parent.parent
CONTROLLER_C = REPO / "armgen" / "data" / "firmware_stub" / "controller.c"
PLANAR3 = REPO / "armgen" / "data" / "robots" / "planar3.toml"


def _define(name: str) -> float:
    match = re.search(rf"#define {name} CTRL_LIT\(([^)]*)\)", CONTROLLER_C.read_text())
    assert match, f"controller.c defines no {name}"
    return float(match.group(1))


def test_mirrored_bounds_equal_the_controllers():
    for name in ("QDOT_MAX_LIMIT", "QDDOT_MAX_LIMIT", "MOVE_TO_BLEND", "MOVE_TO_MARGIN", "MOVE_TO_MAX_TICKS"):
        assert getattr(configuration, name) == _define(name), name


def _planar3_with_speed(tmp_path: Path, qdlim_deg_s: float) -> Path:
    robot = tmp_path / "slow3.toml"
    text = PLANAR3.read_text().replace('name = "planar3"', 'name = "slow3"')
    robot.write_text(text.replace("qdlim = 180", f"qdlim = {qdlim_deg_s!r}", 1))
    return robot


def test_a_speed_limit_the_controller_refuses_is_a_robot_file_error():
    # planar3's joint 1 travels 340° = 5.934 rad; at a 10 ms tick the whole-range move takes
    # 5.934 / (0.75 · 0.999 · qdlim) / 0.01 ticks (the speed phase dominates at these speeds),
    # 2^24 at qdlim = 4.722e-5 rad/s = 2.705e-3 deg/s: 1 % either side is refused / taken.
    bound_deg_s = 5.934119456780721 / (0.75 * 0.999 * 2.0 ** 24 * 0.01) * 180 / math.pi
    slow, fast = (load_robot(str(_planar3_with_speed(Path(tmp), bound_deg_s * f)))
                  for tmp, f in ((tempfile.mkdtemp(), 0.99), (tempfile.mkdtemp(), 1.01)))
    with pytest.raises(RobotFileError, match=r"joint j1: qdlim .* raise the limits in the robot file"):
        configuration.check_controller_limits(slow, 0.01)
    configuration.check_controller_limits(fast, 0.01)
    assert RobotFileError.exit_code == 2


def test_limits_beyond_the_controllers_upper_bounds_are_refused(tmp_path):
    robot = load_robot(str(_planar3_with_speed(tmp_path, 1.0e3 * 180 / math.pi * 1.01)))
    with pytest.raises(RobotFileError, match="qdlim ≤ 1000"):
        configuration.check_controller_limits(robot, 0.01)
