"""The on-board program evaluator (firmware_stub/fw_program.c) and its table
(armgen/firmware/program_table.py) against the planner's ProgramMotion (SciPy's splines and
rotations: an independent implementation of the same formulas), compiled on the host in double
and float with the strict flags (and under ASan/UBSan): the issue's bar program at every tick
of its plan, every time-law node and random times, a poses program, programs with stops and a
turning tool, seeded random programs; fw_program_check refuses corrupted tables."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

if sys.version_info >= (3, 11):
    import tomllib
else:  # tomli is declared for Python < 3.11
    import tomli as tomllib

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from armgen.codegen.toolchain import SANITIZER_FLAGS, STRICT_FLAGS, host_cc
from armgen.firmware.errors import FirmwareError
from armgen.firmware.program_table import MERGE_TOL, merge_segments, program_table_c
from armgen.planning.tasks import configure_task, load_task
from armgen.planning.toolpath.geometry import GeometryError, MoveSpec, Program
from armgen.planning.toolpath.timelaw import ProgramMotion, program_profile

from test_programs import EXAMPLES, bar_task

REPO = Path(__file__).resolve().parent.parent
STUB = REPO / "armgen" / "data" / "firmware_stub"
# ctrl_robot.h needs a robot header for ctrl_real and the precision switch: the default binding.
ROBOT_INCLUDE = REPO / "generated" / "modular8"

# Double: the same formulas on the same doubles; what remains is the order of a few floating-
# point operations (~1e-16 relative on 1 m, 1 rad, 1 m/s scales) and the merged time law
# (MERGE_TOL = 1e-14): 1e-12 leaves two orders of margin and is far below the 1e-9 rad bar.
DOUBLE_TOL = 1e-12  # m, rad (matrix entries), m/s, rad/s
# Float: t itself is rounded to float (an error of eps·T in time moves each quantity by
# eps·T·|d/dt|), the table's numbers to float (eps·|x|), and each formula adds a few roundings.
# The bound per quantity is FLOAT_ULPS·eps32·(max|x| + T·max|dx/dt|), both from the reference
# (dx/dt within pieces: at a piece boundary the angular velocity jumps, and a time within
# eps·T of one may be evaluated on the other side; the seeded times fall on none).
FLOAT_ULPS = 16
EPS32 = float(np.finfo(np.float32).eps)
# Random times (seeded) beyond the plan's ticks, from before the start to after the end.
RANDOM_TIMES = 2000
SEED = 20261125

HARNESS = r"""
#include <stdio.h>
#include "fw_program.h"
#include "table.h"
int main(void) {
  double t;
  if (!fw_program_check(&fw_program_table)) {
    puts("refused");
    return 3;
  }
  printf("%.17g\n", (double)fw_program_duration(&fw_program_table));
  while (scanf("%lf", &t) == 1) {
    ctrl_real p[3], R[9], xd[6];
    int i;
    fw_program_desired(&fw_program_table, (ctrl_real)t, p, R, xd);
    for (i = 0; i < 3; ++i) printf("%.17g ", (double)p[i]);
    for (i = 0; i < 9; ++i) printf("%.17g ", (double)R[i]);
    for (i = 0; i < 6; ++i) printf("%.17g ", (double)xd[i]);
    printf("\n");
  }
  return 0;
}
"""


def build(table: str, folder: Path, use_float: bool, sanitize: bool = False) -> Path:
    """The harness with ``table`` and fw_program.c, compiled with the strict flags."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "table.h").write_text(table)
    (folder / "harness.c").write_text(HARNESS)
    exe = folder / "harness"
    cmd = [host_cc(), *STRICT_FLAGS, "-O2", *(SANITIZER_FLAGS if sanitize else ()), "-I", str(STUB), "-I",
           str(ROBOT_INCLUDE), "-I", str(folder), f"-DMODULAR8_USE_FLOAT={int(use_float)}", str(folder / "harness.c"),
           str(STUB / "fw_program.c"), "-o", str(exe), "-lm"]
    subprocess.run(cmd, check=True, capture_output=True, text=True)
    return exe


