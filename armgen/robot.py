"""Robot description files (TOML): loading, validation, conversion to SI.

A robot file holds a serial chain in standard or modified (Craig) DH. Every length is
converted to metres and every angle to radians on load; the returned :class:`Robot` is
SI-only. Errors name the file, the joint and the field, and say how to fix them.

Format (validation rules: ``docs/input-files.md``; examples: the bundled files in ``robots/``)::

    name = "planar3"
    convention = "standard"            # or "modified"
    [units]
    length = "m"                       # or "mm"
    angle = "deg"                      # or "rad"
    [[joints]]
    name = "j1"                        # optional, default "j<i>"
    type = "revolute"                  # or "prismatic"
    a = 1.0
    d = 0.0
    alpha = 0.0
    offset = 0.0                       # optional, default 0
    qlim = [-170, 170]
    [tool]                             # optional, likewise [base]
    xyz = [0, 0, 0.1]
    rpy = [0, 0, 0]                    # R = Rz(yaw) Ry(pitch) Rx(roll)
    [configurations]
    q0 = [0, 30, -45]
"""

from __future__ import annotations

import hashlib
import math
import re
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from pydantic import ValidationError

from .errors import RobotFileError, excerpt
from .robot_schema import RobotFile, UrdfRobotFile
from .schemas import (IDENTIFIER_PATTERN, MAX_INPUT_FILE_BYTES, format_validation_error, parse_toml_bounded,
                      read_input_file)

BUNDLED_DIR = Path(str(resources.files("armgen.data") / "robots"))

LENGTH_UNITS = {"m": 1.0, "mm": 1e-3}
ANGLE_UNITS = {"rad": 1.0, "deg": math.pi / 180.0}
CONVENTIONS = ("standard", "modified")
JOINT_TYPES = ("revolute", "prismatic")
TASK_ROWS = ("vx", "vy", "vz", "wx", "wy", "wz")

# Angles this close to a multiple of 90 degrees (in units of a quarter turn) are snapped to
# it so that cos/sin become exact 0/±1 and the symbolic core drops the multiplications by
# them; 1e-12 of a quarter turn is far below any physical tolerance but above the rounding
# of a degree-to-radian conversion.
QUARTER_TURN_SNAP = 1e-12
# Physical bounds of a robot file's values (SI, after unit conversion): a 1 km link or a
# joint range of 160 turns is a typo, and keeping values this small keeps every product of
# the generated kinematics far from overflow, also in single precision (FLT_MAX ~ 3e38).
MAX_ABS_LENGTH_M = 1e3
MAX_ABS_ANGLE_RAD = 1e3


@dataclass(frozen=True)
class Joint:
    """One joint, SI units.

    A DH joint (``origin`` None) uses ``a``, ``d``, ``alpha``, ``offset`` and ``theta``; for
    the modified convention ``a`` and ``alpha`` are ``a_{i-1}`` and ``alpha_{i-1}`` of the
    row, exactly as written in the file. A general (URDF) joint has ``origin``, the fixed
    4×4 transform from the previous joint's frame (or the base) to this joint's frame, and
    ``axis``, the unit joint axis in that frame; its DH fields are 0.
    """

    name: str
    type: str
    a: float
    d: float
    alpha: float
    offset: float
    qlim: tuple[float, float]
    theta: float = 0.0  # fixed joint angle of a prismatic joint (revolute joints: q + offset)
    qdlim: float = math.inf  # velocity limit (rad/s or m/s); inf: the file gives none
    qddlim: float = math.inf  # acceleration limit (rad/s² or m/s²); inf: the file gives none
    origin: np.ndarray | None = field(default=None, compare=False)
    axis: tuple[float, float, float] = (0.0, 0.0, 1.0)

    @property
    def revolute(self) -> bool:
        return self.type == "revolute"

    @property
    def link_length(self) -> float:
        """Distance between this joint's frame and the previous one (m), for reach bounds."""
        if self.origin is not None:
            return float(np.linalg.norm(self.origin[:3, 3]))
        return math.hypot(self.a, self.d)


