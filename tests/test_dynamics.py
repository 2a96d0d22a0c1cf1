"""Rigid-body dynamics (issue 39, phase 1): gravity, RNEA, the mass matrix and the Coriolis
torques of armgen.symbolic.dynamics, checked against Pinocchio (an independent implementation)
on the example-robot-data arms with inertials and on a synthetic URDF with oblique axes, a
prismatic joint, lumped fixed links and rotated inertial frames; against Lagrange's equations
in SymPy (no recursion) on small DH and URDF arms; against gravity torques written by hand for
a planar DH arm; and for the physics every inverse dynamics obeys (M symmetric positive
definite, rnea = M q̈ + c + g, the power balance d/dt ½ q̇ᵀ M q̇ = q̇ᵀ (τ − g))."""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
import pytest

from armgen.description import Inertial
from armgen.description.collision import CollisionModel
from armgen.errors import RobotFileError
from armgen.robot import Robot, load_robot
from armgen.symbolic.dynamics import DYNAMIC_FUNCTIONS
from armgen.symbolic.model import ALL_FUNCTIONS, SymbolicModel
from armgen.symbolic.sympy_reference import sympy_lagrange_dynamics

from test_urdf import OBLIQUE_URDF, _example_robot_data_dir

pin = pytest.importorskip("pinocchio", reason="Pinocchio missing: pip install pin example-robot-data")

# Two implementations of the same rigid-body recursions in double precision: the torques of a
# 7-joint arm are sums of a few hundred products of O(1) terms, so a relative error of 1e-10
# (norm-wise: the largest error over the largest reference entry) leaves five orders of
# magnitude above the ~1e-15 rounding (the bar).
PEER_TOL = 1e-10
# Lagrange in SymPy vs Newton–Euler in CasADi on a 2–3 link arm: both double, a few dozen
# operations each, so 1e-12 relative is three orders above rounding.
SYMPY_TOL = 1e-12
# Hand-written closed forms and identities between the functions: rounding only.
IDENTITY_TOL = 1e-12
# The power balance is checked through Simpson's rule on 4000 steps of a smooth motion, whose
# quadrature error (h⁴ times a fourth derivative of order 10) is about 1e-12 of the energy.
ENERGY_TOL = 1e-9
SAMPLES = 200
SEED = 20261127

# (file under example-robot-data/robots, base link, tip link): every arm of example-robot-data 4
# whose chain armgen reads with an inertial on every moving link (None: the URDF's root / its
# single leaf). Not listed: double_pendulum (a joint with lower = upper), ur*_gripper (the
# wrist branches into two chains), the legged and humanoid robots (trees, not arms).
EXAMPLE_ARMS = [
    ("panda_description/urdf/panda.urdf", None, "panda_hand"),
    ("ur_description/urdf/ur3_robot.urdf", None, "tool0"),
    ("ur_description/urdf/ur5_robot.urdf", None, "tool0"),
    ("ur_description/urdf/ur10_robot.urdf", None, "tool0"),
    ("z1_description/urdf/z1.urdf", None, None),
    ("kinova_description/robots/kinova.urdf", None, "j2s6s200_end_effector"),
    ("so_arm_description/urdf/so100.urdf", None, None),
    ("so_arm_description/urdf/so101.urdf", None, None),
    ("xarm_description/urdf/xarm7.urdf", None, None),
    ("talos_data/robots/talos_left_arm.urdf", None, None),
    ("baxter_description/urdf/baxter.urdf", None, "left_gripper"),
    ("tiago_description/robots/tiago_no_hand.urdf", "torso_lift_link", "arm_7_link"),
    ("finger_edu_description/robots/finger_edu.urdf", None, None),
    ("asr_twodof_description/urdf/TwoDofs.urdf", None, None),
]


def _box_tensor(mass: float, sides: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """The tensor of a solid box about its centre, turned by ``rotation``: a physical body's."""
    a, b, c = sides
    principal = mass / 12 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])
    return rotation @ principal @ rotation.T


