"""Joint speed limits in the robot model: robot files (units, absent = unlimited, bad values),
URDF ``<limit velocity>``, the bundled robots' published values, ``armgen show`` and the
generated header's ``<P>_QDLIM`` constants (compiled and read back)."""

from __future__ import annotations

import json
import math
import subprocess
from pathlib import Path

import numpy as np
import pytest

from armgen.errors import RobotFileError
from armgen.robot import Robot, load_robot, parse_robot

from conftest import require_tool

ROBOT = """
name = "two"
convention = "standard"
[units]
length = "mm"
angle = "deg"
[[joints]]
type = "revolute"
a = 100
d = 0
alpha = 0
qlim = [-90, 90]
{j1}
[[joints]]
type = "prismatic"
a = 0
d = 0
alpha = 0
qlim = [0, 200]
{j2}
"""

URDF = """<?xml version="1.0"?>
<robot name="vel">
  <link name="base"/><link name="l1"/><link name="l2"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="10" velocity="{v1}"/></joint>
  <joint name="j2" type="prismatic"><parent link="l1"/><child link="l2"/><origin xyz="0.1 0 0"/><axis xyz="1 0 0"/>
    <limit lower="0" upper="0.2" effort="10" {v2}/></joint>
</robot>
"""


def test_file_units_are_converted_to_si():
    robot = parse_robot(ROBOT.format(j1="qdlim = 90\nqddlim = 360", j2="qdlim = 250"), "two.toml")
    assert robot.qdlim == pytest.approx([math.pi / 2, 0.25], rel=1e-15)
    assert robot.qddlim[0] == pytest.approx(2 * math.pi, rel=1e-15)
    assert robot.qddlim[1] == math.inf  # not given: unlimited


def test_absent_limits_are_unlimited():
    robot = parse_robot(ROBOT.format(j1="", j2=""), "two.toml")
    assert np.all(np.isinf(robot.qdlim)) and np.all(np.isinf(robot.qddlim))


@pytest.mark.parametrize("value", ["0", "-5", "nan", "\"fast\""])
def test_bad_limits_are_rejected(value):
    with pytest.raises(RobotFileError, match="qdlim"):
        parse_robot(ROBOT.format(j1=f"qdlim = {value}", j2=""), "two.toml")


def test_urdf_velocity_is_read(tmp_path):
    path = tmp_path / "vel.urdf"
    path.write_text(URDF.format(v1="1.5", v2='velocity="0.3"'))
    assert Robot.from_urdf(path).qdlim == pytest.approx([1.5, 0.3], rel=1e-15)
    # absent or 0 (an exporter's placeholder): unlimited
    path.write_text(URDF.format(v1="0", v2=""))
    assert np.all(np.isinf(Robot.from_urdf(path).qdlim))
    path.write_text(URDF.format(v1="-1", v2=""))
    with pytest.raises(RobotFileError, match="velocity"):
        Robot.from_urdf(path)


# Published values, typed from the manufacturers' documents (independent of the robot files):
# KUKA LBR iiwa 14 R820 data sheet axis speeds (deg/s), Franka Emika Panda q̇_max (rad/s) and q̈_max.
IIWA14_AXIS_SPEEDS_DEG_S = [85, 85, 100, 75, 130, 135, 135]
PANDA_QD_MAX = [2.1750, 2.1750, 2.1750, 2.1750, 2.6100, 2.6100, 2.6100]
PANDA_QDD_MAX = [15, 7.5, 10, 12.5, 15, 20, 20]


def test_bundled_robots_carry_published_limits():
    assert load_robot("iiwa14").qdlim == pytest.approx(np.radians(IIWA14_AXIS_SPEEDS_DEG_S), rel=1e-15)
    panda = load_robot("panda")
    assert panda.qdlim == pytest.approx(PANDA_QD_MAX, rel=1e-15)
    assert panda.qddlim == pytest.approx(PANDA_QDD_MAX, rel=1e-15)
    for name in ("modular8", "planar3", "snake12"):
        assert np.all(np.isfinite(load_robot(name).qdlim)), f"{name}: every joint needs a documented qdlim"


def test_panda_limits_match_the_example_robot_data_urdf():
    """A second source: the Panda URDF of example-robot-data, read by Pinocchio."""
    pin = pytest.importorskip("pinocchio")
    from test_urdf import _example_robot_data_dir

    model = pin.buildModelFromUrdf(str(_example_robot_data_dir() / "panda_description/urdf/panda.urdf"))
    assert load_robot("panda").qdlim == pytest.approx(np.asarray(model.velocityLimit)[:7], rel=1e-12)