def run(exe: Path, times: np.ndarray) -> tuple[float, np.ndarray]:
    """(duration, one row [p, R column-major, xdot] per time) from the compiled harness."""
    proc = subprocess.run([str(exe)], input="\n".join(repr(float(t)) for t in times), capture_output=True,
                          text=True, check=True)
    lines = proc.stdout.splitlines()
    return float(lines[0]), np.array([[float(x) for x in line.split()] for line in lines[1:]])


def reference(motion: ProgramMotion, times: np.ndarray) -> np.ndarray:
    p, rot, xdot = motion(times)
    return np.hstack([p, np.swapaxes(rot, -1, -2).reshape(-1, 9), xdot])


GROUPS = {"position": slice(0, 3), "rotation": slice(3, 12), "velocity": slice(12, 15),
          "angular velocity": slice(15, 18)}


def float_tolerances(motion: ProgramMotion) -> dict[str, float]:
    """FLOAT_ULPS·eps32·(max|x| + T·max|dx/dt|) per group, from the reference on a dense grid;
    the rate excludes steps across a piece boundary, where the angular velocity (and the
    tangent at a stop) jumps by design."""
    t = np.linspace(0.0, motion.duration, 20001)
    ref = reference(motion, t)
    piece = motion.program.piece_index(motion.profile(t)[0])
    same = (piece[1:] == piece[:-1])[:, None]
    rate = np.where(same, np.abs(np.diff(ref, axis=0)), 0.0) / np.diff(t)[:, None]
    return {g: FLOAT_ULPS * EPS32 * (np.abs(ref[:, sl]).max() + motion.duration * rate[:, sl].max())
            for g, sl in GROUPS.items()}


def near_boundaries(motion: ProgramMotion, times: np.ndarray) -> np.ndarray:
    """Times whose path length is within float resolution (FLOAT_ULPS·eps32·(L + v_max·T)) of
    a boundary between pieces, where the angular velocity jumps: a float evaluation may fall on
    either side (position, rotation and tangent are continuous there)."""
    program, profile = motion.program, motion.profile
    band = FLOAT_ULPS * EPS32 * (program.length + profile.v.max() * motion.duration)
    s = profile(times)[0]
    inner = program.starts[1:-1]
    return np.min(np.abs(s[:, None] - inner[None, :]), axis=1) <= band if inner.size else np.zeros(s.shape, bool)


def compare(motion: ProgramMotion, times: np.ndarray, folder: Path) -> None:
    """The C evaluator in double and float against ProgramMotion at ``times`` (in float the
    angular velocity away from piece boundaries, see near_boundaries)."""
    table = program_table_c(motion)
    ref = reference(motion, times)
    float_tol = float_tolerances(motion)
    jump = near_boundaries(motion, times)
    assert jump.sum() <= 0.01 * times.size  # the exception stays one
    for use_float in (False, True):
        duration, got = run(build(table, folder / ("float" if use_float else "double"), use_float), times)
        assert got.shape == ref.shape
        for group, sl in GROUPS.items():
            tol = float_tol[group] if use_float else DOUBLE_TOL
            rows = ~jump if use_float and group == "angular velocity" else slice(None)
            err = np.abs(got[rows, sl] - ref[rows, sl]).max()
            assert err <= tol, f"{'float' if use_float else 'double'} {group}: {err:.3g} > {tol:.3g}"
        assert duration == pytest.approx(motion.duration, rel=EPS32 if use_float else 1e-16)


def sample_times(motion: ProgramMotion, ticks: np.ndarray) -> np.ndarray:
    """The plan's tick times, the time law's nodes (every cell boundary, piece boundaries and
    stops among them) and seeded random times from before the start to after the end."""
    rng = np.random.default_rng(SEED)
    return np.concatenate([ticks, motion.profile.t, rng.uniform(-0.5, motion.duration + 0.5, RANDOM_TIMES)])


