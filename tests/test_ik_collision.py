"""Issue 38, the IK: ``Robot.ik`` and ``armgen ik`` return configurations clear of the obstacles
and of the arm itself, or say that none was found; the planners' own IK solves keep the task's
obstacles.

The oracle is coal (hpp-fcl's successor): the distance of every checked pair at a returned
configuration, from the capsules placed by the arm's frames, must be at least the clearance.
The scene: the iiwa14 with the capsules of tests/test_collision.py and a sphere in front of its
shoulder, where about one in fifteen of the plain solver's answers to random reachable poses
puts the elbow or the forearm."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import armgen
from armgen.cli.main import cli
from armgen.description import matrix_rpy
from armgen.description.collision import CapsuleObstacle, PlaneObstacle, SphereObstacle
from armgen.errors import PlanningError, RobotFileError, TaskFileError
from armgen.planning.common.collision import load_obstacle_file
from armgen.robot import load_robot
from armgen.symbolic import ik
from test_collision import CAPSULES, REQUEST, _coal_capsule, _coal_obstacle, bare_robot_text, coal
from test_ik import independent_errors

SEED = 3838
POSES = 100
SPHERE = SphereObstacle((0.3, 0.0, 0.6), 0.15)  # m, base frame: in front of the shoulder
CLEARANCE = 0.02  # m
# coal's distances and ours agree to 1e-9 m (tests/test_collision.py, the bar), so a
# configuration ours keeps at the clearance is within this of it by coal's measure.
COAL_TOL = 1e-9
# Every pose of the test is the FK of a configuration at least this far (m) beyond the clearance
# from the sphere and from the arm itself: it has a collision-free solution to find.
GENERATOR_MARGIN = 0.01
# The share of those poses the search must solve collision-free: it solves all 100 on this seed,
# where 8 of the plain solver's answers come closer than the clearance (a search that kept the
# plain answers would solve 92; the scene must hold at least MIN_PLAIN_COLLIDING such poses).
MIN_SUCCESS = 0.97
MIN_PLAIN_COLLIDING = 4


@pytest.fixture(scope="module")
def robot_file(tmp_path_factory):
    text = bare_robot_text("iiwa14").replace('name = "iiwa14"', 'name = "iiwa14c"') + CAPSULES
    path = tmp_path_factory.mktemp("robots") / "iiwa14c.toml"
    path.write_text(text, encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def robot(robot_file):
    return load_robot(robot_file)


def coal_least(robot, q: np.ndarray, obstacles) -> np.ndarray:
    """coal's least distance (m) at each row of ``q`` over the arm's checked self pairs and its
    moving capsules against ``obstacles``."""
    capsules = robot.collision.capsules
    least = np.full(len(q), np.inf)
    for k, frames in enumerate(robot.frames(q)):
        ends = [((frames[c.frame] @ [*c.a, 1.0])[:3], (frames[c.frame] @ [*c.b, 1.0])[:3]) for c in capsules]
        shapes = [_coal_capsule(a, b, c.radius) for (a, b), c in zip(ends, capsules)]
        distances = [coal.distance(*shapes[i], *shapes[j], REQUEST, coal.DistanceResult())
                     for i, j in robot.collision.self_pairs()]
        distances += [coal.distance(*shapes[i], *_coal_obstacle(o), REQUEST, coal.DistanceResult())
                      for i in robot.collision.moving() for o in obstacles]
        least[k] = min(distances)
    return least


@pytest.fixture(scope="module")
def scene(robot):
    """Random reachable poses, each of a configuration clear of the sphere and the arm."""
    rng = np.random.default_rng(SEED)
    q = rng.uniform(robot.qmin, robot.qmax, (20 * POSES, robot.n))
    clear = robot.collision_distances(q, [SPHERE]).min(axis=-1) >= CLEARANCE + GENERATOR_MARGIN
    return robot.fk(q[clear][:POSES])


def test_solutions_keep_the_clearance_by_coals_measure(robot, scene):
    plain = robot.ik(scene, collision_free=False)
    assert plain.success.all() and plain.clearance is None
    plain_least = coal_least(robot, plain.q, [SPHERE])
    assert (plain_least < CLEARANCE).sum() >= MIN_PLAIN_COLLIDING  # the scene tests something

    result = robot.ik(scene, obstacles=[SPHERE], clearance=CLEARANCE)
    least = coal_least(robot, result.q, [SPHERE])
    ok = result.success
    assert ok.mean() >= MIN_SUCCESS, result.reason[~ok]
    assert np.all(least[ok] >= CLEARANCE - COAL_TOL)
    np.testing.assert_allclose(result.clearance, least, atol=COAL_TOL)  # the reported clearance is coal's
    pos, ori = independent_errors(robot, result.q, scene)
    assert np.all(pos[ok] <= ik.TOL_POSITION * 1.001) and np.all(ori[ok] <= ik.TOL_ORIENTATION * 1.001)
    assert robot.within_limits(result.q).all()
    # a pose the plain solver already solved clear keeps its answer
    kept = plain_least >= CLEARANCE + COAL_TOL
    np.testing.assert_array_equal(result.q[kept], plain.q[kept])
    # a miss says why; the others say nothing
    assert all("no collision-free configuration" in reason for reason in result.reason[result.colliding])
    assert not any(result.reason[ok]) and not np.any(result.colliding & ok)


def test_one_pose_gets_its_row_of_the_batch_and_the_answer_is_deterministic(robot, scene):
    batch = robot.ik(scene[:12], obstacles=[SPHERE], clearance=CLEARANCE)
    again = robot.ik(scene[:12], obstacles=[SPHERE], clearance=CLEARANCE)
    np.testing.assert_array_equal(batch.q, again.q)
    for k in range(12):
        one = robot.ik(scene[k], obstacles=[SPHERE], clearance=CLEARANCE)
        np.testing.assert_array_equal(one.q, batch.q[k])
        assert one.success == batch.success[k] and one.iterations == batch.iterations[k]
        assert one.clearance == batch.clearance[k] and isinstance(one.reason, str)


def test_the_arm_is_kept_clear_of_itself_without_obstacles():
    """A robot with capsules is checked against itself by default: poses whose plain answer
    folds the arm into itself are solved by configurations clear of it (coal's measure). The
    bundled iiwa14's capsules (Drake's collision model, 16 checked pairs) fold into each other
    for about one in thirty of the plain answers; the scene's five capsules almost never do."""
    robot = load_robot("iiwa14")
    assert robot.has_collision, "the bundled iiwa14 gives its capsules (issue 38)"
    rng = np.random.default_rng(SEED + 1)
    q = rng.uniform(robot.qmin, robot.qmax, (300, robot.n))
    q = q[robot.collision_distances(q).min(axis=-1) >= GENERATOR_MARGIN]
    poses = robot.fk(q)
    plain = robot.ik(poses, collision_free=False)
    folded = coal_least(robot, plain.q, []) < 0
    assert folded.sum() >= 3
    result = robot.ik(poses[folded])
    assert result.success.all(), result.reason
    assert np.all(coal_least(robot, result.q, []) >= -COAL_TOL)