@dataclass(frozen=True)
class Robot:
    """A serial robot, SI units: joints, base and tool transforms, named configurations.

    Load one with :func:`armgen.load_robot` (bundled name, robot TOML or URDF) or
    :meth:`Robot.from_urdf`. The NumPy methods (:meth:`fk`, :meth:`jacobian`, …) take ``q``
    of shape ``(n,)`` or ``(..., n)`` and evaluate a batch in one vectorised pass; named
    configurations are attributes (``robot.q0``).

    Attributes
    ----------
    name, description
        Identifier (also the default C prefix) and one line of text.
    convention
        ``"standard"`` or ``"modified"`` DH, or ``"urdf"`` (joints with origin and axis).
    joints
        The moving joints, base to tip.
    base, tool
        4×4 homogeneous transforms before the first joint and after the last.
    configurations
        Named joint vectors (rad / m).
    task_rows
        Rows of ``[vx, vy, vz, wx, wy, wz]`` the planners track.
    source, sha256
        The file it was read from and the SHA-256 of its bytes (and of the URDF it references).
    """

    name: str
    convention: str
    joints: tuple[Joint, ...]
    base: np.ndarray  # 4x4 homogeneous
    tool: np.ndarray  # 4x4 homogeneous
    configurations: dict[str, np.ndarray]
    task_rows: tuple[int, ...]
    source: str  # path of the file it was read from
    sha256: str  # of the file's bytes
    description: str = ""
    units: dict[str, str] = field(default_factory=dict)
    # file, base_link, tip_link of a URDF robot; continuous: its continuous joints given ±π
    urdf: dict[str, Any] = field(default_factory=dict)
    _cache: dict[str, Any] = field(default_factory=dict, init=False, compare=False, repr=False)

    @classmethod
    def from_urdf(cls, path: str | Path, base_link: str | None = None, tip_link: str | None = None) -> Robot:
        """Read the serial chain from ``base_link`` to ``tip_link`` of a URDF file.

        Parameters
        ----------
        path
            The URDF file.
        base_link, tip_link
            The chain's ends; None infers them when the file holds a single chain.

        Returns
        -------
        Robot
            Convention ``"urdf"``, tool = the tip link frame, configurations ``qz`` (zeros,
            when inside the limits) and ``qmid`` (middle of the limits).

        Raises
        ------
        RobotFileError
            The file is missing, malformed or has no usable chain (see :mod:`armgen.urdf`).
        """
        path = Path(path)
        data = _read_bounded(path)
        return _urdf_robot(path, data, base_link, tip_link, hashlib.sha256(data).hexdigest())

    @property
    def n(self) -> int:
        return len(self.joints)

    @property
    def qmin(self) -> np.ndarray:
        return np.array([j.qlim[0] for j in self.joints])

    @property
    def qmax(self) -> np.ndarray:
        return np.array([j.qlim[1] for j in self.joints])

    @property
    def qdlim(self) -> np.ndarray:
        """Joint velocity limits (rad/s, m/s); ``inf`` where the robot file gives none."""
        return np.array([j.qdlim for j in self.joints])

    @property
    def qddlim(self) -> np.ndarray:
        """Joint acceleration limits (rad/s², m/s²); ``inf`` where the robot file gives none."""
        return np.array([j.qddlim for j in self.joints])

    @property
    def qmid(self) -> np.ndarray:
        """The middle of the joint ranges (also a named configuration of URDF robots)."""
        return 0.5 * (self.qmin + self.qmax)

    def __getattr__(self, name: str) -> np.ndarray:
        # Only reached when normal lookup fails: named configurations as attributes.
        if name.startswith("_") or name == "configurations":
            raise AttributeError(name)
        if name in self.configurations:
            return self.configurations[name].copy()
        raise AttributeError(f"robot '{self.name}' has no attribute or configuration '{name}' "
                             f"(configurations: {', '.join(sorted(self.configurations)) or 'none'})")

    def __repr__(self) -> str:
        """One line, e.g. ``Robot('gen3', 7 revolute, standard DH)``; :meth:`show` prints everything."""
        counts = {kind: sum(j.type == kind for j in self.joints) for kind in JOINT_TYPES}
        joints = " + ".join(f"{count} {kind}" for kind, count in counts.items() if count) or "0 joints"
        kind = "URDF chain" if self.convention == "urdf" else f"{self.convention} DH"
        return f"Robot({self.name!r}, {joints}, {kind})"

    def show_text(self) -> str:
        """The joints (DH table or URDF origin/axis), limits, base/tool and named
        configurations in mm and deg: what :meth:`show` and ``armgen show`` print."""
        lines = [f"{self.name}: {self.description}"]
        kind = "URDF chain" if self.convention == "urdf" else f"{self.convention} DH"
        lines.append(f"file {self.source} (sha256 {self.sha256[:16]}…), {kind}, {self.n} joints")
        if self.convention == "urdf":
            lines.append(f"links {self.urdf['base_link']} -> {self.urdf['tip_link']}; columns: joint, type, "
                         "origin xyz [mm], origin rpy [deg], axis, qlim")
        else:
            prefix = "a_{i-1}, alpha_{i-1}" if self.convention == "modified" else "a_i, alpha_i"
            lines.append(f"columns: joint, type, offset/theta, d [mm], a [mm], alpha [deg] ({prefix}), qlim")
        for j in self.joints:
            lim = (f"[{math.degrees(j.qlim[0]):8.3f}, {math.degrees(j.qlim[1]):8.3f}] deg" if j.revolute
                   else f"[{j.qlim[0] * 1e3:8.3f}, {j.qlim[1] * 1e3:8.3f}] mm")
            lim += "  " + _speed_limits(j)
            if j.origin is not None:
                xyz = np.round(j.origin[:3, 3] * 1e3, 4).tolist()
                rpy = (np.round(np.degrees(matrix_rpy(j.origin[:3, :3])), 4) + 0.0).tolist()  # + 0.0: no -0.0
                axis = [round(float(v), 6) + 0.0 for v in j.axis]
                lines.append(f"  {j.name:8s} {j.type:9s} xyz={xyz}  rpy={rpy}  axis={axis}  qlim={lim}")
                continue
            fixed = f"theta={math.degrees(j.theta):8.3f}" if not j.revolute else f"offset={math.degrees(j.offset):7.3f}"
            lines.append(f"  {j.name:8s} {j.type:9s} {fixed}  d={j.d * 1e3:9.3f}  a={j.a * 1e3:9.3f}  "
                         f"alpha={math.degrees(j.alpha):8.3f}  qlim={lim}")
        continuous = self.urdf.get("continuous", [])
        if continuous:
            lines.append(f"note: continuous in the URDF, given ±180 deg here: {', '.join(continuous)}; a start or "
                         "home pose at ±180 deg sits on that limit: move the range with [limits] <joint> = [lo, hi] in "
                         "a robot file that references the URDF (docs/urdf.md)")
        for name, T in (("base", self.base), ("tool", self.tool)):
            if not np.allclose(T, np.eye(4)):
                lines.append(f"{name}: xyz = {np.round(T[:3, 3] * 1e3, 4).tolist()} mm, "
                             f"rpy = {(np.round(np.degrees(matrix_rpy(T[:3, :3])), 4) + 0.0).tolist()} deg")
        units = np.array([180 / math.pi if j.revolute else 1e3 for j in self.joints])
        for name, q in self.configurations.items():
            lines.append(f"configuration {name}: {np.round(q * units, 4).tolist()} (deg / mm)")
        return "\n".join(lines)

    def show(self) -> None:
        """Print :meth:`show_text` (the whole description; ``repr`` is one line)."""
        print(self.show_text())

    def __dir__(self) -> list[str]:
        return sorted(set(super().__dir__()) | set(self.configurations))

    def __getstate__(self) -> dict[str, Any]:
        # The evaluator cache holds CasADi SX functions, which do not pickle; it is rebuilt on use.
        return {**self.__dict__, "_cache": {}}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)

    def configuration(self, name: str) -> np.ndarray:
        """A copy of the named configuration; a clear error names the known ones."""
        if name not in self.configurations:
            known = ", ".join(sorted(self.configurations)) or "none"
            raise RobotFileError(
                f"{self.source}: robot '{self.name}' has no configuration '{name}' (known: {known}); "
                "add it under [configurations] or give the joint values explicitly"
            )
        return self.configurations[name].copy()

    def check_within_limits(self, q: np.ndarray, what: str) -> None:
        """Raise a clear error when ``q`` is outside the joint limits or not finite."""
        q = np.asarray(q, dtype=float)
        if q.shape != (self.n,):
            raise RobotFileError(f"{what}: expected {self.n} joint values for robot '{self.name}', got {q.size}")
        for i, joint in enumerate(self.joints):
            if not math.isfinite(q[i]):
                raise RobotFileError(f"{what}: joint '{joint.name}' value is {q[i]}; give a finite number")
            lo, hi = joint.qlim
            if not lo <= q[i] <= hi:
                raise RobotFileError(
                    f"{what}: joint '{joint.name}' = {_fmt_joint(joint, q[i])} is outside its limits "
                    f"[{_fmt_joint(joint, lo)}, {_fmt_joint(joint, hi)}]; choose a start inside the limits"
                )

    # -- NumPy evaluation (vectorised over leading batch axes) -------------------------
    def _numeric(self):
        # The numeric methods are a facade over the symbolic layer, imported on first use so
        # that loading a robot needs no CasADi; the evaluator is cached per robot.
        if "numeric" not in self._cache:
            from .symbolic.numeric import NumericModel

            self._cache["numeric"] = NumericModel(self)
        return self._cache["numeric"]

    def fk(self, q: ArrayLike) -> np.ndarray:
        """Tool pose in the base frame.

        Parameters
        ----------
        q
            Joint values (rad / m), shape ``(n,)`` or ``(..., n)``.

        Returns
        -------
        numpy.ndarray
            Homogeneous transforms, shape ``(4, 4)`` or ``(..., 4, 4)``.
        """
        return self._numeric().evaluate("fk", q)["T"]

    def jacobian(self, q: ArrayLike) -> np.ndarray:
        """Geometric Jacobian: rows ``[v; ω]`` of the tool origin in the base frame.

        Parameters
        ----------
        q
            Joint values, shape ``(n,)`` or ``(..., n)``.

        Returns
        -------
        numpy.ndarray
            Shape ``(6, n)`` or ``(..., 6, n)`` (all six rows, whatever ``task_rows`` says).
        """
        return self._numeric().evaluate("jacobian", q)["J"]

    def fk_jacobian(self, q: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`fk` and :meth:`jacobian` in one pass (shared trigonometry)."""
        out = self._numeric().evaluate("fk_jacobian", q)
        return out["T"], out["J"]

    def manipulability(self, q: ArrayLike, delta: float = 0.0) -> np.ndarray:
        """Manipulability ``w = sqrt(det(J Jᵀ) + δ²)`` on the task rows.

        Parameters
        ----------
        q
            Joint values, shape ``(n,)`` or ``(..., n)``.
        delta
            Regularisation ``δ`` (0: Yoshikawa's measure).

        Returns
        -------
        numpy.ndarray
            Shape ``()`` or ``(...)``.
        """
        return self._numeric().evaluate("manipulability", q, delta=delta)["w"]

    def manipulability_gradient(self, q: ArrayLike, delta: float = 0.0) -> np.ndarray:
        """Gradient of :meth:`manipulability` with respect to ``q``, shape ``(n,)`` or ``(..., n)``.
        Use ``delta > 0`` near singular poses, where ``w`` is not differentiable."""
        return self._numeric().evaluate("manipulability", q, delta=delta)["grad_w"]

    def joint_limit_criterion(self, q: ArrayLike) -> np.ndarray:
        """Zghal's joint-limit criterion ``H_L = Σ (q_max − q_min)² / ((q_max − q)(q − q_min))``,
        shape ``()`` or ``(...)``; ``2n`` at mid-range, growing without bound at a limit."""
        return self._numeric().evaluate("zghal", q)["H_L"]

    def joint_limit_gradient(self, q: ArrayLike) -> np.ndarray:
        """Gradient of :meth:`joint_limit_criterion`, shape ``(n,)`` or ``(..., n)``."""
        return self._numeric().evaluate("zghal", q)["grad_H_L"]

    def repetitive_criterion(self, q: ArrayLike, q_init: ArrayLike) -> np.ndarray:
        """Repetitive criterion ``H_R = ½‖q − q_init‖²``, shape ``()`` or ``(...)``."""
        return self._numeric().evaluate("repetitive", q, q_init=q_init)["H_R"]

    def repetitive_gradient(self, q: ArrayLike, q_init: ArrayLike) -> np.ndarray:
        """Gradient of :meth:`repetitive_criterion` (``q − q_init``), shape ``(n,)`` or ``(..., n)``."""
        return self._numeric().evaluate("repetitive", q, q_init=q_init)["grad_H_R"]

    def joint_manipulability(self, q: ArrayLike, weights: ArrayLike | None = None,
                             delta: float = 0.0) -> dict[str, np.ndarray]:
        """Joint manipulability (spec 30): the manipulability left when joint i locks.

        Parameters
        ----------
        q
            Joint values, shape ``(n,)`` or ``(..., n)``.
        weights
            The ``a_i`` of ``H_M = Σ a_i ω_i`` (default all 1).
        delta
            Regularisation ``δ`` of ``ω_i = sqrt(det(J₋ᵢ J₋ᵢᵀ) + δ²)``.

        Returns
        -------
        dict
            ``omega`` ``(..., n)``, ``H_M`` ``(...)`` and ``grad_H_M`` ``(..., n)``.
        """
        a = np.ones(self.n) if weights is None else weights
        return self._numeric().evaluate("joint_manipulability", q, a=a, delta=delta)

    def within_limits(self, q: ArrayLike) -> np.ndarray:
        """True where every joint value is finite and inside ``[qmin, qmax]``.

        Parameters
        ----------
        q
            Joint values, shape ``(n,)`` or ``(..., n)``.

        Returns
        -------
        numpy.ndarray
            Booleans of shape ``()`` or ``(...)``.
        """
        q = np.asarray(q, dtype=float)
        if q.ndim == 0 or q.shape[-1] != self.n:
            raise ValueError(f"q must have shape (n,) or (..., n) with n = {self.n}, got {q.shape}")
        return np.all((q >= self.qmin) & (q <= self.qmax), axis=-1)


    def ik(self, pose: ArrayLike, q0: ArrayLike | None = None, *, seed: str | ArrayLike | None = None,
           tol_position: float | None = None, tol_orientation: float | None = None, max_iterations: int | None = None):
        """Joint values that put the tool at ``pose`` (inverse kinematics, ``docs/ik.md``).

        Damped least squares (Levenberg–Marquardt) on the pose error over the robot's task
        rows, clamped to the joint limits, with deterministic restarts; the same operations as
        the generated ``<p>_ik``.

        Parameters
        ----------
        pose
            Target tool pose(s) in the base frame: a 4×4 homogeneous matrix or ``(..., 4, 4)``.
        q0
            A configuration to stay near, ``(n,)`` or ``(..., n)``: the self-motion of a
            redundant arm then minimises ``½‖q − q0‖²`` (default: the Zghal distance from the
            limits), and the first attempt starts from it unless ``seed`` is given.
        seed
            The first attempt's start: a named configuration or joint values (default: ``q0``,
            else the middle of the limits).
        tol_position, tol_orientation
            Success thresholds (m, rad; default 1e-6 each).
        max_iterations
            Stop after this many steps (1 to the default, ``armgen.symbolic.ik.MAX_ITERATIONS``):
            a bound on the time a solve takes, at the price of more misses.

        Returns
        -------
        armgen.symbolic.ik.IKResult
            ``q`` (the solution, or the closest configuration reached), ``success``,
            ``position_error``, ``orientation_error``, ``iterations``; arrays with the pose's
            batch shape for a batch.

        Raises
        ------
        ValueError
            A pose that is not a finite homogeneous transform with a rotation part, or a
            ``q0``/``seed`` of the wrong size.
        """
        from .symbolic import ik

        pose = np.asarray(pose, dtype=float)
        if pose.ndim < 2 or pose.shape[-2:] != (4, 4):
            raise ValueError(f"pose must have shape (4, 4) or (..., 4, 4), got {pose.shape}")
        batch_shape = pose.shape[:-2]
        targets = pose.reshape(-1, 4, 4)
        _check_poses(targets)
        size = targets.shape[0]

        def joints(value: ArrayLike, what: str) -> np.ndarray:
            value = np.asarray(value, dtype=float)
            if value.ndim == 0 or value.shape[-1] != self.n or not np.all(np.isfinite(value)):
                raise ValueError(f"{what} must hold {self.n} finite joint values for robot '{self.name}' "
                                 f"(shape ({self.n},) or (..., {self.n})), got shape {value.shape}")
            return np.broadcast_to(value, batch_shape + (self.n,)).reshape(size, self.n)

        cap = ik.MAX_ITERATIONS if max_iterations is None else max_iterations
        if not isinstance(cap, (int, np.integer)) or not 1 <= cap <= ik.MAX_ITERATIONS:
            raise ValueError(f"max_iterations must be an integer from 1 to {ik.MAX_ITERATIONS}, got {max_iterations!r}")
        rest = joints(q0, "q0") if q0 is not None else np.broadcast_to(self.qmid, (size, self.n))
        if isinstance(seed, str):
            start = joints(self.configuration(seed), f"seed '{seed}'")
        elif seed is not None:
            start = joints(seed, "seed")
        else:
            start = rest
        outputs = ik.solve(self, targets, np.ascontiguousarray(start), np.ascontiguousarray(rest),
                           0.0 if q0 is None else 1.0,
                           ik.TOL_POSITION if tol_position is None else tol_position,
                           ik.TOL_ORIENTATION if tol_orientation is None else tol_orientation, int(cap))
        q, pos, ori, iterations, success = outputs
        q = q.T.reshape(batch_shape + (self.n,))
        return ik.IKResult(q, success.reshape(batch_shape) != 0, pos.reshape(batch_shape), ori.reshape(batch_shape),
                           iterations.reshape(batch_shape).astype(int))
def _speed_limits(j: Joint) -> str:
    """``qdlim=… qddlim=…`` of one joint in deg/s(²) or mm/s(²); 'unlimited' where the file gives none."""
    scale, unit = (180 / math.pi, "deg") if j.revolute else (1e3, "mm")
    vel = f"{j.qdlim * scale:.4g} {unit}/s" if math.isfinite(j.qdlim) else "unlimited"
    acc = f"{j.qddlim * scale:.4g} {unit}/s^2" if math.isfinite(j.qddlim) else "unlimited"
    return f"qdlim={vel}  qddlim={acc}"


def _fmt_joint(joint: Joint, value: float) -> str:
    return f"{math.degrees(value):.4g} deg" if joint.revolute else f"{value * 1e3:.4g} mm"


def snap_quarter_turn(angle: float) -> float:
    """Return ``angle`` snapped to the nearest multiple of pi/2 when within QUARTER_TURN_SNAP."""
    quarters = angle / (math.pi / 2)
    nearest = round(quarters)
    if abs(quarters - nearest) < QUARTER_TURN_SNAP:
        return nearest * (math.pi / 2)
    return angle


def exact_cos_sin(angle: float) -> tuple[float, float]:
    """cos and sin, exact (0, ±1) at multiples of pi/2 so products with them vanish symbolically."""
    quarters = angle / (math.pi / 2)
    nearest = round(quarters)
    if abs(quarters - nearest) < QUARTER_TURN_SNAP:
        return [(1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0)][nearest % 4]
    return math.cos(angle), math.sin(angle)


def rpy_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll)."""
    cr, sr = exact_cos_sin(roll)
    cp, sp = exact_cos_sin(pitch)
    cy, sy = exact_cos_sin(yaw)
    rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    return rz @ ry @ rx


# A target rotation may deviate from orthonormal by rounding (a pose typed or computed in
# float): 1e-6 in ‖RᵀR − I‖_max; beyond that it is not a rotation and the error is ill-defined.
POSE_ORTHONORMAL_TOL = 1e-6


def _check_poses(poses: np.ndarray) -> None:
    """Raise ValueError unless every (4, 4) of ``poses`` (B, 4, 4) is a finite homogeneous
    transform whose rotation part is a rotation (det +1)."""
    if not np.all(np.isfinite(poses)):
        raise ValueError("pose holds NaN or inf; give a finite 4x4 homogeneous transform")
    if not np.allclose(poses[:, 3, :], [0.0, 0.0, 0.0, 1.0], rtol=0, atol=0):
        raise ValueError("pose: the last row of a homogeneous transform must be [0, 0, 0, 1]")
    rot = poses[:, :3, :3]
    gram = np.einsum("bki,bkj->bij", rot, rot) - np.eye(3)
    if np.max(np.abs(gram), initial=0.0) > POSE_ORTHONORMAL_TOL or np.any(np.linalg.det(rot) < 0):
        raise ValueError(f"pose: the 3x3 rotation part is not a rotation (R^T R = I within {POSE_ORTHONORMAL_TOL:g}, "
                         "det R = +1); build it e.g. with scipy.spatial.transform.Rotation")


def matrix_rpy(rot: np.ndarray) -> np.ndarray:
    """[roll, pitch, yaw] of R = Rz(yaw) Ry(pitch) Rx(roll) (pitch in [-pi/2, pi/2])."""
    pitch = math.atan2(-rot[2, 0], math.hypot(rot[0, 0], rot[1, 0]))
    yaw = math.atan2(rot[1, 0], rot[0, 0])
    roll = math.atan2(rot[2, 1], rot[2, 2])
    return np.array([roll, pitch, yaw])


class _Reader:
    """Field access with errors that say where (file, table, field) and what to do."""

    def __init__(self, source: str):
        self.source = source

    def fail(self, where: str, message: str) -> RobotFileError:
        return RobotFileError(f"{self.source}: {where}: {message}")

    def number(self, table: dict, key: str, where: str, default: float | None = None) -> float:
        if key not in table:
            if default is not None:
                return default
            raise self.fail(where, f"missing field '{key}'; add '{key} = <number>'")
        value = table[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(where, f"field '{key}' must be a number, got {type(value).__name__} {excerpt(repr(value))}")
        if not math.isfinite(value):
            raise self.fail(where, f"field '{key}' is {value}; give a finite number")
        return float(value)

    def string(self, table: dict, key: str, where: str, choices: tuple[str, ...] | None = None,
               default: str | None = None) -> str:
        if key not in table:
            if default is not None:
                return default
            raise self.fail(where, f"missing field '{key}'")
        value = table[key]
        if not isinstance(value, str) or not value:
            raise self.fail(where, f"field '{key}' must be a non-empty string, got {excerpt(repr(value))}")
        if choices is not None and value not in choices:
            raise self.fail(where, f"field '{key}' = {excerpt(repr(value))} is not one of {', '.join(choices)}")
        return value

    def vector(self, table: dict, key: str, where: str, length: int | None = None,
               default: list[float] | None = None) -> list[float]:
        if key not in table:
            if default is not None:
                return list(default)
            raise self.fail(where, f"missing field '{key}'")
        value = table[key]
        if not isinstance(value, list):
            raise self.fail(where, f"field '{key}' must be an array of numbers, got {type(value).__name__}")
        if length is not None and len(value) != length:
            raise self.fail(where, f"field '{key}' must have {length} entries, got {len(value)}")
        out = []
        for k, item in enumerate(value):
            if isinstance(item, bool) or not isinstance(item, (int, float)):
                raise self.fail(where, f"field '{key}'[{k}] must be a number, got {excerpt(repr(item))}")
            if not math.isfinite(item):
                raise self.fail(where, f"field '{key}'[{k}] is {item}; give a finite number")
            out.append(float(item))
        return out

    def table(self, doc: dict, key: str, where: str, required: bool = False) -> dict:
        if key not in doc:
            if required:
                raise self.fail(where, f"missing table [{key}]")
            return {}
        value = doc[key]
        if not isinstance(value, dict):
            raise self.fail(where, f"'{key}' must be a table ([{key}])")
        return value


def _transform(reader: _Reader, doc: dict, key: str, length_scale: float, angle_scale: float) -> np.ndarray:
    table = reader.table(doc, key, "file")
    where = f"[{key}]"
    unknown = set(table) - {"xyz", "rpy"}
    if unknown:
        raise reader.fail(where, f"unknown field(s) {', '.join(sorted(unknown))}; allowed: xyz, rpy")
    xyz = np.array(reader.vector(table, "xyz", where, 3, [0.0, 0.0, 0.0])) * length_scale
    if np.max(np.abs(xyz)) > MAX_ABS_LENGTH_M:
        raise reader.fail(where, f"field 'xyz' is beyond ±{MAX_ABS_LENGTH_M:g} m; check [units] length and the value")
    rpy = [snap_quarter_turn(v * angle_scale) for v in reader.vector(table, "rpy", where, 3, [0.0, 0.0, 0.0])]
    out = np.eye(4)
    out[:3, :3] = rpy_matrix(*rpy)
    out[:3, 3] = xyz
    return out


_JOINT_FIELDS = {"name", "type", "a", "d", "alpha", "offset", "qlim", "theta", "qdlim", "qddlim"}


def _robot_place(doc: dict[str, Any], loc: tuple) -> str:
    """How robot-file errors name a place: 'file', '[units]', "joint 2 ('elbow')"."""
    if not loc:
        return "file"
    if loc[0] == "joints" and len(loc) > 1 and isinstance(loc[1], int):
        raw = doc["joints"][loc[1]]
        name = raw.get("name") if isinstance(raw, dict) else None
        valid = isinstance(name, str) and re.fullmatch(IDENTIFIER_PATTERN, name)
        label = f"joint {loc[1] + 1}" + (f" ('{name}')" if valid else "")
        return label + "".join(f".{p}" for p in loc[2:])
    return "[" + ".".join(str(p) for p in loc) + "]"


def validate_robot_document(doc: dict[str, Any], source: str) -> RobotFile | UrdfRobotFile:
    """Check a parsed robot file against :class:`RobotFile`, or :class:`UrdfRobotFile` when it
    references a URDF (keys, types, finite numbers, name rules)."""
    try:
        return (UrdfRobotFile if "urdf" in doc else RobotFile).model_validate(doc)
    except ValidationError as exc:
        raise RobotFileError(format_validation_error(exc, source, doc, where=lambda loc: _robot_place(doc, loc))) from None


def _task_rows(reader: _Reader, doc: dict) -> tuple[int, ...]:
    task_rows_raw = doc.get("task_rows", list(TASK_ROWS))
    if not isinstance(task_rows_raw, list) or not task_rows_raw or any(r not in TASK_ROWS for r in task_rows_raw) \
            or len(set(task_rows_raw)) != len(task_rows_raw):
        raise reader.fail("file", f"task_rows = {excerpt(repr(task_rows_raw))} must be a non-empty list of distinct names from {', '.join(TASK_ROWS)}")
    return tuple(sorted(TASK_ROWS.index(r) for r in task_rows_raw))


def parse_robot(text: str, source: str, sha256: str | None = None, directory: Path | None = None) -> Robot:
    """Parse robot TOML text. ``source`` names the file in error messages; ``directory``
    resolves a relative ``urdf`` reference (default: the current directory)."""
    reader = _Reader(source)
    doc = parse_toml_bounded(text, source, RobotFileError)
    sha256 = sha256 or hashlib.sha256(text.encode()).hexdigest()
    validate_robot_document(doc, source)
    if "urdf" in doc:
        return _parse_urdf_robot_file(reader, doc, sha256, directory or Path("."))
    name = reader.string(doc, "name", "file")
    description = reader.string(doc, "description", "file", default="-")
    convention = reader.string(doc, "convention", "file", CONVENTIONS)
    units = reader.table(doc, "units", "file")
    unknown_units = set(units) - {"length", "angle"}
    if unknown_units:
        raise reader.fail("[units]", f"unknown field(s) {', '.join(sorted(unknown_units))}; allowed: length, angle")
    length_unit = reader.string(units, "length", "[units]", tuple(LENGTH_UNITS), default="m")
    angle_unit = reader.string(units, "angle", "[units]", tuple(ANGLE_UNITS), default="rad")
    ls, as_ = LENGTH_UNITS[length_unit], ANGLE_UNITS[angle_unit]

    raw_joints = doc.get("joints")
    if not isinstance(raw_joints, list) or not raw_joints:
        raise reader.fail("file", "missing or empty [[joints]] array; add one [[joints]] table per joint")
    joints: list[Joint] = []
    seen: set[str] = set()
    for i, raw in enumerate(raw_joints):
        label = f"joint {i + 1}"
        if not isinstance(raw, dict):
            raise reader.fail(label, "each [[joints]] entry must be a table")
        jname = reader.string(raw, "name", label, default=f"j{i + 1}")
        where = f"joint {i + 1} ('{jname}')"
        unknown_j = set(raw) - _JOINT_FIELDS
        if unknown_j:
            raise reader.fail(where, f"unknown field(s) {', '.join(sorted(unknown_j))}; allowed: {', '.join(sorted(_JOINT_FIELDS))}")
        if jname in seen:
            raise reader.fail(where, f"duplicate joint name '{jname}'; joint names must be unique")
        seen.add(jname)
        jtype = reader.string(raw, "type", where, JOINT_TYPES)
        q_scale = as_ if jtype == "revolute" else ls
        if jtype == "revolute" and "theta" in raw:
            raise reader.fail(where, "field 'theta' is only for prismatic joints (a revolute joint's angle is q + offset)")
        qlim = reader.vector(raw, "qlim", where, 2)
        lo, hi = qlim[0] * q_scale, qlim[1] * q_scale
        if not lo < hi:
            raise reader.fail(where, f"qlim = {qlim} is empty or reversed; write [lower, upper] with lower < upper")
        q_is_angle = jtype == "revolute"
        for key in ("a", "d", "alpha", "offset", "theta", "qlim"):
            is_angle = key in ("alpha", "theta") or (key in ("offset", "qlim") and q_is_angle)
            scale, bound, unit = (as_, MAX_ABS_ANGLE_RAD, "rad") if is_angle else (ls, MAX_ABS_LENGTH_M, "m")
            values = raw.get(key, 0.0)
            for value in values if isinstance(values, list) else [values]:
                if abs(value * scale) > bound:
                    raise reader.fail(where, f"field '{key}' = {value} is beyond ±{bound:g} {unit}; check the units "
                                             "([units] length/angle) and the value")
        joints.append(Joint(
            name=jname,
            type=jtype,
            a=reader.number(raw, "a", where) * ls,
            d=reader.number(raw, "d", where) * ls,
            alpha=snap_quarter_turn(reader.number(raw, "alpha", where) * as_),
            offset=(snap_quarter_turn if jtype == "revolute" else float)(
                reader.number(raw, "offset", where, default=0.0) * q_scale),
            qlim=(lo, hi),
            theta=snap_quarter_turn(reader.number(raw, "theta", where, default=0.0) * as_),
            qdlim=reader.number(raw, "qdlim", where, default=math.inf) * q_scale,
            qddlim=reader.number(raw, "qddlim", where, default=math.inf) * q_scale,
        ))

    q_scales = np.array([as_ if j.revolute else ls for j in joints])
    configurations: dict[str, np.ndarray] = {}
    for cname, values in reader.table(doc, "configurations", "file").items():
        vec = np.array(reader.vector({cname: values}, cname, "[configurations]", len(joints))) * q_scales
        configurations[cname] = vec

    task_rows = _task_rows(reader, doc)

    robot = Robot(
        name=name,
        convention=convention,
        joints=tuple(joints),
        base=_transform(reader, doc, "base", ls, as_),
        tool=_transform(reader, doc, "tool", ls, as_),
        configurations=configurations,
        task_rows=task_rows,
        source=source,
        sha256=sha256,
        description=description,
        units={"length": length_unit, "angle": angle_unit},
    )
    for cname, vec in configurations.items():
        robot.check_within_limits(vec, f"{source}: [configurations] {cname}")
    return robot


def bundled_robots() -> list[str]:
    return sorted(p.stem for p in BUNDLED_DIR.glob("*.toml"))


def resolve_robot_path(name_or_path: str | Path) -> Path:
    """A bundled robot name or a path to a robot file."""
    candidate = Path(name_or_path)
    try:
        if candidate.suffix == ".toml" or candidate.exists():
            if candidate.exists() and not candidate.is_file():
                raise RobotFileError(f"{candidate}: not a regular file (a folder, FIFO or device); give the robot file "
                                     "itself")
            if not candidate.is_file():
                raise RobotFileError(f"{candidate}: robot file not found")
            return candidate
        bundled = BUNDLED_DIR / f"{name_or_path}.toml"
        if re.fullmatch(IDENTIFIER_PATTERN, str(name_or_path)) and bundled.is_file():
            return bundled
    except (OSError, ValueError) as exc:  # a name too long for the file system, a NUL byte, no permission
        raise RobotFileError(f"{excerpt(str(candidate))}: not a readable robot file ({exc.strerror or exc}); give a "
                             f"bundled name ({', '.join(bundled_robots())}) or a path") from None
    raise RobotFileError(
        f"unknown robot '{excerpt(str(name_or_path))}': not a file and not bundled (bundled: {', '.join(bundled_robots())})"
    )


def load_robot(name_or_path: str | Path) -> Robot:
    """A robot by bundled name, robot TOML path or URDF path (``.urdf``: see :meth:`Robot.from_urdf`)."""
    if Path(name_or_path).suffix.lower() == ".urdf":
        return Robot.from_urdf(name_or_path)
    path = resolve_robot_path(name_or_path)
    data = _read_bounded(path)
    source = path.name if path.parent == BUNDLED_DIR else str(path)
    return parse_robot(_decode(path, data), source, hashlib.sha256(data).hexdigest(), path.parent)


def _read_bounded(path: Path) -> bytes:
    """The bytes of a robot or URDF file, refusing a missing, unreadable, oversized or not regular one."""
    return read_input_file(path, MAX_INPUT_FILE_BYTES, "robot file", RobotFileError)


def _decode(path: Path, data: bytes) -> str:
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise RobotFileError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None


# -- URDF robots ------------------------------------------------------------------------

# A robot name becomes the default C prefix and output directory: letters, digits, _ and -.
_ROBOT_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_-]{0,63}")


def _urdf_robot(path: Path, data: bytes, base_link: str | None, tip_link: str | None, sha256: str,
                reader: _Reader | None = None, doc: dict | None = None) -> Robot:
    """A Robot from URDF bytes; ``doc`` is the referencing robot file's table (None: URDF alone)."""
    from .urdf import parse_urdf

    chain = parse_urdf(_decode(path, data), str(path), base_link, tip_link)
    doc = doc or {}
    reader = reader or _Reader(str(path))
    name = reader.string(doc, "name", "file", default=chain.robot_name)
    if not _ROBOT_NAME.fullmatch(name):
        raise reader.fail("file", f"robot name {excerpt(repr(name))} must be a letter then letters, digits, _ or - "
                                  "(at most 64); set name = \"…\" in a robot file that references the URDF")
    units = reader.table(doc, "units", "file")
    unknown_units = set(units) - {"length", "angle"}
    if unknown_units:
        raise reader.fail("[units]", f"unknown field(s) {', '.join(sorted(unknown_units))}; allowed: length, angle")
    length_unit = reader.string(units, "length", "[units]", tuple(LENGTH_UNITS), default="m")
    angle_unit = reader.string(units, "angle", "[units]", tuple(ANGLE_UNITS), default="rad")
    ls, as_ = LENGTH_UNITS[length_unit], ANGLE_UNITS[angle_unit]
    q_scales = np.array([ls if j.type == "prismatic" else as_ for j in chain.joints])

    limits = reader.table(doc, "limits", "file")
    names = [j.name for j in chain.joints]
    unknown_limits = set(limits) - set(names)
    if unknown_limits:
        raise reader.fail("[limits]", f"no joint named {', '.join(sorted(unknown_limits))} on the chain "
                                      f"(joints: {', '.join(names)})")
    joints = []
    for j, scale in zip(chain.joints, q_scales):
        qlim = j.qlim
        if j.name in limits:
            lo, hi = (v * scale for v in reader.vector(limits, j.name, "[limits]", 2))
            if not lo < hi:
                raise reader.fail("[limits]", f"{j.name} = {limits[j.name]} is empty or reversed; write [lower, upper]")
            qlim = (lo, hi)
        joints.append(Joint(name=j.name, type="prismatic" if j.type == "prismatic" else "revolute",
                            a=0.0, d=0.0, alpha=0.0, offset=0.0, qlim=qlim, origin=j.origin, axis=j.axis,
                            qdlim=j.qdlim))

    qmin, qmax = np.array([j.qlim[0] for j in joints]), np.array([j.qlim[1] for j in joints])
    configurations: dict[str, np.ndarray] = {"qmid": 0.5 * (qmin + qmax)}
    if np.all((qmin <= 0.0) & (qmax >= 0.0)):
        configurations["qz"] = np.zeros(len(joints))
    for cname, values in reader.table(doc, "configurations", "file").items():
        configurations[cname] = np.array(reader.vector({cname: values}, cname, "[configurations]", len(joints))) * q_scales

    robot = Robot(
        name=name,
        convention="urdf",
        joints=tuple(joints),
        base=_transform(reader, doc, "base", ls, as_),
        tool=chain.tip @ _transform(reader, doc, "tool", ls, as_),
        configurations=configurations,
        task_rows=_task_rows(reader, doc),
        source=reader.source,
        sha256=sha256,
        description=reader.string(doc, "description", "file", default=f"URDF {path.name}: {chain.base_link} -> {chain.tip_link}"),
        units={"length": length_unit, "angle": angle_unit},
        urdf={"file": str(path), "base_link": chain.base_link, "tip_link": chain.tip_link,
              "continuous": [j.name for j in chain.joints if j.type == "continuous" and j.name not in limits]},
    )
    for cname, vec in configurations.items():
        robot.check_within_limits(vec, f"{reader.source}: [configurations] {cname}")
    return robot


def _parse_urdf_robot_file(reader: _Reader, doc: dict, sha256: str, directory: Path) -> Robot:
    """A robot file that references a URDF (validated as :class:`UrdfRobotFile`): ``urdf``,
    ``base_link``, ``tip_link`` plus the usual name, units, base, tool, configurations,
    task_rows and a ``[limits]`` table."""
    urdf_path = directory / reader.string(doc, "urdf", "file")
    if not urdf_path.is_file():
        raise reader.fail("urdf", f"URDF file {urdf_path} not found (the path is relative to the robot file)")
    data = _read_bounded(urdf_path)
    base_link = reader.string(doc, "base_link", "file") if "base_link" in doc else None
    tip_link = reader.string(doc, "tip_link", "file") if "tip_link" in doc else None
    combined = hashlib.sha256((sha256 + hashlib.sha256(data).hexdigest()).encode()).hexdigest()
    return _urdf_robot(urdf_path, data, base_link, tip_link, combined, reader, doc)


def load_robot_any(robot: Robot | str | Path) -> Robot:
    return robot if isinstance(robot, Robot) else load_robot(robot)


def describe(robot: Robot) -> dict[str, Any]:
    """A plain-data description for display and metadata."""
    return {
        "name": robot.name,
        "convention": robot.convention,
        "dof": robot.n,
        "source": robot.source,
        "sha256": robot.sha256,
    }