def parsed_task(text: str, source: str):
    """The planner's own parse of a cartesian task: its motion (geometry and time law)."""
    return configure_task(tomllib.loads(text), source).config


@pytest.fixture(scope="module")
def bar():
    return parsed_task(bar_task("cartesian"), "bar.toml")


def ticks_of(task) -> np.ndarray:
    """The plan's tick times: its duration is the motion's rounded up to whole steps."""
    return np.arange(int(round(task.duration / task.step)) + 1) * task.step


def test_bar_program_matches_the_planner(bar, tmp_path):
    """The issue's bar program (4 lines, 2 arcs, 8 mm blends, the tool turning): every tick of
    the plan (including the rest after the time law ends) and random times."""
    assert {type(p).__name__ for p in bar.motion.program.pieces} == {"Trimmed", "Corner"}
    compare(bar.motion, sample_times(bar.motion, ticks_of(bar)), tmp_path)


def test_poses_program_with_stops_matches_the_planner(tmp_path):
    """The bundled polishing example: a line, a sampled contour (pose spline, the tool tilting
    with the surface) and a line, stopping at both corners (blend = 0)."""
    task, _ = load_task(EXAMPLES / "panda_polish_contour_program.toml")
    parsed = configure_task(task, str(EXAMPLES / "panda_polish_contour_program.toml")).config
    motion = parsed.motion
    assert len(motion.program.stops) == 2
    compare(motion, sample_times(motion, ticks_of(parsed)), tmp_path)


def turning_program() -> ProgramMotion:
    """A line, an arc, a sparse pose spline whose tool turns by up to 50° between rows (the
    rotation spline's large-angle branch) and a line back, with rounded corners (one trimming
    the spline's start), a stop (blend 0) after the spline and an angular-speed cap."""
    start_p, start_r = np.array([0.4, 0.0, 0.3]), Rotation.from_euler("xyz", [180, 0, 0], degrees=True)
    angles = np.linspace(0.0, 1.5 * np.pi, 7)
    helix = np.column_stack([0.45 + 0.05 * np.cos(angles), 0.1 + 0.05 * np.sin(angles), 0.35 + 0.02 * angles])
    rots = Rotation.from_euler("xyz", np.column_stack([np.full(7, 180.0), 10 * np.sin(angles), 50 * np.arange(7)]),
                               degrees=True)
    moves = [
        MoveSpec("line", 0.1, 0.5, 0.01, position=np.array([0.45, 0.0, 0.3]),
                 rotation=Rotation.from_euler("xyz", [170, 10, 30], degrees=True)),
        MoveSpec("arc", 0.08, 0.4, 0.005, position=np.array([0.5, 0.1, 0.35]), via=np.array([0.5, 0.03, 0.32]),
                 rotation=Rotation.from_euler("xyz", [180, 0, 0], degrees=True)),
        MoveSpec("poses", 0.05, 0.3, 0.0, points=helix, rotations=rots),
        MoveSpec("line", 0.1, 0.5, 0.0, position=start_p, rotation=start_r),
    ]
    program = Program(start_p, start_r.as_matrix(), moves)
    return ProgramMotion(program, program_profile(program, angular_speed=1.0))


def test_turning_program_with_stops_matches_the_planner(tmp_path):
    motion = turning_program()
    kinds = [type(p.piece if hasattr(p, "piece") else p).__name__ for p in motion.program.pieces]
    assert {"Line", "Arc", "Corner", "PoseSpline"} <= set(kinds) and len(motion.program.stops) == 1
    spline = motion.program.pieces[kinds.index("PoseSpline")]
    assert spline.u0 > 0  # trimmed by the rounded corner before it
    assert np.max(np.linalg.norm(spline.piece.rotation_spline.interpolator.c[2], axis=-1)) > 0.5  # the tool turns
    t = np.arange(0.0, motion.duration + 0.5, 0.01)
    compare(motion, sample_times(motion, t), tmp_path)