def flange_sphere(robot, pose: np.ndarray) -> SphereObstacle:
    """A sphere around the flange's own capsule at ``pose``: every configuration that reaches the
    pose puts that capsule inside it."""
    flange = robot.collision.capsules[-1]
    tool_to_flange = np.linalg.inv(robot.tool)
    centre = (pose @ tool_to_flange @ [*flange.a, 1.0])[:3]
    return SphereObstacle(tuple(centre), 0.05)


def test_a_pose_with_only_colliding_solutions_is_a_clear_failure(robot, scene):
    sphere = flange_sphere(robot, scene[0])
    result = robot.ik(scene[0], obstacles=[sphere], clearance=0.0)
    assert not result.success and result.colliding
    assert "no collision-free configuration was found" in result.reason
    assert result.clearance < 0
    assert result.clearance == pytest.approx(coal_least(robot, result.q[None], [sphere])[0], abs=COAL_TOL)
    pos, ori = independent_errors(robot, result.q, scene[0])  # it does reach the pose
    assert pos <= ik.TOL_POSITION * 1.001 and ori <= ik.TOL_ORIENTATION * 1.001
    # a miss for want of reach says so instead
    far = np.eye(4)
    far[:3, 3] = [3.0, 0.0, 0.5]
    miss = robot.ik(far, obstacles=[SPHERE], clearance=CLEARANCE)
    assert not miss.success and not miss.colliding and miss.reason.startswith("not reached")


