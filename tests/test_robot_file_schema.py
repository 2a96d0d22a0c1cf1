"""The schema is the parser of robot files (issue 36): the pydantic models hold every rule that
needs no units, one pure function per file kind (``dh_description``, ``urdf_description``)
converts the validated model to SI and cross-checks; a robot file and the URDF it references
are each read once, and the sha256 is of the bytes read."""

import hashlib
import json
import math
import os
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from pydantic import ValidationError

from armgen.cli.main import cli
from armgen.description import load_description, parse_description
from armgen.description.files import dh_description, urdf_description
from armgen.description.schema import RobotFile, UrdfRobotFile
from armgen.description.urdf import parse_urdf
from armgen.errors import RobotFileError

DATA = Path(__file__).parent / "data"

TWO = """name = "two"
convention = "standard"
[units]
length = "mm"
angle = "deg"
[[joints]]
name = "shoulder"
type = "revolute"
a = 100
d = 50
alpha = 90
qlim = [-90, 90]
qdlim = 45
[[joints]]
type = "prismatic"
a = 0
d = 20
alpha = 0
theta = 30
qlim = [0, 300]
qddlim = 500
[tool]
xyz = [0, 0, 10]
[configurations]
q0 = [45, 100]
"""

WRAPPER = """urdf = "iiwa7.urdf"
name = "iiwa7_mm"
task_rows = ["vz", "vx", "wz"]
[units]
length = "mm"
angle = "deg"
[base]
xyz = [10, 20, 300]
[limits]
a1 = [-160, 160]
a2 = { qlim = [-100, 110], qdlim = 50, qddlim = 200 }
[configurations]
q0 = [0, 30, 0, -60, 0, 45, 0]
"""


# -- rules without units are the schema's -------------------------------------------------

@pytest.mark.parametrize("edit, rule", [
    (('type = "prismatic"', 'name = "shoulder"\ntype = "prismatic"'), "duplicate joint name 'shoulder'"),
    (("qlim = [-90, 90]", "qlim = [-90, 90]\ntheta = 3"), "field 'theta' is only for prismatic joints"),
    (('convention = "standard"', 'convention = "standard"\ntask_rows = ["vx", "vz", "vx"]'), "distinct names"),
    (('convention = "standard"', 'convention = "standard"\ndescription = ""'), "string_too_short"),
])
def test_rules_without_units_are_checked_by_the_schema(edit, rule):
    old, new = edit
    assert old in TWO
    with pytest.raises(ValidationError, match=rule):
        RobotFile.model_validate(tomllib.loads(TWO.replace(old, new, 1)))


def test_schema_advertises_distinct_task_rows():
    out = CliRunner().invoke(cli, ["schema", "robot"])
    assert out.exit_code == 0, out.output
    defs = json.loads(out.output)["$defs"]
    assert defs["RobotFile"]["properties"]["task_rows"]["uniqueItems"] is True
    assert defs["UrdfRobotFile"]["properties"]["task_rows"]["uniqueItems"] is True


# -- one pure conversion per file kind ----------------------------------------------------

def test_dh_description_converts_the_validated_model_to_si():
    robot = dh_description(RobotFile.model_validate(tomllib.loads(TWO)), "two.toml", "0" * 64)
    shoulder, slide = robot.joints
    assert (shoulder.a, shoulder.d) == pytest.approx((0.1, 0.05)) and shoulder.alpha == math.pi / 2
    assert shoulder.qlim == pytest.approx((-math.pi / 2, math.pi / 2))
    assert shoulder.qdlim == pytest.approx(math.pi / 4) and shoulder.qddlim == math.inf
    assert slide.name == "j2" and slide.qlim == pytest.approx((0.0, 0.3)) and slide.qddlim == pytest.approx(0.5)
    assert slide.theta == pytest.approx(math.pi / 6)
    np.testing.assert_allclose(robot.configurations["q0"], [math.pi / 4, 0.1])
    np.testing.assert_allclose(robot.tool[:3, 3], [0, 0, 0.01])
    assert robot.task_rows == (0, 1, 2, 3, 4, 5) and robot.sha256 == "0" * 64


