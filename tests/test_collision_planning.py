"""Issue 38, phase 2: obstacles in the resolved-rate planners' task files, the collision
criterion H_C in their null-space term, and every plan measured against its clearance.

The scene: the iiwa14 with the capsules of tests/test_collision.py tracks a 0.76 m line with its
orientation held (one degree of redundancy: the elbow's swivel) while a sphere sits where the
minimum-norm plan's elbow passes. The distances are checked by a computation of our own: the
capsules' ends through the arm's frames and the closed-form distance of a point to a segment."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from armgen.description.collision import CapsuleObstacle, PlaneObstacle, SphereObstacle, obstacle_kind
from armgen.errors import PlanningError, TaskFileError
from armgen.planning.common.collision import TaskCollision, clearance_report
from armgen.planning.tasks import run_task
from armgen.robot import load_robot
from test_collision import CAPSULES, bare_robot_text

# The sphere (mm, base frame) where the plain plan's elbow passes 6.5 s into the line, and the
# task's [collision] (mm): the plain plan comes 27 mm into it, the criterion keeps it 54 mm off.
SPHERE = {"type": "sphere", "centre": [-333.0, 239.0, 646.0], "radius": 50.0}
CLEARANCE_MM, ACTIVATION_MM = 20.0, 150.0
# ∇H_C reaches ~40 per metre of lever at d = c + 3 (ρ − c)/4: a gain of 0.01 rad/s per unit keeps
# the self-motion it asks for below a tenth of the joints' speed limits on this scene.
GAIN = 0.01
# The line: from the start's tool position by this offset (m) in 10 s (cubic), Euler at 10 ms.
LINE_OFFSET = np.array([0.5, 0.5, -0.4])
START = np.radians([20, -50, 10, -60, 0, 30, 0])  # the iiwa14's q0_feasible
# J q̇ = ẋ holds to rounding where the step is undamped (|J q̇ − ẋ| of one solve in double).
RESIDUAL_TOL = 1e-12
# Closed loop (1/s; the resolved-rate planners' CLIK): Euler at 10 ms then keeps the tool within
# 0.06 mm of its line, with or without H_C, where open loop drifts 1.3 mm over the 10 s.
CLIK_GAIN = 5.0
# The criterion's self-motion must not move the tool off its line (the bar: 0.5 mm).
PATH_TOL_MM = 0.5
# The summary's least distance is the collision function's; our closed form agrees to rounding.
DISTANCE_TOL = 1e-9  # m


@pytest.fixture(scope="module")
def robot_file(tmp_path_factory) -> Path:
    text = bare_robot_text("iiwa14").replace('name = "iiwa14"', 'name = "iiwa14c"') + CAPSULES
    path = tmp_path_factory.mktemp("robots") / "iiwa14c.toml"
    path.write_text(text, encoding="utf-8")
    return path


def line_task(robot_file: Path, planner: str, method: str, gain: float | None, limits: str = "report") -> dict:
    robot = load_robot(robot_file)
    end = robot.fk(START)[:3, 3] + LINE_OFFSET
    task = {"planner": planner, "robot": str(robot_file), "start": "q0_feasible",
            "units": {"length": "mm", "angle": "deg"},
            "path": {"type": "line", "end": list(end * 1e3), "orientation": "hold"},
            "timing": {"duration": 10.0, "law": "cubic"}, "integrator": {"step": 0.01, "clik_gain": CLIK_GAIN},
            "method": {"name": method}, "check": {"limits": limits}}
    if gain is not None:
        task["obstacles"] = [SPHERE]
        task["collision"] = {"clearance": CLEARANCE_MM, "activation": ACTIVATION_MM, "gain": gain}
    return task


def point_to_segment(point: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The closed-form distance of ``point`` to the segments a–b (arrays of segments)."""
    ab = b - a
    t = np.clip(np.einsum("...i,...i", point - a, ab) / np.maximum(np.einsum("...i,...i", ab, ab), 1e-300), 0, 1)
    return np.linalg.norm(a + t[..., None] * ab - point, axis=-1)


