"""CasADi expressions the resolved-rate planners' fused steps share: the orientation error
between two rotations and a rotation's roll, pitch, yaw."""

from __future__ import annotations

import casadi as ca


def sym_orientation_error(r_actual: ca.SX, r_desired: ca.SX) -> ca.SX:
    """½ Σ r_i × r_d,i over the columns (the usual small-angle orientation error, base frame),
    computed as ½ vee(R_d Rᵀ − R R_dᵀ)."""
    s = ca.mtimes(r_desired, r_actual.T)
    return 0.5 * ca.vertcat(s[2, 1] - s[1, 2], s[0, 2] - s[2, 0], s[1, 0] - s[0, 1])


def sym_rpy(rot: ca.SX) -> ca.SX:
    """:func:`armgen.description.frames.matrix_rpy` in CasADi: [roll, pitch, yaw] of Rz(yaw) Ry(pitch) Rx(roll)."""
    return ca.vertcat(ca.atan2(rot[2, 1], rot[2, 2]), ca.atan2(-rot[2, 0], ca.hypot(rot[0, 0], rot[1, 0])),
                      ca.atan2(rot[1, 0], rot[0, 0]))
