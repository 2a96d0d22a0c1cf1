"""``[path] type = "program"`` of a task file → SI move specs (:class:`ProgramSpec`), the CSV of
a ``poses`` move, and the program from the start pose. Errors name the task file (or the
CSV), the move (``path.moves[k]``, 0-based as TOML tools count) and the fix."""

from __future__ import annotations

import csv
import hashlib
import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ...errors import TaskFileError
from ...description import rpy_matrix
from ...robot import Robot
from ...schemas import read_input_file
from .geometry import GeometryError, MoveSpec, Program
from .timelaw import ProgramMotion, program_profile

# A poses CSV of ~500 000 rows: far beyond a CAD/CAM contour, small enough to read at once.
MAX_POSES_FILE_BYTES = 32 << 20
POSITION_COLUMNS = ("x", "y", "z")
RPY_COLUMNS = ("roll", "pitch", "yaw")
QUATERNION_COLUMNS = ("qw", "qx", "qy", "qz")
# A quaternion shorter than this is no rotation (rows are normalised otherwise).
MIN_QUATERNION_NORM = 1e-6


@dataclass(frozen=True)
class ProgramSpec:
    """A parsed program (SI): its moves, the angular-speed cap (None: none) and the poses files
    read (name, sha256) for the plan's metadata."""

    moves: tuple[MoveSpec, ...]
    angular_speed: float | None
    files: tuple[tuple[str, str], ...] = ()


def _where(k: int, kind: str) -> str:
    return f"path.moves[{k}] ({kind})"


def _fields(move: dict, k: int, source: str, needed: set[str], allowed: set[str]) -> None:
    kind = move["kind"]
    missing = needed - set(move)
    if missing:
        raise TaskFileError(f"{source}: {_where(k, kind)}: missing {', '.join(sorted(missing))}; a {kind} move needs "
                            f"{' and '.join(sorted(needed))}")
    extra = set(move) & ({"to", "via", "file"} - allowed)
    if extra:
        raise TaskFileError(f"{source}: {_where(k, kind)}: {', '.join(sorted(extra))} is not used by a {kind} move; "
                            "remove it")


def parse_program(path: dict, source: str, ls: float, as_: float) -> ProgramSpec:
    """The program of a validated ``[path]`` table; ``ls``/``as_`` scale the file's units to SI."""
    task_dir = Path(source).parent
    moves, files = [], []
    for k, move in enumerate(path["moves"]):
        kind = move["kind"]
        common = {"speed": move.get("speed", path["speed"]) * ls,
                  "acceleration": move.get("acceleration", path["acceleration"]) * ls,
                  "blend": move.get("blend", path.get("blend", 0.0)) * ls}
        if kind == "poses":
            _fields(move, k, source, {"file"}, {"file"})
            points, rotations, name, digest = read_poses(task_dir / move["file"], move["file"], k, source, ls, as_)
            files.append((name, digest))
            moves.append(MoveSpec(kind, points=points, rotations=rotations, **common))
            continue
        _fields(move, k, source, {"to", "via"} if kind == "arc" else {"to"}, {"to", "via"} if kind == "arc" else {"to"})
        to = move["to"]
        rotation = None if to.get("rpy") is None else Rotation.from_matrix(
            rpy_matrix(*(np.asarray(to["rpy"], dtype=float) * as_)))
        via = None
        if kind == "arc":
            if move["via"].get("rpy") is not None:
                raise TaskFileError(f"{source}: {_where(k, kind)}: via.rpy is not used (the orientation turns from the "
                                    "start to `to`); remove it")
            via = np.asarray(move["via"]["xyz"], dtype=float) * ls
        moves.append(MoveSpec(kind, position=np.asarray(to["xyz"], dtype=float) * ls, rotation=rotation, via=via,
                              **common))
    angular = path.get("angular_speed")
    return ProgramSpec(tuple(moves), None if angular is None else angular * as_, tuple(files))


def read_poses(file: Path, label: str, k: int, source: str, ls: float,
               as_: float) -> tuple[np.ndarray, Rotation, str, str]:
    """(positions, rotations, file name, sha256) of a poses CSV: a header row naming x, y, z and
    roll, pitch, yaw or qw, qx, qy, qz (any order, other columns ignored), then one pose a row."""
    where = f"{source}: {_where(k, 'poses')}: {label}"
    try:
        data = read_input_file(file, MAX_POSES_FILE_BYTES, "poses file (relative to the task file; thin the samples "
                               "if it is too large)", TaskFileError)
    except TaskFileError as exc:
        raise TaskFileError(f"{source}: {_where(k, 'poses')}: {exc}") from None
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise TaskFileError(f"{where}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    rows = [r for r in csv.reader(io.StringIO(text)) if r and not r[0].lstrip().startswith("#")]
    if not rows:
        raise TaskFileError(f"{where}: empty; give a header row (x,y,z,roll,pitch,yaw) and one pose a row")
    header = [h.strip().lower() for h in rows[0]]
    orientation = RPY_COLUMNS if set(RPY_COLUMNS) <= set(header) else QUATERNION_COLUMNS
    wanted = POSITION_COLUMNS + orientation
    if not set(wanted) <= set(header):
        raise TaskFileError(f"{where}: the header row {rows[0]} lacks {', '.join(c for c in wanted if c not in header)}; "
                            "name the columns x, y, z and roll, pitch, yaw (or qw, qx, qy, qz)")
    index = [header.index(c) for c in wanted]
    values = np.empty((len(rows) - 1, len(wanted)))
    for r, row in enumerate(rows[1:], start=2):
        for c, col in enumerate(index):
            cell = row[col].strip() if col < len(row) else ""
            try:
                value = float(cell)
            except ValueError:
                raise TaskFileError(f"{where}: line {r}, column {wanted[c]} = {cell!r} is not a number") from None
            if not math.isfinite(value):
                raise TaskFileError(f"{where}: line {r}, column {wanted[c]} is {cell}; every value must be a finite "
                                    "number (fill or drop the row)")
            values[r - 2, c] = value
    points = values[:, :3] * ls
    if orientation == RPY_COLUMNS:
        rotations = Rotation.from_euler("xyz", values[:, 3:] * as_)  # extrinsic x, y, z: Rz(yaw) Ry(pitch) Rx(roll)
    else:
        norms = np.linalg.norm(values[:, 3:], axis=1)
        if values.shape[0] and norms.min() < MIN_QUATERNION_NORM:
            raise TaskFileError(f"{where}: line {int(np.argmin(norms)) + 2}: the quaternion is zero; give a rotation")
        rotations = Rotation.from_quat(values[:, [4, 5, 6, 3]])  # SciPy is scalar-last
    return points, rotations, file.name, hashlib.sha256(data).hexdigest()


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
