"""Inertial parameters (issue 39): robot files and URDFs read each link's mass, centre of mass
and inertia into :class:`armgen.description.Inertial`, SI and in the joint's link frame (the
frame ``symbolic.kinematics.chain`` gives as ``joint_frames[i]``); torque limits and gravity.

References are independent of the code under test: NumPy eigenvalues for the validity of a
tensor, hand-computed unit conversions and lumped bodies, and Pinocchio (``pin``) for the
URDF bodies (its ``model.inertias[j]``, in the joint's child link frame) and their poses."""

from __future__ import annotations

import math
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from pydantic import ValidationError

from armgen.cli.main import cli
from armgen.description import load_description, parse_description, read_urdf
from armgen.description.frames import axis_alignment, rpy_matrix
from armgen.description.inertia import INERTIA_ROUNDING
from armgen.description.schema import RobotFile
from armgen.errors import RobotFileError
from armgen.symbolic.kinematics import chain

from test_urdf import OBLIQUE_URDF, _example_robot_data_dir, pin

# Masses, centres and tensors of O(1e-3 .. 10) in SI: Pinocchio and armgen lump the same
# numbers in double precision in a different order, a few ulps apart; 1e-12 (relative to the
# largest entry) leaves orders of margin and catches any wrong frame or sign.
PINOCCHIO_TOL = 1e-12
# Unit conversions are one multiplication by 1e-3 or 1e-9: exact to an ulp or two.
CONVERSION_RTOL = 1e-15
# Hypothesis tensors this close (relative to their largest moment) to the rule's boundary are
# left out: there, rounding decides, and Cholesky and eigenvalues may round differently.
BOUNDARY_MARGIN = 1e-9
SEED = 20261127

ARM = """name = "arm2"
convention = "standard"
[units]
length = "mm"
angle = "deg"
mass = "g"
[[joints]]
name = "shoulder"
type = "revolute"
a = 300
d = 100
alpha = 90
qlim = [-170, 170]
mass = 2500
com = [-150, 0, 10]
inertia = [4.0e6, 3.0e6, 2.0e6, 1.0e5, -2.0e5, 5.0e4]
motor_inertia = 1.5e5
taumax = 40
[[joints]]
name = "slide"
type = "prismatic"
a = 0
d = 0
alpha = 0
qlim = [0, 200]
mass = 800
com = [0, 5, -40]
inertia = [1.0e6, 1.0e6, 5.0e5, 0, 0, 0]
motor_inertia = 300
"""


def _set(text: str, old: str, new: str) -> str:
    assert text.count(old) == 1, old
    return text.replace(old, new)


# -- robot files -------------------------------------------------------------------------