def _rotation(rng: np.random.Generator) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    return q * np.sign(np.diag(r))


def _oblique_urdf_with_inertials() -> str:
    """OBLIQUE_URDF with an <inertial> on every link: off-centre COMs, rotated inertial frames
    (origin rpy) and full tensors; 'mid' (fixed between j4 and j5) and 'tcp' are lumped."""
    rng = np.random.default_rng(SEED)

    def link(match: re.Match) -> str:
        mass = rng.uniform(0.3, 3.0)
        tensor = _box_tensor(mass, rng.uniform(0.05, 0.4, 3), _rotation(rng))
        xyz = " ".join(f"{v:.17g}" for v in rng.uniform(-0.1, 0.1, 3))
        rpy = " ".join(f"{v:.17g}" for v in rng.uniform(-1.5, 1.5, 3))
        entries = {"ixx": tensor[0, 0], "iyy": tensor[1, 1], "izz": tensor[2, 2], "ixy": tensor[0, 1],
                   "ixz": tensor[0, 2], "iyz": tensor[1, 2]}
        inertia = " ".join(f'{k}="{v:.17g}"' for k, v in entries.items())
        return (f'<link name="{match.group(1)}"><inertial><origin xyz="{xyz}" rpy="{rpy}"/>'
                f'<mass value="{mass:.17g}"/><inertia {inertia}/></inertial></link>')

    return re.sub(r'<link name="(l\d|mid|flange|tcp)"/>', link, OBLIQUE_URDF)


class _Pinocchio:
    """Pinocchio's dynamics of ``robot``'s chain, in armgen's joint order and gravity.

    The URDF's joints outside the chain are locked at their neutral value
    (``buildReducedModel``), their bodies given zero inertia first: armgen's dynamics hold the
    chain's links and the links fixed to them, not a branch moved by another joint (a gripper's
    fingers). Pinocchio's gravity (root frame) is armgen's (its base link's frame) turned by
    the base link's rotation; a continuous joint is (cos q, sin q) in Pinocchio's q."""

    def __init__(self, model, robot: Robot):
        chain = {joint.name for joint in robot.joints}
        locked = [jid for jid in range(1, model.njoints) if model.names[jid] not in chain]
        for jid in locked:
            model.inertias[jid] = pin.Inertia.Zero()
        self.model = pin.buildReducedModel(model, locked, pin.neutral(model)) if locked else model
        self.data = self.model.createData()
        pin.framesForwardKinematics(self.model, self.data, pin.neutral(self.model))
        base = self.data.oMf[self.model.getFrameId(robot.urdf["base_link"])].rotation
        self.model.gravity.linear = base @ np.asarray(robot.gravity)
        self.slots = [self.model.joints[self.model.getJointId(joint.name)] for joint in robot.joints]
        self.v = [slot.idx_v for slot in self.slots]

    def configuration(self, q: np.ndarray) -> np.ndarray:
        out = pin.neutral(self.model)
        for slot, value in zip(self.slots, q):
            if slot.nq == 2:
                out[slot.idx_q:slot.idx_q + 2] = [math.cos(value), math.sin(value)]
            else:
                out[slot.idx_q] = value
        return out

    def rate(self, value: np.ndarray) -> np.ndarray:
        out = np.zeros(self.model.nv)
        out[self.v] = value
        return out

    def __call__(self, q, dq, ddq) -> dict[str, np.ndarray]:
        model, data, v = self.model, self.data, self.v
        qp, vp, ap = self.configuration(q), self.rate(dq), self.rate(ddq)
        gravity = pin.computeGeneralizedGravity(model, data, qp)[v].copy()
        tau = pin.rnea(model, data, qp, vp, ap)[v].copy()
        mass = pin.crba(model, data, qp)
        mass = np.triu(mass) + np.triu(mass, 1).T  # crba fills the upper triangle
        nonlinear = pin.nonLinearEffects(model, data, qp, vp)[v].copy()
        return {"gravity": gravity, "rnea": tau, "mass_matrix": mass[np.ix_(v, v)], "coriolis": nonlinear - gravity}