PLANAR_CAPSULES = """
[[collision]]
link = 1
a = [-0.5, 0, 0]
b = [0, 0, 0]
radius = 0.03

[[collision]]
link = 2
a = [-0.4, 0, 0]
b = [0, 0, 0]
radius = 0.03

[[collision]]
link = 3
a = [-0.3, 0, 0]
b = [0, 0, 0]
radius = 0.03
"""


def test_a_non_redundant_arm_takes_its_other_branch(tmp_path):
    """planar3 (3 joints, 3 task rows) has no self-motion to move along: with a sphere on the
    plain answer's elbow, the search finds the other elbow from other starts."""
    from armgen.robot import parse_robot

    text = Path(load_robot("planar3").path).read_text(encoding="utf-8").replace('name = "planar3"', 'name = "planarc"')
    planar = parse_robot(text + PLANAR_CAPSULES, "planarc.toml")
    pose = planar.fk(np.radians([30.0, -45.0, 60.0]))
    plain = planar.ik(pose, collision_free=False)
    elbow = planar.frames(plain.q)[1, :3, 3]
    sphere = SphereObstacle(tuple(elbow), 0.05)
    assert coal_least(planar, plain.q[None], [sphere])[0] < 0
    result = planar.ik(pose, obstacles=[sphere])
    assert result.success, result.reason
    assert np.sign(result.q[1]) != np.sign(plain.q[1])  # the other elbow
    assert coal_least(planar, result.q[None], [sphere])[0] >= -COAL_TOL
    pos, ori = independent_errors(planar, result.q, pose)
    assert pos <= ik.TOL_POSITION * 1.001 and ori <= ik.TOL_ORIENTATION * 1.001


def test_max_iterations_bounds_the_search_too(robot, scene):
    for cap in (20, 65):
        capped = robot.ik(scene, obstacles=[SPHERE], clearance=CLEARANCE, max_iterations=cap)
        assert np.all(capped.iterations <= cap)
        assert np.all(coal_least(robot, capped.q[capped.success], [SPHERE]) >= CLEARANCE - COAL_TOL)


def test_robots_without_capsules_and_bad_arguments():
    modular = load_robot("modular8")
    pose = modular.fk(modular.qmid)
    assert modular.ik(pose).clearance is None  # nothing to check: the plain solver
    with pytest.raises(RobotFileError, match="no collision model"):
        modular.ik(pose, obstacles=[SPHERE])
    with pytest.raises(RobotFileError, match="no collision model"):
        modular.ik(pose, clearance=0.01)


