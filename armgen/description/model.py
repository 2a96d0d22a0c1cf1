"""The robot description: joints, geometry (DH or URDF origin/axis), limits, speed limits,
base and tool transforms, named configurations and task rows, in SI units.

This is the model the rest of armgen works on (Pinocchio's split: a model here, algorithms on
it in :mod:`armgen.symbolic` and the NumPy façade :class:`armgen.robot.Robot`). It imports
nothing above itself and holds nothing built there: it is plain data, and the models derived
from it live in the :class:`~armgen.robot.Robot`. :mod:`armgen.description.files` and
:mod:`armgen.description.urdf` read it from files.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import RobotFileError
from .collision import CollisionModel
from .frames import matrix_rpy
from .inertia import inertia_matrix

JOINT_TYPES = ("revolute", "prismatic")
TASK_ROWS = ("vx", "vy", "vz", "wx", "wy", "wz")
# Physical bounds of a robot file's values (SI, after unit conversion): a 1 km link or a
# joint range of 160 turns is a typo, and keeping values this small keeps every product of
# the generated kinematics far from overflow, also in single precision (FLT_MAX ~ 3e38).
MAX_ABS_LENGTH_M = 1e3
MAX_ABS_ANGLE_RAD = 1e3
# A revolute joint's limits lie within two turns either side of zero: the widest ranges of
# real arms fit (UR's ±360°, a FANUC wrist's ±720°, a window moved around a continuous joint),
# while limits written in degrees where radians belong (±170, ±360 read as rad) land beyond
# it; accepting them would make every configuration "within the limits" and switch the
# joint-limit protection off.
MAX_REVOLUTE_LIMIT_RAD = 4 * math.pi
# The smallest joint speed or acceleration limit (rad/s or m/s, per s): a joint this slow
# needs over two months for a turn, so a smaller value is a unit slip, and the tiniest ones
# (5e-324 deg/s) would become 0 in SI, a limit every motion exceeds by an infinite ratio.
MIN_JOINT_RATE = 1e-6
# Bounds of the inertial parameters (SI). A link of 10 t is beyond any arm (a heavy industrial
# robot's arm weighs ~1 t) and one below 1 mg is a unit slip (grams given as kg the other way
# round); a tensor of 1e4 kg·m² is 10 t at 1 m. Together with MAX_ABS_LENGTH_M they keep the
# dynamics' products far from overflow in single precision.
MIN_MASS_KG = 1e-6
MAX_MASS_KG = 1e4
MAX_INERTIA_KGM2 = 1e4
# The largest torque (N·m) or force (N) limit: the strongest industrial axes give ~1e5 N·m.
MAX_TORQUE = 1e7
# Gravity of a robot that gives none (m/s², base frame): standard gravity, the base's z up.
DEFAULT_GRAVITY = (0.0, 0.0, -9.81)


@dataclass(frozen=True)
class Inertial:
    """The rigid body a joint moves (its link, with the fixed links lumped into it), SI units.

    Every quantity is in the joint's LINK FRAME: the frame after the joint, which
    :func:`armgen.symbolic.kinematics.chain` gives as ``joint_frames[i]`` (DH: frame i of
    either convention; URDF: the joint's child link frame times the axis alignment ``A`` of
    :func:`armgen.description.frames.axis_alignment`).
    """

    mass: float  # kg (> 0)
    com: tuple[float, float, float]  # m, the centre of mass in the link frame
    inertia: tuple[float, ...]  # kg·m², (ixx, iyy, izz, ixy, ixz, iyz) about the COM, link-frame axes
    motor_inertia: float = 0.0  # kg·m² (kg for prismatic), reflected through the gear, added to M's diagonal

    @property
    def inertia_matrix(self) -> np.ndarray:
        """The 3×3 inertia tensor about the centre of mass (kg·m²), link-frame axes."""
        return inertia_matrix(self.inertia)


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
    # The dynamics: not in the repr, which names the kinematics (the IK loop's C name is a hash
    # of the joints' repr, and the same chain with or without masses has the same IK).
    inertial: Inertial | None = field(default=None, repr=False)  # the link this joint moves; None: not given
    taumax: float = field(default=math.inf, repr=False)  # torque limit (N·m; N for prismatic); inf: not given

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
class RobotDescription:
    """A serial robot, SI units: joints, base and tool transforms, named configurations.

    Read one with :func:`armgen.description.load_description`; :func:`armgen.load_robot`
    returns the same data as an :class:`armgen.robot.Robot`, which adds the NumPy methods
    (``fk``, ``jacobian``, ``ik`` …). Named configurations are attributes (``robot.q0``).

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
    path
        That file's absolute path ("" for a description made in memory): what tells, without
        reading the file again, whether a task's robot reference names this robot.
    gravity
        The gravity vector in the base frame (m/s²), ``DEFAULT_GRAVITY`` unless the file
        gives one; with every joint's :class:`Inertial` (:attr:`has_dynamics`) it defines the
        robot's dynamics.
    collision
        The arm's capsules, the pairs not checked and the obstacle slots
        (:class:`~armgen.description.collision.CollisionModel`); with capsules
        (:attr:`has_collision`) the robot has the collision functions (docs/collision.md).
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
    path: str = ""
    gravity: tuple[float, float, float] = DEFAULT_GRAVITY  # m/s², base frame
    collision: CollisionModel = field(default_factory=CollisionModel, repr=False)

    @property
    def has_collision(self) -> bool:
        """The robot has capsules it can use: the collision functions exist."""
        return self.collision.usable

    @property
    def n(self) -> int:
        return len(self.joints)

    @property
    def has_dynamics(self) -> bool:
        """Every joint's link has an inertial: the dynamic functions (gravity, RNEA, M) exist."""
        return all(j.inertial is not None for j in self.joints)

    @property
    def taumax(self) -> np.ndarray:
        """Joint torque limits (N·m, N); ``inf`` where the robot file gives none."""
        return np.array([j.taumax for j in self.joints])

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
        return f"{type(self).__name__}({self.name!r}, {joints}, {kind})"

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
        lines.append(self._dynamics_line())
        lines.extend(self._collision_lines())
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

    def _dynamics_line(self) -> str:
        """Whether the robot has dynamics (every link's inertial) and its gravity, for :meth:`show_text`."""
        if self.has_dynamics:
            gravity = [round(v, 6) + 0.0 for v in self.gravity]
            return f"dynamics: inertials for all {self.n} links (gravity {gravity} m/s^2)"
        why = self.urdf.get("no_dynamics")
        return "no inertials: no dynamic functions" + (f" ({why})" if why else "")

    def _collision_lines(self) -> list[str]:
        """The capsules (mm, in their frames), which enclose a URDF shape, the pairs checked."""
        model = self.collision
        if model.unusable:
            return [f"no collision model: {model.unusable}"]
        if not model.capsules:
            return ["no collision capsules: no collision functions"]
        enclosed = sum(capsule.enclosed for capsule in model.capsules)
        lines = [f"collision: {len(model.capsules)} capsules (mm, in their frames"
                 + (f"; {enclosed} enclose a URDF cylinder or box" if enclosed else "")
                 + f"), {len(model.self_pairs())} self pairs checked (not the same or adjacent frames"
                 + f"{', not ignored' if model.ignore else ''})"]
        for k, capsule in enumerate(model.capsules):
            a, b = (np.round(np.asarray(v) * 1e3, 3) + 0.0 for v in (capsule.a, capsule.b))
            shape = f"a={a.tolist()} b={b.tolist()}" if capsule.a != capsule.b else f"sphere at {a.tolist()}"
            where = f"frame {capsule.frame}" + (f" ({capsule.link})" if capsule.link != f"frame {capsule.frame}" else "")
            lines.append(f"  capsule {k:2d} {where}: {shape} r={capsule.radius * 1e3:.3f}  [{capsule.origin}]")
        if model.ignore:
            lines.append(f"  ignored pairs: {', '.join(f'{i}-{j}' for i, j in model.ignore)}")
        slots = model.slots
        lines.append(f"  obstacle slots: {slots.sphere} spheres, {slots.capsule} capsules, {slots.box} boxes, "
                     f"{slots.plane} planes")
        return lines

    def show(self) -> None:
        """Print :meth:`show_text` (the whole description; ``repr`` is one line)."""
        print(self.show_text())

    def __dir__(self) -> list[str]:
        return sorted(set(super().__dir__()) | set(self.configurations))

    def configuration(self, name: str) -> np.ndarray:
        """A copy of the named configuration; a clear error names the known ones."""
        if name not in self.configurations:
            known = ", ".join(sorted(self.configurations)) or "none"
            where = ("a URDF holds none: add it in a robot file that references the URDF (urdf = \"...\" and a "
                     "[configurations] table, docs/urdf.md)" if self.source == self.urdf.get("file")
                     else "add it under [configurations]")
            raise RobotFileError(
                f"{self.source}: robot '{self.name}' has no configuration '{name}' (known: {known}); "
                f"{where}, or give the joint values explicitly"
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


def _speed_limits(j: Joint) -> str:
    """``qdlim=… qddlim=…`` of one joint in deg/s(²) or mm/s(²), 'unlimited' where the file gives
    none; ``taumax=…`` (N·m or N) where it gives one."""
    scale, unit = (180 / math.pi, "deg") if j.revolute else (1e3, "mm")
    vel = f"{j.qdlim * scale:.4g} {unit}/s" if math.isfinite(j.qdlim) else "unlimited"
    acc = f"{j.qddlim * scale:.4g} {unit}/s^2" if math.isfinite(j.qddlim) else "unlimited"
    torque = f"  taumax={j.taumax:.4g} {'Nm' if j.revolute else 'N'}" if math.isfinite(j.taumax) else ""
    return f"qdlim={vel}  qddlim={acc}{torque}"


def _fmt_joint(joint: Joint, value: float) -> str:
    return f"{math.degrees(value):.4g} deg" if joint.revolute else f"{value * 1e3:.4g} mm"


def describe(robot: RobotDescription) -> dict[str, Any]:
    """A plain-data description for display and metadata."""
    return {
        "name": robot.name,
        "convention": robot.convention,
        "dof": robot.n,
        "source": robot.source,
        "sha256": robot.sha256,
        "dynamics": robot.has_dynamics,
    }
