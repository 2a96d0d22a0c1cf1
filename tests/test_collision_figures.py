"""Issue 38, the figures: `armgen plot` and `armgen animate` draw the arm's capsules, the task's
obstacles and the plan's closest approach (armgen/planning/collision_scene.py), for a DH robot
(the bundled iiwa14 with the capsules of tests/test_collision.py, in a test robot file) and a URDF
robot (the oblique chain of tests/test_urdf.py with <collision> cylinders, a box, a sphere and a
capsule).

Checked against independent sources: the capsules' drawn axes against the segment ends through a
hand-written standard-DH chain (DH) and Pinocchio's placements of the URDF's collision shapes
(URDF); the drawn surfaces against the closed-form distance of a point to a segment; the box's
faces against SciPy's rotation; the closest approach's witness points and distance against
coal's nearest points and distance. A snake plan with obstacles of the collision vocabulary: its
2-D views outline them where the task file's numbers put them."""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st
from matplotlib.figure import Figure
from PIL import Image
from scipy.spatial.transform import Rotation

from armgen.cli.main import cli
from armgen.description.collision import BoxObstacle, CapsuleObstacle, PlaneObstacle, SphereObstacle
from armgen.planning import animation
from armgen.planning.collision_scene import (FACETS_AROUND, RINGS_PER_CAP, capsule_surface, closest_approach,
                                             obstacle_names)
from armgen.planning.plotting import collision_view, plan_robot
from armgen.planning.result import read_plan
from armgen.planning.tasks import plot_plan
from armgen.robot import Robot, load_robot
from test_collision import CAPSULES, REQUEST, _coal_box, _coal_capsule, _coal_halfspace, _oblique_with_collisions, coal

SEED = 20261128
# Both sides compose the same few transforms in double precision (m): rounding of metre-sized values.
FK_TOL = 1e-12
# coal's GJK/EPA run to 1e-15 (test_collision.REQUEST); the distances are closed forms on both
# sides: 1e-9 m, the bar for the distances. Its nearest points come out of the same
# iterations: 1e-7 m, still far below anything a figure can show.
COAL_TOL = 1e-9
WITNESS_TOL = 1e-7
# A pair whose distance is above this (m) has unique nearest points, so coal's and ours can be compared.
APART = 1e-3
# The figures are in mm: the drawn coordinates are the metres times 1e3 (exact up to rounding).
MM = 1e3
DRAWN_TOL = 1e-9  # mm


def bare_dh_text(name: str) -> str:
    """A bundled DH robot file without the capsules it may bring (from its first [[collision]] or
    its capsules' comment block on)."""
    text = Path(load_robot(name).path).read_text(encoding="utf-8")
    return text.split("\n# -- Collision capsules")[0].split("\n[[collision]]")[0].split("\n[collision_check]")[0]


# The DH scene: the iiwa14 tracks a line (tests/test_collision_planning.py's) beside four
# obstacles, one of each kind (mm); the sphere where the plain plan's elbow passes, small enough
# that it stays 12.9 mm clear of it (a unique pair of nearest points).
DH_OBSTACLES = [
    {"type": "sphere", "centre": [-333.0, 239.0, 646.0], "radius": 10.0},
    {"type": "plane", "point": [0, 0, 0], "normal": [0, 0, 1]},
    {"type": "box", "centre": [300, 300, 100], "size": [200, 200, 200], "rpy": [0, 0, 30]},
    {"type": "capsule", "a": [600, -200, 0], "b": [600, -200, 1200], "radius": 80},
]
START = np.radians([20, -50, 10, -60, 0, 30, 0])  # the iiwa14's q0_feasible
LINE_OFFSET = np.array([0.5, 0.5, -0.4])  # m

# The URDF scene (SI): the oblique arm moves its tool along a line; its capsules 1 and 3 meet
# (an overlap of 45 mm, the least distance), the obstacles stay away.
URDF_START = [0.3, 0.4, 0.5, 0.05, 0.5, 0.5]
URDF_OBSTACLES = [
    {"type": "sphere", "centre": [0.5, 0.3, 0.6], "radius": 0.05},
    {"type": "plane", "point": [0, 0, -0.2], "normal": [0, 0, 1]},
    {"type": "box", "centre": [-0.2, 0.4, 0.6], "size": [0.1, 0.2, 0.3], "rpy": [0.1, 0.2, 0.3]},
    {"type": "capsule", "a": [0.6, -0.3, 0], "b": [0.6, -0.3, 0.5], "radius": 0.05},
]


def _toml(value) -> str:
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {_toml(v)}" for k, v in value.items()) + "}"
    if isinstance(value, list):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    return f'"{value}"' if isinstance(value, str) else repr(value)


def _task_text(fields: dict, obstacles: list[dict], collision: dict) -> str:
    lines = [f"{key} = {_toml(value)}" for key, value in fields.items()]
    lines += [f"[[obstacles]]\n" + "\n".join(f"{k} = {_toml(v)}" for k, v in o.items()) for o in obstacles]
    lines.append("[collision]\n" + "\n".join(f"{k} = {_toml(v)}" for k, v in collision.items()))
    return "\n".join(lines) + "\n"


def _plan(folder: Path, task: str) -> Path:
    (folder / "task.toml").write_text(task, encoding="utf-8")
    with pytest.MonkeyPatch.context() as patch:
        patch.chdir(folder)
        run = CliRunner().invoke(cli, ["plan", "task.toml", "-o", "plan.csv"])
    assert run.exit_code == 0, run.output
    return folder / "plan.csv"