def test_robot_file_inertials_in_grams_and_millimetres_are_si():
    robot = parse_description(ARM, "arm2.toml")
    shoulder, slide = robot.joints
    assert robot.has_dynamics and robot.gravity == (0.0, 0.0, -9.81)
    # hand-computed: 2500 g = 2.5 kg; mm -> m; g·mm² = 1e-3 kg · 1e-6 m² = 1e-9 kg·m²
    assert shoulder.inertial.mass == pytest.approx(2.5, rel=CONVERSION_RTOL)
    np.testing.assert_allclose(shoulder.inertial.com, [-0.15, 0.0, 0.01], rtol=CONVERSION_RTOL)
    np.testing.assert_allclose(shoulder.inertial.inertia, [4.0e-3, 3.0e-3, 2.0e-3, 1.0e-4, -2.0e-4, 5.0e-5],
                               rtol=CONVERSION_RTOL)
    assert shoulder.inertial.motor_inertia == pytest.approx(1.5e-4, rel=CONVERSION_RTOL)  # g·mm² -> kg·m²
    assert shoulder.taumax == 40.0  # N·m whatever [units] says
    assert slide.inertial.mass == pytest.approx(0.8, rel=CONVERSION_RTOL)
    assert slide.inertial.motor_inertia == pytest.approx(0.3, rel=CONVERSION_RTOL)  # prismatic: g -> kg
    assert slide.taumax == math.inf
    np.testing.assert_array_equal(robot.taumax, [40.0, math.inf])
    same_in_si = (ARM.replace('length = "mm"', 'length = "m"').replace('mass = "g"', 'mass = "kg"')
                  .replace("a = 300", "a = 0.3").replace("d = 100", "d = 0.1").replace("qlim = [0, 200]", "qlim = [0, 0.2]")
                  .replace("mass = 2500", "mass = 2.5").replace("com = [-150, 0, 10]", "com = [-0.15, 0, 0.01]")
                  .replace("[4.0e6, 3.0e6, 2.0e6, 1.0e5, -2.0e5, 5.0e4]", "[4.0e-3, 3.0e-3, 2.0e-3, 1.0e-4, -2.0e-4, 5.0e-5]")
                  .replace("motor_inertia = 1.5e5", "motor_inertia = 1.5e-4").replace("mass = 800", "mass = 0.8")
                  .replace("com = [0, 5, -40]", "com = [0, 0.005, -0.04]")
                  .replace("[1.0e6, 1.0e6, 5.0e5, 0, 0, 0]", "[1.0e-3, 1.0e-3, 5.0e-4, 0, 0, 0]")
                  .replace("motor_inertia = 300", "motor_inertia = 0.3"))
    for a, b in zip(robot.joints, parse_description(same_in_si, "si.toml").joints):
        np.testing.assert_allclose(a.inertial.inertia, b.inertial.inertia, rtol=CONVERSION_RTOL)
        np.testing.assert_allclose(a.inertial.com, b.inertial.com, rtol=CONVERSION_RTOL)


def test_gravity_and_defaults_keep_robots_without_inertials_working():
    robot = parse_description(_set(ARM, 'convention = "standard"', 'convention = "standard"\ngravity = [0, -9.81, 0]'),
                              "arm2.toml")
    assert robot.gravity == (0.0, -9.81, 0.0)  # m/s² whatever [units] length says
    for name in ("planar3", "modular8", "snake12"):  # iiwa14 and panda have inertials (test_bundled_inertials)
        bundled = load_description(name)
        assert not bundled.has_dynamics and bundled.gravity == (0.0, 0.0, -9.81)
        assert all(j.inertial is None and j.taumax == math.inf for j in bundled.joints)


def test_show_says_whether_the_robot_has_dynamics():
    robot = parse_description(ARM, "arm2.toml")
    text = robot.show_text()
    assert "dynamics: inertials for all 2 links (gravity [0.0, 0.0, -9.81] m/s^2)" in text
    assert "taumax=40 Nm" in text and text.count("taumax=") == 1
    shown = CliRunner().invoke(cli, ["show", "modular8"])
    assert shown.exit_code == 0 and "no inertials: no dynamic functions" in shown.output


def _eigen_rule(six: list[float]) -> tuple[bool, float]:
    """(the tensor is some body's, its distance to the rule's boundary), by NumPy eigenvalues."""
    ixx, iyy, izz, ixy, ixz, iyz = six
    moments = np.linalg.eigvalsh(np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]]))
    trace = moments.sum()
    excess = moments[2] - moments[0] - moments[1] - INERTIA_ROUNDING * trace  # the triangle inequality's
    largest = np.abs(moments).max()
    return bool(moments[0] > 0 and excess < 0), min(abs(moments[0]), abs(excess)) / largest if largest else 0.0


def _one_joint(**fields) -> dict:
    return {"name": "r", "convention": "standard",
            "joints": [{"type": "revolute", "a": 0.0, "d": 0.0, "alpha": 0.0, "qlim": [-1.0, 1.0], **fields}]}