def _relative_error(ours: np.ndarray, reference: np.ndarray) -> float:
    """Norm-wise: the largest entry error over the largest reference entry (a joint whose
    torque vanishes, e.g. a vertical first axis under gravity, would make entry-wise
    relative errors meaningless)."""
    return float(np.abs(ours - reference).max() / max(np.abs(reference).max(), np.finfo(float).tiny))


def _samples(robot: Robot, count: int, seed: int = SEED) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(q, q̇, q̈): q within the limits, q̇ in ±2 rad/s (m/s), q̈ in ±10 rad/s² (m/s²)."""
    rng = np.random.default_rng(seed)
    q = rng.uniform(robot.qmin, robot.qmax, (count, robot.n))
    return q, rng.uniform(-2.0, 2.0, (count, robot.n)), rng.uniform(-10.0, 10.0, (count, robot.n))


def _worst_against_pinocchio(robot: Robot, reference: _Pinocchio) -> dict[str, float]:
    q, dq, ddq = _samples(robot, SAMPLES)
    ours = {"gravity": robot.gravity_torques(q), "rnea": robot.rnea(q, dq, ddq), "mass_matrix": robot.mass_matrix(q),
            "coriolis": robot.coriolis(q, dq)}  # the batched path
    worst = dict.fromkeys(ours, 0.0)
    for k in range(SAMPLES):
        expected = reference(q[k], dq[k], ddq[k])
        for name in worst:
            worst[name] = max(worst[name], _relative_error(ours[name][k], expected[name]))
    single = reference(q[0], dq[0], ddq[0])  # the single-sample path (CasADi called directly)
    assert _relative_error(robot.rnea(q[0], dq[0], ddq[0]), single["rnea"]) <= PEER_TOL
    assert _relative_error(robot.mass_matrix(q[0]), single["mass_matrix"]) <= PEER_TOL
    return worst


@pytest.mark.parametrize("relative,base,tip", EXAMPLE_ARMS, ids=[arm[0].split("/")[-1] for arm in EXAMPLE_ARMS])
def test_example_robot_data_arms_match_pinocchio(relative, base, tip):
    path = _example_robot_data_dir() / relative
    robot = Robot.from_urdf(path, base_link=base, tip_link=tip)
    assert robot.has_dynamics, robot.urdf.get("no_dynamics")
    worst = _worst_against_pinocchio(robot, _Pinocchio(pin.buildModelFromUrdf(str(path)), robot))
    print(f"{relative}: {robot.n} joints, max relative error vs Pinocchio "
          + ", ".join(f"{k} {v:.1e}" for k, v in worst.items()))
    assert max(worst.values()) <= PEER_TOL, worst


def test_example_arm_count():
    assert len(EXAMPLE_ARMS) >= 10  # the bar: ten foreign URDFs with inertials


def test_oblique_prismatic_lumped_chain_matches_pinocchio(tmp_path):
    text = _oblique_urdf_with_inertials()
    path = tmp_path / "oblique.urdf"
    path.write_text(text)
    robot = Robot.from_urdf(path)
    assert "prismatic" in [j.type for j in robot.joints] and robot.has_dynamics
    robot = Robot.from_description(dataclasses.replace(robot, gravity=(1.5, -2.0, -9.5)))  # not along an axis
    worst = _worst_against_pinocchio(robot, _Pinocchio(pin.buildModelFromXML(text), robot))
    assert max(worst.values()) <= PEER_TOL, worst


def test_motor_inertia_adds_to_the_diagonal():
    """A reflected rotor inertia I_m adds I_m q̈ᵢ to τᵢ and I_m to Mᵢᵢ (Pinocchio's ``armature``
    in its 3.x rnea and crba; added here by hand so that any Pinocchio ≥ 2.7 serves)."""
    path = _example_robot_data_dir() / "panda_description/urdf/panda.urdf"
    robot = Robot.from_urdf(path, tip_link="panda_hand")
    armature = np.linspace(0.1, 0.7, robot.n)
    joints = tuple(dataclasses.replace(j, inertial=dataclasses.replace(j.inertial, motor_inertia=float(a)))
                   for j, a in zip(robot.joints, armature))
    robot = Robot.from_description(dataclasses.replace(robot, joints=joints))
    reference = _Pinocchio(pin.buildModelFromUrdf(str(path)), robot)
    q, dq, ddq = _samples(robot, 20)
    for k in range(20):
        expected = reference(q[k], dq[k], ddq[k])
        assert _relative_error(robot.rnea(q[k], dq[k], ddq[k]), expected["rnea"] + armature * ddq[k]) <= PEER_TOL
        assert _relative_error(robot.mass_matrix(q[k]), expected["mass_matrix"] + np.diag(armature)) <= PEER_TOL
        assert _relative_error(robot.gravity_torques(q[k]), expected["gravity"]) <= PEER_TOL


# -- arms built in memory: inertials added to the bundled DH robots and a URDF chain --------

def _with_inertials(robot, gravity=(0.3, -2.0, -9.81), seed: int = SEED) -> Robot:
    """``robot`` with a random physical inertial (box tensor turned at random, off-centre COM,
    a motor inertia) on every link."""
    rng = np.random.default_rng(seed)
    joints = []
    for joint in robot.joints:
        mass = float(rng.uniform(0.5, 3.0))
        tensor = _box_tensor(mass, rng.uniform(0.05, 0.4, 3), _rotation(rng))
        inertial = Inertial(mass, tuple(float(v) for v in rng.uniform(-0.2, 0.2, 3)),
                            (tensor[0, 0], tensor[1, 1], tensor[2, 2], tensor[0, 1], tensor[0, 2], tensor[1, 2]),
                            float(rng.uniform(0.0, 0.1)))
        joints.append(dataclasses.replace(joint, inertial=inertial))
    return Robot.from_description(dataclasses.replace(robot, joints=tuple(joints), gravity=gravity))


def _oblique_robot(tmp_path) -> Robot:
    path = tmp_path / "oblique.urdf"
    path.write_text(OBLIQUE_URDF)
    return Robot.from_urdf(path)


def _prismatic_dh(joint) -> object:
    """``joint`` made prismatic with every DH parameter in use: a fixed angle θ, d, a, α off the
    quarter turns and an offset."""
    return dataclasses.replace(joint, type="prismatic", theta=0.4, d=0.05, a=0.1, alpha=0.7, offset=0.02,
                               qlim=(-0.2, 0.3))


def _small_arms(tmp_path) -> dict[str, Robot]:
    """Three 3-joint arms: standard DH (modular8's first rows: offsets, d, α = ±90°; a
    prismatic middle joint; a turned and shifted base), modified DH (the Panda's first rows, a
    prismatic last joint), and a URDF chain with an oblique revolute axis, a continuous joint
    and an oblique prismatic joint (joints j2–j4 of OBLIQUE_URDF)."""
    modular, panda, oblique = load_robot("modular8"), load_robot("panda"), _oblique_robot(tmp_path)
    base = np.eye(4)
    base[:3, :3], base[:3, 3] = _rotation(np.random.default_rng(SEED)), [0.1, -0.2, 0.3]
    standard = dataclasses.replace(modular, joints=(modular.joints[0], _prismatic_dh(modular.joints[1]),
                                                    modular.joints[2]), base=base)
    # (without the Panda's capsules: they sit on frames beyond these three joints)
    modified = dataclasses.replace(panda, joints=(*panda.joints[:2], _prismatic_dh(panda.joints[2])),
                                   collision=CollisionModel())
    return {"standard DH": _with_inertials(standard), "modified DH": _with_inertials(modified),
            "URDF": _with_inertials(dataclasses.replace(oblique, joints=oblique.joints[1:4]))}


@pytest.mark.parametrize("kind", ["standard DH", "modified DH", "URDF"])
def test_small_arms_match_lagrange_in_sympy(tmp_path, kind):
    robot = _small_arms(tmp_path)[kind]
    assert [j.type for j in robot.joints].count("prismatic") == 1
    reference = sympy_lagrange_dynamics(robot)
    q, dq, ddq = _samples(robot, 20)
    for k in range(len(q)):
        M, c, g = reference(q[k], dq[k])
        assert _relative_error(robot.mass_matrix(q[k]), M) <= SYMPY_TOL
        assert _relative_error(robot.coriolis(q[k], dq[k]), c) <= SYMPY_TOL
        assert _relative_error(robot.gravity_torques(q[k]), g) <= SYMPY_TOL
        assert _relative_error(robot.rnea(q[k], dq[k], ddq[k]), M @ ddq[k] + c + g) <= SYMPY_TOL


def test_planar_dh_arm_gravity_by_hand():
    """planar3 (standard DH: frame i at the end of link i, x along it) in a vertical plane,
    gravity along −y: each link's COM halfway along it, so τ_k = Σ_{i≥k} m_i g (x_ci − x_k)."""
    planar = load_robot("planar3")
    masses, lengths = [2.0, 1.5, 1.0], [j.a for j in planar.joints]
    joints = tuple(dataclasses.replace(j, inertial=Inertial(m, (-j.a / 2, 0.0, 0.0), (0.01, 0.02, 0.03, 0.0, 0.0, 0.0)))
                   for j, m in zip(planar.joints, masses))
    robot = Robot.from_description(dataclasses.replace(planar, joints=joints, gravity=(0.0, -9.81, 0.0)))
    for q in np.random.default_rng(SEED).uniform(-2.9, 2.9, (50, 3)):
        angles = np.cumsum(q)
        joint_x = np.concatenate([[0.0], np.cumsum(np.multiply(lengths, np.cos(angles)))])
        com_x = joint_x[:3] + np.multiply(lengths, np.cos(angles)) / 2
        expected = [sum(masses[i] * 9.81 * (com_x[i] - joint_x[k]) for i in range(k, 3)) for k in range(3)]
        assert np.abs(robot.gravity_torques(q) - expected).max() <= IDENTITY_TOL