# Seeded random programs (lines, arcs up to ~300° of sweep, pose splines, random blends, tool
# rotations and angular-speed caps) beyond the hand-made ones.
RANDOM_PROGRAMS = 6


def random_motion(rng: np.random.Generator) -> ProgramMotion:
    """A random valid program from a random pose (drawn again while the geometry refuses it)."""
    while True:
        start_p = np.array([0.5, 0.0, 0.3]) + rng.uniform(-0.1, 0.1, 3)
        start_r = Rotation.random(random_state=rng)
        p, moves = start_p, []
        for _ in range(int(rng.integers(2, 6))):
            kind = str(rng.choice(["line", "arc", "poses"], p=[0.45, 0.35, 0.2]))
            direction = rng.normal(size=3)
            direction /= np.linalg.norm(direction)
            length = rng.uniform(0.05, 0.2)
            rotation = Rotation.random(random_state=rng) if rng.random() < 0.6 else None
            common = dict(speed=rng.uniform(0.02, 0.2), acceleration=rng.uniform(0.1, 1.0),
                          blend=0.0 if rng.random() < 0.3 else rng.uniform(1e-3, 0.02))
            if kind == "poses":
                side = np.cross(direction, rng.normal(size=3))
                side /= np.linalg.norm(side)
                i = np.arange(1, int(rng.integers(4, 12)))
                points = p + np.outer(i * length / i[-1], direction) + np.outer(0.01 * np.sin(0.7 * i), side)
                rots = Rotation.random(random_state=rng) * Rotation.from_rotvec(np.outer(i * 0.15, rng.normal(size=3)))
                moves.append(MoveSpec("poses", points=points, rotations=rots, **common))
                p = points[-1]
                continue
            end = p + length * direction
            via = None
            if kind == "arc":
                side = np.cross(direction, rng.normal(size=3))
                via = 0.5 * (p + end) + side / np.linalg.norm(side) * length * rng.uniform(0.1, 1.5)
            moves.append(MoveSpec(kind, position=end, via=via, rotation=rotation, **common))
            p = end
        try:
            program = Program(start_p, start_r.as_matrix(), moves)
        except GeometryError:
            continue
        angular = None if rng.random() < 0.5 else rng.uniform(0.5, 3.0)
        return ProgramMotion(program, program_profile(program, angular))


def test_random_programs_match_the_planner(tmp_path):
    rng = np.random.default_rng(SEED)
    for k in range(RANDOM_PROGRAMS):
        motion = random_motion(rng)
        compare(motion, sample_times(motion, np.arange(0.0, motion.duration + 0.1, 0.01)), tmp_path / f"p{k}")


def test_sanitizers_and_nan_time(tmp_path):
    """ASan/UBSan over the turning program (every piece kind), double and float; a NaN time is
    the start, +inf the end at rest."""
    motion = turning_program()
    table = program_table_c(motion)
    times = np.concatenate([np.arange(0.0, motion.duration + 0.05, 0.05), [np.nan, -np.inf, np.inf]])
    for use_float in (False, True):
        _, got = run(build(table, tmp_path / f"san{use_float}", use_float, sanitize=True), times)
        np.testing.assert_array_equal(got[-3], got[0])  # NaN: at rest at the start (t = 0)
        np.testing.assert_array_equal(got[-2], got[0])
        assert np.all(got[-1, 12:] == 0.0)  # after the end: at rest