def sphere_clearance_to(robot_file: Path, q: np.ndarray, sphere: dict, scale: float = 1e-3) -> np.ndarray:
    """Per sample, the least distance (m) of the arm's moving capsules to ``sphere`` (lengths in
    m per ``scale``: mm by default)."""
    robot = load_robot(robot_file)
    frames = robot.frames(q)
    centre, radius = np.array(sphere["centre"]) * scale, sphere["radius"] * scale
    least = np.full(len(q), np.inf)
    for capsule in robot.collision.capsules:
        if capsule.frame == 0:
            continue
        pose = frames[:, capsule.frame]
        a = pose[:, :3, :3] @ np.array(capsule.a) + pose[:, :3, 3]
        b = pose[:, :3, :3] @ np.array(capsule.b) + pose[:, :3, 3]
        least = np.minimum(least, point_to_segment(centre, a, b) - capsule.radius - radius)
    return least


def sphere_clearance(robot_file: Path, q: np.ndarray) -> np.ndarray:
    return sphere_clearance_to(robot_file, q, SPHERE)


PLANNERS = [("cartesian", "pinv"), ("fault_tolerant", "gpm"), ("wgpm", "wgpm")]


@pytest.mark.parametrize("planner, method", PLANNERS)
def test_the_criterion_keeps_the_clearance_the_plain_plan_breaks(robot_file, planner, method):
    plain = run_task(line_task(robot_file, planner, method, 0.0), "plain.toml")
    avoiding = run_task(line_task(robot_file, planner, method, GAIN), "avoiding.toml")
    q_plain, q_avoid = plain.data[:, 1:8], avoiding.data[:, 1:8]
    ours_plain, ours_avoid = sphere_clearance(robot_file, q_plain), sphere_clearance(robot_file, q_avoid)
    assert ours_plain.min() < 0  # the plain plan's elbow runs into the sphere
    assert ours_avoid.min() >= CLEARANCE_MM * 1e-3  # the criterion keeps the clearance at every sample
    report = avoiding.metadata["summary"]["collision"]
    assert report["within_clearance"] and report["samples_checked"] == len(q_avoid)
    if "obstacles[0]" in report["pair"]:  # the least distance is the sphere's: equal to our closed form
        assert report["min_clearance_m"] == pytest.approx(ours_avoid.min(), abs=DISTANCE_TOL)
    plain_report = plain.metadata["summary"]["collision"]
    assert plain_report["pair"] == "capsule 1 – obstacles[0] (sphere)" and not plain_report["within_clearance"]
    assert plain_report["min_clearance_m"] == pytest.approx(ours_plain.min(), abs=DISTANCE_TOL)
    for result in (plain, avoiding):
        summary = result.metadata["summary"]
        assert summary["max_pos_error_mm"] <= PATH_TOL_MM
        assert not summary["limit_violations"] and summary["joint_speed"]["within_speed_limits"]
    if planner == "cartesian":  # J q̇ = ẋ_cmd: the criterion moves the arm in the null space only
        assert avoiding.column("task_residual_1").max() <= RESIDUAL_TOL


def test_a_plan_below_the_clearance_is_refused_naming_pair_time_and_distance(robot_file):
    with pytest.raises(PlanningError) as error:
        run_task(line_task(robot_file, "cartesian", "pinv", 0.0, limits="error"), "job.toml")
    message = str(error.value)
    assert "job.toml" in message and "capsule 1" in message and "obstacles[0] (sphere)" in message
    assert "t = 6.510 s" in message and "clearance = 20.0 mm" in message and "gain" in message
    assert "capsule 1 to -27.1 mm into obstacles[0] (sphere)" in message
    assert error.value.exit_code == 3


def test_self_clearance_is_reported_without_obstacles(robot_file):
    result = run_task(line_task(robot_file, "cartesian", "pinv", None), "self.toml")
    report = result.metadata["summary"]["collision"]
    robot = load_robot(robot_file)
    expected = robot.collision_distances(result.data[:, 1:8])[:, :len(robot.collision.self_pairs())].min()
    assert report["obstacles"] == 0 and report["min_self_clearance_m"] == report["min_clearance_m"] == expected
    assert report["pair"] == report["self_pair"] and report["within_clearance"]


