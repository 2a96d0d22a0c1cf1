"""The on-board program table: a :class:`~armgen.planning.toolpath.timelaw.ProgramMotion` as
constant C arrays for ``fw_program.c`` (the table format is documented at the top of
``armgen/data/firmware_stub/fw_program.h``).

Only the planner's own numbers go in — the time law's nodes, each piece's geometry, the
Hermite tables that map path length to a curve's parameter, the pose splines' coefficients —
written as ``CTRL_LIT(repr(x))`` so that the double build reads exactly the planner's doubles
and ``fw_program_desired`` evaluates the same formulas. The time law's ~4000 cells are merged
where one quadratic reproduces several (cruising, ramps at the acceleration limit): each merged
segment is checked against the cells it replaces (:data:`MERGE_TOL`).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from ..planning.toolpath.geometry import Arc, Corner, Line, Piece, PoseSpline, Trimmed
from ..planning.toolpath.timelaw import PathProfile, ProgramMotion
from .errors import FirmwareError
from .literals import c_real, c_reals

# A merged time-law segment reproduces the planner's s(t) and ṡ(t) at every node and cell
# midpoint it replaces to this (m, m/s): a hundredth of the 1e-12 the double build is tested
# to, far below anything a float build resolves.
MERGE_TOL = 1e-14
# fw_program.h's piece kinds.
PIECE_KINDS = {"line": 0, "arc": 1, "corner": 2, "spline": 3}
_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]{0,62}\Z")


@dataclass(frozen=True)
class Segments:
    """The time law as merged segments: start times ``t``, path lengths ``s``, speeds ``v`` and
    constant accelerations ``a`` (one each per segment)."""

    t: np.ndarray
    s: np.ndarray
    v: np.ndarray
    a: np.ndarray


def merge_segments(profile: PathProfile, breaks: np.ndarray, tol: float = MERGE_TOL) -> Segments:
    """Greedy merge of the profile's cells: a segment starting at node k keeps the cell's
    acceleration a_k and grows while ``s_k + v_k τ + a_k τ²/2`` and ``v_k + a_k τ`` stay within
    ``tol`` of the planner's values at every node and cell midpoint it covers (the planner's
    s(t) is quadratic per cell, so between those points the two differ by at most
    ``|Δa| τ²/8`` more, which the midpoint check bounds). A segment starts at each node of
    ``breaks`` (the piece boundaries): there the evaluator's s is the planner's exactly, so it
    picks the same piece where the angular velocity jumps."""
    s, v, t, acc = profile.s, profile.v, profile.t, profile.cell_acc
    must_start = np.zeros(len(s), dtype=bool)
    must_start[breaks] = True
    starts = [0]
    k = 0
    for i in range(1, len(s) - 1):  # can the segment from node k also cover cell i?
        tau_mid, tau_end = 0.5 * (t[i] + t[i + 1]) - t[k], t[i + 1] - t[k]
        h = 0.5 * (t[i + 1] - t[i])
        ref_mid = (s[i] + v[i] * h + 0.5 * acc[i] * h * h, v[i] + acc[i] * h)
        ref_end = (s[i + 1], v[i + 1])
        fits = all(abs(s[k] + v[k] * tau + 0.5 * acc[k] * tau * tau - rs) <= tol
                   and abs(v[k] + acc[k] * tau - rv) <= tol
                   for tau, (rs, rv) in ((tau_mid, ref_mid), (tau_end, ref_end)))
        if must_start[i] or not fits:
            k = i
            starts.append(k)
    idx = np.array(starts)
    return Segments(t[idx], s[idx], v[idx], acc[idx])


def _lit(x: float) -> str:
    return c_real(x, "the program table's number")


def _lits(values) -> str:
    return c_reals(values, "the program table's number")


def _nested(values: np.ndarray) -> str:
    """Braced initialiser of a (nested) array."""
    values = np.asarray(values, dtype=float)
    if values.ndim == 1:
        return _lits(values)
    return "{" + ", ".join(_nested(row) for row in values) + "}"


class _Table:
    """The arrays of one program, built piece by piece."""

    def __init__(self):
        self.lines: list[str] = []
        self.arcs: list[str] = []
        self.corners: list[str] = []
        self.splines: list[str] = []
        self.maps: list[str] = []
        self.knots: list[str] = []
        self.pieces: list[str] = []
        # every run of numbers fw_program_check wants strictly increasing: (what, values)
        self.increasing: list[tuple[str, np.ndarray]] = []

    def _map(self, curve) -> tuple[int, int]:
        """The Hermite map w(u) of a curve: one (u, w, dw/du) row per node, the numbers the
        planner's CubicHermiteSpline is built from."""
        u, w, slope = curve.map_nodes
        first = len(self.maps)
        self.increasing.append((f"the path-length map of piece {len(self.pieces)}: rows", u))
        self.maps += [f"{{{_lit(a)}, {_lit(b)}, {_lit(c)}}}" for a, b, c in zip(u, w, slope)]
        return first, len(self.maps) - first

    def add(self, piece: Piece, start: float) -> None:
        raw, u0 = (piece.piece, piece.u0) if isinstance(piece, Trimmed) else (piece, 0.0)
        if isinstance(raw, Line):
            kind, index = "line", len(self.lines)
            o = raw.orientation
            self.lines.append(f"{{{_lits(raw.p0)}, {_lits(raw.direction)}, {_lit(raw.length)}, "
                              f"{_lits(o.r0.as_quat())}, {_lits(o.rotvec)}, {_lits(o.omega / raw.length)}}}")
        elif isinstance(raw, Arc):
            kind, index = "arc", len(self.arcs)
            o = raw.orientation
            self.arcs.append(f"{{{_lits(raw.centre)}, {_lit(raw.radius)}, {_lits(raw.e1)}, {_lits(raw.e2)}, "
                             f"{_lit(raw.length)}, {_lits(o.r0.as_quat())}, {_lits(o.rotvec)}, "
                             f"{_lits(o.omega / raw.length)}}}")
        elif isinstance(raw, Corner):
            kind, index = "corner", len(self.corners)
            o, ctrl = raw.orientation, raw.control
            first, count = self._map(raw)
            self.corners.append(f"{{{_nested(ctrl)}, {_nested(np.diff(ctrl, axis=0))}, {_lits(o.r0.as_quat())}, "
                                f"{_lits(o.rotvec)}, {_lits(o.omega)}, {first}, {count}}}")
        elif isinstance(raw, PoseSpline):
            kind, index = "spline", len(self.splines)
            first, count = self._map(raw)
            knot = len(self.knots)
            spline, rot = raw.spline, raw.rotation_spline
            if not np.all(rot.interpolator.c[3] == 0):  # the rotation vector starts at 0 in each interval
                raise FirmwareError("a poses move's rotation spline has a constant term; cannot encode it")
            quats = rot.rotations.as_quat()
            self.increasing.append((f"the pose spline of piece {len(self.pieces)}: knots", spline.x[:-1]))
            for i in range(len(spline.x) - 1):
                self.knots.append(f"{{{_lit(spline.x[i])}, {_lits(quats[i])}, {_nested(spline.c[:, i, :])}, "
                                  f"{_nested(rot.interpolator.c[:3, i, :])}}}")
            self.splines.append(f"{{{first}, {count}, {knot}, {len(self.knots) - knot}}}")
        else:
            raise FirmwareError(f"the program holds a {type(raw).__name__} piece, which the on-board evaluator "
                                "cannot encode")
        self.pieces.append(f"{{{PIECE_KINDS[kind]}, {index}, {_lit(start)}, {_lit(u0)}, {_lit(piece.length)}}}")