def test_merged_time_law_reproduces_every_node(bar):
    """The merged segments hit the planner's nodes (s and ṡ) to MERGE_TOL, and merging pays."""
    profile = bar.motion.profile
    starts = np.isin(profile.s, bar.motion.program.starts)
    seg = merge_segments(profile, np.flatnonzero(starts))
    assert np.isin(profile.t[starts][:-1], seg.t).all()  # every piece boundary but the end starts a segment
    k = np.clip(np.searchsorted(seg.t, profile.t, side="right") - 1, 0, len(seg.t) - 1)
    tau = profile.t - seg.t[k]
    assert np.max(np.abs(seg.s[k] + seg.v[k] * tau + 0.5 * seg.a[k] * tau * tau - profile.s)) <= MERGE_TOL
    assert np.max(np.abs(seg.v[k] + seg.a[k] * tau - profile.v)) <= MERGE_TOL
    assert len(seg.t) < len(profile.s) / 10


def test_bad_name_is_refused(bar):
    for name in ("1table", "a-b", "x; int y", ""):
        with pytest.raises(FirmwareError, match="not a C identifier"):
            program_table_c(bar.motion, name)


def test_pieces_below_float_resolution_are_refused():
    """A move left 10 nm long between two rounded corners, 1 m along the path (where a float
    resolves 1.2e-7 m): the table would not be increasing in single precision."""
    length_b = 0.1
    blend = length_b / 2 - 5e-9
    moves = [MoveSpec("line", 0.1, 0.5, blend, position=np.array([1.0, 0.0, 0.0])),
             MoveSpec("line", 0.1, 0.5, blend, position=np.array([1.0, length_b, 0.0])),
             MoveSpec("line", 0.1, 0.5, 0.0, position=np.array([1.1, length_b, 0.0]))]
    program = Program(np.zeros(3), np.eye(3), moves)
    assert min(p.length for p in program.pieces) < 2e-8
    with pytest.raises(FirmwareError, match="single precision"):
        program_table_c(ProgramMotion(program, program_profile(program, None)))


# ------------------------------------------------------------------ corrupted tables

CHECK_HARNESS = r"""
#include "fw_program.h"
#include "table.h"
int main(void) { return fw_program_check(&fw_program_table) ? 0 : 3; }
"""
LITERAL = re.compile(r"CTRL_LIT\(([^()]*)\)")


def check_flags(folder: Path, use_float: bool) -> list[str]:
    return [*STRICT_FLAGS, "-O1", *SANITIZER_FLAGS, "-I", str(STUB), "-I", str(ROBOT_INCLUDE), "-I", str(folder),
            f"-DMODULAR8_USE_FLOAT={int(use_float)}"]


