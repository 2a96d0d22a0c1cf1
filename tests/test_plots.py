"""Figures of every planner: formats follow the extension, panels are the ones promised, the
executed tool path (NumPy FK) matches the planner's own (CasADi) poses, bounds are drawn."""

from __future__ import annotations

from importlib.resources import files

import numpy as np
import pytest
from click.testing import CliRunner
from matplotlib.backends.backend_agg import FigureCanvasAgg

from armgen.cli.main import cli
from armgen.planning.plotting import JOINT_COLOURS, FigureWriteError, executed_tool_path, plan_robot, save_figure
from armgen.planning.result import read_plan, write_plan
from armgen.planning.tasks import load_task, plot_plan, run_task

# example -> axes the figure promises: planner panels + twin axes + 3 tool-path views (3-D, top, side)
EXPECTED_AXES = {
    "modular8_circle_combined": 4 + 1 + 3,  # angles, velocities, criteria (+ windows twin), task error
    "modular8_circle_pinv": 4 + 3,  # pinv still logs H_L (criteria panel) but opens no window (no twin)
    "iiwa14_fault_circle_gpm": 5 + 3,  # no WLN-weights panel: GPM has no weights
    "modular8_fault_circle_wln": 6 + 3,  # with the weights
    "modular8_wgpm_demo": 6 + 3,
    "ptp_single_joint": 4 * 3,  # θ ω ε jerk × three compared methods
    "snake_planar": 6 + 2 + 1,  # six snapshots (top view), angles, accuracy (+ clearance twin)
    "snake_tank": 12 + 2 + 1,  # six snapshots × (top, side)
}
SIGNATURES = {"png": (b"\x89PNG",), "svg": (b"<?xml", b"<svg"), "pdf": (b"%PDF",)}
# FK of the plan's angles vs the planner's logged pose: both double precision, same chain
FK_TOL = 1e-9  # m


def example(name: str):
    return files("armgen.data").joinpath("examples", f"{name}.toml")


@pytest.fixture(scope="module")
def plans(tmp_path_factory):
    out = {}
    root = tmp_path_factory.mktemp("plans")
    for name in EXPECTED_AXES:
        path = example(name)
        task, sha = load_task(path)
        result = run_task(task, str(path), sha)
        csv, _ = write_plan(result, root / f"{name}.csv")
        out[name] = (result, csv)
    return out


def labelled_lines(ax) -> list[str]:
    return [line.get_label() for line in ax.get_lines() if not line.get_label().startswith("_")]


@pytest.mark.parametrize("name", sorted(EXPECTED_AXES))
def test_figure_has_the_promised_panels_none_empty(plans, name):
    result, _ = plans[name]
    fig = plot_plan(result, name)
    # a plan on a robot with capsules (summary.collision) adds two 3-D panels: the arm at its closest
    # approach, seen as usual and across the gap (tests/test_collision_figures.py)
    collision_row = "collision" in result.metadata["summary"]
    assert len(fig.axes) == EXPECTED_AXES[name] + 2 * collision_row
    for ax in fig.axes:
        # a panel may state its content in words (the snake's "exact to rounding")
        assert ax.get_lines() or ax.collections or ax.patches or ax.texts, f"empty panel {ax.get_title()!r}"
    if result.metadata["planner"] in ("cartesian", "fault_tolerant", "wgpm"):
        n = len(result.metadata["robot"]["qlim_rad"])
        angles = next(ax for ax in fig.axes if ax.get_title().startswith("joint angles"))
        assert labelled_lines(angles)[:n] == [f"θ{i + 1}" for i in range(n)]
        # each joint's limits are drawn in the joint's own colour
        limit_colours = {line.get_color() for line in angles.get_lines() if line.get_label().startswith("_")}
        assert {JOINT_COLOURS[i] for i in range(n)} <= limit_colours
        velocities = next(ax for ax in fig.axes if ax.get_title().startswith("joint velocities"))
        assert labelled_lines(velocities)[:n] == [f"θ̇{i + 1}" for i in range(n)]
        title = fig.get_suptitle()
        assert "closed path: final joint deviation" in title  # every bundled example is a closed circle
        paths = [ax for ax in fig.axes if ax.get_title().startswith("tool path")]
        assert len(paths) == 3 and all("executed" in " ".join(labelled_lines(ax)) for ax in paths)
    if name == "iiwa14_fault_circle_gpm":
        assert not any("WLN" in ax.get_title() for ax in fig.axes)
    if name == "modular8_fault_circle_wln":
        assert any("WLN" in ax.get_title() for ax in fig.axes)