def test_obstacles_need_a_robot_with_capsules_and_a_collision_table(robot_file):
    task = line_task(robot_file, "cartesian", "pinv", GAIN)
    task["robot"], task["start"] = "modular8", "q0"
    with pytest.raises(TaskFileError, match=r"job\.toml: field 'obstacles': robot 'modular8' has no collision capsules.*"
                                            r"give the robot file \[\[collision\]\] capsules"):
        run_task(task, "job.toml")
    task = line_task(robot_file, "wgpm", "wgpm", GAIN)
    del task["collision"]
    with pytest.raises(TaskFileError, match=r"job\.toml: field 'collision': the task has \[\[obstacles\]\] but no "
                                            r"\[collision\] table; add \[collision\] with activation"):
        run_task(task, "job.toml")
    task = line_task(robot_file, "fault_tolerant", "gpm", GAIN)
    task["obstacles"] = [SPHERE] * 5
    with pytest.raises(TaskFileError, match=r"field 'obstacles': 5 sphere obstacles, but the robot's collision "
                                            r"functions take 4"):
        run_task(task, "job.toml")


# -- PTP plans: every sample checked -------------------------------------------------------------

PTP_TURN_DEG = 60.0  # joint a1 turns this far from the start, 2 s rest to rest


def ptp_task(robot_file: Path, obstacles: list[dict], collision: dict | None) -> dict:
    start = np.degrees(START)
    end = start + np.array([PTP_TURN_DEG, 0, 0, 0, 0, 0, 0])
    task = {"planner": "ptp", "robot": str(robot_file), "method": "3-4", "step": 0.001, "units": {"angle": "deg"},
            "waypoints": {"t": [0.0, 2.0], "theta": {f"a{k + 1}": [start[k], end[k]] for k in range(7)},
                          "omega": {f"a{k + 1}": [0.0, 0.0] for k in range(7)}}}
    if obstacles:
        task["obstacles"] = obstacles
    if collision:
        task["collision"] = collision
    return task


def elbow_half_way(robot_file: Path) -> np.ndarray:
    """The elbow (DH frame 4's origin, m) half-way through the PTP turn."""
    robot = load_robot(robot_file)
    q = START + np.radians([PTP_TURN_DEG / 2, 0, 0, 0, 0, 0, 0])
    return robot.frames(q)[4, :3, 3]


def test_a_ptp_plan_through_an_obstacle_is_refused_at_the_sample_it_hits(robot_file):
    # a ptp task's lengths are in m (its [units] has the angle only)
    sphere = {"type": "sphere", "centre": list(elbow_half_way(robot_file)), "radius": 0.05}
    collision = {"clearance": CLEARANCE_MM * 1e-3, "activation": ACTIVATION_MM * 1e-3}
    with pytest.raises(PlanningError) as error:
        run_task(ptp_task(robot_file, [sphere], collision), "ptp.toml")
    message = str(error.value)
    assert "ptp.toml" in message and "obstacles[0] (sphere)" in message and error.value.exit_code == 3
    # written with limits = "report": the report's least distance and time against our closed form
    task = ptp_task(robot_file, [sphere], collision)
    task["check"] = {"limits": "report"}
    result = run_task(task, "ptp.toml")
    report = result.metadata["summary"]["collision"]
    q = np.column_stack([result.column(f"theta_a{k + 1}_rad") for k in range(7)])
    ours = sphere_clearance_to(robot_file, q, sphere, scale=1.0)
    assert report["samples_checked"] == len(result.data) and not report["within_clearance"]
    assert report["min_clearance_m"] == pytest.approx(ours.min(), abs=DISTANCE_TOL)
    assert report["t_s"] == pytest.approx(result.data[int(np.argmin(ours)), 0])
    assert f"t = {report['t_s']:.3f} s" in message
    # the same turn with the sphere a metre higher plans (exit 0)
    sphere["centre"][2] += 1.0
    clear = run_task(ptp_task(robot_file, [sphere], collision), "ptp.toml")
    assert clear.metadata["summary"]["collision"]["within_clearance"]


def test_a_ptp_plan_closer_to_itself_than_the_clearance_is_refused(robot_file):
    free = run_task(ptp_task(robot_file, [], None), "ptp.toml").metadata["summary"]["collision"]
    closest = free["min_self_clearance_m"]
    with pytest.raises(PlanningError) as error:  # a clearance beyond the arm's closest self approach
        run_task(ptp_task(robot_file, [], {"clearance": closest + 0.01, "activation": 0.5}), "ptp.toml")
    first, second = free["self_pair"].split(" – ")
    assert f"brings {first} to {closest * 1e3:.1f} mm from {second}" in str(error.value)


# -- snake plans: the links' capsules against each other at every sample --------------------------

SNAKE_LINK_RADIUS_MM = 30.0


