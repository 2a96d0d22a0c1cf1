"""Corners a blend cannot round (issue 37, item 6): a program that turns back onto its previous
corner stops there instead of crashing; rounded corners keep the tool's normal acceleration
within its bound; and a hypothesis fuzz of programs (reversals, near-reversals, zero-length
and tiny moves, tangent arcs) ends every case in a plan or a clean ArmgenError."""

from __future__ import annotations

import math

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from armgen.cli.main import cli
from armgen.errors import ArmgenError
from armgen.planning.result import read_plan
from armgen.planning.tasks import run_task
from armgen.planning.toolpath.geometry import MAX_BLEND_TURN, MoveSpec, Program
from armgen.planning.toolpath.task import ProgramSpec, program_motion
from armgen.planning.toolpath.timelaw import program_profile
from armgen.robot import load_robot

R_DOWN = Rotation.from_euler("xyz", [180, 0, 0], degrees=True).as_matrix()
# The tool's normal acceleration ṡ²κ may exceed path.acceleration by the time law's
# resolution of the curvature (cells of a quarter of the corner's smallest bend radius).
NORMAL_ACCELERATION_TOL = 0.01
# Second differences of positions 1 µm apart: truncation ~h²κ³ and rounding ~1e-16 m / h²
# (1e-4 1/m) are far below the curvatures measured (≥ 10 1/m).
FD_STEP = 1e-6  # m

# The program: a 7-DOF arm, a start pose, an 8 mm blend, and a move that turns back
# 180° onto the corner before it.
REVERSAL_TASK = """
planner = "cartesian"
robot = "panda"
start = {{ pose = {{ xyz = [400, -100, 200], rpy = [180, 0, 0] }}, seed = "ready" }}
[units]
length = "mm"
angle = "deg"
[path]
type = "program"
speed = 50
acceleration = 500
blend = 8
moves = [
  {{ kind = "line", to = {{ xyz = [400, 0, 200] }} }},
  {{ kind = "line", to = {{ xyz = [500, 0, 200] }} }},
  {{ kind = "line", to = {{ xyz = [{back}, 200] }} }},
  {{ kind = "line", to = {{ xyz = [400, 100, 200] }} }},
]
[integrator]
method = "rk4"
"""


def _line(to, blend=0.0, speed=0.1, acc=1.0):
    return MoveSpec("line", speed, acc, blend, position=np.asarray(to, float))


@pytest.mark.parametrize("back", ["400, 0", "400, 3"])  # a reversal, and a turn of 178.3°
def test_reversal_with_a_blend_stops_at_the_corner(back, tmp_path):
    """The issue's crash (exit 1, `dydx must contain only finite values`): now a plan that
    comes to rest at the corner it turns back at, rounds the other corners, and says so."""
    task = tmp_path / "weld.toml"
    task.write_text(REVERSAL_TASK.format(back=back))
    out = tmp_path / "plan.csv"
    result = CliRunner().invoke(cli, ["plan", str(task), "-o", str(out)])
    assert result.exit_code == 0, result.output
    plan = read_plan(out)
    path = plan.metadata["path"]
    (unrounded,) = path["unrounded_corners"]
    assert unrounded["move"] == 1 and unrounded["turn_deg"] > math.degrees(MAX_BLEND_TURN)
    assert len(path["stops_mm"]) == 1  # at the far corner
    assert len(path["blend_zones_mm"]) == 2  # the two 90° corners are rounded
    # the tool reaches the far corner (the task's point [500, 0, 200] mm)
    robot = load_robot("panda")
    q = np.column_stack([plan.column(f"q{i + 1}_rad") for i in range(robot.n)])
    tool = robot.fk(q)[:, :3, 3]
    assert np.min(np.linalg.norm(tool - [0.5, 0.0, 0.2], axis=1)) < 1e-4


