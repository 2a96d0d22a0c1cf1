"""Rigid-body inertia: the physical validity of an inertia tensor, and the lumping of bodies
fixed to each other into one (mass sum, combined centre of mass, parallel-axis theorem).

Tensors are given as six numbers ``(ixx, iyy, izz, ixy, ixz, iyz)``: the entries of the 3×3
tensor about the centre of mass (URDF's convention: ``ixy = -∫ x y dm``, the tensor entry,
not CAD's product of inertia ``∫ x y dm``). A tensor some body has is positive (semi)definite
and its principal moments obey the triangle inequality (each at most the sum of the other
two): it is ``tr(Σ) E − Σ`` for the body's second moment ``Σ = ∫ r rᵀ dm``, which is positive
semidefinite. Both are checked with Cholesky factorisations (no eigenvalues), the triangle
inequality as ``Σ = tr(I)/2 · E − I`` positive semidefinite.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

# Principal moments written with six significant digits (CAD exports, URDFs) break the
# triangle inequality of a flat body (izz = ixx + iyy exactly) by up to ~1e-6 of the trace;
# a tensor off by more than this fraction of its trace is no body's.
INERTIA_ROUNDING = 1e-6


def inertia_matrix(inertia: Sequence[float]) -> np.ndarray:
    """The symmetric 3×3 tensor of ``(ixx, iyy, izz, ixy, ixz, iyz)``."""
    ixx, iyy, izz, ixy, ixz, iyz = (float(v) for v in inertia)
    return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])


def inertia_six(matrix: np.ndarray) -> tuple[float, ...]:
    """``(ixx, iyy, izz, ixy, ixz, iyz)`` of a 3×3 tensor (symmetrised: rounding of a rotation)."""
    m = 0.5 * (matrix + matrix.T)
    return tuple(float(v) for v in (m[0, 0], m[1, 1], m[2, 2], m[0, 1], m[0, 2], m[1, 2]))


def _positive_definite(matrix: np.ndarray) -> bool:
    try:
        np.linalg.cholesky(matrix)
    except np.linalg.LinAlgError:
        return False
    return True


def inertia_problem(inertia: Sequence[float], definite: bool = True) -> str | None:
    """Why no body has this tensor, or None when one does.

    ``definite``: every principal moment must be positive (a robot file's link); otherwise a
    point mass or a thin rod (zero moments, within ``INERTIA_ROUNDING``) is accepted too, as a
    URDF's lumped links may be."""
    given = inertia_matrix(inertia)
    scale = float(np.abs(given).max())
    if scale == 0.0:
        return None if not definite else (f"is not positive definite (principal moments {_moments(given, 1.0)}): "
                                          "every moment of inertia of a body is positive")
    matrix = given / scale  # the rule is scale-free; this keeps every sum below far from overflow
    trace = float(np.trace(matrix))
    slack = INERTIA_ROUNDING * abs(trace) * np.eye(3)
    if not _positive_definite(matrix if definite else matrix + slack):
        return (f"is not positive {'definite' if definite else 'semidefinite'} (principal moments "
                f"{_moments(matrix, scale)}): every moment of inertia of a body is positive")
    if not _positive_definite(0.5 * trace * np.eye(3) - matrix + 0.5 * slack):
        return (f"has principal moments {_moments(matrix, scale)}, the largest above the sum of the other two: no body "
                "has such a tensor (the triangle inequality, e.g. ixx + iyy ≥ izz on the principal axes)")
    return None


def _moments(matrix: np.ndarray, scale: float) -> str:
    """The principal moments of ``scale · matrix``, for a message."""
    with np.errstate(over="ignore"):
        return "(" + ", ".join(f"{v * scale:.6g}" for v in np.linalg.eigvalsh(matrix)) + ")"


def lump(parts: Sequence[tuple[float, np.ndarray, np.ndarray]]) -> tuple[float, np.ndarray, np.ndarray]:
    """One body of several fixed to each other: ``parts`` are ``(mass, com, inertia)`` with
    the centre of mass (3,) and the 3×3 tensor about it in one common frame; the result is
    (total mass, combined centre of mass, tensor about it) in that frame (parallel-axis
    theorem: each part adds ``m (|d|² E − d dᵀ)`` for its offset ``d`` from the combined
    centre). Massless parts add their tensor only; the total mass must be positive."""
    mass = sum(m for m, _, _ in parts)
    com = sum(m * c for m, c, _ in parts) / mass
    inertia = np.zeros((3, 3))
    for m, c, tensor in parts:
        d = c - com
        inertia += tensor + m * (d.dot(d) * np.eye(3) - np.outer(d, d))
    return mass, com, inertia
