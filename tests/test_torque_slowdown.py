"""A program is slowed where a joint would exceed its torque limit (issue 39): a Panda that is
not bundled (example-robot-data's URDF, its inertials, behind a robot file with a job's tight
``taumax``) runs a fast welding-like program. The plan's joint torques are recomputed by an
independent inverse dynamics, Pinocchio's ``rnea`` on the same URDF at every sample of the
plan (``q``, ``q̇`` from its columns, ``q̈`` by the documented rule: central differences of
``q̇`` over ``t``), and the tool's position by Pinocchio's forward kinematics against the
program's point at that time. A pose where gravity alone needs more than ``taumax`` is exit 3
naming the joint and the time; a robot without inertials plans as it did before."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
import tomli_w
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st

from armgen.cli.main import cli
from armgen.errors import PlanningError
from armgen.planning.plan_schema import TorqueSlowing
from armgen.planning.tasks import configure_task, run_task
from armgen.planning.toolpath.accuracy import DEFAULT_PATH_TOLERANCE
from armgen.planning.toolpath.timelaw import JointBounds, PathProfile
from armgen.robot import load_robot

pin = pytest.importorskip("pinocchio")

from test_dynamics import _Pinocchio  # noqa: E402  (Pinocchio's dynamics of armgen's chain, fingers locked)
from test_urdf import _example_robot_data_dir  # noqa: E402

PANDA_URDF = "panda_description/urdf/panda.urdf"
READY = [0, -0.7853981633974483, 0, -2.356194490192345, 0, 1.5707963267948966, 0.7853981633974483]
# A job's drives, N·m: tight enough that the program below at full speed asks joints 1–6 for
# more (its peaks with the URDF's 87/12 N·m: 19.9, 41.4, 17.8, 33.0, 1.58, 3.92, 0.014), yet
# above the gravity torques along its path (at most 0, 38.6, 2.7, 22.6, 0.6, 2.3, 0).
TIGHT_TAUMAX = (10.0, 45.0, 8.0, 28.0, 1.0, 3.0, 12.0)

ROBOT = """name = "{name}"
urdf = "{urdf}"
tip_link = "panda_hand"
task_rows = ["vx", "vy", "vz", "wx", "wy", "wz"]
[units]
length = "mm"
angle = "rad"
[limits]
{limits}
[configurations]
ready = {ready}
"""

# A welding-like program at 800 mm/s and 6 m/s²: lines, a rise, an arc, 20 mm blends.
PROGRAM = {
    "planner": "cartesian", "start": {"pose": {"xyz": [400, -200, 250], "rpy": [180, 0, 0]}, "seed": "ready"},
    "units": {"length": "mm", "angle": "deg"},
    "path": {"type": "program", "speed": 800.0, "acceleration": 6000.0, "blend": 20.0,
             "moves": [{"kind": "line", "to": {"xyz": [400, 200, 250]}},
                       {"kind": "line", "to": {"xyz": [600, 200, 450]}},
                       {"kind": "arc", "via": {"xyz": [650, 0, 450]}, "to": {"xyz": [600, -200, 450]}},
                       {"kind": "line", "to": {"xyz": [400, -200, 250]}}]},
    "integrator": {"method": "rk4"},
}

# armgen's and Pinocchio's inverse dynamics agree to ~1e-15 relative (tests/test_dynamics.py)
# and are evaluated at the same samples: the plan is within taumax up to that rounding.
PIN_RATIO_TOL = 1.0 + 1e-9
# Not slower than needed: the slowed plan uses at least this share of some joint's taumax (the
# slowing aims at 95 % of the headroom above gravity; measured 0.99).
MIN_PEAK_TORQUE_RATIO = 0.9
# ... and takes no longer than the by-hand remedy: the unlimited plan slowed uniformly in time
# by k with k² the worst |τ − g| / (taumax − |g|) (the dynamic torque of a path scales as 1/k²;
# this k is the smallest uniform factor the triangle inequality proves feasible).
MAX_DURATION_OVER_UNIFORM = 1.0
# Pinocchio's tool position against the planner's: the same kinematics in double.
FK_ATOL = 1e-9  # m


def _robot_file(folder: Path, name: str, taumax: tuple[float, ...] | None, inertials: bool = True) -> Path:
    """A robot file on example-robot-data's Panda with ``taumax`` (None: the URDF's efforts);
    ``inertials=False``: on a copy of the URDF without its ``<inertial>`` elements."""
    urdf = _example_robot_data_dir() / PANDA_URDF
    if not inertials:
        stripped = folder / f"{name}.urdf"
        stripped.write_text(re.sub(r"<inertial>.*?</inertial>", "", urdf.read_text(), flags=re.S))
        urdf = stripped
    limits = "" if taumax is None else "\n".join(f"panda_joint{k} = {{ taumax = {v} }}"
                                                 for k, v in enumerate(taumax, start=1))
    path = folder / f"{name}.toml"
    path.write_text(ROBOT.format(name=name, urdf=urdf.as_posix(), limits=limits, ready=READY))
    return path


def _pinocchio(robot) -> _Pinocchio:
    return _Pinocchio(pin.buildModelFromUrdf(str(Path(robot.urdf["file"]))), robot)


def _columns(result, stem: str) -> np.ndarray:
    return np.column_stack([result.column(stem.format(k=k)) for k in range(1, 8)])


def _pinocchio_torques(reference: _Pinocchio, result, with_gravity: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """(τ, g) by Pinocchio at every sample of the plan (g zeros unless ``with_gravity``)."""
    t, q, dq = result.column("t_s"), _columns(result, "q{k}_rad"), _columns(result, "dq{k}_rad_s")
    ddq = np.gradient(dq, t, axis=0)
    model, data, v = reference.model, reference.data, reference.v
    tau, gravity = np.empty_like(q), np.zeros_like(q)
    for k in range(t.size):
        config = reference.configuration(q[k])
        tau[k] = pin.rnea(model, data, config, reference.rate(dq[k]), reference.rate(ddq[k]))[v]
        if with_gravity:
            gravity[k] = pin.computeGeneralizedGravity(model, data, config)[v]
    return tau, gravity


def _task(robot: Path) -> dict:
    return PROGRAM | {"robot": str(robot)}


@pytest.fixture(scope="module")
def plans(tmp_path_factory):
    """The program on the tight Panda and on the same Panda with the URDF's efforts."""
    folder = tmp_path_factory.mktemp("torque_slowdown")
    tight = run_task(_task(_robot_file(folder, "panda_tight_tau", TIGHT_TAUMAX)), str(folder / "tight.toml"))
    free = run_task(_task(_robot_file(folder, "panda_free_tau", None)), str(folder / "free.toml"))
    return tight, free