@pytest.fixture(scope="module")
def dh_plan(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("dh")
    (folder / "iiwa14c.toml").write_text(bare_dh_text("iiwa14").replace('name = "iiwa14"', 'name = "iiwa14c"')
                                         + CAPSULES, encoding="utf-8")
    end = load_robot(folder / "iiwa14c.toml").fk(START)[:3, 3] + LINE_OFFSET
    task = _task_text({"planner": "cartesian", "robot": "iiwa14c.toml", "start": "q0_feasible",
                       "units": {"length": "mm", "angle": "deg"},
                       "path": {"type": "line", "end": [float(v) for v in end * 1e3], "orientation": "hold"},
                       "timing": {"duration": 10.0, "law": "cubic"}, "integrator": {"step": 0.01, "clik_gain": 5.0},
                       "method": {"name": "pinv"}, "check": {"limits": "report"}},
                      DH_OBSTACLES, {"clearance": 20, "activation": 150, "gain": 0.0})
    return _plan(folder, task)


@pytest.fixture(scope="module")
def urdf_plan(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("urdf")
    (folder / "oblique.urdf").write_text(_oblique_with_collisions(), encoding="utf-8")
    task = _task_text({"planner": "cartesian", "robot": "oblique.urdf", "start": URDF_START,
                       "path": {"type": "line", "end": [0.3, 0.1, 0.3], "orientation": "hold"},
                       "timing": {"duration": 2.0}, "integrator": {"step": 0.02}, "method": {"name": "pinv"},
                       "check": {"limits": "report"}},
                      URDF_OBSTACLES, {"activation": 0.1})
    return _plan(folder, task)


# -- independent references ----------------------------------------------------------------------


def dh_frames(robot_file: Path, q: np.ndarray) -> list[np.ndarray]:
    """Frames 0…n of a standard-DH robot file (no [base]), from its joints' d, a, alpha (mm, deg):
    T_i = T_{i−1} Rz(q_i) Tz(d_i) Tx(a_i) Rx(alpha_i), in m."""
    joints = tomllib.loads(robot_file.read_text(encoding="utf-8"))["joints"]
    frames = [np.eye(4)]
    for joint, angle in zip(joints, q):
        d, a, alpha = joint["d"] * 1e-3, joint["a"] * 1e-3, math.radians(joint["alpha"])
        ct, st_, ca, sa = math.cos(angle), math.sin(angle), math.cos(alpha), math.sin(alpha)
        frames.append(frames[-1] @ np.array([[ct, -st_ * ca, st_ * sa, a * ct], [st_, ct * ca, -ct * sa, a * st_],
                                             [0, sa, ca, d], [0, 0, 0, 1]]))
    return frames


def dh_capsule_ends(robot_file: Path, q: np.ndarray) -> list[np.ndarray]:
    """Each [[collision]] capsule's ends (2 × 3, m) through :func:`dh_frames`, read from the file."""
    frames = dh_frames(robot_file, q)
    out = []
    for capsule in tomllib.loads(robot_file.read_text(encoding="utf-8"))["collision"]:
        pose = frames[capsule["link"]]
        ends = [np.asarray(capsule["a"]) * 1e-3, np.asarray(capsule.get("b", capsule["a"])) * 1e-3]
        out.append(np.array([pose[:3, :3] @ end + pose[:3, 3] for end in ends]))
    return out


def pinocchio_capsule_ends(urdf: Path, robot: Robot, q: np.ndarray) -> list[np.ndarray]:
    """The URDF's collision shapes' axes (2 × 3, m) where Pinocchio places them at q (as
    tests/test_collision.py: the shape's z, or the box's longest side, its local y here)."""
    pin = pytest.importorskip("pinocchio", reason="Pinocchio missing: pip install pin")
    model = pin.buildModelFromUrdf(str(urdf))
    data = model.createData()
    geometry_model = pin.buildGeomFromUrdf(model, str(urdf), pin.GeometryType.COLLISION)
    configuration = pin.neutral(model)
    for joint, value in zip(robot.joints, q):
        index, nq = model.joints[model.getJointId(joint.name)].idx_q, model.joints[model.getJointId(joint.name)].nq
        configuration[index:index + nq] = [math.cos(value), math.sin(value)] if nq == 2 else [value]
    pin.framesForwardKinematics(model, data, configuration)
    geometry_data = pin.GeometryData(geometry_model)
    pin.updateGeometryPlacements(model, data, geometry_model, geometry_data)
    out = []
    for capsule, placement in zip(robot.collision.capsules, geometry_data.oMg):
        axis = 1 if capsule.origin == "urdf box (enclosed)" else 2
        half = 0.5 * np.linalg.norm(np.subtract(capsule.b, capsule.a))
        out.append(np.array([placement.translation + sign * half * placement.rotation[:, axis]
                             for sign in (-1.0, 1.0)]))
    # Pinocchio's URDF parser skips <capsule> (the tcp's, the last shape): its link frame by
    # Pinocchio, and the shape's axis composed by hand (origin z = -0.05 m, length 0.1 m along z)
    assert len(out) == len(robot.collision.capsules) - 1 and robot.collision.capsules[-1].origin == "urdf capsule"
    tcp = data.oMf[model.getFrameId("tcp")]
    out.append(np.array([tcp.translation + tcp.rotation @ [0.0, 0.0, z] for z in (-0.1, 0.0)]))
    return out


def point_segment_distance(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ab = b - a
    t = np.clip((points - a) @ ab / max(float(ab @ ab), 1e-300), 0.0, 1.0)
    return np.linalg.norm(a + t[:, None] * ab - points, axis=1)


def coal_shape(robot: Robot, ends: np.ndarray, name: str, obstacles, names=None) -> tuple:
    """(shape, transform) of coal for a pair's side: ``capsule k`` at ``ends[k]`` or a task obstacle
    (named as summary.collision names it: ``names``, default obstacles[0], obstacles[1], …)."""
    if name.startswith("capsule"):
        k = int(name.split()[1])
        return _coal_capsule(*ends[k], robot.collision.capsules[k].radius)
    obstacle = obstacles[(names or obstacle_names(obstacles)).index(name)]
    if isinstance(obstacle, SphereObstacle):
        return coal.Sphere(obstacle.radius), coal.Transform3s(np.eye(3), np.asarray(obstacle.centre))
    if isinstance(obstacle, CapsuleObstacle):
        return _coal_capsule(np.asarray(obstacle.a), np.asarray(obstacle.b), obstacle.radius)
    if isinstance(obstacle, BoxObstacle):
        rotation = Rotation.from_euler("ZYX", obstacle.rpy[::-1]).as_matrix()
        return _coal_box(np.asarray(obstacle.centre), rotation, 0.5 * np.asarray(obstacle.size))
    normal = np.asarray(obstacle.normal) / np.linalg.norm(obstacle.normal)
    return _coal_halfspace(normal, float(normal @ np.asarray(obstacle.point)))


def coal_pair(robot: Robot, ends: np.ndarray, pair: str, obstacles, names=None) -> tuple[float, np.ndarray]:
    """coal's signed distance and nearest points (2 × 3) of a pair named as summary.collision names it."""
    first, second = pair.split(" – ")
    result = coal.DistanceResult()
    distance = coal.distance(*coal_shape(robot, ends, first, obstacles, names),
                             *coal_shape(robot, ends, second, obstacles, names), REQUEST, result)
    return distance, np.array([result.getNearestPoint1(), result.getNearestPoint2()])


# -- helpers on the drawn figure ---------------------------------------------------------------


def scene_axes(fig: Figure) -> list:
    """The collision row's two 3-D panels (each draws the marker): the usual view, then the one
    across the gap, whose camera looks at right angles to the marker."""
    axes = [ax for ax in fig.axes if by_gid(ax, "closest approach")]
    assert [ax.get_title().startswith("closest approach") for ax in axes] == [True, False]
    gap = np.diff(drawn_segment(by_gid(axes[1], "closest approach")[0]), axis=0)[0]
    camera = np.array([math.cos(math.radians(axes[1].azim)), math.sin(math.radians(axes[1].azim))])
    assert abs(camera @ gap[:2]) <= 1e-9 * np.linalg.norm(gap)
    return axes


def by_gid(ax, gid: str) -> list:
    return [artist for artist in (*ax.lines, *ax.collections) if artist.get_gid() == gid]


def drawn_points(artist) -> np.ndarray:
    """The 3-D vertices (m) of a surface or polygon collection: mplot3d keeps them only in the
    collection's ``_faces`` (the drawn 2-D paths are projections)."""
    return np.asarray(artist._faces).reshape(-1, 3) / MM


def drawn_segment(line) -> np.ndarray:
    return np.column_stack(line.get_data_3d()) / MM


def task_obstacles_si(plan: Path):
    from armgen.planning.collision_scene import task_obstacles

    return task_obstacles(read_plan(plan).metadata)


def check_scene(ax, robot: Robot, expected_ends: list[np.ndarray], obstacles, names=None) -> None:
    """Each capsule drawn once, its axis at ``expected_ends``, its surface ``radius`` from it; each
    obstacle drawn once where the task puts it (named ``names``, as in :func:`coal_shape`)."""
    capsules = robot.collision.capsules
    assert len(expected_ends) == len(capsules)
    for k, (ends, capsule) in enumerate(zip(expected_ends, capsules)):
        (surface,), (axis,) = by_gid(ax, f"capsule {k}"), by_gid(ax, f"capsule {k} axis")
        drawn = drawn_segment(axis)  # Pinocchio's shape axis may run the other way
        assert np.allclose(drawn, ends, atol=FK_TOL, rtol=0) or np.allclose(drawn, ends[::-1], atol=FK_TOL, rtol=0), \
            (k, drawn, ends)
        distance = point_segment_distance(drawn_points(surface), *ends)
        np.testing.assert_allclose(distance, capsule.radius, atol=FK_TOL, rtol=0)
    assert not by_gid(ax, f"capsule {len(capsules)}")
    for obstacle, name in zip(obstacles, names or obstacle_names(obstacles)):
        (drawn,) = [a for a in by_gid(ax, name)]
        points = drawn_points(drawn)
        if isinstance(obstacle, SphereObstacle):
            centre = np.asarray(obstacle.centre)
            np.testing.assert_allclose(np.linalg.norm(points - centre, axis=1), obstacle.radius, atol=FK_TOL, rtol=0)
        elif isinstance(obstacle, CapsuleObstacle):
            distance = point_segment_distance(points, np.asarray(obstacle.a), np.asarray(obstacle.b))
            np.testing.assert_allclose(distance, obstacle.radius, atol=FK_TOL, rtol=0)
        elif isinstance(obstacle, BoxObstacle):
            rotation = Rotation.from_euler("ZYX", obstacle.rpy[::-1]).as_matrix()
            local = (points - np.asarray(obstacle.centre)) @ rotation
            np.testing.assert_allclose(np.abs(local), np.broadcast_to(0.5 * np.asarray(obstacle.size), local.shape),
                                       atol=FK_TOL, rtol=0)  # every vertex is a corner
            assert len({tuple(np.sign(p).astype(int)) for p in local}) == 8
        else:
            normal = np.asarray(obstacle.normal) / np.linalg.norm(obstacle.normal)
            np.testing.assert_allclose((points - np.asarray(obstacle.point)) @ normal, 0.0, atol=FK_TOL, rtol=0)


def check_approach(ax, robot: Robot, ends: list[np.ndarray], report: dict, obstacles, names=None) -> None:
    """The marker joins the pair's nearest points: as far apart as summary.collision says, that
    distance is coal's for the pair at the sample (the capsules at ``ends``, from an independent
    chain), and (apart) its points are coal's nearest points."""
    (marker,) = by_gid(ax, "closest approach")
    points = drawn_segment(marker)
    distance = report["min_clearance_m"]
    assert np.linalg.norm(points[1] - points[0]) == pytest.approx(abs(distance), abs=COAL_TOL)
    assert report["pair"] in marker.get_label() and f"{distance * MM:.1f} mm" in marker.get_label()
    theirs, nearest = coal_pair(robot, ends, report["pair"], obstacles, names)
    assert distance == pytest.approx(theirs, abs=COAL_TOL)
    if distance > APART:
        np.testing.assert_allclose(points, nearest, atol=WITNESS_TOL, rtol=0)


# -- the tests ---------------------------------------------------------------------------------------


@settings(max_examples=200, deadline=None, derandomize=True)
@given(a=st.lists(st.floats(-2, 2), min_size=3, max_size=3), b=st.lists(st.floats(-2, 2), min_size=3, max_size=3),
       radius=st.floats(1e-3, 1.0), point=st.booleans())
def test_capsule_surface_lies_at_its_radius_and_covers_both_caps(a, b, radius, point):
    a = np.array(a)
    b = a.copy() if point else np.array(b)
    grid = np.stack(capsule_surface(a, b, radius), axis=-1)
    assert grid.shape == (2 * (RINGS_PER_CAP + 1), FACETS_AROUND + 1, 3)
    distance = point_segment_distance(grid.reshape(-1, 3), a, b)
    np.testing.assert_allclose(distance, radius, rtol=1e-12, atol=1e-12)
    axis = b - a
    unit = axis / np.linalg.norm(axis) if np.linalg.norm(axis) > 0 else np.array([0.0, 0.0, 1.0])
    np.testing.assert_allclose(grid[0], np.broadcast_to(a - radius * unit, grid[0].shape), atol=1e-12, rtol=0)  # the poles
    np.testing.assert_allclose(grid[-1], np.broadcast_to(b + radius * unit, grid[-1].shape), atol=1e-12, rtol=0)


def test_witness_points_are_coals_nearest_points_for_every_kind_of_pair(tmp_path):
    """At random configurations, every checked pair of a 7-DOF arm with every obstacle kind: the
    marker's distance is coal's, and apart, its points are coal's nearest points."""
    path = tmp_path / "iiwa14c.toml"
    path.write_text(bare_dh_text("iiwa14") + CAPSULES, encoding="utf-8")
    robot = load_robot(path)
    obstacles = (SphereObstacle((0.4, 0.2, 0.7), 0.08), CapsuleObstacle((0.5, -0.3, 0.0), (0.5, -0.3, 1.2), 0.06),
                 BoxObstacle((-0.4, 0.3, 0.5), (0.2, 0.3, 0.4), (0.2, -0.1, 0.5)),
                 PlaneObstacle((0, 0, 0.05), (0, 0.2, 1)))
    names = obstacle_names(obstacles)
    pairs = [f"capsule {i} – capsule {j}" for i, j in robot.collision.self_pairs()]
    pairs += [f"capsule {i} – {name}" for i in robot.collision.moving() for name in names]
    rng = np.random.default_rng(SEED)
    compared = {"capsule": 0, "sphere": 0, "box": 0, "plane": 0}
    for q in rng.uniform(robot.qmin, robot.qmax, size=(40, robot.n)):
        ends = dh_capsule_ends(path, q)
        for pair in pairs:
            ours = closest_approach(robot, q, obstacles, pair)
            theirs, nearest = coal_pair(robot, ends, pair, obstacles)
            axis_inside_box = pair.endswith("(box)") and ours.distance < -robot.collision.capsules[
                int(pair.split()[1])].radius
            if axis_inside_box:  # documented: armgen's value is then at least coal's (docs/collision.md)
                assert ours.distance >= theirs - COAL_TOL
                continue
            assert ours.distance == pytest.approx(theirs, abs=COAL_TOL), pair
            assert np.linalg.norm(ours.points[1] - ours.points[0]) == pytest.approx(abs(ours.distance), abs=COAL_TOL)
            if ours.distance > APART:
                np.testing.assert_allclose(ours.points, nearest, atol=WITNESS_TOL, rtol=0, err_msg=pair)
                compared[pair.rsplit("(", 1)[-1].rstrip(")") if "obstacles" in pair else "capsule"] += 1
    assert min(compared.values()) > 0, compared  # every kind compared apart at least once


def test_dh_plan_figure_draws_capsules_obstacles_and_the_closest_approach(dh_plan, tmp_path):
    result = read_plan(dh_plan)
    robot = plan_robot(result, dh_plan)
    report = result.metadata["summary"]["collision"]
    assert report["pair"] == "capsule 1 – obstacles[0] (sphere)" and report["min_clearance_m"] > APART
    fig = plot_plan(result, str(dh_plan), robot)
    sample = int(np.flatnonzero(result.column("t_s") == report["t_s"])[0])
    q = np.column_stack([result.column(f"q{i + 1}_rad") for i in range(robot.n)])[sample]
    obstacles = task_obstacles_si(dh_plan)
    assert len(obstacles) == len(DH_OBSTACLES)
    ends = dh_capsule_ends(dh_plan.parent / "iiwa14c.toml", q)
    for ax in scene_axes(fig):
        check_scene(ax, robot, ends, obstacles)
        check_approach(ax, robot, ends, report, obstacles)
    assert f"t = {report['t_s']:.2f} s" in scene_axes(fig)[0].get_title()
    out = tmp_path / "plan.png"
    run = CliRunner().invoke(cli, ["plot", str(dh_plan), "-o", str(out)])
    assert run.exit_code == 0, run.output
    with Image.open(out) as image:  # the collision row adds to the figure's height
        assert image.size[1] > image.size[0]


def test_urdf_plan_figure_draws_its_collision_shapes_where_pinocchio_places_them(urdf_plan):
    result = read_plan(urdf_plan)
    robot = plan_robot(result, urdf_plan)
    assert robot.urdf is not None and robot.has_collision
    report = result.metadata["summary"]["collision"]
    assert report["pair"] == "capsule 1 – capsule 3" and report["min_clearance_m"] < 0  # an overlap
    sample = int(np.flatnonzero(result.column("t_s") == report["t_s"])[0])
    q = np.column_stack([result.column(f"q{i + 1}_rad") for i in range(robot.n)])[sample]
    obstacles = task_obstacles_si(urdf_plan)
    ends = pinocchio_capsule_ends(urdf_plan.parent / "oblique.urdf", robot, q)
    for ax in scene_axes(plot_plan(result, str(urdf_plan), robot)):
        check_scene(ax, robot, ends, obstacles)
        check_approach(ax, robot, ends, report, obstacles)


def test_ptp_figure_draws_the_arm_at_its_closest_approach(tmp_path):
    """A PTP plan names its robot: on one with capsules its figure gets the same collision row
    (joint values from the theta_<joint>_rad columns), here the wrist above a table in m."""
    (tmp_path / "iiwa14c.toml").write_text(bare_dh_text("iiwa14").replace('name = "iiwa14"', 'name = "iiwa14c"')
                                           + CAPSULES, encoding="utf-8")
    waypoints = {"t": [0, 2], "theta": {f"a{i + 1}": [0, v] for i, v in enumerate([30, 50, 0, -80, 0, 30, 0])},
                 "omega": {f"a{i + 1}": [0, 0] for i in range(7)}}
    task = _task_text({"planner": "ptp", "robot": "iiwa14c.toml", "method": "3-4", "step": 0.01,
                       "units": {"angle": "deg"}, "waypoints": waypoints},
                      [{"type": "plane", "point": [0, 0, 0.1], "normal": [0, 0, 1]}], {"activation": 0.1})
    plan = _plan(tmp_path, task)
    result = read_plan(plan)
    robot = plan_robot(result, plan)
    report = result.metadata["summary"]["collision"]
    assert report["pair"].endswith("obstacles[0] (plane)") and report["min_clearance_m"] > APART, report
    sample = int(np.flatnonzero(result.column("t_s") == report["t_s"])[0])
    q = np.array([result.column(f"theta_a{i + 1}_rad")[sample] for i in range(7)])
    ends = dh_capsule_ends(tmp_path / "iiwa14c.toml", q)
    obstacles = task_obstacles_si(plan)
    for ax in scene_axes(plot_plan(result, str(plan), robot)):
        check_scene(ax, robot, ends, obstacles)
        check_approach(ax, robot, ends, report, obstacles)


@pytest.mark.parametrize("fixture", ["dh_plan", "urdf_plan"])
def test_animation_frames_move_the_capsules_with_the_arm(fixture, request, tmp_path):
    """Each frame draws the capsules at that frame's configuration (the previous frame's removed);
    the obstacles and the marker once; and `armgen animate` writes the GIF."""
    plan = request.getfixturevalue(fixture)
    result = read_plan(plan)
    robot = plan_robot(result, plan)
    frames = np.array([0, len(result.data) // 2, len(result.data) - 1])
    fig = Figure()
    draw = animation._serial_scene(fig, result, frames, robot)
    ax = fig.axes[0]
    q = np.column_stack([result.column(f"q{i + 1}_rad") for i in range(robot.n)])
    for f, sample in enumerate(frames):
        draw(f)
        expected = (dh_capsule_ends(plan.parent / "iiwa14c.toml", q[sample]) if fixture == "dh_plan"
                    else pinocchio_capsule_ends(plan.parent / "oblique.urdf", robot, q[sample]))
        check_scene(ax, robot, expected, task_obstacles_si(plan))
    assert len(by_gid(ax, "closest approach")) == 1
    out = tmp_path / "arm.gif"
    run = CliRunner().invoke(cli, ["animate", str(plan), "-o", str(out), "--fps", "2", "--duration", "1.5",
                                   "--size", "320x240"])
    assert run.exit_code == 0, run.output
    with Image.open(out) as gif:
        assert gif.n_frames == 3


def test_a_robot_without_capsules_keeps_its_figures(tmp_path):
    """No capsules and no obstacles (the bare iiwa14): no collision row, no scene artists, and the
    animation scene draws only the arm."""
    (tmp_path / "iiwa14b.toml").write_text(bare_dh_text("iiwa14").replace('name = "iiwa14"', 'name = "iiwa14b"'),
                                           encoding="utf-8")
    end = load_robot(tmp_path / "iiwa14b.toml").fk(START)[:3, 3] + [0.1, 0.1, -0.1]
    task = ('planner = "cartesian"\nrobot = "iiwa14b.toml"\nstart = "q0_feasible"\n'
            f'[path]\ntype = "line"\nend = {_toml([float(v) for v in end])}\n[timing]\nduration = 1.0\n'
            '[integrator]\nstep = 0.01\n[method]\nname = "pinv"\n')
    plan = _plan(tmp_path, task)
    result = read_plan(plan)
    assert "collision" not in result.metadata["summary"]
    robot = plan_robot(result, plan)
    assert collision_view(result, robot) is None
    fig = plot_plan(result, str(plan), robot)
    assert len(fig.axes) == 4 + 3  # angles, velocities, criteria, task error; the three tool-path views
    assert not any(a.get_gid() for ax in fig.axes for a in (*ax.lines, *ax.collections))
    scene = Figure()
    animation._serial_scene(scene, result, np.array([0, 1]), robot)(1)
    assert not any(a.get_gid() for a in (*scene.axes[0].lines, *scene.axes[0].collections))


# -- a snake arm with capsules: the shared collision row, and its animation's outlines ---------------

SNAKE_RADIUS_MM = 30.0


def snake_task_with_capsules(folder: Path) -> dict:
    """The bundled planar snake example on snake12 with a capsule around each 104 mm link: link k
    runs from joint centre k to k + 1, the origin of DH frame 2k + 3 and 104 mm back along its x
    (frame 2k + 2 turns by α, 2k + 3 by β and carries the link's length)."""
    from armgen.planning.tasks import load_task

    text = Path(load_robot("snake12").path).read_text(encoding="utf-8").replace('name = "snake12"', 'name = "snake12c"')
    text = text.split("\n[[collision]]")[0]
    for link in range(12):
        text += f"\n[[collision]]\nlink = {2 * link + 3}\na = [-104, 0, 0]\nb = [0, 0, 0]\nradius = {SNAKE_RADIUS_MM}\n"
    text += "\n[collision_check]\nignore = [" + ", ".join(f"[{k}, {k + 1}]" for k in range(11)) + "]\n"
    (folder / "snake12c.toml").write_text(text, encoding="utf-8")
    task, _ = load_task(Path(load_robot("snake12").path).parents[1] / "examples" / "snake_planar.toml")
    task["robot"] = str(folder / "snake12c.toml")
    return task


@pytest.fixture(scope="module")
def snake_plan(tmp_path_factory) -> Path:
    """:func:`snake_task_with_capsules`, planned."""
    from armgen.planning.result import write_plan
    from armgen.planning.tasks import run_task

    folder = tmp_path_factory.mktemp("snake")
    csv, _ = write_plan(run_task(snake_task_with_capsules(folder), "snake.toml"), folder / "plan.csv")
    return csv


def snake_centres(plan: Path, robot: Robot) -> np.ndarray:
    """The joint centres (samples × 13 × 3, m, robot base frame) by the snake planner's own numpy chain."""
    from armgen.planning.snake.arm import snake_arm
    from armgen.planning.snake.plots import snake_joint_values

    arm = snake_arm(robot, "test")
    return arm.joint_centres(snake_joint_values(read_plan(plan), arm))[0]


def test_snake_figure_draws_each_link_between_its_joint_centres(snake_plan):
    result = read_plan(snake_plan)
    robot = plan_robot(result, snake_plan)
    report = result.metadata["summary"]["collision"]
    sample = int(np.flatnonzero(result.column("t_s") == report["t_s"])[0])
    centres = snake_centres(snake_plan, robot)[sample]
    ends = [centres[[k, k + 1]] for k in range(12)]
    fig = plot_plan(result, str(snake_plan), robot)
    for ax in scene_axes(fig):
        check_scene(ax, robot, ends, ())
        check_approach(ax, robot, ends, report, ())
    # the snapshots outline each link at their instant, where they draw the arm's centres
    from armgen.planning.snake.arm import snake_arm

    place = np.asarray(result.metadata["rail"]["start_m"]) - snake_arm(robot, "test").base0
    snapshots = [ax for ax in fig.axes if ax.get_title().startswith("t = ")]
    assert snapshots
    all_centres = snake_centres(snake_plan, robot) + place
    for ax in snapshots:
        (arm_line,) = [line for line in ax.get_lines() if line.get_label() == "arm"]
        drawn = np.column_stack(arm_line.get_data()) / MM
        # the snapshot's sample: one whose centres are the drawn ones (the arm rests at either end)
        matches = [k for k in range(len(all_centres)) if np.allclose(all_centres[k, :, :2], drawn, rtol=0, atol=FK_TOL)]
        assert matches
        check_outlines(ax, all_centres[matches[0]])


def test_snake_animation_outlines_each_link_in_its_views(snake_plan):
    """Each frame outlines every link's capsule in the top view: the stadium of its radius around
    the projected segment between consecutive joint centres, where the snapshots place the arm."""
    from armgen.planning.snake.plots import animation_scene

    result = read_plan(snake_plan)
    robot = plan_robot(result, snake_plan)
    frames = np.array([0, 500, 1000])
    fig = Figure()
    draw = animation_scene(fig, result, frames, robot)
    (ax,) = fig.axes  # a planar path: the top view only
    centres = snake_centres(snake_plan, robot)
    from armgen.planning.snake.arm import snake_arm

    place = np.asarray(result.metadata["rail"]["start_m"]) - snake_arm(robot, "test").base0
    for f, sample in enumerate(frames):
        draw(f)
        check_outlines(ax, centres[sample] + place)
    assert len(by_gid(ax, "closest approach")) == 1


def check_outlines(ax, centres: np.ndarray) -> None:
    """Each link's outline in a top view: the stadium of the capsule's radius around the segment
    between its joint centres (m), once."""
    for k in range(12):
        (patch,) = [p for p in ax.patches if p.get_gid() == f"capsule {k}"]
        a, b = centres[[k, k + 1], :2]
        outline = patch.get_xy() / MM
        distance = point_segment_distance(np.column_stack([outline, np.zeros(len(outline))]), np.append(a, 0.0),
                                          np.append(b, 0.0))
        np.testing.assert_allclose(distance, SNAKE_RADIUS_MM / MM, atol=FK_TOL, rtol=0)


# -- a snake task with obstacles of the collision vocabulary ------------------------------------

# Beside the example's tube obstacles (mm, the task's frame): a sphere whose surface is 32 mm from
# the last straight (y = 300 mm), so the 30 mm capsules pass 2 mm from it, the least distance of
# the plan (the links' own least is 44 mm) with a unique pair of nearest points; a pillar below
# the rail, a box turned 30° about z beside the wall, a wall half-space (solid above y = 400 mm,
# seen edge-on in the top view) and a floor (seen face-on from above: not in the top view).
SNAKE_OBSTACLES = [
    {"type": "sphere", "centre": [700.0, 360.0, 0.0], "radius": 28.0},
    {"type": "capsule", "a": [-300.0, -120.0, -200.0], "b": [-300.0, -120.0, 200.0], "radius": 40.0},
    {"type": "box", "centre": [150.0, -150.0, 0.0], "size": [100.0, 80.0, 60.0], "rpy": [0.0, 0.0, 30.0]},
    {"type": "plane", "point": [0.0, 400.0, 0.0], "normal": [0.0, -1.0, 0.0]},
    {"type": "plane", "point": [0.0, 0.0, -200.0], "normal": [0.0, 0.0, 1.0]},
]


@pytest.fixture(scope="module")
def snake_obstacle_plan(tmp_path_factory) -> Path:
    """:func:`snake_task_with_capsules` with :data:`SNAKE_OBSTACLES` after its own (tube) obstacles."""
    from armgen.planning.result import write_plan
    from armgen.planning.tasks import run_task

    folder = tmp_path_factory.mktemp("snake_obstacles")
    task = snake_task_with_capsules(folder)
    task["obstacles"] = task["obstacles"] + SNAKE_OBSTACLES
    task["collision"] = {"clearance": 1.0, "activation": 100.0}
    csv, _ = write_plan(run_task(task, "snake.toml"), folder / "plan.csv")
    return csv


def snake_obstacles_by_hand(result) -> tuple[tuple, list[str], np.ndarray]:
    """:data:`SNAKE_OBSTACLES` in the robot's base frame (m: the task's numbers × 1e-3 less where
    the base sits, the rail's start less the base joint's centre at feed 0), their names as
    summary.collision names them (their index in the task file), and that place (m)."""
    from armgen.planning.snake.arm import snake_arm

    robot = plan_robot(result)
    place = np.asarray(result.metadata["rail"]["start_m"]) - snake_arm(robot, "test").base0
    first = len(result.metadata["obstacles"])  # the tube's come first in the task file

    def at(point) -> tuple:
        return tuple(np.asarray(point) * 1e-3 - place)

    obstacles = []
    for o in SNAKE_OBSTACLES:
        if o["type"] == "sphere":
            obstacles.append(SphereObstacle(at(o["centre"]), o["radius"] * 1e-3))
        elif o["type"] == "capsule":
            obstacles.append(CapsuleObstacle(at(o["a"]), at(o["b"]), o["radius"] * 1e-3))
        elif o["type"] == "box":
            obstacles.append(BoxObstacle(at(o["centre"]), tuple(np.asarray(o["size"]) * 1e-3),
                                         tuple(np.radians(o["rpy"]))))
        else:
            obstacles.append(PlaneObstacle(at(o["point"]), tuple(o["normal"])))
    names = [f"obstacles[{first + k}] ({o['type']})" for k, o in enumerate(SNAKE_OBSTACLES)]
    return tuple(obstacles), names, place


def drawn_outline(ax, name: str) -> np.ndarray:
    (patch,) = [p for p in ax.patches if p.get_gid() == name]
    return patch.get_xy() / MM


def check_obstacle_outlines(ax, names: list[str]) -> None:
    """A top view (x–y, the task's frame, mm) outlines each of :data:`SNAKE_OBSTACLES` where the
    task file puts it: the sphere's disc and the vertical pillar's (its radius around the centre),
    the box's turned rectangle (its corners by SciPy's rotation, its area the product of its two
    horizontal sides), the wall's part of the view on its solid side; the floor is not drawn."""
    sphere, pillar, box, wall, floor = SNAKE_OBSTACLES
    for obstacle, name in ((sphere, names[0]), (pillar, names[1])):
        centre = np.asarray(obstacle.get("centre", obstacle.get("a")))[:2] * 1e-3
        np.testing.assert_allclose(np.linalg.norm(drawn_outline(ax, name) - centre, axis=1), obstacle["radius"] * 1e-3,
                                   atol=FK_TOL, rtol=0)
    rotation = Rotation.from_euler("ZYX", np.radians(box["rpy"][::-1])).as_matrix()
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    corners = ((signs * np.asarray(box["size"]) / 2) @ rotation.T + box["centre"])[:, :2] * 1e-3
    outline = drawn_outline(ax, names[2])
    assert all(np.min(np.linalg.norm(corners - p, axis=1)) <= FK_TOL for p in outline)  # each vertex a corner
    x, y = outline[:-1].T  # the closing vertex repeats the first
    area = 0.5 * abs(x @ np.roll(y, -1) - y @ np.roll(x, -1))
    assert area == pytest.approx(box["size"][0] * box["size"][1] * 1e-6, abs=FK_TOL)
    outline = drawn_outline(ax, names[3])
    boundary = wall["point"][1] * 1e-3  # the solid side is y above it (the normal points away from it)
    assert np.sum(np.abs(outline[:-1, 1] - boundary) <= FK_TOL) == 2
    assert np.all(outline[:, 1] >= boundary - FK_TOL)
    assert np.max(outline[:, 1]) == pytest.approx(ax.get_ylim()[1] / MM, abs=FK_TOL)  # to the view's edge
    assert (np.min(outline[:, 0]), np.max(outline[:, 0])) == pytest.approx(np.array(ax.get_xlim()) / MM, abs=FK_TOL)
    assert not [p for p in ax.patches if p.get_gid() == names[4]]


def test_snake_figure_draws_the_task_obstacles_and_the_approach_to_them(snake_obstacle_plan):
    """The collision row (base frame) draws the collision vocabulary's obstacles where the task
    puts them and the marker against the sphere at coal's distance; the snapshots (the task's
    frame) outline them there too."""
    result = read_plan(snake_obstacle_plan)
    robot = plan_robot(result, snake_obstacle_plan)
    obstacles, names, place = snake_obstacles_by_hand(result)
    report = result.metadata["summary"]["collision"]
    assert report["pair"] == f"capsule 11 – {names[0]}" and report["min_clearance_m"] > APART, report
    sample = int(np.flatnonzero(result.column("t_s") == report["t_s"])[0])
    centres = snake_centres(snake_obstacle_plan, robot)[sample]
    ends = [centres[[k, k + 1]] for k in range(12)]
    fig = plot_plan(result, str(snake_obstacle_plan), robot)
    for ax in scene_axes(fig):
        check_scene(ax, robot, ends, obstacles, names)
        check_approach(ax, robot, ends, report, obstacles, names)
    snapshots = [ax for ax in fig.axes if ax.get_title().startswith("t = ")]
    assert len(snapshots) == 6
    for ax in snapshots:
        check_obstacle_outlines(ax, names)


def test_snake_animation_draws_the_task_obstacles_and_the_approach_to_them(snake_obstacle_plan):
    """The animation's top view outlines the obstacles where the task puts them, and its marker
    joins coal's nearest points of the pair (the plan is planar: the top view shows the gap whole)."""
    from armgen.planning.snake.plots import animation_scene

    result = read_plan(snake_obstacle_plan)
    robot = plan_robot(result, snake_obstacle_plan)
    obstacles, names, place = snake_obstacles_by_hand(result)
    report = result.metadata["summary"]["collision"]
    fig = Figure()
    draw = animation_scene(fig, result, np.array([0, 500, 1000]), robot)
    (ax,) = fig.axes
    for f in range(3):
        draw(f)
        check_obstacle_outlines(ax, names)
    (marker,) = by_gid(ax, "closest approach")
    drawn = np.column_stack(marker.get_data()) / MM
    sample = int(np.flatnonzero(result.column("t_s") == report["t_s"])[0])
    centres = snake_centres(snake_obstacle_plan, robot)[sample]
    theirs, nearest = coal_pair(robot, [centres[[k, k + 1]] for k in range(12)], report["pair"], obstacles, names)
    assert np.linalg.norm(drawn[1] - drawn[0]) == pytest.approx(theirs, abs=COAL_TOL)
    np.testing.assert_allclose(drawn, (nearest + place)[:, :2], atol=WITNESS_TOL, rtol=0)


@settings(max_examples=200, deadline=None, derandomize=True)
@given(angle=st.floats(0, 2 * math.pi), point=st.lists(st.floats(-2, 2), min_size=3, max_size=3),
       rpy=st.lists(st.floats(-math.pi, math.pi), min_size=3, max_size=3),
       size=st.lists(st.floats(0.01, 1), min_size=3, max_size=3), view=st.sampled_from([(0, 1), (0, 2), (1, 2)]))
def test_outlines_of_a_wall_and_a_box_in_any_view(angle, point, rpy, size, view):
    """In a 2-D view: a half-space seen edge-on is the part of the view's rectangle on its solid
    side (every vertex inside the rectangle and on that side, every corner of the rectangle on
    that side among them, two vertices on the boundary where it crosses the rectangle); a box is
    the outline of its corners' projections (SciPy's rotation): each vertex a corner, every corner
    inside or on it."""
    from matplotlib.path import Path as Outline

    from armgen.planning.collision_scene import obstacle_outline

    i, j = view
    limits = np.array([[-1.0, 1.5], [-0.5, 1.0]])
    normal = np.zeros(3)
    normal[[i, j]] = math.cos(angle), math.sin(angle)
    outline = obstacle_outline(PlaneObstacle(tuple(point), tuple(normal)), view, limits)
    corners = np.array([[x, y] for x in limits[0] for y in limits[1]])
    height = (corners - np.asarray(point)[[i, j]]) @ normal[[i, j]]
    if np.all(height > 0):  # the solid side misses the view
        assert outline is None
    if np.any(height < 0):
        assert outline is not None
        inside = (outline >= limits[:, 0] - FK_TOL) & (outline <= limits[:, 1] + FK_TOL)
        assert np.all(inside)
        vertex_height = (outline - np.asarray(point)[[i, j]]) @ normal[[i, j]]
        assert np.all(vertex_height <= FK_TOL)
        for corner in corners[height <= 0]:
            assert np.min(np.linalg.norm(outline - corner, axis=1)) <= FK_TOL
        if np.any(height > 0):
            assert np.sum(np.abs(vertex_height) <= FK_TOL) >= 2
    tilted = normal + np.eye(3)[3 - i - j]  # leaning out of the view: its projection covers it
    assert obstacle_outline(PlaneObstacle(tuple(point), tuple(tilted)), view, limits) is None
    box = BoxObstacle(tuple(point), tuple(size), tuple(rpy))
    outline = obstacle_outline(box, view, limits)
    rotation = Rotation.from_euler("ZYX", rpy[::-1]).as_matrix()
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    projected = ((signs * np.asarray(size) / 2) @ rotation.T + point)[:, [i, j]]
    assert all(np.min(np.linalg.norm(projected - vertex, axis=1)) <= FK_TOL for vertex in outline)
    assert np.all(Outline(outline).contains_points(projected, radius=FK_TOL)
                  | Outline(outline).contains_points(projected, radius=-FK_TOL))


def test_a_hand_edited_snake_obstacle_is_a_clear_error(snake_obstacle_plan, tmp_path):
    """A snake plan.json whose task obstacle is edited into nonsense: `armgen plot` and `armgen
    animate` exit 2 naming task.obstacles and the fix, nothing written."""
    import json
    import shutil

    from armgen.errors import PlanFileError

    for name in ("plan.csv", "plan.json"):
        shutil.copy(snake_obstacle_plan.parent / name, tmp_path / name)
    meta = json.loads((tmp_path / "plan.json").read_text(encoding="utf-8"))
    meta["task"]["obstacles"][-5]["radius"] = -1.0  # the sphere
    (tmp_path / "plan.json").write_text(json.dumps(meta), encoding="utf-8")
    for command, out in (("plot", "out.png"), ("animate", "out.gif")):
        run = CliRunner().invoke(cli, [command, str(tmp_path / "plan.csv"), "-o", str(tmp_path / out)])
        assert run.exit_code == PlanFileError.exit_code == 2, run.output
        assert "plan.json: task.obstacles:" in run.output and "re-run `armgen plan`" in run.output
        assert not (tmp_path / out).exists()


# -- a hand-edited plan.json ---------------------------------------------------------------------


@pytest.mark.parametrize("edit, message", [
    (lambda meta: meta["task"]["obstacles"][0].update(type="cone"), "plan.json: task.obstacles:"),
    (lambda meta: meta["task"]["obstacles"][2].update(size=[0, 1, 1]), "plan.json: task.obstacles:"),
    (lambda meta: meta["summary"]["collision"].update(pair="capsule 99 – capsule 1"), "summary.collision.pair"),
    (lambda meta: meta["summary"]["collision"].update(pair="capsule 1 – obstacles[1] (sphere)"),
     "summary.collision.pair"),
    (lambda meta: meta["summary"]["collision"].update(pair="the elbow"), "summary.collision.pair"),
])
def test_a_hand_edited_collision_record_is_a_clear_error(dh_plan, tmp_path, edit, message):
    """plan.json's obstacles or closest pair edited into nonsense: `armgen plot` and `armgen animate`
    exit 2 naming the field and the fix (re-run armgen plan), no traceback, nothing written."""
    import json
    import shutil

    from armgen.errors import PlanFileError

    for name in ("plan.csv", "plan.json", "iiwa14c.toml"):
        shutil.copy(dh_plan.parent / name, tmp_path / name)
    meta = json.loads((tmp_path / "plan.json").read_text(encoding="utf-8"))
    edit(meta)
    (tmp_path / "plan.json").write_text(json.dumps(meta), encoding="utf-8")
    for command, out in (("plot", "out.png"), ("animate", "out.gif")):
        run = CliRunner().invoke(cli, [command, str(tmp_path / "plan.csv"), "-o", str(tmp_path / out)])
        assert run.exit_code == PlanFileError.exit_code == 2, run.output
        assert message in run.output and "re-run `armgen plan`" in run.output and "Traceback" not in run.output
        assert not (tmp_path / out).exists()


@pytest.fixture(scope="module")
def pair_robot(tmp_path_factory) -> Robot:
    """The iiwa14 with the test capsules."""
    path = tmp_path_factory.mktemp("pair") / "iiwa14c.toml"
    path.write_text(bare_dh_text("iiwa14") + CAPSULES, encoding="utf-8")
    return load_robot(path)


@settings(max_examples=300, deadline=None, derandomize=True)
@given(pair=st.one_of(st.text(max_size=60), st.builds(lambda i, j, k, kind: f"capsule {i} – " + (
    f"capsule {j}" if kind is None else f"obstacles[{k}] ({kind})"), st.integers(0, 9), st.integers(0, 9),
    st.integers(0, 5), st.sampled_from([None, "sphere", "capsule", "box", "plane", "cone"]))))
def test_any_pair_name_gives_a_marker_or_a_clear_error(pair_robot, pair):
    """Whatever summary.collision.pair holds, the closest approach is found (for a pair the robot
    and the task have) or a PlanFileError names the field; nothing else escapes."""
    from armgen.errors import PlanFileError

    robot = pair_robot
    obstacles = (SphereObstacle((0.4, 0.2, 0.7), 0.08), PlaneObstacle((0, 0, 0), (0, 0, 1)))
    try:
        approach = closest_approach(robot, np.zeros(robot.n), obstacles, pair)
    except PlanFileError as error:
        assert "summary.collision.pair" in str(error)
        return
    assert np.isfinite(approach.distance) and np.all(np.isfinite(approach.points))