@pytest.mark.parametrize("turn_deg,rounded", [(90, True), (169.5, True), (170.5, False), (179.999, False), (180, False)])
def test_corners_beyond_the_blend_limit_are_stops(turn_deg, rounded):
    corner = np.array([0.5, 0.0, 0.3])
    a = math.radians(turn_deg)
    end = corner + 0.1 * np.array([math.cos(a), math.sin(a), 0.0])
    program = Program(corner - [0.1, 0, 0], R_DOWN, [_line(corner, blend=0.008), _line(end)])
    profile = program_profile(program, None)
    if rounded:
        assert len(program.blend_zones()) == 1 and not program.unrounded and program.stops.size == 0
    else:
        assert not program.blend_zones() and program.unrounded[0][0] == 0
        np.testing.assert_allclose(program.stops, [0.1], atol=1e-12)
        assert profile.speed_at(program.stops[0]) == 0.0
    assert np.isfinite(profile.duration)


@settings(max_examples=30, deadline=None, derandomize=True)
@given(st.floats(20, 170), st.sampled_from([(0.1, 0.008), (1.0, 0.008), (1.0, 0.002), (2.0, 0.001)]))
def test_rounded_corners_keep_the_normal_acceleration(turn_deg, sizes):
    """ṡ²κ ≤ a (within the grid's resolution) through a rounded corner of any turn up to the
    limit, on short and long programs (before: 2–50× at a tight corner of a long program).
    κ from second differences of the positions, not from the code's tangents."""
    length, blend = sizes
    turn = min(math.radians(turn_deg), MAX_BLEND_TURN * (1 - 1e-9))
    corner = np.array([0.5, 0.0, 0.3])
    end = corner + length * np.array([math.cos(turn), math.sin(turn), 0.0])
    acc = 2.0
    program = Program(corner - [length, 0, 0], R_DOWN, [_line(corner, blend, 0.2, acc), _line(end, 0, 0.2, acc)])
    (s0, s1, _, _), = program.blend_zones()
    s = np.linspace(s0 + FD_STEP, s1 - FD_STEP, 20001)
    p = [program.evaluate(s + d)[0] for d in (-FD_STEP, 0.0, FD_STEP)]
    kappa = np.linalg.norm(p[0] - 2 * p[1] + p[2], axis=1) / FD_STEP ** 2
    speed = program_profile(program, None).speed_at(s)
    assert np.max(speed ** 2 * kappa) <= acc * (1 + NORMAL_ACCELERATION_TOL)


# -- fuzz --------------------------------------------------------------------------------------

# Lengths of "tiny" moves and blends around the geometry's 1 µm floor, and ordinary ones.
TINY = [0.0, 1e-9, 5e-7, 1e-6, 1.5e-6, 3e-6, 1e-5, 1e-4]
ORDINARY = [1e-3, 0.01, 0.05, 0.12]
# Angles (rad) a move turns away from reversing the one before: 0 is a reversal.
NEAR_REVERSAL = [0.0, 1e-12, 1e-9, 1e-6, 1e-3, 0.01, 0.1, math.radians(10) + 1e-9, math.radians(10) - 1e-9]

# Kinds of move, repeated by how often the fuzz should draw them (a zero-length move always
# ends the case with its error, so it is drawn rarely).
KINDS = ["near_reverse", "reverse", "line", "tangent_arc", "tiny", "near_reverse", "zero", "arc", "line", "reverse",
         "tangent_arc", "line"]
_unit_dir = st.sampled_from([np.array(v, float) for v in ([1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0], [-1, 0.5, 0.2])])


