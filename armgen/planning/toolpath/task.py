"""``[path] type = "program"`` of a task file (validated: :class:`.schema.ProgramPath`) → SI
move specs (:class:`ProgramSpec`), the CSV of a ``poses`` move, and the program from the start
pose. Errors name the task file (or the
CSV), the move (``path.moves[k]``, 0-based as TOML tools count) and the fix."""

from __future__ import annotations

import csv
import hashlib
import io
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ...errors import TaskFileError, excerpt
from ...description import rpy_matrix
from ...description.model import MAX_ABS_ANGLE_RAD, MAX_ABS_LENGTH_M
from ...robot import Robot
from ...schemas import read_input_file
from .geometry import GeometryError, MoveSpec, Program
from .schema import ProgramPath
from .timelaw import ProgramMotion, program_profile

# A poses CSV of ~500 000 rows: far beyond a CAD/CAM contour, small enough to read at once.
MAX_POSES_FILE_BYTES = 32 << 20
POSITION_COLUMNS = ("x", "y", "z")
RPY_COLUMNS = ("roll", "pitch", "yaw")
QUATERNION_COLUMNS = ("qw", "qx", "qy", "qz")
# A quaternion shorter than this is no rotation (rows are normalised otherwise).
MIN_QUATERNION_NORM = 1e-6
# A quaternion component beyond this is no unit quaternion written out, but a wrong column or
# unit (and its square would leave the floating-point range on the way to the norm).
MAX_QUATERNION_COMPONENT = 1e6


@dataclass(frozen=True)
class ProgramSpec:
    """A program in SI: its moves, the angular-speed cap (None: none) and the poses files
    read (name, sha256) for the plan's metadata."""

    moves: tuple[MoveSpec, ...]
    angular_speed: float | None
    files: tuple[tuple[str, str], ...] = ()


def _where(k: int, kind: str) -> str:
    return f"path.moves[{k}] ({kind})"


def program_spec(path: ProgramPath, source: str, ls: float, as_: float) -> ProgramSpec:
    """The program of a validated ``[path]`` table (``type = "program"``) in SI; ``ls``/``as_``
    scale the file's units to SI (the schema saw to the targets each kind of move takes). A
    ``poses`` move's CSV is read here, relative to the task file's folder."""
    task_dir = Path(source).parent
    moves, files = [], []
    for k, move in enumerate(path.moves):
        kind = move.kind
        common = {"speed": (path.speed if move.speed is None else move.speed) * ls,
                  "acceleration": (path.acceleration if move.acceleration is None else move.acceleration) * ls,
                  "blend": (path.blend if move.blend is None else move.blend) * ls}
        if kind == "poses":
            points, rotations, name, digest = read_poses(task_dir / move.file, move.file, k, source, ls, as_)
            files.append((name, digest))
            moves.append(MoveSpec(kind, points=points, rotations=rotations, **common))
            continue
        rotation = None if move.to.rpy is None else Rotation.from_matrix(
            rpy_matrix(*(np.asarray(move.to.rpy, dtype=float) * as_)))
        via = None if kind != "arc" else np.asarray(move.via.xyz, dtype=float) * ls
        moves.append(MoveSpec(kind, position=np.asarray(move.to.xyz, dtype=float) * ls, rotation=rotation, via=via,
                              **common))
    angular = path.angular_speed
    return ProgramSpec(tuple(moves), None if angular is None else angular * as_, tuple(files))