_ARRAYS = (  # (attribute of _Table and array suffix, C type, size macro)
    ("pieces", "fw_program_piece", "FW_PROGRAM_PIECES"),
    ("lines", "fw_program_line", "FW_PROGRAM_LINES"),
    ("arcs", "fw_program_arc", "FW_PROGRAM_ARCS"),
    ("corners", "fw_program_corner", "FW_PROGRAM_CORNERS"),
    ("splines", "fw_program_spline", "FW_PROGRAM_SPLINES"),
    ("maps", "fw_program_map", "FW_PROGRAM_MAPS"),
    ("knots", "fw_program_knot", "FW_PROGRAM_KNOTS"),
)


def _check_float_resolution(name: str, runs: list[tuple[str, np.ndarray]]) -> None:
    """The same table serves the float build: each increasing run must stay strictly
    increasing once rounded to single precision (fw_program_check refuses it otherwise)."""
    for what, values in runs:
        bad = np.flatnonzero(np.diff(np.asarray(values, dtype=np.float32)) <= 0)
        if bad.size:
            k = int(bad[0])
            raise FirmwareError(f"{name}: {what} {k} and {k + 1} ({values[k]!r}, {values[k + 1]!r}) coincide in "
                                "single precision; the program cannot be encoded for a float controller (a piece or "
                                "time-law cell too short for the path's scale: lengthen the moves or change the "
                                "blends)")