@settings(max_examples=400, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(moments=st.lists(st.floats(-0.3, 2.0), min_size=3, max_size=3),
       angles=st.lists(st.floats(-math.pi, math.pi), min_size=3, max_size=3),
       exponent=st.integers(-6, 3))
def test_the_schema_accepts_exactly_the_tensors_some_body_has(moments, angles, exponent):
    rotation = rpy_matrix(*angles)
    tensor = 10.0 ** exponent * rotation @ np.diag(moments) @ rotation.T
    six = [tensor[0, 0], tensor[1, 1], tensor[2, 2], tensor[0, 1], tensor[0, 2], tensor[1, 2]]
    valid, margin = _eigen_rule(six)
    assume(margin > BOUNDARY_MARGIN)
    doc = _one_joint(mass=1.0, com=[0.0, 0.0, 0.0], inertia=six)
    if valid:
        RobotFile.model_validate(doc)
    else:
        with pytest.raises(ValidationError, match="field 'inertia'"):
            RobotFile.model_validate(doc)


def test_boundary_tensors_flat_bodies_and_rods():
    # a flat plate (izz = ixx + iyy) is a body; a thin rod (a zero moment) is not positive definite
    RobotFile.model_validate(_one_joint(mass=1.0, com=[0.0, 0.0, 0.0], inertia=[0.1, 0.2, 0.3, 0.0, 0.0, 0.0]))
    with pytest.raises(ValidationError, match="not positive definite"):
        RobotFile.model_validate(_one_joint(mass=1.0, com=[0.0, 0.0, 0.0], inertia=[0.1, 0.1, 0.0, 0.0, 0.0, 0.0]))


ERRORS = [
    (("mass = 800\n", ""), r"arm2.toml: joint 2 \('slide'\): field 'com' needs 'mass' too: .*give all three or none"),
    (("mass = 2500\ncom = [-150, 0, 10]\ninertia = [4.0e6, 3.0e6, 2.0e6, 1.0e5, -2.0e5, 5.0e4]\nmotor_inertia = 1.5e5\n",
      ""), r"arm2.toml: joint 1 \('shoulder'\): no mass, com and inertia, while joint\(s\) slide have them: the dynamics "
          r"need every link's inertial; give this joint's too, or remove them all"),
    (("inertia = [1.0e6, 1.0e6, 5.0e5, 0, 0, 0]", "inertia = [1.0e6, 1.0e6, 3.0e6, 0, 0, 0]"),
     r"joint 2 \('slide'\): field 'inertia' = \[1000000\.0, 1000000\.0, 3000000\.0, 0\.0, 0\.0, 0\.0\] has principal moments "
     r"\(1e\+06, 1e\+06, 3e\+06\), the largest above the sum of the other two: no body has such a tensor .*ixy = -∫xy dm"),
    (("inertia = [1.0e6, 1.0e6, 5.0e5, 0, 0, 0]", "inertia = [1.0e6, 1.0e6, 5.0e5, 2.0e6, 0, 0]"),
     r"joint 2 \('slide'\): field 'inertia' = .* is not positive definite"),
    (("mass = 800", "mass = -800"), r"joint 2 \('slide'\): field 'mass' = -800 must be > 0"),
    (("mass = 800", "mass = 8e9"), r"joint 2 \('slide'\): field 'mass' = 8000000000.0 g is outside \[1e-06, 10000\] kg, no "
                                   r"arm link's mass: check the value and \[units\] mass = \"g\""),
    (("com = [0, 5, -40]", "com = [0, 5, -4e7]"), r"joint 2 \('slide'\): field 'com' = .* is beyond ±1000 m"),
    (("com = [0, 5, -40]", "com = [0, 5]"), r"joint 2 \('slide'\): field 'com' must have at least 3 entries, got 2"),
    (("com = [0, 5, -40]", "com = [0, 5, nan]"), r"joint 2 \('slide'\): field 'com'\[2\] is nan; give a finite number"),
    (("inertia = [1.0e6, 1.0e6, 5.0e5, 0, 0, 0]", "inertia = [3e-316, 3e-316, 2e-316, 0, 0, 0]"),
     r"joint 2 \('slide'\): field 'inertia' = \[3e-316, 3e-316, 2e-316, 0.0, 0.0, 0.0\] is too small to hold in kg·m² .*"
     r"\[units\] mass = \"g\" and length"),
    (("taumax = 40", "taumax = 0"), r"joint 1 \('shoulder'\): field 'taumax' = 0 must be > 0"),
    (("taumax = 40", "taumax = 1e9"), r"joint 1 \('shoulder'\): field 'taumax' = 1000000000.0 is beyond 1e\+07 N·m"),
    (("motor_inertia = 1.5e5", "motor_inertia = -1"), r"field 'motor_inertia' = -1 must be ≥ 0"),
    (('convention = "standard"', 'convention = "standard"\ngravity = [0, 0, -9810]'),
     r"arm2.toml: file: field 'gravity'\[2\] = -9810 must be ≥ -100"),
    (('mass = "g"', 'mass = "lb"'), r"field 'mass' = 'lb' is not one of kg, g"),
]


@pytest.mark.parametrize("edit, message", ERRORS)
def test_bad_inertials_are_one_error_naming_file_joint_field_and_fix(edit, message):
    with pytest.raises(RobotFileError, match=message):
        parse_description(_set(ARM, *edit), "arm2.toml")


def test_motor_inertia_alone_is_an_error():
    doc = ("name = \"r\"\nconvention = \"standard\"\n[[joints]]\ntype = \"revolute\"\na = 0\nd = 0\nalpha = 0\n"
           "qlim = [-1, 1]\nmotor_inertia = 0.1\n")
    with pytest.raises(RobotFileError, match=r"r.toml: joint 1: field 'motor_inertia' needs the link's mass, com and "
                                             r"inertia: give them too, or remove it"):
        parse_description(doc, "r.toml")


# -- URDF --------------------------------------------------------------------------------

# (file under example-robot-data/robots, tip link): arms whose every moving link has an inertial.
URDF_ARMS = [
    ("panda_description/urdf/panda.urdf", "panda_hand"),
    ("ur_description/urdf/ur5_robot.urdf", "tool0"),
    ("ur_description/urdf/ur10_robot.urdf", "tool0"),
    ("z1_description/urdf/z1.urdf", None),
    ("kinova_description/robots/kinova.urdf", "j2s6s200_end_effector"),
    ("so_arm_description/urdf/so100.urdf", None),
    ("so_arm_description/urdf/so101.urdf", None),
    ("xarm_description/urdf/xarm7.urdf", None),
    ("talos_data/robots/talos_left_arm.urdf", None),
    ("finger_edu_description/robots/finger_edu.urdf", None),
]


def _child_frame_values(joint) -> tuple[float, np.ndarray, np.ndarray]:
    """(mass, com, tensor about it) of a joint's body turned back from its link frame into the
    URDF child link frame (Pinocchio's joint frame): the link frame is child · A."""
    turn = axis_alignment(joint.axis)[:3, :3]
    ixx, iyy, izz, ixy, ixz, iyz = joint.inertial.inertia
    tensor = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    return joint.inertial.mass, turn @ np.array(joint.inertial.com), turn @ tensor @ turn.T


def _assert_bodies_match_pinocchio(robot, model) -> None:
    assert robot.has_dynamics
    for joint in robot.joints:
        body = model.inertias[model.getJointId(joint.name)]
        mass, com, tensor = _child_frame_values(joint)
        assert mass == pytest.approx(body.mass, rel=PINOCCHIO_TOL), joint.name  # lumped: the total mass per joint
        np.testing.assert_allclose(com, body.lever, rtol=0, atol=PINOCCHIO_TOL * max(1.0, np.abs(body.lever).max()),
                                   err_msg=joint.name)
        np.testing.assert_allclose(tensor, body.inertia, rtol=0, atol=PINOCCHIO_TOL * np.abs(body.inertia).max(),
                                   err_msg=joint.name)


@pytest.mark.parametrize("relative, tip", URDF_ARMS, ids=[Path(r).stem for r, _ in URDF_ARMS])
def test_urdf_bodies_match_pinocchio(relative, tip):
    path = _example_robot_data_dir() / relative
    robot = read_urdf(path, tip_link=tip)
    _assert_bodies_match_pinocchio(robot, pin.buildModelFromUrdf(str(path)))
    efforts = [model_effort for model_effort in pin.buildModelFromUrdf(str(path)).effortLimit]
    assert all(t > 0 for t in robot.taumax) and efforts  # every one of these arms gives its efforts


def _random_inertial(rng: np.random.Generator) -> str:
    """An <inertial> of a random body: a mass, an origin (xyz, rpy) and a tensor some body has."""
    moments = rng.uniform(0.01, 0.1, 3)
    moments[2] = rng.uniform(abs(moments[0] - moments[1]), moments[0] + moments[1])  # the triangle inequality
    rotation = rpy_matrix(*rng.uniform(-math.pi, math.pi, 3))
    t = rotation @ np.diag(moments) @ rotation.T
    xyz, rpy = rng.uniform(-0.2, 0.2, 3).tolist(), rng.uniform(-math.pi, math.pi, 3).tolist()
    t = t.tolist()
    return (f"<inertial><origin xyz='{' '.join(map(repr, xyz))}' rpy='{' '.join(map(repr, rpy))}'/>"
            f"<mass value='{float(rng.uniform(0.2, 5.0))!r}'/><inertia ixx='{t[0][0]!r}' iyy='{t[1][1]!r}' "
            f"izz='{t[2][2]!r}' ixy='{t[0][1]!r}' ixz='{t[0][2]!r}' iyz='{t[1][2]!r}'/></inertial>")


def _oblique_with_inertials(tmp_path: Path) -> Path:
    """The oblique chain of test_urdf (axes off the coordinate axes, a prismatic and a
    continuous joint, fixed joints before, between and after) with an inertial on every link,
    a camera fixed beside link l2 (lumped) and a finger moving off the chain (not lumped)."""
    rng = np.random.default_rng(SEED)
    text = OBLIQUE_URDF
    for link in ("world", "base", "l1", "l2", "l3", "l4", "mid", "l5", "flange", "tcp"):
        text = _set(text, f'<link name="{link}"/>', f'<link name="{link}">{_random_inertial(rng)}</link>')
    extra = (f'<link name="camera">{_random_inertial(rng)}</link><link name="finger">{_random_inertial(rng)}</link>'
             '<joint name="camera_mount" type="fixed"><parent link="l2"/><child link="camera"/>'
             '<origin xyz="0.05 0.1 -0.02" rpy="0.3 -0.2 1.1"/></joint>'
             '<joint name="finger_slide" type="prismatic"><parent link="l5"/><child link="finger"/>'
             '<origin xyz="0 0.03 0.05"/><axis xyz="0 1 0"/><limit effort="5" velocity="1" lower="0" upper="0.04"/>'
             '</joint></robot>')
    path = tmp_path / "oblique.urdf"
    path.write_text(_set(text, "</robot>", extra))
    return path


def test_oblique_urdf_bodies_and_their_link_frames_match_pinocchio(tmp_path):
    path = _oblique_with_inertials(tmp_path)
    robot = read_urdf(path, tip_link="tcp")
    model = pin.buildModelFromUrdf(str(path))
    _assert_bodies_match_pinocchio(robot, model)
    # the link frame is chain()'s joint_frames[i]: the body's centre and tensor in the base
    # frame, through it, are Pinocchio's through its joint placements, at random q
    q = ca.SX.sym("q", robot.n)
    frames = ca.Function("frames", [q], chain(robot, q)[1])
    data = model.createData()
    rng = np.random.default_rng(SEED)
    for _ in range(20):
        values = rng.uniform(robot.qmin, robot.qmax)
        qp = pin.neutral(model)
        for joint, value in zip(robot.joints, values):
            placement = model.joints[model.getJointId(joint.name)]
            if placement.nq == 2:  # continuous joints are (cos, sin) in Pinocchio
                qp[placement.idx_q:placement.idx_q + 2] = [math.cos(value), math.sin(value)]
            else:
                qp[placement.idx_q] = value
        pin.forwardKinematics(model, data, qp)
        for joint, frame in zip(robot.joints, frames(values)):
            frame = np.array(frame)
            pose, body = data.oMi[model.getJointId(joint.name)], model.inertias[model.getJointId(joint.name)]
            ixx, iyy, izz, ixy, ixz, iyz = joint.inertial.inertia
            tensor = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
            np.testing.assert_allclose(frame[:3, :3] @ joint.inertial.com + frame[:3, 3], pose.act(body.lever),
                                       atol=PINOCCHIO_TOL * 10)  # through a chain of 6 joints: a few more ulps
            np.testing.assert_allclose(frame[:3, :3] @ tensor @ frame[:3, :3].T,
                                       pose.rotation @ body.inertia @ pose.rotation.T, atol=PINOCCHIO_TOL * 10)


LUMPED = """<robot name="lumped">
  <link name="base"/>
  <link name="upper"><inertial><origin xyz="0.1 0 0"/><mass value="2"/>
    <inertia ixx="0.01" iyy="0.02" izz="0.02" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="flange"><inertial><origin xyz="0 0 0.4" rpy="0 0 1.5707963267948966"/><mass value="1"/>
    <inertia ixx="0.001" iyy="0.003" izz="0.003" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="frame_only"/>
  <joint name="lift" type="revolute"><parent link="base"/><child link="upper"/><axis xyz="1 0 0"/>
    <limit lower="-1" upper="1" effort="0" velocity="1"/></joint>
  <joint name="bolted" type="fixed"><parent link="upper"/><child link="flange"/><origin xyz="0.3 0 0"/></joint>
  <joint name="tip" type="fixed"><parent link="flange"/><child link="frame_only"/></joint>
</robot>"""


def test_fixed_links_are_lumped_by_the_parallel_axis_theorem(tmp_path):
    path = tmp_path / "lumped.urdf"
    path.write_text(LUMPED)
    (joint,) = read_urdf(path).joints
    assert joint.taumax == math.inf  # effort="0": none
    # by hand, in the child link frame: 2 kg at (0.1, 0, 0) and 1 kg at (0.3, 0, 0.4), its
    # tensor turned by 90° about z (ixx <-> iyy); combined centre (0.5/3, 0, 0.4/3);
    # offsets d1 = (-1/15, 0, -2/15), d2 = (2/15, 0, 4/15)
    d1, d2 = np.array([-1 / 15, 0, -2 / 15]), np.array([2 / 15, 0, 4 / 15])
    expected = (np.diag([0.01, 0.02, 0.02]) + 2 * (d1 @ d1 * np.eye(3) - np.outer(d1, d1))
                + np.diag([0.003, 0.001, 0.003]) + 1 * (d2 @ d2 * np.eye(3) - np.outer(d2, d2)))
    mass, com, tensor = _child_frame_values(joint)
    assert mass == pytest.approx(3.0, rel=1e-15)
    np.testing.assert_allclose(com, [0.5 / 3, 0, 0.4 / 3], atol=1e-15)
    np.testing.assert_allclose(tensor, expected, atol=1e-15)
    # the axis is x: the link frame's z is the child's x, so the stored com is A^T com
    np.testing.assert_allclose(joint.inertial.com, axis_alignment((1.0, 0.0, 0.0))[:3, :3].T @ com, atol=1e-15)


@pytest.mark.parametrize("edit, reason", [
    (('<link name="upper"><inertial><origin xyz="0.1 0 0"/><mass value="2"/>\n'
      '    <inertia ixx="0.01" iyy="0.02" izz="0.02" ixy="0" ixz="0" iyz="0"/></inertial></link>', '<link name="upper"/>'),
     "link 'upper' (moved by joint 'lift') has no <inertial>"),
    (('<mass value="2"/>', '<mass value="0"/>'), None),  # the flange alone still gives the body mass
    (('<mass value="1"/>', '<mass value="0"/>'), None),
    (('izz="0.02"', 'izz="2"'), "the inertia of the links joint 'lift' moves ('upper' and those fixed to it) has "
                                  "principal moments"),
])
def test_a_urdf_body_without_a_usable_inertial_leaves_the_robot_without_dynamics(tmp_path, edit, reason):
    path = tmp_path / "lumped.urdf"
    path.write_text(_set(LUMPED, *edit))
    robot = read_urdf(path)
    assert robot.has_dynamics == (reason is None)
    if reason:
        assert robot.joints[0].inertial is None and reason in robot.urdf["no_dynamics"]
        assert f"no inertials: no dynamic functions ({robot.urdf['no_dynamics']})" in robot.show_text()


def test_urdf_massless_body_has_no_dynamics(tmp_path):
    path = tmp_path / "lumped.urdf"
    path.write_text(_set(_set(LUMPED, '<mass value="2"/>', '<mass value="0"/>'), '<mass value="1"/>', '<mass value="0"/>'))
    robot = read_urdf(path)
    assert not robot.has_dynamics and "have mass 0" in robot.urdf["no_dynamics"]


@pytest.mark.parametrize("edit, message", [
    (('<mass value="2"/>', '<mass value="-2"/>'), r"link 'upper' <inertial> <mass>: value = -2 is outside \[0, 10000\] "
                                                  r"kg \(URDF masses are kg\)"),
    (('<mass value="2"/>', ""), r"link 'upper' <inertial>: needs <mass value=\"…\" \(kg\)/>"),
    (('ixx="0.01" ', ""), r"link 'upper' <inertial> <inertia>: element needs attribute 'ixx'|<inertia> needs attribute 'ixx'"),
    (('ixy="0" ixz="0" iyz="0"/></inertial></link>\n  <link name="flange">', 'ixy="x" ixz="0" iyz="0"/></inertial></link>\n'
                                                                          '  <link name="flange">'),
     r"link 'upper' <inertial> <inertia>: <inertia ixy=\"x\"> must be 1 numbers"),
    (('effort="0"', 'effort="-3"'), r"joint 'lift' <limit>: effort = -3.0 is negative; give the torque limit"),
    (('effort="0"', 'effort="1e12"'), r"joint 'lift' <limit>: effort = 1e\+12 is beyond 1e\+07 N·m or N"),
])
def test_bad_urdf_inertials_are_one_error_naming_the_link(tmp_path, edit, message):
    path = tmp_path / "lumped.urdf"
    path.write_text(_set(LUMPED, *edit))
    with pytest.raises(RobotFileError, match=message):
        read_urdf(path)


def test_wrapper_sets_taumax_and_gravity(tmp_path):
    (tmp_path / "lumped.urdf").write_text(LUMPED)
    wrapper = tmp_path / "arm.toml"
    wrapper.write_text('urdf = "lumped.urdf"\ngravity = [0, 0, -1.62]\n[limits]\nlift = { taumax = 12.5 }\n')
    robot = load_description(wrapper)
    assert robot.joints[0].taumax == 12.5 and robot.gravity == (0.0, 0.0, -1.62) and robot.has_dynamics
    wrapper.write_text('urdf = "lumped.urdf"\n[limits]\nlift = { taumax = -1 }\n')
    with pytest.raises(RobotFileError, match=r"arm.toml: \[limits.lift\]: field 'taumax' = -1 must be > 0"):
        load_description(wrapper)


_URDF_NUMBER = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.sampled_from([0.0, -0.0, 1e400, 1e-320]),
                         st.integers(-10, 10)).map(str) | st.sampled_from(["", "x", "1 2", "nan"])


