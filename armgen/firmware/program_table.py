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

from ..data import render_template
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


def _row(kind: str, /, **values: object) -> str:
    """One initialiser of a table's array (``armgen/data/templates/firmware/program_<kind>.c``)."""
    return render_template(f"firmware/program_{kind}.c", **values)


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
        self.maps += [_row("map", u=_lit(a), w=_lit(b), slope=_lit(c)) for a, b, c in zip(u, w, slope)]
        return first, len(self.maps) - first

    def add(self, piece: Piece, start: float) -> None:
        raw, u0 = (piece.piece, piece.u0) if isinstance(piece, Trimmed) else (piece, 0.0)
        if isinstance(raw, Line):
            kind, index = "line", len(self.lines)
            o = raw.orientation
            self.lines.append(_row("line", p0=_lits(raw.p0), direction=_lits(raw.direction), length=_lit(raw.length),
                                   quaternion=_lits(o.r0.as_quat()), rotvec=_lits(o.rotvec),
                                   omega=_lits(o.omega / raw.length)))
        elif isinstance(raw, Arc):
            kind, index = "arc", len(self.arcs)
            o = raw.orientation
            self.arcs.append(_row("arc", centre=_lits(raw.centre), radius=_lit(raw.radius), e1=_lits(raw.e1),
                                  e2=_lits(raw.e2), length=_lit(raw.length), quaternion=_lits(o.r0.as_quat()),
                                  rotvec=_lits(o.rotvec), omega=_lits(o.omega / raw.length)))
        elif isinstance(raw, Corner):
            kind, index = "corner", len(self.corners)
            o, ctrl = raw.orientation, raw.control
            first, count = self._map(raw)
            self.corners.append(_row("corner", control=_nested(ctrl), differences=_nested(np.diff(ctrl, axis=0)),
                                     quaternion=_lits(o.r0.as_quat()), rotvec=_lits(o.rotvec), omega=_lits(o.omega),
                                     first_map=first, maps=count))
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
                self.knots.append(_row("knot", x=_lit(spline.x[i]), quaternion=_lits(quats[i]),
                                       position=_nested(spline.c[:, i, :]),
                                       rotvec=_nested(rot.interpolator.c[:3, i, :])))
            self.splines.append(_row("spline", first_map=first, maps=count, first_knot=knot,
                                     knots=len(self.knots) - knot))
        else:
            raise FirmwareError(f"the program holds a {type(raw).__name__} piece, which the on-board evaluator "
                                "cannot encode")
        self.pieces.append(_row("piece", kind=PIECE_KINDS[kind], index=index, start=_lit(start), u0=_lit(u0),
                                length=_lit(piece.length)))


ROW_SEPARATOR = ",\n  "  # one initialiser per line in an array
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
    rows = [_row("segment", t=_lit(t), s=_lit(s), v=_lit(v), a=_lit(a))
            for t, s, v, a in zip(seg.t, seg.s, seg.v, seg.a)]
    arrays, counts, pointers = [], {}, {}
    for attr, ctype, macro in _ARRAYS:
        items = getattr(table, attr)
        counts[f"n_{attr}"] = len(items)
        if not items:  # C has no empty arrays: the pointer is NULL and the count 0
            pointers[f"{attr}_array"] = "NULL"
            continue
        arrays.append(render_template("firmware/program_array.h", ctype=ctype, name=name, attr=attr, macro=macro,
                                      items=ROW_SEPARATOR.join(items)) + "\n")
        pointers[f"{attr}_array"] = f"{name}_{attr}"
    return render_template("firmware/program_table.h", name=name, moves=len(program.moves), pieces=len(program.pieces),
                           cells=len(profile.s) - 1, segments=len(seg.t), length=repr(program.length),
                           duration=repr(profile.duration), segment_rows=ROW_SEPARATOR.join(rows),
                           arrays="".join(arrays), duration_literal=_lit(profile.duration),
                           length_literal=_lit(program.length), **counts, **pointers) + "\n"