@pytest.mark.parametrize("name", ["modular8_circle_combined", "iiwa14_fault_circle_gpm", "snake_tank",
                                  "ptp_single_joint"])
@pytest.mark.parametrize("fmt", sorted(SIGNATURES))
def test_plot_cli_writes_the_extensions_format(plans, tmp_path, name, fmt):
    _, csv = plans[name]
    out = tmp_path / f"figure.{fmt}"
    run = CliRunner().invoke(cli, ["plot", str(csv), "-o", str(out)])
    assert run.exit_code == 0, run.output
    head = out.read_bytes()[:200].lstrip()
    assert head.startswith(SIGNATURES[fmt]), head[:20]
    assert list(tmp_path.iterdir()) == [out]  # no temporary left behind


@pytest.mark.parametrize("bad", ["-", "figure.jpg", "figure", "outdir/"])
def test_bad_output_is_a_clear_error_and_writes_nothing(plans, tmp_path, monkeypatch, bad):
    _, csv = plans["ptp_single_joint"]
    monkeypatch.chdir(tmp_path)
    (tmp_path / "outdir").mkdir()
    run = CliRunner().invoke(cli, ["plot", str(csv), "-o", bad])
    assert run.exit_code == 2
    assert "png" in run.output and "svg" in run.output and "pdf" in run.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["outdir"] and not any((tmp_path / "outdir").iterdir())


def test_save_figure_rejects_a_directory(plans, tmp_path):
    fig = plot_plan(plans["ptp_single_joint"][0], "ptp")
    with pytest.raises(FigureWriteError, match="is a directory"):
        save_figure(fig, tmp_path)


@pytest.mark.parametrize("name", ["modular8_circle_combined", "iiwa14_fault_circle_gpm", "modular8_wgpm_demo"])
def test_executed_tool_path_matches_the_planners_pose(plans, name):
    """NumPy FK (plots, animation) against the planner's CasADi FK logged in x_m, y_m, z_m."""
    result, _ = plans[name]
    executed = executed_tool_path(result, plan_robot(result))
    logged = np.column_stack([result.column(c) for c in ("x_m", "y_m", "z_m")])
    np.testing.assert_allclose(executed, logged, atol=FK_TOL, rtol=0)


def test_frames_end_in_the_generated_fk(robot):
    from armgen.symbolic.model import SymbolicModel

    fk = SymbolicModel(robot).functions()["fk"]
    q = np.random.default_rng(16).uniform(robot.qmin, robot.qmax, size=(20, robot.n))
    frames = robot.frames(q)
    assert frames.shape == (20, robot.n + 2, 4, 4)
    for k in range(q.shape[0]):
        np.testing.assert_allclose(frames[k, -1], np.array(fk(q[k])), atol=FK_TOL, rtol=0)
    np.testing.assert_allclose(frames[:, 0], np.broadcast_to(robot.base, (20, 4, 4)))
    np.testing.assert_array_equal(robot.frames(q[3]), frames[3])  # one sample, same numbers


# -- a URDF arm is drawn through its own kinematics (issue 37 item 2) ----------------------------

URDF_TIP = "panda_hand_tcp"
# Pinocchio and armgen compose the same URDF transforms in double precision: a few ulps of
# metre-sized values (as in test_urdf.PINOCCHIO_TOL).
PINOCCHIO_TOL = 1e-12  # m
URDF_ARM = f"""name = "panda_urdf"
urdf = "panda.urdf"
tip_link = "{URDF_TIP}"
[units]
length = "mm"
angle = "deg"
[configurations]
q0 = [0, -45, 0, -135, 0, 90, 45]
"""
URDF_TASK = """planner = "cartesian"
robot = "arm.toml"
start = "q0"
[units]
length = "mm"
angle = "deg"
[path]
type = "line"
end = [400, 100, 500]
[timing]
duration = 2
[integrator]
method = "rk4"
step = 0.01
"""