@settings(max_examples=300, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(values=st.fixed_dictionaries({key: _URDF_NUMBER for key in ("mass", "ixx", "iyy", "izz", "ixy", "effort")}))
def test_fuzzed_urdf_inertials_load_or_fail_cleanly(tmp_path_factory, values):
    text = LUMPED
    for key, old in (("mass", 'mass value="2"'), ("ixx", 'ixx="0.01"'), ("iyy", 'iyy="0.02"'), ("izz", 'izz="0.02"'),
                     ("ixy", 'ixy="0" ixz="0" iyz="0"/></inertial></link>\n  <link name="flange"'),
                     ("effort", 'effort="0"')):
        head, _, rest = old.split('"', 2)  # the fuzzed value replaces the first attribute's
        text = _set(text, old, f'{head}"{values[key]}"{rest}')
    path = tmp_path_factory.mktemp("fuzz") / "lumped.urdf"
    path.write_text(text)
    try:
        robot = read_urdf(path)
    except RobotFileError as exc:
        assert str(exc).startswith(str(path))
        return
    assert robot.joints[0].taumax > 0
    if robot.has_dynamics:
        inertial = robot.joints[0].inertial
        assert inertial.mass > 0 and all(math.isfinite(v) for v in (*inertial.com, *inertial.inertia))
    else:
        assert robot.urdf["no_dynamics"]
