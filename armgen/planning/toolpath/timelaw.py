"""The time law of a program: the path speed ``ṡ`` as a function of the path length ``s``,
trapezoidal (bounded speed and acceleration), rest to rest.

On a grid over ``s`` each node has a speed cap (the move's ``speed``, the ``angular_speed``
cap ``ω_max / |ω_s|``, 0 at a corner without a blend, and any slow-down the joint limits
asked for) and each cell an acceleration bound (the move's, and where the joints' acceleration
limits asked for it, ``|q′ s̈| + |q″| ṡ² ≤ q̈_max`` per joint). A forward pass accelerates as fast as
allowed, a backward pass decelerates in time for every cap; between two nodes the path
acceleration is constant, so ``s(t)`` is piecewise quadratic and evaluated exactly.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .geometry import Corner, Program

# Grid cells along the whole program (plus every piece boundary): the caps are resolved to
# ~1/4000 of the path length, and the pass costs ~2 ms.
GRID_CELLS = 4000
# Cells per piece at least (short rounded corners still get their speed cap resolved).
MIN_CELLS_PER_PIECE = 8
# Cells per smallest radius of curvature of a rounded corner: the centripetal cap averages the
# curvature over half a cell, so cells must be small against the sharpest bend. With 4, the
# tool's normal acceleration ṡ²κ stays within 1 % of its bound at every corner up to
# geometry.MAX_BLEND_TURN (a tight corner on a long program had 2–50× at 8 cells a corner).
CELLS_PER_MIN_RADIUS = 4


def _cells(piece, step: float) -> int:
    cells = max(MIN_CELLS_PER_PIECE, int(math.ceil(piece.length / step)))
    if isinstance(piece, Corner):
        cells = max(cells, int(math.ceil(CELLS_PER_MIN_RADIUS * piece.length / piece.min_radius)))
    return cells


def program_grid(program: Program) -> np.ndarray:
    """Path lengths of the grid: every piece boundary, cells of ~length/GRID_CELLS, finer in
    tight rounded corners."""
    step = program.length / GRID_CELLS
    parts = [np.linspace(program.starts[k], program.starts[k + 1], _cells(piece, step) + 1)
             for k, piece in enumerate(program.pieces)]
    return np.unique(np.concatenate(parts))


class JointBounds(NamedTuple):
    """Joint acceleration bounds on a time law, per grid cell and joint: ``|q′ s̈| + |q″| ṡ² ≤
    limit`` with ``dq = |q′|`` (rad or m per m of path) and ``ddq = |q″|`` (per m²) the joint
    path's derivatives along the path length."""

    dq: np.ndarray
    ddq: np.ndarray
    limit: np.ndarray


def _joint_step(u: float, beta: np.ndarray, limit: np.ndarray, ddq: np.ndarray) -> float:
    """The largest ṡ² at the far end of a cell from ``u`` at its near end: with s̈ = Δu / 2ds
    constant over the cell and u largest at the far end, ``β |Δu| + |q″| u_far ≤ limit``
    (``β = |q′| / 2ds`` per joint) gives ``u_far ≤ (β u + limit) / (β + |q″|)``."""
    with np.errstate(divide="ignore"):  # a joint that does not move along the cell bounds nothing
        return float(np.min((beta * u + limit) / (beta + ddq)))