def program_table_c(motion: ProgramMotion, name: str = "fw_program_table") -> str:
    """C text defining the program table ``name`` (a ``static const fw_program``), to be placed
    after ``#include "fw_program.h"`` in a generated header. Size macros ``FW_PROGRAM_SEGMENTS``,
    ``FW_PROGRAM_PIECES``, ``FW_PROGRAM_LINES``, ``FW_PROGRAM_ARCS``, ``FW_PROGRAM_CORNERS``,
    ``FW_PROGRAM_SPLINES``, ``FW_PROGRAM_MAPS`` and ``FW_PROGRAM_KNOTS`` give the array sizes
    (one program per header). Raises FirmwareError for a motion it cannot encode."""
    if not _IDENTIFIER.match(name):
        raise FirmwareError(f"program table name {name!r} is not a C identifier")
    program, profile = motion.program, motion.profile
    if program.length != profile.s[-1]:
        raise FirmwareError("the time law does not end where the path does; cannot encode the motion")
    seg = merge_segments(profile, np.flatnonzero(np.isin(profile.s, program.starts)))
    table = _Table()
    for piece, start in zip(program.pieces, program.starts):
        table.add(piece, start)
    _check_float_resolution(name, [("time-law segments", np.append(seg.t, profile.duration)),
                                   ("time-law segments (path length)", np.append(seg.s, program.length)),
                                   ("pieces", program.starts), *table.increasing])
    out = [f"/* Program table {name}: {len(program.moves)} moves, {len(program.pieces)} pieces, "
           f"{len(profile.s) - 1} time-law cells merged into {len(seg.t)} segments; "
           f"length {program.length!r} m, duration {profile.duration!r} s. Generated by armgen. */",
           f"#define FW_PROGRAM_SEGMENTS {len(seg.t)}"]
    out += [f"#define {macro} {len(getattr(table, attr))}" for attr, _, macro in _ARRAYS]
    rows = [f"{{{_lit(t)}, {_lit(s)}, {_lit(v)}, {_lit(a)}}}" for t, s, v, a in zip(seg.t, seg.s, seg.v, seg.a)]
    out.append(f"static const fw_program_segment {name}_segments[FW_PROGRAM_SEGMENTS] = {{\n  "
               + ",\n  ".join(rows) + "\n};")
    pointers = {}
    for attr, ctype, macro in _ARRAYS:
        items = getattr(table, attr)
        if not items:  # C has no empty arrays: the pointer is NULL and the count 0
            pointers[attr] = "NULL"
            continue
        out.append(f"static const {ctype} {name}_{attr}[{macro}] = {{\n  " + ",\n  ".join(items) + "\n};")
        pointers[attr] = f"{name}_{attr}"
    out.append(
        f"static const fw_program {name} = {{\n"
        f"  {_lit(profile.duration)}, {_lit(program.length)},\n"
        f"  FW_PROGRAM_SEGMENTS, {name}_segments,\n"
        + "".join(f"  {macro}, {pointers[attr]},\n" for attr, _, macro in _ARRAYS)
        + "};")
    return "\n".join(out) + "\n"