def test_show_reports_limits_and_unlimited(tmp_path):
    from click.testing import CliRunner

    from armgen.cli.main import cli

    out = CliRunner().invoke(cli, ["show", "iiwa14"])
    assert out.exit_code == 0 and "qdlim=85 deg/s" in out.output and "qddlim=unlimited" in out.output
    data = json.loads(CliRunner().invoke(cli, ["show", "panda", "--json"]).output)
    assert [j["qddlim"] for j in data["joints"]] == pytest.approx(PANDA_QDD_MAX)
    path = tmp_path / "two.toml"
    path.write_text(ROBOT.format(j1="", j2=""))
    data = json.loads(CliRunner().invoke(cli, ["show", str(path), "--json"]).output)
    assert [j["qdlim"] for j in data["joints"]] == [None, None]


def test_header_constants_compile_and_hold_the_limits(tmp_path):
    """<P>_QDLIM initialises an array in strict C99 (float and double) to the robot's limits;
    a robot without acceleration limits has no <P>_QDDLIM."""
    require_tool("gcc")
    from armgen.codegen.generate import CodegenConfig, generate
    from armgen.codegen.toolchain import STRICT_FLAGS

    robot = load_robot("iiwa14")
    files = generate(CodegenConfig(robot, functions=("fk",))).files
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    assert "#define IIWA14_QDDLIM" not in files["iiwa14.h"]
    (tmp_path / "main.c").write_text(
        '#include <stdio.h>\n#include "iiwa14.h"\nint main(void) {\n'
        "  static const iiwa14_real qdlim[IIWA14_NDOF] = IIWA14_QDLIM;\n"
        '  for (int i = 0; i < IIWA14_NDOF; ++i) { printf("%.17g\\n", (double)qdlim[i]); }\n  return 0;\n}\n')
    for define, rel in (("IIWA14_USE_FLOAT=0", 1e-15), ("IIWA14_USE_FLOAT=1", 1e-7)):
        exe = tmp_path / "main"
        subprocess.run(["gcc", *STRICT_FLAGS, f"-D{define}", str(tmp_path / "main.c"), str(tmp_path / "iiwa14.c"),
                        "-lm", "-o", str(exe)], check=True, capture_output=True)
        values = [float(v) for v in subprocess.run([str(exe)], check=True, capture_output=True,
                                                    text=True).stdout.split()]
        assert values == pytest.approx(np.radians(IIWA14_AXIS_SPEEDS_DEG_S), rel=rel)


# A fixed-duration circle: the iiwa14 fault example, two turns in 4 s (joint a4 at 0.56 of its
# qdlim); squeezed into SQUEEZED_S (the lock at 2 s stays inside) it asks a4 for more than its limit.
CIRCLE_EXAMPLE = "iiwa14_fault_circle_gpm.toml"
EXAMPLES = Path(__file__).resolve().parent.parent / "armgen" / "data" / "examples"
SQUEEZED_S = 2.0


def _plan_circle(tmp_path, *extra: str):
    from click.testing import CliRunner

    from armgen.cli.main import cli

    out = tmp_path / "plan.csv"
    result = CliRunner().invoke(cli, ["plan", str(EXAMPLES / CIRCLE_EXAMPLE), "-o", str(out),
                                      "--set", f"timing.duration={SQUEEZED_S}", *extra])
    return result, out


def test_a_fixed_duration_path_beyond_the_speed_limits_is_infeasible(tmp_path):
    result, out = _plan_circle(tmp_path)
    assert result.exit_code == 3, result.output
    assert "times its velocity limit" in result.output and "lengthen timing.duration" in result.output
    assert not out.exists() and not out.with_suffix(".json").exists()


def test_report_mode_writes_it_and_names_the_joints_beyond(tmp_path):
    result, out = _plan_circle(tmp_path, "--set", "check.limits=report")
    assert result.exit_code == 0, result.output
    robot = load_robot("iiwa14")
    header = out.read_text().splitlines()[0].split(",")
    rows = np.loadtxt(out, delimiter=",", skiprows=1)
    qd = rows[:, [header.index(f"dq{i + 1}_rad_s") for i in range(robot.n)]]
    ratios = np.abs(qd).max(axis=0) / robot.qdlim  # from the CSV and the robot file, not the report
    reported = {v["joint"]: v["ratio"] for v in json.loads(out.with_suffix(".json").read_text())
                ["summary"]["joint_speed"]["beyond_speed_limits"] if v["limit"] == "velocity"}
    expected = {j.name: r for j, r in zip(robot.joints, ratios) if r > 1}
    assert expected and reported.keys() == expected.keys()
    for name, ratio in expected.items():
        assert reported[name] == pytest.approx(ratio, rel=1e-12)