def read_poses(file: Path, label: str, k: int, source: str, ls: float,
               as_: float) -> tuple[np.ndarray, Rotation, str, str]:
    """(positions, rotations, file name, sha256) of a poses CSV: a header row naming x, y, z and
    roll, pitch, yaw or qw, qx, qy, qz (any order, other columns ignored), then one pose a row.
    Every error names the file and the line, quoting at most an excerpt of what is there."""
    where = f"{source}: {_where(k, 'poses')}: {excerpt(label)}"
    try:
        data = read_input_file(file, MAX_POSES_FILE_BYTES, "poses file (relative to the task file; thin the samples "
                               "if it is too large)", TaskFileError)
    except TaskFileError as exc:
        raise TaskFileError(f"{source}: {_where(k, 'poses')}: {exc}") from None
    _refuse_pseudo_file(file, len(data), where)
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise TaskFileError(f"{where}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    rows = _csv_rows(text, where)
    if not rows:
        raise TaskFileError(f"{where}: empty; give a header row (x,y,z,roll,pitch,yaw) and one pose a row")
    header = [h.strip().lower() for h in rows[0][1]]
    orientation = RPY_COLUMNS if set(RPY_COLUMNS) <= set(header) else QUATERNION_COLUMNS
    wanted = POSITION_COLUMNS + orientation
    if not set(wanted) <= set(header):
        raise TaskFileError(f"{where}: line {rows[0][0]}: the header row {excerpt(repr(','.join(rows[0][1])))} lacks "
                            f"{', '.join(c for c in wanted if c not in header)}; name the columns x, y, z and roll, "
                            "pitch, yaw (or qw, qx, qy, qz)")
    if len(rows) == 1:
        raise TaskFileError(f"{where}: only the header row, no pose; give one pose a row below it")
    index = [header.index(c) for c in wanted]
    values = np.empty((len(rows) - 1, len(wanted)))
    for r, (line, row) in enumerate(rows[1:]):
        for c, col in enumerate(index):
            cell = row[col].strip() if col < len(row) else ""
            try:
                value = float(cell)
            except ValueError:
                raise TaskFileError(f"{where}: line {line}, column {wanted[c]} = {excerpt(repr(cell))} is not a "
                                    "number") from None
            if not math.isfinite(value):
                raise TaskFileError(f"{where}: line {line}, column {wanted[c]} is {excerpt(cell)}; every value must "
                                    "be a finite number (fill or drop the row)")
            values[r, c] = value
    lines = [line for line, _ in rows[1:]]
    points = values[:, :3] * ls
    _check_bound(np.abs(points), MAX_ABS_LENGTH_M, "m", POSITION_COLUMNS, lines, where)
    if orientation == RPY_COLUMNS:
        angles = values[:, 3:] * as_
        _check_bound(np.abs(angles), MAX_ABS_ANGLE_RAD, "rad", RPY_COLUMNS, lines, where)
        rotations = Rotation.from_euler("xyz", angles)  # extrinsic x, y, z: Rz(yaw) Ry(pitch) Rx(roll)
    else:
        # bounded first, so that the norms below cannot overflow
        _check_bound(np.abs(values[:, 3:]), MAX_QUATERNION_COMPONENT, "", QUATERNION_COLUMNS, lines, where,
                     "a quaternion's components are near 1 (each row is normalised): check the column")
        norms = np.linalg.norm(values[:, 3:], axis=1)
        if norms.min() < MIN_QUATERNION_NORM:
            raise TaskFileError(f"{where}: line {lines[int(np.argmin(norms))]}: the quaternion is zero; give a "
                                "rotation")
        rotations = Rotation.from_quat(values[:, [4, 5, 6, 3]])  # SciPy is scalar-last
    return points, rotations, file.name, hashlib.sha256(data).hexdigest()


def _refuse_pseudo_file(file: Path, size: int, where: str) -> None:
    """A file of /proc or /sys passes as a regular file but reports a size (0, 4096) unlike
    what it holds: refuse it rather than quote the machine's state (its environment) back."""
    try:
        reported = os.stat(file).st_size
    except OSError as exc:
        raise TaskFileError(f"{where}: cannot read the poses file: {exc.strerror or exc}") from None
    if reported != size:
        raise TaskFileError(f"{where}: the file system says {reported} bytes but {size} were read: a pseudo-file "
                            "(as under /proc or /sys) or a file being written; give a finished poses CSV")


def _csv_rows(text: str, where: str) -> list[tuple[int, list[str]]]:
    """The non-empty rows of the CSV text with their line numbers (1-based); comment lines (#)
    are blanked before the CSV reader sees them, so a long or quoted comment is only a comment."""
    lines = ("\n" if line.lstrip().startswith("#") else line for line in io.StringIO(text, newline=""))
    reader = csv.reader(lines)
    rows = []
    try:
        for row in reader:
            if row:
                rows.append((reader.line_num, row))
    except csv.Error as exc:
        raise TaskFileError(f"{where}: line {reader.line_num}: not CSV ({excerpt(str(exc))}); a value holds at "
                            f"most {csv.field_size_limit()} characters and a quoted one ends with a quote") from None
    return rows


def _check_bound(magnitudes: np.ndarray, bound: float, unit: str, columns: tuple[str, ...], lines: list[int],
                 where: str, fix: str = "no pose of an arm is that far out: check the value and [units]") -> None:
    """Refuse the first value beyond ``bound`` (SI, after [units]), naming its line and column."""
    beyond = magnitudes > bound
    if beyond.any():
        r, c = np.argwhere(beyond)[0]
        raise TaskFileError(f"{where}: line {lines[r]}, column {columns[c]} is beyond ±{f'{bound:g} {unit}'.strip()}; "
                            f"{fix}")


def build_program(spec: ProgramSpec, start_pose: np.ndarray, source: str) -> Program:
    """The program from the start pose (4×4); bad geometry is a task-file error naming the move."""
    try:
        return Program(start_pose[:3, 3].copy(), start_pose[:3, :3].copy(), list(spec.moves))
    except GeometryError as exc:
        kind = spec.moves[exc.move].kind
        raise TaskFileError(f"{source}: {_where(exc.move, kind)}: {exc}") from None


def reach_radius(robot: Robot) -> float:
    """Radius of a sphere about the base that contains every reachable tool position."""
    reach = sum(j.link_length + (j.qlim[1] if not j.revolute else 0.0) for j in robot.joints)
    return reach + float(np.linalg.norm(robot.tool[:3, 3]))


def check_reach(program: Program, robot: Robot, source: str) -> None:
    """Refuse a program that leaves the sphere the arm can reach, naming the first move that does
    (a pose outside the workspace: bad input, exit 2)."""
    s = np.linspace(0.0, program.length, 2001)
    points = program.evaluate(s)[0]
    dist = np.linalg.norm(points - robot.base[:3, 3], axis=1)
    reach = reach_radius(robot)
    if dist.max() > reach:
        k = int(np.argmax(dist > reach))
        move = int(program.move_at(s[k])[0])
        raise TaskFileError(
            f"{source}: {_where(move, program.moves[move].kind)} is unreachable: point "
            f"{np.round(points[k] * 1e3, 1).tolist()} mm is {dist[k] * 1e3:.0f} mm from the base, beyond the arm's "
            f"reach of {reach * 1e3:.0f} mm; move the program closer to the base")


# A program longer than this (s) is a mistake of units or speeds (a day of motion).
MAX_PROGRAM_DURATION = 86_400.0


def program_motion(spec: ProgramSpec, start_pose: np.ndarray, robot: Robot, source: str) -> ProgramMotion:
    """The program from the start pose and its nominal time law; a program that leaves the
    arm's reach or would take longer than a day is a task-file error (exit 2)."""
    program = build_program(spec, start_pose, source)
    check_reach(program, robot, source)
    with np.errstate(all="ignore"):
        motion = ProgramMotion(program, program_profile(program, spec.angular_speed))
    if not motion.duration <= MAX_PROGRAM_DURATION:
        raise TaskFileError(f"{source}: the program would take {motion.duration:.3g} s (more than "
                            f"{MAX_PROGRAM_DURATION:g} s): path.speed, path.acceleration or path.angular_speed (or a "
                            "move's) is far too small; check the values and [units]")
    return motion
