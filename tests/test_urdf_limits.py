"""Joint limits of URDF robots (issue 37, items 3–5): limits a URDF cannot carry set in a robot
file that references it (velocity, acceleration, position) and reaching the planners and the
firmware; revolute limits written in degrees refused; a pose start without a q0 solved from
the seed ``armgen ik`` uses. Reference values are closed forms (planar FK, degree conversion)
and finite differences of the written plan; a seeded hypothesis fuzz of limit values checks
that every file loads as a sane robot or fails with one clean error."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from armgen.cli.main import cli
from armgen.description.model import MAX_REVOLUTE_LIMIT_RAD
from armgen.errors import ArmgenError, RobotFileError, TaskFileError
from armgen.firmware.configuration import acceleration_limit, speed_guard
from armgen.robot import load_robot, parse_robot

# A planar 3R arm (links 0.4, 0.3, 0.1 m, every axis along z) as a URDF: its FK has a closed form.
LINKS = (0.4, 0.3, 0.1)
PLANAR_LIMITS = (("-2.9", "2.9"), ("-2.5", "2.5"), ("-2.8", "2.8"))


def planar_urdf(limits=PLANAR_LIMITS, velocity: str = "2", jtype: str = "revolute") -> str:
    joints = []
    for k, (lower, upper) in enumerate(limits):
        xyz = "0 0 0" if k == 0 else f"{LINKS[k - 1]} 0 0"
        joints.append(f'<joint name="j{k + 1}" type="{jtype}"><parent link="l{k}"/><child link="l{k + 1}"/>'
                      f'<origin xyz="{xyz}"/><axis xyz="0 0 1"/>'
                      f'<limit lower="{lower}" upper="{upper}" effort="1" velocity="{velocity}"/></joint>')
    joints.append('<joint name="tcp" type="fixed"><parent link="l3"/><child link="tool"/>'
                  f'<origin xyz="{LINKS[2]} 0 0"/></joint>')
    links = "".join(f'<link name="l{k}"/>' for k in range(4)) + '<link name="tool"/>'
    return f'<robot name="planar">{links}{"".join(joints)}</robot>'


def planar_fk_xy_yaw(q: np.ndarray) -> np.ndarray:
    """Closed form: x, y of the tool and its yaw."""
    angles = np.cumsum(q)
    return np.array([sum(a * math.cos(t) for a, t in zip(LINKS, angles)),
                     sum(a * math.sin(t) for a, t in zip(LINKS, angles)), angles[-1]])


def write(folder: Path, name: str, text: str) -> Path:
    path = folder / name
    path.write_text(text)
    return path


# A unit conversion (deg → rad) is one multiplication: one rounding.
CONVERSION_RTOL = 1e-15
# armgen ik prints joint angles with 9 significant digits (values up to ~180 deg).
IK_PRINT_TOL_DEG = 1e-6

WRAPPER = 'urdf = "planar.urdf"\ntask_rows = ["vx", "vy", "wz"]\n'


# -- 4. revolute limits written in degrees --------------------------------------------------------

@pytest.mark.parametrize("lower, upper", [("-170", "170"), ("-360", "360"), ("0", "270"), ("-1e300", "1e300")])
def test_urdf_limits_in_degrees_are_refused(tmp_path, lower, upper):
    path = write(tmp_path, "arm.urdf", planar_urdf(((lower, upper),) + PLANAR_LIMITS[1:]))
    with pytest.raises(RobotFileError) as info:
        load_robot(path)
    message = str(info.value)
    assert message.startswith(f"{path}: joint 'j1' <limit>:") and "URDF angles are radians" in message
    degrees = max(abs(float(lower)), abs(float(upper)))
    if degrees <= 720:  # the message gives the values converted, when degrees would make sense
        assert f'upper="{math.radians(float(upper)):.6g}"' in message


@pytest.mark.parametrize("limit", ["6.283185307179586", "12.566370614359172"])  # UR's ±360°, FANUC J6's ±720°
def test_wide_real_ranges_still_load(tmp_path, limit):
    path = write(tmp_path, "arm.urdf", planar_urdf(((f"-{limit}", limit),) + PLANAR_LIMITS[1:]))
    assert load_robot(path).qmax[0] == float(limit)


def test_a_prismatic_joint_is_not_bound_by_turns(tmp_path):
    path = write(tmp_path, "planar.urdf", planar_urdf(jtype="prismatic", limits=(("-20", "20"),) * 3))
    assert load_robot(path).qmax.tolist() == [20.0] * 3
    # a robot file's limits of a prismatic joint are in its length unit
    robot = load_robot(write(tmp_path, "arm.toml", WRAPPER + '[units]\nlength = "mm"\nangle = "deg"\n[limits]\n'
                             'j1 = { qlim = [-500, 500], qdlim = 250, qddlim = 1000 }\n'))
    assert robot.joints[0].qlim == pytest.approx((-0.5, 0.5), rel=CONVERSION_RTOL)
    assert (robot.qdlim[0], robot.qddlim[0]) == pytest.approx((0.25, 1.0), rel=CONVERSION_RTOL)


def test_dh_file_with_degree_limits_in_radians_is_refused():
    text = ('name = "one"\nconvention = "standard"\n[[joints]]\ntype = "revolute"\na = 0.3\nd = 0\nalpha = 0\n'
            'qlim = [-170, 170]\n')
    with pytest.raises(RobotFileError, match=r"^one.toml: joint 1 \('j1'\): qlim = \[-170.0, 170.0\] rad reaches "
                                             r"beyond ±12.57 rad.*set \[units\] angle = \"deg\""):
        parse_robot(text, "one.toml")
    robot = parse_robot(text.replace("[[joints]]", '[units]\nangle = "deg"\n[[joints]]'), "one.toml")
    assert robot.qmax[0] == pytest.approx(math.radians(170))


def test_wrapper_limits_in_degrees_under_radians_are_refused(tmp_path):
    write(tmp_path, "planar.urdf", planar_urdf())
    path = write(tmp_path, "arm.toml", WRAPPER + "[limits]\nj2 = [-150, 150]\n")
    with pytest.raises(RobotFileError, match=r"arm.toml: \[limits\]: j2 = \[-150.0, 150.0\] rad reaches beyond"):
        load_robot(path)
    path = write(tmp_path, "arm.toml", WRAPPER + '[units]\nangle = "deg"\n[limits]\nj3 = { qlim = [-1e3, 1e3] }\n')
    with pytest.raises(RobotFileError, match=r"j3.qlim = \[-1000.0, 1000.0\] deg reaches beyond.*check the values"):
        load_robot(path)


# -- 3. limits a URDF cannot carry, set in a robot file -------------------------------------------

LIMITED = WRAPPER + """
[units]
angle = "deg"
[limits]
j1 = { qddlim = 90 }
j2 = { qdlim = 60, qddlim = 120 }
[limits.j3]
qlim = [-90, 45]
qddlim = 180
[configurations]
q0 = [10, 40, -30]
"""


def test_wrapper_sets_speed_acceleration_and_position_limits(tmp_path):
    write(tmp_path, "planar.urdf", planar_urdf())
    robot = load_robot(write(tmp_path, "arm.toml", LIMITED))
    # j1, j3: the URDF's velocity; j2: the robot file's
    np.testing.assert_allclose(robot.qdlim, [2.0, math.radians(60), 2.0], rtol=CONVERSION_RTOL)
    np.testing.assert_allclose(robot.qddlim, np.radians([90, 120, 180]), rtol=CONVERSION_RTOL)
    np.testing.assert_allclose(robot.joints[2].qlim, np.radians([-90, 45]), rtol=CONVERSION_RTOL)
    assert robot.joints[0].qlim == (-2.9, 2.9)
    # the firmware's MOVE_TO and speed guard take them as they are
    np.testing.assert_allclose(acceleration_limit(robot), np.radians([90, 120, 180]), rtol=CONVERSION_RTOL)
    np.testing.assert_allclose(speed_guard(robot), [2.0, math.radians(60), 2.0], rtol=CONVERSION_RTOL)
    shown = CliRunner().invoke(cli, ["show", str(tmp_path / "arm.toml")])
    assert shown.exit_code == 0 and "qdlim=60 deg/s  qddlim=120 deg/s^2" in shown.output
    # the generated header's constants, which the firmware compiles in
    generated = CliRunner().invoke(cli, ["gen", str(tmp_path / "arm.toml"), "-o", str(tmp_path / "gen")])
    assert generated.exit_code == 0, generated.output
    header = (tmp_path / "gen" / "planar.h").read_text()
    qddlim = re.search(r"#define PLANAR_QDDLIM \{(.*)\}", header).group(1)
    np.testing.assert_allclose([float(v) for v in re.findall(r"LIT\(([^)]*)\)", qddlim)], np.radians([90, 120, 180]),
                               rtol=CONVERSION_RTOL)


@pytest.mark.parametrize("limits, match", [
    ("j1 = { qddlim = 0 }", r"\[limits.j1\]: field 'qddlim' = 0 must be > 0"),
    ("j1 = { qdlim = -2 }", r"\[limits.j1\]: field 'qdlim' = -2 must be > 0"),
    ("j1 = { qdlim = 1e-9 }", r"\[limits\] j1: field 'qdlim' = 1e-09 is below 1e-06"),
    ("j1 = { qddlim = nan }", r"qddlim"),
    ("j1 = { qlim = [1, -1] }", r"j1.qlim = \[1.0, -1.0\] is empty or reversed"),
    ("j1 = { acceleration = 3 }", r"unknown field.*acceleration"),
    ("j9 = { qdlim = 1 }", r"no joint named j9"),
])
def test_bad_wrapper_limits_are_one_clean_error(tmp_path, limits, match):
    write(tmp_path, "planar.urdf", planar_urdf())
    with pytest.raises(RobotFileError, match=match) as info:
        load_robot(write(tmp_path, "arm.toml", WRAPPER + "[limits]\n" + limits + "\n"))
    assert "arm.toml" in str(info.value)


PROGRAM_TASK = """
planner = "cartesian"
robot = "{robot}"
start = "q0"
[units]
length = "mm"
angle = "deg"
[path]
type = "program"
speed = 200
acceleration = 2000
blend = 8
[[path.moves]]
kind = "line"
to = {{ xyz = [420, 350, 0] }}
[[path.moves]]
kind = "line"
to = {{ xyz = [520, 250, 0] }}
[[path.moves]]
kind = "line"
to = {{ xyz = [420, 150, 0] }}
[integrator]
method = "rk4"
step = 0.005
"""
# q̈ is measured as differences of the written q̇ samples; the planner measures the same way,
# so the bound holds to rounding of the CSV's text (17 significant digits) over one step.
ACCELERATION_RATIO_TOL = 1.0 + 1e-6
QDDLIM = 3.0  # rad/s², every joint


def _peak_accelerations(csv: Path) -> np.ndarray:
    data = np.genfromtxt(csv, delimiter=",", names=True)
    qd = np.column_stack([data[f"dq{i + 1}_rad_s"] for i in range(3)])
    return np.max(np.abs(np.diff(qd, axis=0) / np.diff(data["t_s"])[:, None]), axis=0)


def test_wrapper_acceleration_limits_bound_a_blended_program(tmp_path, monkeypatch):
    """Without qddlim the blended corners ask several rad/s²; with the robot file's qddlim the
    plan keeps every joint within it (finite differences of the CSV's q̇)."""
    monkeypatch.chdir(tmp_path)
    write(tmp_path, "planar.urdf", planar_urdf())
    write(tmp_path, "free.toml", WRAPPER + '[configurations]\nq0 = [0.3, 1.2, -1.0]\n')
    limits = "".join(f"j{i} = {{ qddlim = {QDDLIM} }}\n" for i in (1, 2, 3))
    write(tmp_path, "limited.toml", WRAPPER + "[limits]\n" + limits + "[configurations]\nq0 = [0.3, 1.2, -1.0]\n")
    runner = CliRunner()
    peaks = {}
    for robot in ("free", "limited"):
        write(tmp_path, f"{robot}_task.toml", PROGRAM_TASK.format(robot=f"{robot}.toml"))
        result = runner.invoke(cli, ["plan", f"{robot}_task.toml", "-o", f"{robot}.csv"])
        assert result.exit_code == 0, result.output
        peaks[robot] = _peak_accelerations(tmp_path / f"{robot}.csv")
    assert peaks["free"].max() > 2 * QDDLIM  # the corners ask for far more (10.5 rad/s² measured)
    assert peaks["limited"].max() <= QDDLIM * ACCELERATION_RATIO_TOL, peaks["limited"]


# -- 5. a pose start without q0 -----------------------------------------------------------------

POSE_TASK = """
planner = "cartesian"
robot = "planar.urdf"
{start}
[units]
length = "mm"
angle = "deg"
[path]
type = "line"
end = [450, 250, 0]
[timing]
duration = 1.0
[integrator]
method = "rk4"
step = 0.01
"""
START = 'start = { pose = { xyz = [500, 200, 0], rpy = [0, 0, 40] } }'
# The IK's success threshold (armgen.symbolic.ik.TOL_POSITION is 1e-6 m) with a margin.
START_POSE_TOL = 2e-6  # m, rad


def test_pose_start_without_q0_uses_the_seed_of_armgen_ik(tmp_path, monkeypatch):
    from armgen.planning.tasks import load_task, run_task

    monkeypatch.chdir(tmp_path)
    write(tmp_path, "planar.urdf", planar_urdf())
    task, _ = load_task(write(tmp_path, "task.toml", POSE_TASK.format(start=START)))
    result = run_task(task, "task.toml")
    start = result.metadata["start"]
    assert "IK from the middle of the joint limits" in start["label"] and "note:" in start["label"]
    assert "set start.seed" in start["label"]
    q = np.array(start["q_rad"])
    np.testing.assert_allclose(planar_fk_xy_yaw(q), [0.5, 0.2, math.radians(40)], atol=START_POSE_TOL)
    ik = CliRunner().invoke(cli, ["ik", "planar.urdf", "--xyz", "0.5", "0.2", "0", "--rpy", "0", "0", "40",
                                  "--units", "deg"])
    assert ik.exit_code == 0, ik.output
    shown = [float(line.split()[1]) for line in ik.output.splitlines() if line.split()[:1] in (["j1"], ["j2"], ["j3"])]
    np.testing.assert_allclose(np.degrees(q), shown, atol=IK_PRINT_TOL_DEG)
    planned = CliRunner().invoke(cli, ["plan", "task.toml", "-o", "plan.csv"])
    assert planned.exit_code == 0, planned.output
    assert "note: robot 'planar' has no configuration q0" in planned.stderr and "note" not in planned.stdout


@pytest.mark.parametrize("start, match", [
    (START[:-2] + ', seed = "q0" }', r"task.toml: field 'start.seed' = 'q0' is not a configuration of robot "
                                              r"'planar' \(known: qmid, qz\); name one.*leave start.seed out"),
    ("", r"task.toml: field 'start' = 'q0' \(the default\) is not a configuration.*start = \{ pose = .*a URDF holds "
         r"no named configurations: add one in a robot file that references it"),
    (START.replace("500, 200", "900, 200"), r"field 'start.pose' is not reachable: the inverse kinematics from the "
                                            r"middle of the joint limits stopped.*give a seed \(start.seed"),
])
def test_start_errors_name_the_fix(tmp_path, monkeypatch, start, match):
    from armgen.planning.tasks import load_task, run_task

    monkeypatch.chdir(tmp_path)
    write(tmp_path, "planar.urdf", planar_urdf())
    task, _ = load_task(write(tmp_path, "task.toml", POSE_TASK.format(start=start)))
    with pytest.raises(TaskFileError, match=match):
        run_task(task, "task.toml")


def test_robot_configuration_of_a_bare_urdf_names_the_robot_file_fix(tmp_path):
    robot = load_robot(write(tmp_path, "planar.urdf", planar_urdf()))
    with pytest.raises(RobotFileError, match=r"has no configuration 'q0' \(known: qmid, qz\); a URDF holds none: add "
                                             r"it in a robot file that references the URDF"):
        robot.configuration("q0")


# -- fuzzing the limits ---------------------------------------------------------------------------

# Limit values a URDF or robot file may hold: sane radians, degree-like values, the bound's
# edges, non-finite and malformed text, anything.
DEGREE_LIKE = [90, 120, 150, 170, 180, 185, 270, 360, 720]
_LIMIT_TEXT = st.one_of(
    st.sampled_from(["nan", "-nan", "inf", "-inf", "1e400", "-1e400", "", " ", "x", "1 2", "0x10", "1e-320"]),
    st.sampled_from(DEGREE_LIKE).flatmap(lambda v: st.sampled_from([str(v), str(-v), f"{v}.0"])),
    st.sampled_from([MAX_REVOLUTE_LIMIT_RAD, math.nextafter(MAX_REVOLUTE_LIMIT_RAD, math.inf), math.pi, 1e3, 1e-9])
    .flatmap(lambda v: st.sampled_from([repr(v), repr(-v)])),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.floats(-20, 20).map(repr),
)
URDF_FUZZ_EXAMPLES = 1000
WRAPPER_FUZZ_EXAMPLES = 500
# An error message names the file, the place and the fix in one bounded line.
MAX_MESSAGE_CHARS = 600


def _check_sane(robot) -> None:
    """What a loaded robot guarantees: finite, ordered limits, revolute ones within the bound,
    positive speed limits, a finite middle configuration."""
    assert np.all(np.isfinite(robot.qmin)) and np.all(np.isfinite(robot.qmax)) and np.all(robot.qmin < robot.qmax)
    revolute = np.array([j.revolute for j in robot.joints])
    assert np.all(np.maximum(np.abs(robot.qmin), np.abs(robot.qmax))[revolute] <= MAX_REVOLUTE_LIMIT_RAD)
    assert np.all(robot.qdlim > 0) and np.all(robot.qddlim > 0) and not np.any(np.isnan(robot.qdlim))
    assert np.all(np.isfinite(robot.qmid))


def _clean(error: ArmgenError, path: Path) -> None:
    message = str(error)
    assert error.exit_code == 2 and str(path) in message and len(message) <= MAX_MESSAGE_CHARS, message


@settings(derandomize=True, max_examples=URDF_FUZZ_EXAMPLES, deadline=None, database=None,
          suppress_health_check=list(HealthCheck))
@given(st.lists(st.tuples(_LIMIT_TEXT, _LIMIT_TEXT), min_size=3, max_size=3),
       st.sampled_from(["revolute", "prismatic", "continuous"]), _LIMIT_TEXT)
def test_fuzzed_urdf_limits_load_sanely_or_fail_cleanly(tmp_path_factory, limits, jtype, velocity):
    path = write(tmp_path_factory.mktemp("fuzz"), "f.urdf", planar_urdf(limits, velocity, jtype))
    try:
        robot = load_robot(path)
    except ArmgenError as exc:
        _clean(exc, path)
        values = [float(v) for pair in limits for v in pair if _is_float(v)]
        if jtype == "revolute" and len(values) == 6 and all(map(math.isfinite, values)) \
                and all(lo < hi for lo, hi in zip(values[::2], values[1::2])) \
                and max(map(abs, values)) > MAX_REVOLUTE_LIMIT_RAD:
            assert "URDF angles are radians" in str(exc) or "velocity" in str(exc), str(exc)
        event("refused: beyond two turns" if "URDF angles are radians" in str(exc) else "refused: other")
        return
    _check_sane(robot)
    event("loaded")


def _is_float(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


_TOML_NUMBER = st.one_of(
    st.sampled_from(["nan", "inf", "-inf", "0", "-1", '"1"', "true", "[]", "1e308", "5e-324", "1e-7"]),
    st.sampled_from(DEGREE_LIKE).flatmap(lambda v: st.sampled_from([str(v), str(-v)])),
    st.floats(-20, 20, allow_nan=False).map(repr),
)
_SANE_RATE = st.floats(1e-3, 1e3).map(repr)
_PAIR = st.one_of(
    st.tuples(_TOML_NUMBER, _TOML_NUMBER),
    st.lists(st.floats(-15, 15), min_size=2, max_size=2, unique=True).map(sorted).map(lambda p: tuple(map(repr, p))),
    st.lists(st.sampled_from(DEGREE_LIKE + [-v for v in DEGREE_LIKE]), min_size=2, max_size=2, unique=True)
    .map(sorted).map(lambda p: tuple(map(str, p))),
).map(lambda p: f"[{p[0]}, {p[1]}]")
_ENTRY = st.one_of(
    _PAIR,
    st.fixed_dictionaries({}, optional={"qlim": _PAIR, "qdlim": st.one_of(_TOML_NUMBER, _SANE_RATE),
                                        "qddlim": st.one_of(_TOML_NUMBER, _SANE_RATE), "qdddlim": _TOML_NUMBER})
    .map(lambda d: "{ " + ", ".join(f"{k} = {v}" for k, v in d.items()) + " }"),
)


@settings(derandomize=True, max_examples=WRAPPER_FUZZ_EXAMPLES, deadline=None, database=None,
          suppress_health_check=list(HealthCheck))
@given(st.dictionaries(st.sampled_from(["j1", "j2", "j3", "j4"]), _ENTRY, max_size=3),
       st.sampled_from(["rad", "deg"]), st.sampled_from(["m", "mm"]))
def test_fuzzed_wrapper_limits_load_sanely_or_fail_cleanly(tmp_path_factory, entries, angle, length):
    folder = tmp_path_factory.mktemp("fuzz")
    write(folder, "planar.urdf", planar_urdf())
    body = WRAPPER + f'[units]\nangle = "{angle}"\nlength = "{length}"\n[limits]\n'
    path = write(folder, "arm.toml", body + "".join(f"{k} = {v}\n" for k, v in entries.items()))
    try:
        robot = load_robot(path)
    except ArmgenError as exc:
        _clean(exc, path)
        event("refused: beyond two turns" if "two turns" in str(exc) else "refused: other")
        return
    _check_sane(robot)
    event("loaded")
