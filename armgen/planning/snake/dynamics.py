"""The paper's solver (spec 50, solver 1): a virtual-power multi-link model with axial
stiffness and model denoising.

Coordinates: the track coordinates ``s_1 … s_{n+1}`` of the joint centres (joint 1 on the rail,
the others on the spline, see :class:`~armgen.planning.snake.spline.Track`). Link ``i`` is a
uniform bar from ``x_i = P_i(s_i)`` to ``x_{i+1}``; its material points
``x(ζ) = (1 − ζ) x_i + ζ x_{i+1}`` move with ``ẋ = N_ζ G ṡ_e`` where ``G = [r_s(s_i), r_s(s_{i+1})]`` and
``ṡ_e = (ṡ_i, ṡ_{i+1})``. Per element, with ``a = r_s``, ``b = r_ss``, ``e`` the unit chord, ``l`` its
length, ``k = EA / L_B``:

- mass ``M_r = m [[a_i·a_i/3, a_i·a_j/6], [a_i·a_j/6, a_j·a_j/3]]`` (the consistent bar mass);
- quadratic-velocity force ``F_r = m [a_i·(b_i ṡ_i²/3 + b_j ṡ_j²/6), a_j·(b_i ṡ_i²/6 + b_j ṡ_j²/3)]``;
- strain ``ε = (l − L_B)/L_B`` with ``δε = N_ε δs_e``, ``N_ε = gᵀ/L_B``, ``g = ∂l/∂s_e = [−e·a_i, e·a_j]``;
  elastic force ``F_s = EA L_B ∫ N_εᵀ ε dζ = EA ε g``; stiffness ``K = EA L_B ∫ N_εᵀ N_ε dζ = k g gᵀ``;
  ``K̇_c = EA L_B ∫ N_εᵀ Ṅ_ε dζ = k g ġᵀ`` (not dK/dt, not symmetric);
- external force ``F_e = 0`` (the arm's weight is carried by the rail and the path guides:
  along-path gravity would change a chord by m g / k ≈ 7e-11 m).

Assembled (``T_i`` picks the element's two coordinates): ``M s̈ + C ṡ = F`` with
``M = Σ Tᵢᵀ(M_r + a_h K)Tᵢ``, ``C = Σ Tᵢᵀ(a_h K̇_c + b_h K)Tᵢ``, ``F = Σ Tᵢᵀ(F_e − F_r − F_s)``,
``a_h = h²/6``, ``b_h = h/2``: the elastic force averaged over the window ``[t, t + h]``
(``F_s + h/2 Ḟ_s + h²/6 F̈_s``). Along a chord this makes ``a_h c̈ + b_h ċ + c ≈ 0`` for the chord
error ``c``: a damped mode at |λ| = √6/h instead of the bar's axial mode at √(k/m) ≈ 4e5 rad/s,
so an explicit solver works. The driven coordinate ``c`` follows the velocity law and the free
ones ``a`` obey ``M_aa s̈_a = F_a − M_ac s̈_c − C_ac ṡ_c − C_aa ṡ_a`` (the paper's ``M_aaᵀ`` is the inverse).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy.integrate import BDF, LSODA, RK23, RK45, DOP853, Radau

from .spline import Track


METHODS = {"RK45": RK45, "RK23": RK23, "DOP853": DOP853, "Radau": Radau, "BDF": BDF, "LSODA": LSODA}
EXPLICIT_METHODS = ("RK45", "RK23", "DOP853")


@dataclass(frozen=True)
class BarModel:
    """The links as axially elastic bars (SI)."""

    link: float  # L_B, joint centre to joint centre
    mass: float  # per link
    EA: float  # axial stiffness, N
    h: float  # denoising window, s (0: the plain, stiff model)

    @property
    def a_h(self) -> float:
        return self.h * self.h / 6.0

    @property
    def b_h(self) -> float:
        return self.h / 2.0


@dataclass
class DynamicsRun:
    t: np.ndarray  # output instants reached
    s: np.ndarray  # (samples, n+1)
    sdot: np.ndarray
    completed: bool
    t_reached: float
    wall_s: float
    nfev: int
    njev: int
    message: str


class DenoisedDynamics:
    """Right-hand side of the multi-link model for one driven joint (0: base, n: tip)."""

    def __init__(self, track: Track, model: BarModel, n_links: int, driven: int,
                 law: Callable[[float], tuple[float, float, float]]):
        self.track, self.model, self.n, self.driven, self.law = track, model, n_links, driven, law
        joints = n_links + 1
        self.free = np.array([j for j in range(joints) if j != driven])
        self.joints = joints
        self.nfev = 0
        # chain order from the driven joint along the follow direction, and the sign of the
        # coordinate steps along it (+1 base driven, −1 tip driven)
        self.order = np.arange(joints) if driven == 0 else np.arange(joints)[::-1]
        self.sign = 1.0 if driven == 0 else -1.0
        self.state = "link"

    # -- state <-> coordinates ----------------------------------------------------------
    # state "absolute": y = (s_a, ṡ_a). state "link": y = (w, ẇ) with
    # w_m = sign·(s_{o_m} − s_{o_{m−1}}) − L_B along the chain o from the driven joint: each
    # joint's coordinate step from its leader minus one link (the arc-minus-chord excess,
    # millimetres), so the integrator's relative tolerance is not spent on the metres of the
    # coordinates' arbitrary origin.
    def to_state(self, s: np.ndarray, sdot: np.ndarray) -> np.ndarray:
        if self.state == "absolute":
            return np.concatenate([s[self.free], sdot[self.free]])
        so, vo = s[self.order], sdot[self.order]
        return np.concatenate([self.sign * np.diff(so) - self.model.link, self.sign * np.diff(vo)])

    def from_state(self, y: np.ndarray, sc: float, vc: float) -> tuple[np.ndarray, np.ndarray]:
        nf = self.free.size
        s = np.empty(self.joints)
        sdot = np.empty(self.joints)
        if self.state == "absolute":
            s[self.driven], sdot[self.driven] = sc, vc
            s[self.free], sdot[self.free] = y[:nf], y[nf:]
            return s, sdot
        s[self.order[0]], sdot[self.order[0]] = sc, vc
        s[self.order[1:]] = sc + self.sign * np.cumsum(y[:nf] + self.model.link)
        sdot[self.order[1:]] = vc + self.sign * np.cumsum(y[nf:])
        return s, sdot

    def accelerations(self, t: float, s: np.ndarray, sdot: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Assembled M (dense), C (dense) and F at the full coordinate state."""
        mdl = self.model
        x, a, b = self.track.joints(s, 2)
        d = x[1:] - x[:-1]
        length = np.sqrt(np.einsum("ij,ij->i", d, d))
        e = d / length[:, None]
        ai, aj, bi, bj = a[:-1], a[1:], b[:-1], b[1:]
        vi, vj = sdot[:-1], sdot[1:]
        # g = dl/ds_e and its rate
        g0 = -np.einsum("ij,ij->i", e, ai)
        g1 = np.einsum("ij,ij->i", e, aj)
        ddot = aj * vj[:, None] - ai * vi[:, None]
        edot = (ddot - e * np.einsum("ij,ij->i", e, ddot)[:, None]) / length[:, None]
        gd0 = -(np.einsum("ij,ij->i", edot, ai) + np.einsum("ij,ij->i", e, bi) * vi)
        gd1 = np.einsum("ij,ij->i", edot, aj) + np.einsum("ij,ij->i", e, bj) * vj
        m = mdl.mass
        k = mdl.EA / mdl.link
        aii = np.einsum("ij,ij->i", ai, ai)
        ajj = np.einsum("ij,ij->i", aj, aj)
        aij = np.einsum("ij,ij->i", ai, aj)
        # element matrices, entries (0,0) (0,1) (1,0) (1,1)
        kh = mdl.a_h * k
        M00 = m * aii / 3.0 + kh * g0 * g0
        M11 = m * ajj / 3.0 + kh * g1 * g1
        M01 = m * aij / 6.0 + kh * g0 * g1
        kb = mdl.b_h * k
        C00 = kh * g0 * gd0 + kb * g0 * g0
        C01 = kh * g0 * gd1 + kb * g0 * g1
        C10 = kh * g1 * gd0 + kb * g1 * g0
        C11 = kh * g1 * gd1 + kb * g1 * g1
        wi = bi * (vi * vi)[:, None]
        wj = bj * (vj * vj)[:, None]
        Fr0 = m * np.einsum("ij,ij->i", ai, wi / 3.0 + wj / 6.0)
        Fr1 = m * np.einsum("ij,ij->i", aj, wi / 6.0 + wj / 3.0)
        fs = mdl.EA * (length - mdl.link) / mdl.link
        F0 = -Fr0 - fs * g0
        F1 = -Fr1 - fs * g1
        nj = self.joints
        M = np.zeros((nj, nj))
        C = np.zeros((nj, nj))
        F = np.zeros(nj)
        i = np.arange(nj - 1)
        M[i, i] += M00
        M[i + 1, i + 1] += M11
        M[i, i + 1] = M01
        M[i + 1, i] = M01
        C[i, i] += C00
        C[i + 1, i + 1] += C11
        C[i, i + 1] = C01
        C[i + 1, i] = C10
        F[:-1] += F0
        F[1:] += F1
        return M, C, F

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        self.nfev += 1
        nf = self.free.size
        sc, vc, ac = self.law(t)
        s, sdot = self.from_state(y, sc, vc)
        M, C, F = self.accelerations(t, s, sdot)
        fr, c = self.free, self.driven
        rhs = F[fr] - M[fr, c] * ac - C[fr, c] * vc - C[np.ix_(fr, fr)] @ sdot[fr]
        acc = np.linalg.solve(M[np.ix_(fr, fr)], rhs)
        if self.state == "absolute":
            return np.concatenate([y[nf:], acc])
        full = np.empty(self.joints)
        full[c], full[fr] = ac, acc
        return np.concatenate([y[nf:], self.sign * np.diff(full[self.order])])

    def run(self, s0: np.ndarray, t_eval: np.ndarray, method: str = "RK45", rtol: float = 1e-3,
            atol: float = 1e-6, max_wall_s: float = np.inf, state: str = "link") -> DynamicsRun:
        """Integrate from rest at ``s0`` (all joints) and sample at ``t_eval`` (dense output of each
        step). A run over its wall-clock cap stops after the step in progress and returns the
        samples it reached (``completed`` False)."""
        self.state = state
        sc0, vc0, _ = self.law(float(t_eval[0]))
        s0 = np.array(s0, dtype=float)
        s0[self.driven] = sc0
        y0 = self.to_state(s0, np.zeros(self.joints))
        self.nfev = 0
        started = time.perf_counter()
        solver = METHODS[method](self.rhs, float(t_eval[0]), y0, float(t_eval[-1]), rtol=rtol, atol=atol)
        ys = [y0]
        k = 1  # next output index
        status, message = "running", ""
        while k < t_eval.size:
            message = solver.step()
            if solver.status == "failed":
                status = "failed"
                break
            if k < t_eval.size and t_eval[k] <= solver.t:
                upto = np.searchsorted(t_eval, solver.t, side="right")
                dense = solver.dense_output()
                ys.extend(dense(t_eval[k:upto]).T)
                k = upto
            if time.perf_counter() - started > max_wall_s and k < t_eval.size:
                status = "capped"
                message = f"wall-clock cap of {max_wall_s:g} s reached at t = {solver.t:.6g} s"
                break
        wall = time.perf_counter() - started
        ts = t_eval[:k]
        s, sdot = self._full(ts, np.array(ys[:k]))
        njev = int(getattr(solver, "njev", 0))
        completed = k == t_eval.size
        if completed:
            status, message = "completed", ""
        return DynamicsRun(ts, s, sdot, completed, float(solver.t), wall, self.nfev, njev, str(message or status))

    def _full(self, ts: np.ndarray, ys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        s = np.empty((ts.size, self.joints))
        sdot = np.empty((ts.size, self.joints))
        for k, t in enumerate(ts):
            sc, vc, _ = self.law(t)
            s[k], sdot[k] = self.from_state(ys[k], sc, vc)
        return s, sdot