def test_the_slowed_program_never_needs_more_than_taumax_by_pinocchio(plans):
    tight, _ = plans
    robot = tight.config.robot
    tau, _ = _pinocchio_torques(_pinocchio(robot), tight, with_gravity=False)
    ratio = np.abs(tau) / np.array(TIGHT_TAUMAX)
    print(f"peak |tau|/taumax by Pinocchio per joint: {np.round(ratio.max(axis=0), 4).tolist()}")
    assert ratio.max() <= PIN_RATIO_TOL, ratio.max(axis=0)
    assert ratio.max() >= MIN_PEAK_TORQUE_RATIO, ratio.max(axis=0)
    report = tight.metadata["summary"]["joint_torque"]
    assert report["within_torque_limits"] and report["max_torque_ratio"] == pytest.approx(ratio.max(), rel=1e-9)


def test_the_slowed_program_keeps_the_tool_on_its_path(plans):
    tight, _ = plans
    reference = _pinocchio(tight.config.robot)
    model, data = reference.model, reference.data
    frame = model.getFrameId("panda_hand")
    t, q = tight.column("t_s"), _columns(tight, "q{k}_rad")
    tool = np.empty((t.size, 3))
    for k in range(t.size):
        pin.framesForwardKinematics(model, data, reference.configuration(q[k]))
        tool[k] = data.oMf[frame].translation
    program_point = tight.motion(t)[0]
    error = np.linalg.norm(tool - program_point, axis=1)
    print(f"max distance of the tool (Pinocchio's FK) from the program's point: {error.max() * 1e3:.3g} mm")
    assert error.max() <= DEFAULT_PATH_TOLERANCE + FK_ATOL
    assert np.max(np.abs(error - tight.column("pos_err_m"))) <= FK_ATOL