def test_urdf_description_applies_the_robot_files_additions():
    urdf = DATA / "iiwa7.urdf"
    chain = parse_urdf(urdf.read_text(), str(urdf))
    robot = urdf_description(UrdfRobotFile.model_validate(tomllib.loads(WRAPPER)), chain, "w.toml", "0" * 64, urdf)
    a1, a2 = robot.joints[:2]
    assert a1.qlim == pytest.approx(tuple(np.radians([-160, 160])))
    assert a1.qdlim == chain.joints[0].qdlim and a1.qddlim == math.inf  # the URDF's velocity, no acceleration
    assert a2.qlim == pytest.approx(tuple(np.radians([-100, 110])))
    assert (a2.qdlim, a2.qddlim) == pytest.approx((math.radians(50), math.radians(200)))
    assert list(robot.configurations) == ["qmid", "qz", "q0"]
    np.testing.assert_allclose(robot.configurations["q0"], np.radians([0, 30, 0, -60, 0, 45, 0]))
    np.testing.assert_allclose(robot.base[:3, 3], [0.01, 0.02, 0.3])
    assert robot.task_rows == (0, 2, 5) and robot.description == "URDF iiwa7.urdf: base_link -> tool0"


# -- every message names the file, the place and the fix ---------------------------------

@pytest.mark.parametrize("edit, message", [
    (('type = "prismatic"', 'name = "shoulder"\ntype = "prismatic"'),
     "two.toml: joint 2 ('shoulder'): duplicate joint name 'shoulder'; joint names must be unique"),
    (('name = "shoulder"', 'name = "j2"'),
     "two.toml: joint 2: duplicate joint name 'j2' (the default name of joint 2, which has none); joint names must be "
     "unique"),
    (("qlim = [-90, 90]", "qlim = [-90, 90]\ntheta = 3"),
     "two.toml: joint 1 ('shoulder'): field 'theta' is only for prismatic joints (a revolute joint's angle is q + "
     "offset)"),
    (('convention = "standard"', 'convention = "standard"\ntask_rows = ["vx", "vz", "vx"]'),
     "two.toml: file: task_rows = ['vx', 'vz', 'vx'] must be a non-empty list of distinct names from vx, vy, vz, wx, "
     "wy, wz"),
    (('convention = "standard"', 'convention = "standard"\ndescription = ""'),
     "two.toml: file: field 'description' must be a non-empty string, got ''"),
    (("a = 100", "a = 1e300"),
     "two.toml: joint 1 ('shoulder'): field 'a' = 1e+300 is beyond ±1000 m; check the units ([units] length/angle) "
     "and the value"),
    (("qddlim = 500", "qddlim = 1e-4"),
     "two.toml: joint 2 ('j2'): field 'qddlim' = 0.0001 is below 1e-06 SI units (rad or m per s, per s²): a unit "
     "slip; check the value and [units]"),
    (("xyz = [0, 0, 10]", "xyz = [0, 0, 2e6]"),
     "two.toml: [tool]: field 'xyz' is beyond ±1000 m; check [units] length and the value"),
    (("q0 = [45, 100]", "q0 = [45]"), "two.toml: [configurations]: field 'q0' must have 2 entries, got 1"),
    (("q0 = [45, 100]", "q0 = [45, 400]"),
     "two.toml: [configurations] q0: joint 'j2' = 400 mm is outside its limits [0 mm, 300 mm]; choose a start inside "
     "the limits"),
])
def test_dh_file_messages(edit, message):
    old, new = edit
    assert old in TWO
    with pytest.raises(RobotFileError) as info:
        parse_description(TWO.replace(old, new, 1), "two.toml")
    assert str(info.value) == message and info.value.exit_code == 2