class PathProfile:
    """``ṡ(s)`` from caps at the grid nodes ``s`` and accelerations per cell (and, optionally,
    joint acceleration bounds per cell); ``(s, ṡ, s̈)`` at times."""

    def __init__(self, s: np.ndarray, cap: np.ndarray, acceleration: np.ndarray, joints: JointBounds | None = None):
        self.s, self.cap, self.acceleration = s, cap, acceleration
        ds = np.diff(s)
        v = np.array(cap, dtype=float)
        beta = None
        if joints is not None:
            with np.errstate(divide="ignore"):
                # ṡ² ≤ limit / |q″| in a cell, or no s̈ would keep q̈ within the limit: a cap at its nodes
                u_cell = np.min(np.where(joints.ddq > 0, joints.limit / joints.ddq, np.inf), axis=1)
            beta = joints.dq / (2 * ds[:, None])
            u_node = np.minimum(np.concatenate([u_cell[:1], u_cell]), np.concatenate([u_cell, u_cell[-1:]]))
            v = np.minimum(v, np.sqrt(u_node))
        v[0] = v[-1] = 0.0
        for k in range(len(s) - 1):  # forward: accelerate as allowed
            u = min(v[k + 1] ** 2, v[k] * v[k] + 2 * acceleration[k] * ds[k])
            if beta is not None:
                u = min(u, _joint_step(v[k] * v[k], beta[k], joints.limit[k], joints.ddq[k]))
            v[k + 1] = math.sqrt(u)
        for k in range(len(s) - 2, -1, -1):  # backward: decelerate in time
            u = min(v[k] ** 2, v[k + 1] * v[k + 1] + 2 * acceleration[k] * ds[k])
            if beta is not None:
                u = min(u, _joint_step(v[k + 1] * v[k + 1], beta[k], joints.limit[k], joints.ddq[k]))
            v[k] = math.sqrt(u)
        self.v = v
        self.cell_acc = (v[1:] ** 2 - v[:-1] ** 2) / (2 * ds)
        self.t = np.concatenate([[0.0], np.cumsum(2 * ds / (v[1:] + v[:-1]))])
        self.duration = float(self.t[-1])

    def __call__(self, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(s, ṡ, s̈) at times ``t`` (clamped to [0, duration]: at rest before and after)."""
        t = np.clip(np.asarray(t, dtype=float), 0.0, self.duration)
        k = np.clip(np.searchsorted(self.t, t, side="right") - 1, 0, len(self.s) - 2)
        tau = t - self.t[k]
        acc = self.cell_acc[k]
        sdot = self.v[k] + acc * tau
        s = np.minimum(self.s[k] + self.v[k] * tau + 0.5 * acc * tau * tau, self.s[-1])
        at_end = t >= self.duration
        return s, np.where(at_end, 0.0, sdot), np.where(at_end, 0.0, acc)

    def speed_at(self, s) -> np.ndarray:
        """The planned ``ṡ`` at path lengths ``s`` (exact at nodes; between them from ṡ² linear in s)."""
        return np.sqrt(np.maximum(np.interp(s, self.s, self.v ** 2), 0.0))


def _centripetal_cap(program: Program, s: np.ndarray, acc: np.ndarray) -> np.ndarray:
    """``√(a/κ)`` at the nodes: the tool's acceleration bound holds for the normal part ``ṡ²κ``
    too. The curvature of each cell comes from tangents a quarter cell either side of its
    middle (one piece: cells never straddle a piece boundary, where a stop may sit), and that
    at each node inside a piece from tangents a quarter of its shorter cell either side (the
    peak of a rounded corner sits on a node)."""
    mid, half = 0.5 * (s[1:] + s[:-1]), 0.25 * np.diff(s)
    tangent_hi, tangent_lo = program.tangent(mid + half), program.tangent(mid - half)
    kappa = np.linalg.norm(tangent_hi - tangent_lo, axis=-1) / (2 * half)
    with np.errstate(divide="ignore"):
        cell = np.where(kappa > 0, np.sqrt(acc / kappa), np.inf)
    cap = np.minimum(np.concatenate([cell[:1], cell]), np.concatenate([cell, cell[-1:]]))
    inner = np.flatnonzero(np.isin(s[1:-1], program.starts, invert=True)) + 1  # not on a piece boundary
    reach = np.minimum(half[inner - 1], half[inner])
    node_kappa = np.linalg.norm(program.tangent(s[inner] + reach) - program.tangent(s[inner] - reach), axis=-1) / (2 * reach)
    node_acc = np.minimum(acc[inner - 1], acc[inner])
    with np.errstate(divide="ignore"):
        cap[inner] = np.minimum(cap[inner], np.where(node_kappa > 0, np.sqrt(node_acc / node_kappa), np.inf))
    return cap


def program_profile(program: Program, angular_speed: float | None, slowdown: np.ndarray | None = None,
                    joints: JointBounds | None = None) -> PathProfile:
    """The program's time law: each move's speed and acceleration (also bounding the normal
    acceleration ṡ²κ on curves), the angular-speed cap, rest
    at every corner without a blend, and, from the joint limits, ``slowdown`` (extra speed caps
    at the grid nodes) and ``joints`` (joint acceleration bounds per cell); None: none."""
    s = program_grid(program)
    piece = program.piece_index(s)
    moves = program.moves
    # a node on a boundary belongs to the piece it starts; the slower move governs a rounded corner
    speed = np.array([moves[program.pieces[k].move].speed for k in piece])
    cell_piece = program.piece_index(0.5 * (s[1:] + s[:-1]))
    acc = np.array([moves[program.pieces[k].move].acceleration for k in cell_piece])
    for k, p in enumerate(program.pieces):
        nxt = p.move + 1 if p.move + 1 < len(moves) else p.move
        if isinstance(p, Corner):
            inside = (s >= program.starts[k]) & (s <= program.starts[k + 1])
            speed[inside] = min(moves[p.move].speed, moves[nxt].speed)
            cells = (cell_piece == k)
            acc[cells] = min(moves[p.move].acceleration, moves[nxt].acceleration)
    cap = np.minimum(speed.astype(float), _centripetal_cap(program, s, acc))
    if angular_speed is not None:
        omega = np.linalg.norm(program.evaluate(s)[3], axis=-1)
        with np.errstate(divide="ignore"):
            cap = np.minimum(cap, np.where(omega > 0, angular_speed / omega, np.inf))
    for stop in program.stops:
        cap[np.argmin(np.abs(s - stop))] = 0.0
    if slowdown is not None:
        cap = np.minimum(cap, slowdown)
    return PathProfile(s, cap, acc, joints)


class ProgramMotion:
    """A program driven by its time law: the desired pose and twist at times ``t``."""

    def __init__(self, program: Program, profile: PathProfile):
        self.program, self.profile = program, profile
        self.duration = profile.duration

    def __call__(self, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(position, rotation, twist [v; ω]) at times ``t`` (a number or an array)."""
        s, sdot, _ = self.profile(t)
        p, tangent, rot, omega = self.program.evaluate(s)
        sdot = sdot[..., None]
        return p, rot, np.concatenate([tangent * sdot, omega * sdot], axis=-1)

    def path_length(self, t) -> np.ndarray:
        return self.profile(t)[0]