PLANAR_ROBOT_FILE = """
name = "vertical2"
convention = "standard"
gravity = [0, -9.81, 0]   # the arm moves in the vertical x-y plane

[units]
length = "mm"
angle = "deg"
mass = "g"

[[joints]]
name = "shoulder"
type = "revolute"
a = 400
d = 0
alpha = 0
qlim = [-170, 170]
mass = 2000                  # g
com = [-200, 0, 0]           # mm, halfway back along the link (frame 1 is at its end)
inertia = [1e5, 3e7, 3e7, 0, 0, 0]   # g mm^2 about the COM: izz = 0.03 kg m^2
motor_inertia = 1e5            # g mm^2 = 1e-4 kg m^2, reflected

[[joints]]
name = "elbow"
type = "revolute"
a = 300
d = 0
alpha = 0
qlim = [-170, 170]
mass = 1000
com = [-100, 0, 0]           # a third back: the heavy wrist end
inertia = [5e4, 8e6, 8e6, 0, 0, 0]     # izz = 0.008 kg m^2
"""


def test_robot_file_inertials_in_grams_and_millimetres(tmp_path):
    """A robot file's inertials in g and mm, read in SI: the gravity torques of a 2R arm in a
    vertical plane by hand (τ_k = g Σ_{i≥k} m_i (x_ci − x_k)), and M at the straight pose with the
    motor inertia on its diagonal."""
    path = tmp_path / "vertical2.toml"
    path.write_text(PLANAR_ROBOT_FILE)
    robot = load_robot(path)
    assert robot.has_dynamics
    for q in np.random.default_rng(SEED).uniform(-2.9, 2.9, (20, 2)):
        c1, c12 = math.cos(q[0]), math.cos(q[0] + q[1])
        elbow_x, com1_x, com2_x = 0.4 * c1, 0.2 * c1, 0.4 * c1 + 0.2 * c12
        expected = [9.81 * (2.0 * com1_x + 1.0 * com2_x), 9.81 * 1.0 * (com2_x - elbow_x)]
        assert np.abs(robot.gravity_torques(q) - expected).max() <= IDENTITY_TOL
    # M at q = 0 (the arm straight along x), each link's izz plus its mass at its COM's distance
    # from the joint (the COMs at x = 0.2 m and 0.6 m; 0.2 m beyond the elbow), motor on M11
    m22 = 0.008 + 1.0 * 0.2 ** 2
    m12 = 0.008 + 1.0 * (0.2 ** 2 + 0.4 * 0.2)
    m11 = 0.03 + 2.0 * 0.2 ** 2 + 0.008 + 1.0 * 0.6 ** 2 + 1e-4
    assert np.abs(robot.mass_matrix(np.zeros(2)) - [[m11, m12], [m12, m22]]).max() <= IDENTITY_TOL