@pytest.mark.parametrize("arguments, error, message", [
    ({"clearance": -0.01}, ValueError, "clearance = -0.01 m"),
    ({"clearance": math.nan}, ValueError, "clearance = nan m"),
    ({"clearance": "1 cm"}, TypeError, "clearance must be a number"),
    ({"clearance": 0.05, "activation": 0.05}, ValueError, "must be beyond clearance"),
    ({"obstacles": [SPHERE], "collision_free": False}, ValueError, "collision_free=True"),
    ({"obstacles": [(0.3, 0.0, 0.5)]}, TypeError, "is no obstacle"),
    ({"obstacles": SPHERE}, TypeError, "must be a sequence"),
    ({"obstacles": [SPHERE] * 5}, ValueError, "max_obstacles.sphere"),
    ({"obstacles": [SphereObstacle((math.nan, 0.0, 0.5), 0.1)]}, ValueError, r"obstacles\[0\] \(SphereObstacle\)"),
    ({"obstacles": [SPHERE, CapsuleObstacle((0, 0, 0), (2e3, 0, 0), 0.1)]}, ValueError, "beyond ±1000"),
])
def test_bad_collision_arguments_are_named(robot, scene, arguments, error, message):
    with pytest.raises(error, match=message):
        robot.ik(scene[0], **arguments)


