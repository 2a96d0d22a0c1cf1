"""Robot file loader: SI conversion, field-level errors, fuzzing (only clean errors)."""

import math
import re

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from armgen.errors import RobotFileError
from armgen.robot import bundled_robots, load_robot, parse_robot, resolve_robot_path

GOOD = """
name = "two"
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
offset = 10
qlim = [-90, 90]
[[joints]]
name = "slide"
type = "prismatic"
a = 0
d = 20
alpha = 0
qlim = [0, 300]
[tool]
xyz = [0, 0, 10]
[configurations]
q0 = [45, 100]
"""


def test_bundled_robots_load():
    assert {"modular8", "iiwa14", "panda", "planar3"} <= set(bundled_robots())
    for name in bundled_robots():
        robot = load_robot(name)
        assert robot.n == len(robot.joints) > 0


def test_units_converted_to_si():
    robot = parse_robot(GOOD, "two.toml")
    shoulder, slide = robot.joints
    assert shoulder.a == pytest.approx(0.1) and shoulder.d == pytest.approx(0.05)
    assert shoulder.alpha == math.pi / 2  # snapped exactly to a quarter turn
    assert shoulder.offset == pytest.approx(math.radians(10))
    assert shoulder.qlim == pytest.approx((-math.pi / 2, math.pi / 2))
    assert slide.qlim == pytest.approx((0.0, 0.3))  # prismatic limits are lengths
    np.testing.assert_allclose(robot.configurations["q0"], [math.pi / 4, 0.1])
    np.testing.assert_allclose(robot.tool[:3, 3], [0, 0, 0.01])


@pytest.mark.parametrize("edit, message", [
    (("a = 100", ""), r"joint 1 \('shoulder'\): missing field 'a'"),
    (("a = 100", 'a = "x"'), r"field 'a' must be a number"),
    (("a = 100", "a = nan"), r"field 'a' is nan"),
    (("qlim = [-90, 90]", "qlim = [90, -90]"), r"qlim .* empty or reversed"),
    (("qlim = [-90, 90]", "qlim = [5, 5]"), r"qlim .* empty or reversed"),
    (('convention = "standard"', 'convention = "craig"'), r"'convention' = 'craig' is not one of standard, modified"),
    (('name = "slide"', 'name = "shoulder"'), r"duplicate joint name 'shoulder'"),
    (('length = "mm"', 'length = "inch"'), r"\[units\].*'length'"),
    (("q0 = [45, 100]", "q0 = [45]"), r"q0.*2 entries"),
    (("q0 = [45, 100]", "q0 = [120, 100]"), r"shoulder.*outside its limits"),
    (('type = "prismatic"', 'type = "spherical"'), r"'type' = 'spherical'"),
    (("alpha = 90", "alpha = 90\nbogus = 1"), r"unknown field\(s\) bogus"),
])
def test_field_level_errors(edit, message):
    old, new = edit
    assert old in GOOD
    with pytest.raises(RobotFileError, match=message) as info:
        parse_robot(GOOD.replace(old, new, 1), "two.toml")
    assert str(info.value).startswith("two.toml:")


def test_not_toml_and_missing_file(tmp_path):
    with pytest.raises(RobotFileError, match="not valid TOML"):
        parse_robot("name = ", "bad.toml")
    with pytest.raises(RobotFileError, match="not found"):
        resolve_robot_path(tmp_path / "nope.toml")
    with pytest.raises(RobotFileError, match="unknown robot 'nope'"):
        load_robot("nope")


def test_named_configuration_lookup():
    robot = load_robot("modular8")
    np.testing.assert_allclose(np.degrees(robot.configuration("q0")), [-57, -45, 71, -45, 32, 80, 34, -28])
    with pytest.raises(RobotFileError, match="no configuration 'qx'.*known: q0, qz"):
        robot.configuration("qx")


def _mutations():
    lines = GOOD.strip().splitlines()
    junk = st.sampled_from(['"x"', "nan", "inf", "-1e400", "[]", "[1, 2, 3]", "{}", "true", "0", "1e9", '"standard"',
                            "[1, nan]", "[\"a\", 1]"])

    @st.composite
    def mutate(draw):
        out = list(lines)
        for _ in range(draw(st.integers(1, 4))):
            k = draw(st.integers(0, len(out) - 1))
            action = draw(st.sampled_from(["drop", "value", "dup", "garble"]))
            if action == "drop":
                out.pop(k)
            elif action == "value" and "=" in out[k]:
                out[k] = out[k].split("=")[0] + "= " + draw(junk)
            elif action == "dup":
                out.insert(k, out[k])
            else:
                text = draw(st.text(alphabet="[]=\"'#.,x 0\n", max_size=8))
                out[k] = out[k][: len(out[k]) // 2] + text
            if not out:
                break
        return "\n".join(out)

    return mutate()


@settings(max_examples=300, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(_mutations())
def test_fuzzed_robot_files_fail_cleanly(text):
    """Any mutation either loads (and is then SI-consistent) or raises a RobotFileError
    naming the file — never another exception."""
    try:
        robot = parse_robot(text, "fuzz.toml")
    except RobotFileError as exc:
        assert str(exc).startswith("fuzz.toml:")
        assert re.search(r"\w", str(exc))
        return
    assert all(j.qlim[0] < j.qlim[1] for j in robot.joints)
    assert all(np.isfinite([j.a, j.d, j.alpha, j.offset]).all() for j in robot.joints)