def snake_with_capsules(tmp_path: Path, ignore_adjacent: bool) -> Path:
    """snake12 with a capsule around each 104 mm link: link k runs from joint centre k to k + 1,
    the origin of DH frame 2k + 3 and 104 mm back along its x (frame 1 is the rail's, frame 2k + 2
    turns by alpha, 2k + 3 by beta and carries the link's length)."""
    text = Path(load_robot("snake12").path).read_text(encoding="utf-8").replace('name = "snake12"', 'name = "snake12c"')
    for link in range(12):
        text += f"\n[[collision]]\nlink = {2 * link + 3}\na = [-104, 0, 0]\nb = [0, 0, 0]\nradius = {SNAKE_LINK_RADIUS_MM}\n"
    if ignore_adjacent:  # neighbours meet at their universal joint by construction
        text += "\n[collision_check]\nignore = [" + ", ".join(f"[{k}, {k + 1}]" for k in range(11)) + "]\n"
    path = tmp_path / "snake12c.toml"
    path.write_text(text, encoding="utf-8")
    return path


def snake_task(robot: Path) -> dict:
    from armgen.planning.tasks import load_task

    task, _ = load_task(Path(load_robot("snake12").path).parents[1] / "examples" / "snake_planar.toml")
    task["robot"] = str(robot)
    return task


def test_snake_plans_report_their_links_clearance_and_are_refused_when_links_overlap(tmp_path):
    coal = pytest.importorskip("coal")
    from test_collision import REQUEST, _coal_capsule

    robot_file = snake_with_capsules(tmp_path, ignore_adjacent=True)
    result = run_task(snake_task(robot_file), "snake.toml")
    report = result.metadata["summary"]["collision"]
    robot = load_robot(robot_file)
    q = np.column_stack([result.column("feed_m")] + [result.column(f"{ab}{i + 1}_rad")
                                                      for i in range(12) for ab in "ab"])
    assert report["samples_checked"] == len(q) and report["within_clearance"]
    # the reported least distance against coal's capsule distances at its sample
    k = int(np.argmin(np.abs(result.column("t_s") - report["t_s"])))
    frames = robot.frames(q[k])
    first, second = (int(name.split()[1]) for name in report["pair"].split(" – "))

    def capsule(index):
        c = robot.collision.capsules[index]
        pose = frames[c.frame]
        return _coal_capsule(pose[:3, :3] @ np.array(c.a) + pose[:3, 3], pose[:3, :3] @ np.array(c.b) + pose[:3, 3],
                             c.radius)

    ours = coal.distance(*capsule(first), *capsule(second), REQUEST, coal.DistanceResult())
    assert report["min_clearance_m"] == pytest.approx(ours, abs=DISTANCE_TOL)
    # without the adjacent pairs ignored, neighbours overlap at their joint by 2 radii at every
    # sample (the example writes its plan under [check] limits = "report", which the refusal follows)
    overlapping = run_task(snake_task(snake_with_capsules(tmp_path, ignore_adjacent=False)), "snake.toml")
    report = overlapping.metadata["summary"]["collision"]
    assert not report["within_clearance"] and report["t_s"] == 0.0
    assert report["min_clearance_m"] == pytest.approx(-2 * SNAKE_LINK_RADIUS_MM * 1e-3, abs=DISTANCE_TOL)
    first, second = (int(name.split()[1]) for name in report["pair"].split(" – "))
    assert second == first + 1


# -- a program above a table -------------------------------------------------------------------

TABLE_Z_MM = 250.0  # the bundled weld seam runs at z = 400 mm with the tool pointing down


def test_a_cartesian_program_over_a_table_reports_the_wrist_sphere_height(robot_file):
    from armgen.planning.tasks import load_task

    task, _ = load_task(Path(load_robot("iiwa14").path).parents[1] / "examples" / "iiwa14_weld_seam_program.toml")
    task.update(planner="cartesian", robot=str(robot_file), method={"name": "pinv"})
    task["obstacles"] = [{"type": "plane", "point": [0, 0, TABLE_Z_MM], "normal": [0, 0, 1]}]
    task["collision"] = {"clearance": CLEARANCE_MM, "activation": 100.0}
    result = run_task(task, "weld.toml")
    report = result.metadata["summary"]["collision"]
    robot = load_robot(robot_file)
    q = np.column_stack([result.column(f"q{k + 1}_rad") for k in range(7)])
    # closed form: every moving capsule's lower end above the table, less its radius
    frames = robot.frames(q)
    heights = []
    for capsule in robot.collision.capsules:
        if capsule.frame:
            pose = frames[:, capsule.frame]
            ends = [pose[:, :3, :3] @ np.array(end) + pose[:, :3, 3] for end in (capsule.a, capsule.b)]
            heights.append(np.minimum(ends[0][:, 2], ends[1][:, 2]) - TABLE_Z_MM * 1e-3 - capsule.radius)
    ours = np.min(heights, axis=0)
    assert report["pair"].endswith(" – obstacles[0] (plane)") and report["within_clearance"]
    assert report["min_clearance_m"] == pytest.approx(ours.min(), abs=DISTANCE_TOL)
    assert report["samples_checked"] == len(q)