def test_the_program_is_slowed_for_torque_and_says_how_much(plans):
    tight, free = plans
    slowing = tight.metadata["summary"]["joint_torque"]["slowing"]
    speed = tight.metadata["summary"]["joint_speed"]
    duration, free_duration = tight.motion.duration, free.motion.duration
    assert slowing["enforced"] and slowing["duration_s"] == duration
    assert slowing["duration_without_torque_s"] == pytest.approx(free_duration, rel=1e-12)  # the same speed slowing
    assert slowing["time_added_s"] == pytest.approx(duration - free_duration, rel=1e-9) and slowing["time_added_s"] > 0
    assert slowing["slowdown_factor"] == pytest.approx(duration / free_duration, rel=1e-12)
    assert slowing["slowed"] and all(zone["slowest_speed_fraction"] < 1 for zone in slowing["slowed"])
    assert isinstance(tight.summary.joint_torque.slowing, TorqueSlowing)
    assert speed["duration_s"] == duration and speed["nominal_duration_s"] == slowing["nominal_duration_s"]
    free_slowing = free.metadata["summary"]["joint_torque"]["slowing"]
    assert free_slowing["time_added_s"] == 0 and free_slowing["slowed"] == []
    # no slower than slowing the free plan uniformly until the triangle inequality proves it within
    tau, gravity = _pinocchio_torques(_pinocchio(free.config.robot), free)
    headroom = np.array(TIGHT_TAUMAX) - np.abs(gravity)
    assert headroom.min() > 0
    uniform = free_duration * math.sqrt((np.abs(tau - gravity) / headroom).max())
    print(f"slowed for torque: {free_duration:.3f} s -> {duration:.3f} s (x{duration / free_duration:.3f}); "
          f"uniform remedy {uniform:.3f} s")
    assert duration <= MAX_DURATION_OVER_UNIFORM * uniform


def test_gravity_beyond_taumax_is_exit_3_naming_the_joint_and_time(tmp_path, monkeypatch):
    """Shoulder (joint 2) limited below the gravity torque of the start pose: no speed helps, and
    the message names the joint, t = 0, the torque (Pinocchio's gravity at the start) and the
    limit, and says what to change."""
    monkeypatch.chdir(tmp_path)
    probe = _robot_file(tmp_path, "panda_probe", None)
    start = configure_task(_task(probe), "probe.toml").config.q_start
    reference = _pinocchio(load_robot(probe))
    gravity = pin.computeGeneralizedGravity(reference.model, reference.data, reference.configuration(start))[reference.v]
    limit = round(0.9 * abs(gravity[1]), 3)
    robot = _robot_file(tmp_path, "panda_weak", (87.0, limit, 87.0, 87.0, 12.0, 12.0, 12.0))
    (tmp_path / "weak.toml").write_text(tomli_w.dumps(_task(robot)))
    run = CliRunner().invoke(cli, ["plan", "weak.toml", "-o", "weak.csv"])
    assert run.exit_code == 3, run.output
    text = " ".join(run.output.split())
    expected = (f"joint 'panda_joint2' needs {abs(gravity[1]):.4g} N·m against gravity alone at t = 0.000 s "
                f"(path.moves[0], line), {abs(gravity[1]) / limit:.2f} times its torque limit of {limit:.4g} N·m")
    assert expected in text, text
    assert "the joint cannot hold that pose, so slowing cannot make the program feasible" in text and "raise taumax" in text
    assert not (tmp_path / "weak.csv").exists() and not (tmp_path / "weak.json").exists()