def test_mass_matrix_symmetric_positive_definite(tmp_path):
    for robot in [*_small_arms(tmp_path).values(), _with_inertials(load_robot("iiwa14")),
                  _with_inertials(load_robot("snake12"))]:
        q, _, _ = _samples(robot, 100)
        M = robot.mass_matrix(q)
        assert np.array_equal(M, np.swapaxes(M, -1, -2))
        assert np.linalg.eigvalsh(M).min() > 0


def test_rnea_is_mass_matrix_coriolis_and_gravity(tmp_path):
    """The RNEA against the other three (a consistency check of the functions, not of the
    physics: that is the peer's and the power balance's)."""
    for robot in [*_small_arms(tmp_path).values(), _with_inertials(load_robot("iiwa14"))]:
        q, dq, ddq = _samples(robot, 100)
        g = robot.gravity_torques(q)
        zeros = np.zeros_like(q)
        scale = np.abs(robot.rnea(q, dq, ddq)).max()
        assert np.abs(robot.rnea(q, zeros, zeros) - g).max() <= IDENTITY_TOL * scale
        expected = np.einsum("kij,kj->ki", robot.mass_matrix(q), ddq) + robot.coriolis(q, dq) + g
        assert np.abs(robot.rnea(q, dq, ddq) - expected).max() <= IDENTITY_TOL * scale