def check_exit(table: str, folder: Path, evaluator: Path, use_float: bool) -> int:
    """fw_program_check's verdict on ``table``: 0 accepted, 3 refused (under ASan/UBSan, which
    abort with another code on any undefined behaviour). ``evaluator``: fw_program.o."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "table.h").write_text(table)
    (folder / "check.c").write_text(CHECK_HARNESS)
    exe = folder / "check"
    subprocess.run([host_cc(), *check_flags(folder, use_float), str(folder / "check.c"), str(evaluator), "-o", str(exe),
                    "-lm"], check=True, capture_output=True, text=True)
    return subprocess.run([str(exe)]).returncode


def _replace_literal(table: str, index: int, text: str) -> str:
    m = list(LITERAL.finditer(table))[index]
    return table[:m.start()] + text + table[m.end():]


def _edit_row(table: str, array: str, k: int, edit) -> str:
    """``table`` with row ``k`` of ``array`` (one row a line) replaced by ``edit(row, previous row)``."""
    body = re.search(rf"{array}\[[A-Z_]+\] = \{{\n(.*?)\n\}};", table, re.S)
    lines = body.group(1).split("\n")
    lines[k] = edit(lines[k], lines[k - 1] if k else None)
    return table[:body.start(1)] + "\n".join(lines) + table[body.end(1):]


def _set_literal(row: str, index: int, text: str) -> str:
    m = list(LITERAL.finditer(row))[index]
    return row[:m.start()] + text + row[m.end():]


def _rows(table: str, array: str) -> int:
    """The row count of ``array`` (its size macro's value)."""
    macro = re.search(rf"{array}\[([A-Z_]+)\]", table).group(1)
    return int(re.search(rf"^#define {macro} (\d+)", table, re.M).group(1))


# The key (sorted number) of each array's rows: its literal index in the row.
SORTED_KEYS = {"fw_program_table_segments": 0, "fw_program_table_pieces": 0, "fw_program_table_maps": 0,
               "fw_program_table_knots": 0}
# Non-finite numbers put at this many seeded places of the table.
NONFINITE_PLACES = 24


def corruptions(table: str, rng: np.random.Generator) -> list[tuple[str, str]]:
    """(label, corrupted table): non-finite numbers at seeded places, a sorted key repeating
    its predecessor (segment time, piece start, map node, spline knot), counts of 0 or one
    short, a bad piece kind or index, a non-unit quaternion."""
    out = []
    count = len(LITERAL.findall(table))
    for index in rng.choice(count, NONFINITE_PLACES, replace=False):
        bad = str(rng.choice(["((ctrl_real)NAN)", "((ctrl_real)INFINITY)", "(-(ctrl_real)INFINITY)"]))
        out.append((f"literal {index} = {bad}", _replace_literal(table, int(index), bad)))
    for array, key in SORTED_KEYS.items():
        k = int(rng.integers(1, _rows(table, array)))
        out.append((f"{array} row {k} repeats its key", _edit_row(
            table, array, k, lambda row, prev: _set_literal(row, key, list(LITERAL.finditer(prev))[key].group(0)))))
    for macro, array in (("FW_PROGRAM_SEGMENTS", "segments"), ("FW_PROGRAM_PIECES", "pieces")):
        out.append((f"{array}: count 0", table.replace(f"  {macro}, fw_program_table_{array}",
                                                       f"  0, fw_program_table_{array}")))
        # one short: the time law no longer ends at rest where the path does / the pieces stop short
        # (a count beyond the array cannot be detected: the sizes are the generated header's)
        out.append((f"{array}: count one short", table.replace(f"  {macro}, fw_program_table_{array}",
                                                               f"  {macro} - 1, fw_program_table_{array}")))
    out.append(("piece kind 7", _edit_row(table, "fw_program_table_pieces", 0,
                                          lambda row, _: re.sub(r"^  \{\d+,", "  {7,", row))))
    out.append(("piece index 99", _edit_row(table, "fw_program_table_pieces", 0,
                                            lambda row, _: re.sub(r"^  \{(\d+), \d+,", r"  {\1, 99,", row))))
    # a line row: p0 (3), direction (3), length, q0 (4): q0's x off by 0.01
    out.append(("non-unit quaternion", _edit_row(
        table, "fw_program_table_lines", 0,
        lambda row, _: _set_literal(row, 7, f"CTRL_LIT({float(list(LITERAL.finditer(row))[7].group(1)) + 0.01!r})"))))
    return out


@pytest.mark.parametrize("use_float", [False, True])
def test_check_refuses_corrupted_tables(tmp_path, use_float):
    """On the turning program (every piece kind): the table is accepted, each corruption refused."""
    table = "#include <math.h>\n" + program_table_c(turning_program())
    evaluator = tmp_path / "fw_program.o"
    subprocess.run([host_cc(), *check_flags(tmp_path, use_float), "-c", str(STUB / "fw_program.c"), "-o",
                    str(evaluator)], check=True, capture_output=True, text=True)
    assert check_exit(table, tmp_path / "good", evaluator, use_float) == 0
    rng = np.random.default_rng(SEED + use_float)
    for k, (label, bad) in enumerate(corruptions(table, rng)):
        assert check_exit(bad, tmp_path / f"bad{k}", evaluator, use_float) == 3, label