def test_a_program_still_beyond_taumax_after_the_rounds_names_joint_time_and_torques(tmp_path, monkeypatch):
    """With one round allowed, the tight program's first plan (its nominal time law) is still
    beyond: the error names the joint, the time, its torque and its limit."""
    monkeypatch.setattr("armgen.planning.toolpath.limits.MAX_SLOWDOWN_ROUNDS", 1)
    robot = _robot_file(tmp_path, "panda_tight_tau", TIGHT_TAUMAX)
    with pytest.raises(PlanningError) as caught:
        run_task(_task(robot), "tight.toml")
    text = str(caught.value)
    found = re.search(r"asks joint 'panda_joint(\d)' for ([0-9.]+) N·m at t = ([0-9.]+) s, ([0-9.]+) times its torque "
                      r"limit of ([0-9.]+) N·m, after 1 rounds of slowing", text)
    assert found, text
    joint, torque, _, ratio, limit = (float(v) for v in found.groups())
    assert limit == TIGHT_TAUMAX[int(joint) - 1] and ratio > 1
    assert torque / limit == pytest.approx(ratio, abs=0.01)  # both as printed, to 4 and 2 digits
    assert "lower path.speed" in text and "raise taumax" in text


def test_a_robot_without_inertials_plans_as_one_whose_torques_fit(tmp_path, monkeypatch):
    """Without inertials no torque is computed and nothing is slowed for it: the plan is the one
    of the same Panda with its inertials and the URDF's efforts (not slowed for torque), byte
    for byte, and plan.json has no joint_torque."""
    monkeypatch.chdir(tmp_path)
    for name, inertials in (("bare", False), ("massive", True)):
        (tmp_path / f"{name}.toml").write_text(tomli_w.dumps(_task(_robot_file(tmp_path, f"panda_{name}", None,
                                                                               inertials))))
        run = CliRunner().invoke(cli, ["plan", f"{name}.toml", "-o", f"{name}.csv"])
        assert run.exit_code == 0, run.output
    assert not load_robot(tmp_path / "panda_bare.toml").has_dynamics
    assert (tmp_path / "bare.csv").read_bytes() == (tmp_path / "massive.csv").read_bytes()
    bare, massive = (json.loads((tmp_path / f"{name}.json").read_text())["summary"] for name in ("bare", "massive"))
    assert "joint_torque" not in bare and massive["joint_torque"]["slowing"]["time_added_s"] == 0


FUZZ_SEED = 20261128
FUZZ_PROGRAMS = 8


def test_random_programs_under_tight_taumax_are_slowed_to_fit(tmp_path):
    """Seeded random rectangles with a rise and an arc (position, size, 200–1200 mm/s, blend
    0–20 mm, RK4 or Euler with the path tolerance's step halving), each under random limits
    between its free plan's gravity and peak torques (``taumax`` = 1.05–1.5 × the largest
    gravity torque on the path + 0.2–0.8 × the largest dynamic torque, by Pinocchio): every one
    is slowed to within every ``taumax`` by Pinocchio, the tool within the path tolerance."""
    rng = np.random.default_rng(FUZZ_SEED)
    free_robot = _robot_file(tmp_path, "panda_free_tau", None)
    reference = _pinocchio(load_robot(free_robot))
    slowdowns = []
    for case in range(FUZZ_PROGRAMS):
        x, y, z = rng.uniform(350, 450), rng.uniform(-150, -50), rng.uniform(150, 400)
        w, h = rng.uniform(50, 250), rng.uniform(50, 250)
        speed, blend = float(rng.choice([200, 400, 800, 1200])), float(rng.choice([0, 5, 20]))
        task = PROGRAM | {
            "start": {"pose": {"xyz": [x, y, z], "rpy": [180, 0, 0]}, "seed": "ready"},
            "path": {"type": "program", "speed": speed, "acceleration": 8.0 * speed, "blend": blend,
                     "moves": [{"kind": "line", "to": {"xyz": [x, y + h, z]}},
                               {"kind": "line", "to": {"xyz": [x + w, y + h, z + 50]}},
                               {"kind": "arc", "via": {"xyz": [x + w + 40, y + h / 2, z + 50]},
                                "to": {"xyz": [x + w, y, z]}},
                               {"kind": "line", "to": {"xyz": [x, y, z]}}]},
            "integrator": {"method": "rk4"} if rng.random() < 0.5 else {}}
        free = run_task(task | {"robot": str(free_robot)}, str(tmp_path / "free.toml"))
        tau, gravity = _pinocchio_torques(reference, free)
        gravity_peak, dynamic_peak = np.abs(gravity).max(axis=0), np.abs(tau - gravity).max(axis=0)
        taumax = tuple(np.round(gravity_peak * rng.uniform(1.05, 1.5, 7) + dynamic_peak * rng.uniform(0.2, 0.8, 7), 4))
        tight_robot = _robot_file(tmp_path, "panda_fuzz_tau", taumax)
        tight = run_task(task | {"robot": str(tight_robot)}, str(tmp_path / "tight.toml"))
        tau, _ = _pinocchio_torques(reference, tight, with_gravity=False)
        ratio = np.abs(tau) / np.array(taumax)
        assert ratio.max() <= PIN_RATIO_TOL, (case, task, taumax, ratio.max(axis=0))
        assert tight.column("pos_err_m").max() <= DEFAULT_PATH_TOLERANCE, case
        slowdowns.append(tight.metadata["summary"]["joint_torque"]["slowing"]["slowdown_factor"])
    print(f"torque slowdown factors: {np.round(slowdowns, 3).tolist()}")
    assert min(slowdowns) > 1  # every case needed slowing