@settings(max_examples=25, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(fractions=st.lists(st.floats(0.05, 0.95), min_size=7, max_size=7),
       centre=st.tuples(st.floats(-0.6, 0.6), st.floats(-0.6, 0.6), st.floats(0.2, 1.2)),
       radius=st.floats(0.02, 0.3), clearance=st.sampled_from([0.0, 0.01, 0.05]))
def test_whatever_the_sphere_an_answer_is_clear_or_says_why(robot, fractions, centre, radius, clearance):
    """Property: for a reachable pose and any sphere, Robot.ik's answer reaches the pose and
    keeps the clearance by coal's measure, or is a failure that says which of the two it missed."""
    pose = robot.fk(robot.qmin + (robot.qmax - robot.qmin) * np.array(fractions))
    sphere = SphereObstacle(centre, radius)
    result = robot.ik(pose, obstacles=[sphere], clearance=clearance)
    least = coal_least(robot, result.q[None], [sphere])[0]
    assert result.clearance == pytest.approx(least, abs=COAL_TOL)
    pos, ori = independent_errors(robot, result.q, pose)
    if result.success:
        assert least >= clearance - COAL_TOL and pos <= ik.TOL_POSITION * 1.001 and ori <= ik.TOL_ORIENTATION * 1.001
    elif result.colliding:  # reached, not clear
        assert least < clearance and pos <= ik.TOL_POSITION * 1.001 and "no collision-free" in result.reason
    else:
        assert result.reason.startswith("not reached")


# -- the planners' own IK solves ------------------------------------------------------------------

def _sphere_entry(sphere: SphereObstacle) -> dict:
    return {"type": "sphere", "centre": list(sphere.centre), "radius": sphere.radius}


def test_ptp_pose_waypoints_and_a_pose_start_keep_the_tasks_obstacles(robot_file, robot, scene):
    plain = robot.ik(scene, collision_free=False)
    colliding = np.flatnonzero(coal_least(robot, plain.q, [SPHERE]) < CLEARANCE)
    poses = scene[colliding[:2]]
    collision = {"obstacles": [_sphere_entry(SPHERE)], "collision": {"clearance": CLEARANCE, "activation": 0.1}}
    task = {"planner": "ptp", "robot": str(robot_file), "units": {"angle": "deg"},
            "waypoints": {"xyz": poses[:, :3, 3].tolist(),
                          "rpy": [np.degrees(matrix_rpy(p[:3, :3])).tolist() for p in poses], "t": [0.0, 4.0]},
            "check": {"limits": "report"}, **collision}
    solved = np.array(armgen.plan(task).metadata["ik"]["waypoints"])
    assert np.all(coal_least(robot, solved, [SPHERE]) >= CLEARANCE - COAL_TOL)
    # a waypoint only colliding configurations reach is refused, naming it
    task["obstacles"].append(_sphere_entry(flange_sphere(robot, poses[1])))
    with pytest.raises(PlanningError, match="waypoint 1 .*every configuration"):
        armgen.plan(task)

    start = poses[0]
    cartesian = {"planner": "cartesian", "robot": str(robot_file), "units": {"length": "m", "angle": "deg"},
                 "start": {"pose": {"xyz": start[:3, 3].tolist(), "rpy": np.degrees(matrix_rpy(start[:3, :3])).tolist()}},
                 "path": {"type": "line", "end": (start[:3, 3] + [0.0, 0.0, 0.01]).tolist()},
                 "timing": {"duration": 1.0}, "check": {"limits": "report"}, **collision}
    plan = armgen.plan(cartesian)
    assert coal_least(robot, plan.data[:1, 1:1 + robot.n], [SPHERE])[0] >= CLEARANCE - COAL_TOL
    cartesian["obstacles"] = [_sphere_entry(flange_sphere(robot, start))]
    with pytest.raises(TaskFileError, match="start.pose': every configuration"):
        armgen.plan(cartesian)


# -- armgen ik --obstacles -----------------------------------------------------------------------

def _cli_pose(pose: np.ndarray) -> list[str]:
    roll, pitch, yaw = np.degrees(matrix_rpy(pose[:3, :3]))
    return ["--xyz", *(repr(float(v)) for v in pose[:3, 3]), "--rpy", *(repr(float(v)) for v in (roll, pitch, yaw)),
            "--units", "deg"]


OBSTACLE_FILE = """[units]
length = "mm"

[[obstacles]]
type = "sphere"
centre = [300, 0, 600]
radius = 150

[collision]
clearance = 20
activation = 100
"""


def test_cli_solves_clear_of_the_file_obstacles_and_exits_3_when_none_is(robot_file, robot, scene, tmp_path):
    plain = robot.ik(scene, collision_free=False)
    k = int(np.flatnonzero(coal_least(robot, plain.q, [SPHERE]) < CLEARANCE)[0])
    obstacles = tmp_path / "cell.toml"
    obstacles.write_text(OBSTACLE_FILE, encoding="utf-8")
    run = CliRunner().invoke(cli, ["ik", str(robot_file), *_cli_pose(scene[k]), "--obstacles", str(obstacles)])
    assert run.exit_code == 0, run.output
    lines = run.output.splitlines()
    q = np.radians([float(line.split()[1]) for line in lines[1:1 + robot.n]])
    assert coal_least(robot, q[None], [SPHERE])[0] >= CLEARANCE - 1e-6  # printed to 9 digits
    assert lines[-1].startswith("least distance") and "clearance 20.0 mm" in lines[-1]

    flange = flange_sphere(robot, scene[k])
    obstacles.write_text(OBSTACLE_FILE.replace("[300, 0, 600]", str([float(1e3 * v) for v in flange.centre]))
                         .replace("radius = 150", "radius = 50"), encoding="utf-8")
    run = CliRunner().invoke(cli, ["ik", str(robot_file), *_cli_pose(scene[k]), "--obstacles", str(obstacles)])
    assert run.exit_code == 3
    assert "no collision-free configuration" in run.output and "obstacles[0] (sphere)" in run.output


@pytest.mark.parametrize("text, field, fix", [
    (OBSTACLE_FILE.replace("centre", "center"), "center", "did you mean `centre`"),
    (OBSTACLE_FILE.replace("[collision]\nclearance = 20\nactivation = 100\n", ""), "field 'collision'",
     "add [collision] with activation"),
    (OBSTACLE_FILE.replace("activation = 100", "activation = 10"), "collision", "must be beyond clearance"),
    (OBSTACLE_FILE.replace('type = "sphere"', 'type = "cone"'), "'obstacles'[0]", "'sphere', 'capsule'"),
    (OBSTACLE_FILE.replace("radius = 150", "radius = -1"), "radius", "≥ 0"),
    (OBSTACLE_FILE + "[[obstacles]]\ntype = \"plane\"\npoint = [0, 0, 0]\nnormal = [0, 0, 0]\n", "normal",
     "has no direction"),
    ("[[obstacles]\n", "not valid TOML", "line 1"),
    (OBSTACLE_FILE.replace("radius = 150", "radius = 2e6"), "'obstacles[0].radius' = 2000000.0", "beyond ±1000 m"),
    (OBSTACLE_FILE + "[[obstacles]]\ntype = \"box\"\ncentre = [0, 0, 0]\nsize = [1, 1, 1]\nrpy = [0, 0, 1e5]\n",
     "'obstacles[1].rpy'", "beyond ±1000 rad"),
])
def test_cli_bad_obstacle_files_name_file_field_and_fix(robot_file, tmp_path, text, field, fix):
    path = tmp_path / "cell.toml"
    path.write_text(text, encoding="utf-8")
    run = CliRunner().invoke(cli, ["ik", str(robot_file), "--xyz", "0.5", "0", "0.5", "--obstacles", str(path)])
    assert run.exit_code == 2, run.output
    assert str(path) in run.output and field in run.output and fix in run.output, run.output


def test_cli_obstacles_need_a_robot_with_capsules_and_a_file(tmp_path):
    path = tmp_path / "cell.toml"
    path.write_text(OBSTACLE_FILE, encoding="utf-8")
    run = CliRunner().invoke(cli, ["ik", "modular8", "--xyz", "0.5", "0", "0.5", "--obstacles", str(path)])
    assert run.exit_code == 2 and "no collision capsules" in run.output and "[[collision]]" in run.output
    run = CliRunner().invoke(cli, ["ik", "modular8", "--xyz", "0.5", "0", "0.5", "--obstacles",
                                   str(tmp_path / "none.toml")])
    assert run.exit_code == 2 and "none.toml: obstacle file not found" in run.output


_NUMBER = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10, 10), st.text(max_size=3))
_ENTRY = st.fixed_dictionaries(
    {"type": st.sampled_from(["sphere", "capsule", "box", "plane", "cone", 3])},
    optional={"centre": st.lists(_NUMBER, max_size=4), "a": st.lists(_NUMBER, max_size=4),
              "b": st.lists(_NUMBER, max_size=4), "radius": _NUMBER, "size": st.lists(_NUMBER, max_size=4),
              "rpy": st.lists(_NUMBER, max_size=4), "point": st.lists(_NUMBER, max_size=4),
              "normal": st.lists(_NUMBER, max_size=4), "colour": _NUMBER})