def test_power_balance_along_a_motion(tmp_path):
    """Along q(t) = q₀ + a sin(ω t + φ): the kinetic energy ½ q̇ᵀ M q̇ (from the mass matrix
    only) changes by the work of τ − g (from the RNEA): ΔT = ∫ q̇ᵀ (τ − g) dt, Simpson's rule.
    This holds only if c = C q̇ is the Coriolis term of that M (q̇ᵀ (Ṁ/2 − C) q̇ = 0)."""
    rng = np.random.default_rng(SEED)
    duration, steps = 1.5, 4000
    t = np.linspace(0.0, duration, steps + 1)[:, None]
    for robot in [*_small_arms(tmp_path).values(), _with_inertials(load_robot("iiwa14"))]:
        n = robot.n
        q0, amplitude = robot.qmid, rng.uniform(0.2, 0.6, n) * np.where([j.revolute for j in robot.joints], 1, 0.1)
        omega, phase = rng.uniform(1.0, 4.0, n), rng.uniform(0, 2 * np.pi, n)
        q = q0 + amplitude * np.sin(omega * t + phase)
        dq = amplitude * omega * np.cos(omega * t + phase)
        ddq = -amplitude * omega ** 2 * np.sin(omega * t + phase)
        kinetic = 0.5 * np.einsum("ki,kij,kj->k", dq, robot.mass_matrix(q), dq)
        power = np.einsum("ki,ki->k", dq, robot.rnea(q, dq, ddq) - robot.gravity_torques(q))
        h = duration / steps
        work = h / 3 * (power[0] + power[-1] + 4 * power[1:-1:2].sum() + 2 * power[2:-1:2].sum())
        assert abs(work - (kinetic[-1] - kinetic[0])) <= ENERGY_TOL * np.abs(kinetic).max()