@st.composite
def _moves(draw):
    """Move descriptions relative to the tool: ('line', offset), ('arc', via, to),
    each with a blend and a speed, built from the kinds the issue names."""
    moves = []
    direction = np.array([1.0, 0.0, 0.0])
    for _ in range(draw(st.integers(1, 5))):
        kind = draw(st.sampled_from(KINDS))
        size = draw(st.sampled_from(ORDINARY))
        d = draw(_unit_dir)
        d = d / np.linalg.norm(d)
        if kind == "line":
            entry = ("line", size * d)
        elif kind == "reverse":
            entry = ("line", -size * direction)
        elif kind == "near_reverse":
            eps = draw(st.sampled_from(NEAR_REVERSAL))
            side = np.cross(direction, d)
            side = side / np.linalg.norm(side) if np.linalg.norm(side) > 1e-9 else np.array([0.0, 0.0, 1.0])
            entry = ("line", size * (-math.cos(eps) * direction + math.sin(eps) * side))
        elif kind == "zero":
            entry = ("line", np.zeros(3))
        elif kind == "tiny":
            entry = ("line", draw(st.sampled_from(TINY[::-1])) * d)
        else:
            normal = np.cross(direction, d)
            if np.linalg.norm(normal) < 1e-9:  # d along the direction: any normal of it
                normal = np.cross(direction, [0.0, 0.0, 1.0] if abs(direction[2]) < 0.9 else [1.0, 0.0, 0.0])
            normal /= np.linalg.norm(normal)
            towards = np.cross(normal, direction) if kind == "tangent_arc" else d  # tangent: centre off the tangent
            sweep = draw(st.sampled_from([math.pi / 2, 0.3, math.pi, 1.9 * math.pi, 1e-4, 2 * math.pi - 1e-7]))
            radius = size
            centre = radius * towards / np.linalg.norm(towards)
            start = -centre
            axis_e2 = np.cross(normal, start / radius)
            point = lambda phi: centre + radius * (math.cos(phi) * start / radius + math.sin(phi) * axis_e2)  # noqa: E731
            entry = ("arc", point(sweep / 2), point(sweep))
        blend = draw(st.one_of(st.sampled_from([0.008, 0.0] + ORDINARY), st.sampled_from(TINY[1:] + [0.0])))
        speed = draw(st.sampled_from([1e-3, 0.05, 0.2, 2.0]))
        moves.append((entry, blend, speed))
        step = entry[1] if entry[0] == "line" else entry[2] - entry[1]
        if np.linalg.norm(step) > 0:
            direction = step / np.linalg.norm(step)
    return moves


def _specs(moves, start: np.ndarray) -> list[MoveSpec]:
    specs, p = [], start.copy()
    for entry, blend, speed in moves:
        if entry[0] == "line":
            p = p + entry[1]
            specs.append(MoveSpec("line", speed, 1.0, blend, position=p.copy()))
        else:
            via, to = p + entry[1], p + entry[2]
            specs.append(MoveSpec("arc", speed, 1.0, blend, position=to, via=via))
            p = to
    return specs


FUZZ_ROBOT = load_robot("panda")
FUZZ_START = FUZZ_ROBOT.fk(FUZZ_ROBOT.configuration("ready"))


@settings(max_examples=400, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck))
@given(_moves())
def test_fuzzed_programs_build_or_fail_cleanly(moves):
    """The program and its time law from the task's code path (program_motion): a motion whose
    samples are finite, or a clean ArmgenError (exit 2, the move named)."""
    spec = ProgramSpec(tuple(_specs(moves, FUZZ_START[:3, 3])), None)
    try:
        with np.errstate(all="ignore"):
            motion = program_motion(spec, FUZZ_START, FUZZ_ROBOT, "fuzz.toml")
    except ArmgenError as exc:
        assert "fuzz.toml" in str(exc)
        return
    assert np.isfinite(motion.duration) and motion.duration > 0
    p, rot, twist = motion(np.linspace(0.0, motion.duration, 501))
    assert np.all(np.isfinite(p)) and np.all(np.isfinite(rot)) and np.all(np.isfinite(twist))
    assert np.all(np.diff(motion.profile.s) > 0)


@settings(max_examples=25, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck))
@given(_moves())
def test_fuzzed_programs_plan_or_fail_cleanly(moves):
    """The whole planner (cartesian, panda from a pose): a plan or a clean ArmgenError."""
    start = FUZZ_START[:3, 3]
    task = {"planner": "cartesian", "robot": "panda", "start": "ready", "units": {"length": "mm", "angle": "deg"},
            "path": {"type": "program", "speed": 50.0, "acceleration": 500.0, "moves": []},
            "integrator": {"method": "rk4", "step": 0.02}}
    for spec in _specs(moves, start):
        move = {"kind": spec.kind, "to": {"xyz": (spec.position * 1e3).tolist()}, "blend": spec.blend * 1e3,
                "speed": spec.speed * 1e3}
        if spec.kind == "arc":
            move["via"] = {"xyz": (spec.via * 1e3).tolist()}
        task["path"]["moves"].append(move)
    try:
        result = run_task(task, "fuzz.toml", backend="c")
    except ArmgenError as exc:
        assert "fuzz.toml" in str(exc) or "path" in str(exc)
        return
    assert np.all(np.isfinite(result.data))