def test_plan_json_keeps_the_clearance_report(robot_file, tmp_path):
    from armgen.planning.result import read_plan, write_plan

    result = run_task(line_task(robot_file, "wgpm", "wgpm", GAIN), "job.toml")
    csv, _ = write_plan(result, tmp_path / "plan.csv")
    summary = read_plan(csv).summary
    assert summary.collision.pair == result.metadata["summary"]["collision"]["pair"]
    assert summary.collision.min_clearance_m == result.metadata["summary"]["collision"]["min_clearance_m"]
    assert summary.collision.within_clearance


# -- the report names the obstacle the task gave ---------------------------------------------------

_COORD = st.floats(-0.8, 0.8, allow_nan=False)
_POINT = st.tuples(_COORD, _COORD, st.floats(0.0, 1.2, allow_nan=False))
_OBSTACLE = st.one_of(
    st.builds(SphereObstacle, _POINT, st.floats(0.0, 0.2)),
    st.builds(CapsuleObstacle, _POINT, _POINT, st.floats(0.0, 0.2)),
    st.builds(PlaneObstacle, _POINT, st.sampled_from([(0.0, 0.0, 1.0), (1.0, 0.0, 0.0), (0.3, -0.4, 0.5)])))


@settings(max_examples=25, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow,
                                                                                   HealthCheck.function_scoped_fixture])
@given(obstacles=st.lists(_OBSTACLE, min_size=1, max_size=6), seed=st.integers(0, 2 ** 16))
def test_the_report_names_the_task_obstacle_it_measured(robot_file, obstacles, seed):
    """Whatever the mix of kinds (the collision functions take them grouped by kind), the pair the
    report names gives its least distance when measured alone: the task's obstacle k and capsule i."""
    robot = load_robot(robot_file)
    kinds = [obstacle_kind(o) for o in obstacles]
    # at most the robot's slots of each kind (more is refused when configured)
    obstacles = [o for k, o in enumerate(obstacles) if kinds[:k].count(kinds[k]) < robot.collision.slots.count(kinds[k])]
    given = {kind: sum(obstacle_kind(o) == kind for o in obstacles) for kind in ("sphere", "capsule", "box", "plane")}
    q = np.random.default_rng(seed).uniform(robot.qmin, robot.qmax, size=(5, robot.n))
    report = clearance_report(robot, np.arange(5.0), q, TaskCollision(tuple(obstacles), None, {}))
    everything = robot.collision_distances(q, obstacles)
    self_pairs = len(robot.collision.self_pairs())
    given_columns = [k for k, (_, other) in enumerate(robot.collision_pairs())
                     if k < self_pairs or int(other.split()[1]) < given[other.split()[0]]]
    assert report["min_clearance_m"] == pytest.approx(everything[:, given_columns].min(), abs=DISTANCE_TOL)
    first, second = report["pair"].split(" – ")
    sample = int(report["t_s"])
    if second.startswith("obstacles["):
        k = int(second[len("obstacles["):second.index("]")])
        alone = robot.collision_distances(q[sample], [obstacles[k]])
        kind = second.split("(")[1].rstrip(")")
        column = robot.collision_pairs().index((first, f"{kind} 0"))
        assert alone[column] == pytest.approx(report["min_clearance_m"], abs=DISTANCE_TOL)


# The compiled kernel (generated C, double) against CasADi's interpreter of the same expression:
# the bar for the host build, 1e-9 rad.
HOST_C_TOL = 1e-9