@settings(max_examples=60, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(entries=st.lists(_ENTRY, max_size=3),
       collision=st.one_of(st.none(), st.fixed_dictionaries({}, optional={"clearance": _NUMBER, "activation": _NUMBER,
                                                                          "gain": _NUMBER})),
       units=st.sampled_from([{}, {"length": "mm"}, {"length": "km"}]))
def test_fuzzed_obstacle_files_load_or_fail_cleanly(robot, tmp_path, entries, collision, units):
    """Property: an obstacle file either loads into obstacles in SI or is one TaskFileError naming
    the file; never another exception."""
    import tomli_w

    document = {"units": units, "obstacles": entries, **({} if collision is None else {"collision": collision})}
    try:
        text = tomli_w.dumps(document)
    except (TypeError, ValueError):  # not representable as TOML (NaN is: nan)
        return
    path = tmp_path / "fuzz.toml"
    path.write_text(text, encoding="utf-8")
    try:
        loaded = load_obstacle_file(path, robot)
    except TaskFileError as exc:
        assert str(path) in str(exc)
        return
    assert loaded is not None and len(loaded.obstacles) == len(entries)
    assert robot.ik(robot.fk(robot.qmid), obstacles=loaded.obstacles).q.shape == (robot.n,)  # Robot.ik takes them
    assert all(isinstance(o, (SphereObstacle, CapsuleObstacle, PlaneObstacle)) or type(o).__name__ == "BoxObstacle"
               for o in loaded.obstacles)