# -- the interface -------------------------------------------------------------------------

def test_functions_are_named_and_follow_the_kinematic_ones(tmp_path):
    robot = _small_arms(tmp_path)["URDF"]
    model = SymbolicModel(robot)
    assert model.dynamic_functions() == DYNAMIC_FUNCTIONS
    signatures = {name: (model.function(name).name_in(), model.function(name).name_out()) for name in DYNAMIC_FUNCTIONS}
    assert signatures == {"gravity": (["q"], ["tau"]), "rnea": (["q", "dq", "ddq"], ["tau"]),
                          "mass_matrix": (["q"], ["M"]), "coriolis": (["q", "dq"], ["c"])}
    assert all(model.function(name).name() == name for name in DYNAMIC_FUNCTIONS)
    # code generation takes them after the kinematic ones (tests/test_dynamics_codegen.py: their C)
    assert model.available() == ALL_FUNCTIONS + DYNAMIC_FUNCTIONS


def test_batches_broadcast_and_equal_single_samples(tmp_path):
    robot = _small_arms(tmp_path)["modified DH"]
    q, dq, ddq = _samples(robot, 6)
    q, dq, ddq = q.reshape(2, 3, 3), dq.reshape(2, 3, 3), ddq.reshape(2, 3, 3)
    tau, M = robot.rnea(q, dq, ddq), robot.mass_matrix(q)
    assert tau.shape == (2, 3, 3) and M.shape == (2, 3, 3, 3) and robot.gravity_torques(q).shape == (2, 3, 3)
    for index in np.ndindex(2, 3):
        assert np.abs(tau[index] - robot.rnea(q[index], dq[index], ddq[index])).max() <= IDENTITY_TOL * 100
        assert np.abs(M[index] - robot.mass_matrix(q[index])).max() <= IDENTITY_TOL
    # one configuration, many rates: q broadcast against dq
    c = robot.coriolis(q[0, 0], dq)
    assert c.shape == (2, 3, 3)
    assert np.abs(c[1, 2] - robot.coriolis(q[0, 0], dq[1, 2])).max() <= IDENTITY_TOL * 100
    with pytest.raises(ValueError, match=r"dq must have shape \(3,\) or \(\.\.\., 3\)"):
        robot.rnea(q, dq[..., :2], ddq)
    with pytest.raises(ValueError, match="do not broadcast"):
        robot.rnea(q, dq[:, :2], ddq)


def test_robot_without_inertials_says_so():
    robot = load_robot("modular8")  # a bundled robot without inertials
    assert not robot.has_dynamics
    assert SymbolicModel(robot).dynamic_functions() == ()
    for call in (lambda: robot.gravity_torques(robot.qmid), lambda: robot.mass_matrix(robot.qmid),
                 lambda: robot.rnea(robot.qmid, robot.qmid, robot.qmid), lambda: robot.coriolis(robot.qmid, robot.qmid),
                 lambda: SymbolicModel(robot).function("gravity")):
        with pytest.raises(RobotFileError, match=r"modular8.toml: robot 'modular8' has no inertials, so it has no dynamics"
                                                 r".*mass, com and inertia.*docs/dynamics.md"):
            call()
    partly = Robot.from_description(dataclasses.replace(
        robot, joints=_with_inertials(robot).joints[:-1] + robot.joints[-1:]))
    with pytest.raises(RobotFileError, match=r"robot 'modular8' has no inertials for joint\(s\) j8, so"):
        partly.gravity_torques(partly.qmid)