def test_the_compiled_kernel_plans_the_same_avoidance(robot_file):
    symbolic = run_task(line_task(robot_file, "cartesian", "pinv", GAIN), "job.toml", backend="symbolic")
    compiled = run_task(line_task(robot_file, "cartesian", "pinv", GAIN), "job.toml", backend="c")
    q = [result.data[:, 1:8] for result in (symbolic, compiled)]
    assert np.max(np.abs(q[0] - q[1])) <= HOST_C_TOL
    assert compiled.metadata["summary"]["collision"]["within_clearance"]


# -- snake plans against the task's sphere, capsule, plane and centred-box obstacles --------------

# Beside the planar example's last straight (y = 300 mm, the links' centres on it): a sphere whose
# surface is 40 mm from that line, so the 30 mm capsules pass 10 mm from it.
SNAKE_SPHERE = {"type": "sphere", "centre": [700.0, 360.0, 0.0], "radius": 20.0}


def test_snake_links_are_measured_against_the_task_obstacles_and_refused_below_the_clearance(tmp_path):
    from armgen.planning.tasks import configure_task
    from test_collision import REQUEST, _coal_capsule

    coal = pytest.importorskip("coal")
    robot_file = snake_with_capsules(tmp_path, ignore_adjacent=True)
    task = snake_task(robot_file)
    task["obstacles"] = task.get("obstacles", []) + [SNAKE_SPHERE]
    index = len(task["obstacles"]) - 1  # after the example's own (tube) obstacles
    task["collision"] = {"clearance": 5.0, "activation": 100.0}
    result = run_task(task, "snake.toml")
    report = result.metadata["summary"]["collision"]
    assert report["within_clearance"] and report["obstacles"] == 1
    # the least distance to the sphere by coal, every sample, the capsules placed in the task's frame
    robot, config = load_robot(robot_file), configure_task(task, "snake.toml").config
    place = config.rail_start - config.arm.base0
    q = np.column_stack([result.column("feed_m")] + [result.column(f"{ab}{i + 1}_rad")
                                                      for i in range(12) for ab in "ab"])
    centre = np.array(SNAKE_SPHERE["centre"]) * 1e-3
    sphere = (coal.Sphere(SNAKE_SPHERE["radius"] * 1e-3), coal.Transform3s(np.eye(3), centre))
    ours = np.full(len(q), np.inf)
    for k in range(0, len(q)):
        frames = robot.frames(q[k])
        for c in robot.collision.capsules:
            ends = [frames[c.frame][:3, :3] @ np.array(end) + frames[c.frame][:3, 3] + place for end in (c.a, c.b)]
            ours[k] = min(ours[k], coal.distance(*_coal_capsule(*ends, c.radius), *sphere, REQUEST,
                                                 coal.DistanceResult()))
    assert ours.min() == pytest.approx(10e-3, abs=1e-3)  # the scene as designed
    sphere_pairs = report["pair"].endswith(f"obstacles[{index}] (sphere)")
    if sphere_pairs:
        assert report["min_clearance_m"] == pytest.approx(ours.min(), abs=DISTANCE_TOL)
    else:  # the links' own least distance is smaller than the sphere's
        assert report["min_clearance_m"] <= ours.min()
    # above the sphere's 10 mm: refused (exit 3) naming the sphere by its index in the file; the
    # same travel at 3/4 of the example's speed, which keeps the joints' speed limits checked first
    task["collision"]["clearance"] = 20.0
    task["check"] = {"limits": "error"}
    task["motion"].update(v=90.0, duration=13.0)
    with pytest.raises(PlanningError) as error:
        run_task(task, "snake.toml")
    assert error.value.exit_code == 3 and f"obstacles[{index}] (sphere)" in str(error.value)
    assert "clearance = 20.0 mm" in str(error.value)


def test_snake_task_obstacles_of_the_collision_vocabulary_need_capsules():
    task = snake_task(Path(load_robot("snake12").path))
    task["obstacles"] = task.get("obstacles", []) + [SNAKE_SPHERE]
    task["collision"] = {"clearance": 5.0, "activation": 100.0}
    with pytest.raises(TaskFileError, match=r"snake\.toml: field 'obstacles': robot 'snake12' has no collision "
                                            r"capsules") as error:
        run_task(task, "snake.toml")
    assert error.value.exit_code == 2
    task["robot"] = "snake12"
    del task["collision"]
    task["obstacles"][-1] = {"type": "sphere", "centre": [700.0, 360.0, 0.0]}
    with pytest.raises(TaskFileError, match=r"obstacles\[\d+\]\.radius.*is missing; a sphere takes centre and radius"):
        run_task(task, "snake.toml")