# The passes work in ṡ² with one square root per node and back, and s̈ is a difference of two
# ṡ² over 2 ds: the bound holds to rounding of the terms so differenced, |m| max(ṡ²) / 2 ds,
# beside the limit (a few ulps; measured up to 1e-15 of them).
BOUND_RTOL = 1e-12


@settings(max_examples=100, deadline=None, derandomize=True)
@given(st.data())
def test_the_time_law_keeps_every_torque_row_within_its_bound(data):
    """The invariant the slowing relies on (:class:`~armgen.planning.toolpath.timelaw.JointBounds`,
    rows of torque or acceleration): on any grid, with any caps, path accelerations and rows
    ``|m|``, ``|c|`` ≥ 0, limit > 0, every cell of the time law has
    ``|m| |s̈| + |c| max(ṡ²) ≤ limit`` (ṡ² is linear in s over a cell, so its largest is at an
    end), and no node is faster than its cap."""
    cells = data.draw(st.integers(2, 40))
    rows = data.draw(st.integers(1, 3))
    positive = st.floats(1e-3, 1e3)
    ds = np.array(data.draw(st.lists(st.floats(1e-4, 0.1), min_size=cells, max_size=cells)))
    s = np.concatenate([[0.0], np.cumsum(ds)])
    cap = np.array(data.draw(st.lists(st.floats(1e-3, 5.0), min_size=cells + 1, max_size=cells + 1)))
    acceleration = np.array(data.draw(st.lists(positive, min_size=cells, max_size=cells)))

    def table(elements):
        return np.array(data.draw(st.lists(st.lists(elements, min_size=rows, max_size=rows),
                                           min_size=cells, max_size=cells)))

    bounds = JointBounds(table(st.one_of(st.just(0.0), positive)), table(st.one_of(st.just(0.0), positive)),
                         table(positive))
    profile = PathProfile(s, cap, acceleration, bounds)
    u = profile.v ** 2
    fastest = np.maximum(u[1:], u[:-1])[:, None]
    excess = bounds.dq * np.abs(profile.cell_acc)[:, None] + bounds.ddq * fastest - bounds.limit
    rounding = bounds.limit + bounds.dq * fastest / (2 * ds[:, None])
    assert np.max(excess / rounding) <= BOUND_RTOL, np.max(excess / rounding)
    assert np.all(profile.v <= cap * (1.0 + BOUND_RTOL))
    beyond = np.abs(profile.cell_acc) - acceleration
    assert np.max(beyond / (acceleration + fastest[:, 0] / (2 * ds))) <= BOUND_RTOL


def test_the_plan_table_says_how_long_the_torque_slowing_added(plans):
    from armgen.cli.summary import summary_rows

    tight, free = plans
    added = tight.metadata["summary"]["joint_torque"]["slowing"]["time_added_s"]
    rows = {label: (value, unit) for label, value, unit in summary_rows(tight.metadata)}
    value, unit = rows["time added for torque"]
    assert unit == "s" and float(value) == pytest.approx(added, rel=1e-3)
    assert "time added for torque" not in {label for label, _, _ in summary_rows(free.metadata)}