@pytest.fixture(scope="module")
def urdf_plan(tmp_path_factory):
    """A URDF arm (example-robot-data's Panda, through a robot file) planned from the project
    folder as `armgen plan job/task.toml -o job/plan.csv`: plan.json records job/arm.toml."""
    pin = pytest.importorskip("pinocchio")
    from test_urdf import _example_robot_data_dir

    project = tmp_path_factory.mktemp("urdf_project")
    job = project / "job"
    job.mkdir()
    urdf = _example_robot_data_dir() / "panda_description/urdf/panda.urdf"
    (job / "panda.urdf").write_bytes(urdf.read_bytes())
    (job / "arm.toml").write_text(URDF_ARM)
    (job / "task.toml").write_text(URDF_TASK)
    with pytest.MonkeyPatch.context() as patch:
        patch.chdir(project)
        run = CliRunner().invoke(cli, ["plan", "job/task.toml", "-o", "job/plan.csv"])
    assert run.exit_code == 0, run.output
    return project, job / "plan.csv", pin.buildModelFromUrdf(str(urdf))


def pinocchio_frames(model, robot, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(joint origins (samples, n, 3), tool poses (samples, 4, 4)) of ``robot``'s joint vectors by Pinocchio."""
    pin = pytest.importorskip("pinocchio")

    data = model.createData()
    ids = [model.getJointId(joint.name) for joint in robot.joints]
    tip = model.getFrameId(URDF_TIP)
    origins, tools = [], []
    for sample in np.atleast_2d(q):
        configuration = pin.neutral(model)
        for jid, value in zip(ids, sample):
            configuration[model.joints[jid].idx_q] = value
        pin.forwardKinematics(model, data, configuration)
        pin.updateFramePlacements(model, data)
        origins.append([data.oMi[jid].translation.copy() for jid in ids])
        tools.append(data.oMf[tip].homogeneous.copy())
    return np.array(origins), np.array(tools)


def test_urdf_frames_match_pinocchio(urdf_plan):
    """Every joint frame's origin and the tool pose, against an independent implementation."""
    _, csv, model = urdf_plan
    robot = plan_robot(read_plan(csv), csv)
    assert robot.urdf is not None and robot.n == 7
    q = np.random.default_rng(37).uniform(robot.qmin, robot.qmax, size=(50, robot.n))
    frames = robot.frames(q)
    origins, tools = pinocchio_frames(model, robot, q)
    np.testing.assert_allclose(frames[:, 1:-1, :3, 3], origins, atol=PINOCCHIO_TOL, rtol=0)
    np.testing.assert_allclose(frames[:, -1], tools, atol=PINOCCHIO_TOL, rtol=0)
    np.testing.assert_allclose(frames[:, 0], np.broadcast_to(np.eye(4), (50, 4, 4)), atol=0)


def test_urdf_plan_figure_draws_the_executed_path_by_the_arms_fk(urdf_plan, tmp_path):
    """The executed tool path drawn for a URDF plan is the arm's FK (Pinocchio) of the plan's
    angles; the old DH-only chain collapsed it to one point."""
    _, csv, model = urdf_plan
    result = read_plan(csv)
    robot = plan_robot(result, csv)
    q = np.column_stack([result.column(f"q{i + 1}_rad") for i in range(robot.n)])
    _, tools = pinocchio_frames(model, robot, q)
    expected_mm = tools[:, :3, 3] * 1e3
    assert np.ptp(expected_mm, axis=0).max() > 50  # the tool moves (a 0.2 m line)
    fig = plot_plan(result, str(csv), robot)
    inset = next(ax for ax in fig.axes if ax.get_title() == "tool path, 3-D")
    (executed,) = [line for line in inset.get_lines() if line.get_label().startswith("executed")]
    np.testing.assert_allclose(np.column_stack(executed.get_data_3d()), expected_mm, atol=PINOCCHIO_TOL * 1e3, rtol=0)
    planned = next(line for line in inset.get_lines() if line.get_label() == "planned path")
    start = np.column_stack(planned.get_data_3d())[0]
    np.testing.assert_allclose(start, expected_mm[0], atol=1e-6)  # the planned path starts at the tool
    out = tmp_path / "urdf.png"
    run = CliRunner().invoke(cli, ["plot", str(csv), "-o", str(out)])
    assert run.exit_code == 0, run.output
    assert out.read_bytes()[:4] == b"\x89PNG"


def test_plot_finds_the_recorded_robot_from_another_folder(urdf_plan, tmp_path, monkeypatch):
    """plan.json records job/arm.toml relative to the folder `armgen plan` ran in: found from
    the plan's folder, from an unrelated folder, and after the plan was copied elsewhere."""
    project, csv, _ = urdf_plan
    for folder in (csv.parent, tmp_path):
        monkeypatch.chdir(folder)
        out = tmp_path / f"from_{folder.name}.png"
        run = CliRunner().invoke(cli, ["plot", str(csv), "-o", str(out)])
        assert run.exit_code == 0, run.output
    moved = tmp_path / "moved"
    moved.mkdir()
    for name in ("plan.csv", "plan.json"):
        (moved / name).write_bytes((csv.parent / name).read_bytes())
    run = CliRunner().invoke(cli, ["plot", str(moved / "plan.csv"), "-o", str(tmp_path / "moved.png")])
    assert run.exit_code == 2
    assert "job/arm.toml" in run.output and str(moved / "job" / "arm.toml") in run.output  # where it looked
    assert "--robot" in run.output and not (tmp_path / "moved.png").exists()
    run = CliRunner().invoke(cli, ["plot", str(moved / "plan.csv"), "-o", str(tmp_path / "moved.png"),
                                   "--robot", str(project / "job" / "arm.toml")])
    assert run.exit_code == 0, run.output
    run = CliRunner().invoke(cli, ["plot", str(moved / "plan.csv"), "--robot", "planar3"])
    assert run.exit_code == 2 and "3 joints" in run.output and "has 7" in run.output


def test_an_edited_robot_file_is_not_drawn_as_the_plans(urdf_plan, tmp_path):
    """The recorded file with another sha256 is not the plan's robot: named in the error."""
    project, csv, _ = urdf_plan
    copy = tmp_path / "project"
    (copy / "job").mkdir(parents=True)
    for name in ("plan.csv", "plan.json", "panda.urdf"):
        (copy / "job" / name).write_bytes((csv.parent / name).read_bytes())
    (copy / "job" / "arm.toml").write_text(URDF_ARM.replace('tip_link = "panda_hand_tcp"', 'tip_link = "panda_hand"'))
    run = CliRunner().invoke(cli, ["plot", str(copy / "job" / "plan.csv"), "-o", str(tmp_path / "p.png")])
    assert run.exit_code == 2 and "changed since planning" in run.output, run.output


def test_ptp_bounds_drawn_and_violations_marked(plans):
    result, _ = plans["ptp_single_joint"]
    fig = plot_plan(result, "ptp")
    method_col = result.metadata["comparison"]["methods"].index(result.metadata["method"])
    omega_ax = fig.axes[1 * 3 + method_col]  # row ω, the planned method's column
    assert "bound j1" in labelled_lines(omega_ax)
    crosses = [line for line in omega_ax.get_lines() if line.get_marker() == "x"]
    failing = [c for c in result.metadata["timing"]["bound_check"] if not c["within_bounds"]]
    assert len(crosses) == len(failing) > 0  # the planner's own bound check names the same segments
    assert "bounds exceeded" in fig.axes[method_col].get_title()


def test_joint_colours_distinct_for_25_joints():
    assert len(set(JOINT_COLOURS[:25])) == 25


# -- the 2-D views come from the path's own plane; readable insets and labels (issue 29) --------

def _circle(centre, e1, e2, radius=0.1, samples=200):
    angle = np.linspace(0, 2 * np.pi, samples, endpoint=False)  # the mean is the centre
    return np.asarray(centre) + radius * (np.outer(np.cos(angle), e1) + np.outer(np.sin(angle), e2))


def test_views_of_a_circle_are_face_on_to_its_plane():
    from armgen.planning.plotting import principal_views

    # a y–z circle at constant x (the iiwa14 fault circle's plane): drawn in y–z, as a circle
    face, edge = principal_views(_circle([0.4, 0.1, 0.9], [0, 1, 0], [0, 0, 1]))
    assert face.name == "y–z plane" and (face.u_label, face.v_label) == ("y", "z")
    assert edge.name.endswith("edge-on") and "x" in (edge.u_label, edge.v_label)
    u, v = face.project(_circle([0.4, 0.1, 0.9], [0, 1, 0], [0, 0, 1]))
    np.testing.assert_allclose(np.hypot(u - 0.1, v - 0.9), 0.1, rtol=1e-12)
    # an oblique plane: its own axes, named by its normal; still a circle of the true radius
    e1, e2 = np.array([1, 1, 0]) / np.sqrt(2), np.array([-1, 1, 2]) / np.sqrt(6)
    points = _circle([0.2, 0.0, 0.5], e1, e2)
    face, _ = principal_views(points)
    normal = np.cross(e1, e2)
    assert face.name == "its own plane, normal (" + ", ".join(f"{c:.2f}" for c in normal) + ")"
    u, v = face.project(points - points.mean(axis=0))
    np.testing.assert_allclose(np.hypot(u, v), 0.1, rtol=1e-9)
    # a straight line along x: the top view (x–y), where it shows its length
    face, _ = principal_views(np.outer(np.linspace(0, 1, 20), [1, 0, 0]))
    assert face.name == "x–y plane"


def _overlap(a, b) -> bool:
    return a.x0 < b.x1 and b.x0 < a.x1 and a.y0 < b.y1 and b.y0 < a.y1


def test_fault_circle_figure_views_inset_ticks_and_labels(plans):
    result, _ = plans["iiwa14_fault_circle_gpm"]
    fig = plot_plan(result, "iiwa14")
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.canvas.draw()
    titles = [ax.get_title() for ax in fig.axes if ax.get_title().startswith("tool path")]
    assert titles == ["tool path, 3-D", "tool path, y–z plane", "tool path, x–z, edge-on"]
    inset = next(ax for ax in fig.axes if ax.get_title() == "tool path, 3-D")
    for axis in (inset.xaxis, inset.yaxis, inset.zaxis):  # x is constant along the circle
        shown = [t.get_text() for t in axis.get_ticklabels() if t.get_text()]
        assert len(shown) >= 2 and len(set(shown)) == len(shown), shown
    figure_box = fig.bbox
    label = inset.xaxis.label.get_window_extent(renderer)
    assert figure_box.x0 <= label.x0 and label.x1 <= figure_box.x1 and figure_box.y0 <= label.y0, "x label clipped"
    angles = next(ax for ax in fig.axes if ax.get_title().startswith("joint angles"))
    boxes = [t.get_window_extent(renderer) for t in angles.texts if "limit" in t.get_text()]
    assert len(boxes) >= 2
    assert not any(_overlap(a, b) for k, a in enumerate(boxes) for b in boxes[k + 1:])


def test_close_joint_limit_labels_do_not_overlap():
    """The Kinova Gen3's limits (deg): ±128.9 (j2), ±147.8 (j4), ±120.3 (j6), the continuous
    joints ±180: labels 8.6° apart on a 360° axis used to sit on each other."""
    from armgen.planning.plotting import limit_lines, new_figure

    gen3 = [(-180, 180), (-128.9, 128.9), (-180, 180), (-147.8, 147.8), (-180, 180), (-120.3, 120.3), (-180, 180)]
    fig = new_figure(7, 4.2)
    ax = fig.add_subplot()
    t = np.linspace(0, 10, 50)
    ax.plot(t, 100 * np.sin(t))
    limit_lines(ax, gen3, [f"θ{i + 1}" for i in range(7)], t[-1])
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.canvas.draw()
    boxes = [text.get_window_extent(renderer) for text in ax.texts]
    assert not any(_overlap(a, b) for k, a in enumerate(boxes) for b in boxes[k + 1:])
    shown = "\n".join(text.get_text() for text in ax.texts)
    for value in (180, 128.9, 147.8, 120.3, -180, -128.9, -147.8, -120.3):
        assert f"limit {value:g}°" in shown  # every limit keeps its label


def test_snake_accuracy_panel_says_exact_instead_of_drawing_rounding(plans):
    result, _ = plans["snake_planar"]
    fig = plot_plan(result, "snake")
    accuracy = next(ax for ax in fig.axes if ax.get_title().startswith("accuracy"))
    tip_mm = np.max(result.column("tip_dev_m")) * 1e3
    assert tip_mm < 1e-9  # the exact solver: rounding only
    assert accuracy.get_title().endswith("mm") and "exact to" in accuracy.get_title()
    assert not accuracy.get_lines()  # no noise drawn on the left axis
    assert any(f"≤ {tip_mm:.1e} mm" in text.get_text() for text in accuracy.texts)
    legend = accuracy.get_legend()
    colours = [handle.get_color() for handle in legend.legend_handles]
    assert len(set(colours)) == len(colours)


@pytest.mark.parametrize("record", [{"file": 5, "name": ["x"], "sha256": 7}, {"file": "x\u0000y", "name": "nope"},
                                    {"file": "x" * 5000, "name": "nope"}, {}, {"file": "../../arm.toml"}])
def test_a_hand_edited_robot_record_is_a_clear_error(urdf_plan, tmp_path, record):
    import json

    _, csv, _ = urdf_plan
    (tmp_path / "plan.csv").write_bytes(csv.read_bytes())
    meta = json.loads(csv.with_suffix(".json").read_text())
    meta["robot"] = record
    (tmp_path / "plan.json").write_text(json.dumps(meta))
    for command in ("plot", "animate"):
        run = CliRunner().invoke(cli, [command, str(tmp_path / "plan.csv"), "-o", str(tmp_path / f"x.{command}.png")])
        assert run.exit_code == 2, run.output
        assert "plan.json" in run.output and "--robot" in run.output and "internal error" not in run.output


# The planned circle's samples against the circumcircle of its three points: rounding only.
CIRCLE_TOL = 1e-9  # m


def test_planned_circle_is_the_circle_through_the_tasks_points(plans):
    """The planned path drawn for a circle plan is the circle through the start tool position
    (the arm's FK of the recorded start) and the task's via and end (mm → m), checked against
    the circumcircle computed here with NumPy."""
    from armgen.planning.plotting import planned_tool_path

    result, _ = plans["modular8_circle_combined"]
    robot = plan_robot(result)
    start = robot.fk(np.array(result.metadata["start"]["q_rad"]))[:3, 3]
    task = result.metadata["task"]
    via, end = (np.array(task["path"][k], dtype=float) * 1e-3 for k in ("via", "end"))
    normal = np.cross(via - start, end - start)
    # the circumcentre: equidistant from the three points, in their plane
    system = np.array([2 * (via - start), 2 * (end - start), normal])
    rhs = np.array([via @ via - start @ start, end @ end - start @ start, normal @ start])
    centre = np.linalg.solve(system, rhs)
    points = planned_tool_path(result, robot)
    assert points is not None and len(points) >= 100
    np.testing.assert_allclose(np.linalg.norm(points - centre, axis=1), np.linalg.norm(start - centre),
                               atol=CIRCLE_TOL, rtol=0)
    np.testing.assert_allclose((points - centre) @ normal / np.linalg.norm(normal), 0.0, atol=CIRCLE_TOL)
    np.testing.assert_allclose(points[0], start, atol=CIRCLE_TOL)


def test_plotting_imports_no_planner():
    """plotting rebuilds the planned path through the shared floor (planning.common, toolpath),
    never through a planner's package (issue 36), deferred imports included."""
    import ast

    from armgen.planning import plotting
    from armgen.planning.registry import PLANNER_NAMES

    tree = ast.parse(open(plotting.__file__, encoding="utf-8").read())
    modules = [node.module or "" for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)]
    modules += [alias.name for node in ast.walk(tree) if isinstance(node, ast.Import) for alias in node.names]
    planners = [m for m in modules if m.removeprefix("armgen.planning.").split(".")[0] in PLANNER_NAMES]
    assert not planners, f"plotting imports planner modules: {planners}"