@pytest.mark.parametrize("edit, message", [
    (('urdf = "iiwa7.urdf"', 'urdf = "missing.urdf"'),
     "urdf: URDF file {dir}/missing.urdf not found (the path is relative to the robot file)"),
    (("a1 = [-160, 160]", "a9 = [-160, 160]"),
     "[limits]: no joint named a9 on the chain (joints: a1, a2, a3, a4, a5, a6, a7)"),
    (("a1 = [-160, 160]", "a1 = [160, -160]"),
     "[limits]: a1 = [160.0, -160.0] is empty or reversed; write [lower, upper]"),
    (("qdlim = 50", "qdlim = 1e-7"),
     "[limits] a2: field 'qdlim' = 1e-07 is below 1e-06 SI units (rad or m per s, per s²): a unit slip; check the "
     "value and [units]"),
    (("q0 = [0, 30, 0, -60, 0, 45, 0]", "q0 = [0, 30]"), "[configurations]: field 'q0' must have 7 entries, got 2"),
    (("xyz = [10, 20, 300]", "xyz = [10, 20, 3e7]"),
     "[base]: field 'xyz' is beyond ±1000 m; check [units] length and the value"),
    (('task_rows = ["vz", "vx", "wz"]', 'task_rows = ["vz", "vz"]'),
     "file: task_rows = ['vz', 'vz'] must be a non-empty list of distinct names from vx, vy, vz, wx, wy, wz"),
])
def test_urdf_robot_file_messages(tmp_path, edit, message):
    old, new = edit
    assert old in WRAPPER
    (tmp_path / "iiwa7.urdf").write_bytes((DATA / "iiwa7.urdf").read_bytes())
    path = tmp_path / "w.toml"
    path.write_text(WRAPPER.replace(old, new, 1))
    with pytest.raises(RobotFileError) as info:
        load_description(path)
    assert str(info.value) == f"{path}: " + message.format(dir=tmp_path) and info.value.exit_code == 2


# -- each file read once ------------------------------------------------------------------

_opened: list[str] | None = None


def _count_opens(event: str, args: tuple) -> None:
    if event == "open" and _opened is not None and args and isinstance(args[0], (str, os.PathLike)):
        _opened.append(os.fspath(args[0]))


sys.addaudithook(_count_opens)  # audit hooks cannot be removed; it records only inside _opens()


def _opens(call) -> tuple[object, list[str]]:
    """The result of ``call()`` and the real paths of the files it opened."""
    global _opened
    _opened = []
    try:
        result = call()
    finally:
        opened, _opened = _opened, None
    return result, [os.path.realpath(p) for p in opened]


def test_a_robot_file_and_its_urdf_are_each_read_once_and_hashed_as_read(tmp_path):
    urdf, path = tmp_path / "iiwa7.urdf", tmp_path / "w.toml"
    urdf.write_bytes((DATA / "iiwa7.urdf").read_bytes())
    path.write_text(WRAPPER)
    robot, opened = _opens(lambda: load_description(path))
    assert opened.count(str(path.resolve())) == 1 and opened.count(str(urdf.resolve())) == 1
    digest = hashlib.sha256(path.read_bytes()).hexdigest() + hashlib.sha256(urdf.read_bytes()).hexdigest()
    assert robot.sha256 == hashlib.sha256(digest.encode()).hexdigest()

    dh = tmp_path / "two.toml"
    dh.write_text(TWO)
    robot, opened = _opens(lambda: load_description(dh))
    assert opened.count(str(dh.resolve())) == 1 and robot.sha256 == hashlib.sha256(dh.read_bytes()).hexdigest()

    robot, opened = _opens(lambda: load_description(urdf))
    assert opened.count(str(urdf.resolve())) == 1 and robot.sha256 == hashlib.sha256(urdf.read_bytes()).hexdigest()
