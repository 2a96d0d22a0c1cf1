"""URDF robots: kinematics against Pinocchio (an independent implementation) on the URDFs of
example-robot-data and on a synthetic chain with oblique axes, the SymPy derivation, the
generated C, the DH Panda, robot files that reference a URDF, a short plan, and clean errors
for bad files (listed cases and a seeded hypothesis fuzz)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from armgen.errors import RobotFileError
from armgen.robot import Robot, load_robot
from armgen.symbolic.model import SymbolicModel
from armgen.symbolic.sympy_reference import sympy_fk_jacobian
from armgen.description.urdf import CONTINUOUS_LIMIT

from conftest import require_tool

pin = pytest.importorskip("pinocchio", reason="Pinocchio missing: pip install pin example-robot-data")

# Pose and Jacobian entries are O(1) m; two implementations of the same products in double
# precision agree to a few ulps, so 1e-12 leaves three orders of margin (the bar).
PINOCCHIO_TOL = 1e-12
SAMPLES = 1000
SEED = 20261123


def _example_robot_data_dir() -> Path:
    import importlib.util

    spec = importlib.util.find_spec("cmeel")
    if spec is not None:
        for root in spec.submodule_search_locations or []:
            candidate = Path(root).parent / "cmeel.prefix" / "share" / "example-robot-data" / "robots"
            if candidate.is_dir():
                return candidate
    candidate = Path(pin.__file__).resolve().parents[3] / "share" / "example-robot-data" / "robots"
    if candidate.is_dir():
        return candidate
    pytest.skip("example-robot-data missing: pip install example-robot-data")


# (file under example-robot-data/robots, tip link); the iiwa is not shipped by example-robot-data 6.
EXAMPLE_ARMS = [
    ("panda_description/urdf/panda.urdf", "panda_hand"),
    ("ur_description/urdf/ur5_robot.urdf", "tool0"),
    ("z1_description/urdf/z1.urdf", None),
    ("kinova_description/robots/kinova.urdf", "j2s6s200_end_effector"),
]

# Joint axes off the coordinate axes, a continuous and a prismatic joint, fixed joints
# before, between and after the moving ones, and non-quarter-turn origins.
OBLIQUE_URDF = """<?xml version="1.0"?>
<robot name="oblique">
  <link name="world"/><link name="base"/><link name="l1"/><link name="l2"/><link name="l3"/>
  <link name="l4"/><link name="mid"/><link name="l5"/><link name="flange"/><link name="tcp"/>
  <joint name="mount" type="fixed"><parent link="world"/><child link="base"/>
    <origin xyz="0.1 -0.2 0.05" rpy="0.1 0.2 0.3"/></joint>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0.3"/><axis xyz="0 0 1"/><limit effort="10" velocity="1" lower="-2.9" upper="2.9"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="0.05 0.02 0.1" rpy="-1.5707963267948966 0 0.4"/><axis xyz="0.3 0.5 0.8"/>
    <limit effort="10" velocity="1" lower="-1.5" upper="1.7"/></joint>
  <joint name="j3" type="continuous"><parent link="l2"/><child link="l3"/>
    <origin xyz="0.3 0 0" rpy="0 0.7 0"/><axis xyz="0 -1 0"/></joint>
  <joint name="j4" type="prismatic"><parent link="l3"/><child link="l4"/>
    <origin xyz="0 0.1 0.2" rpy="0.2 -0.1 1.0"/><axis xyz="1 1 0"/><limit effort="10" velocity="1" lower="-0.1" upper="0.25"/></joint>
  <joint name="elbow_fixed" type="fixed"><parent link="l4"/><child link="mid"/>
    <origin xyz="0.01 0.02 0.03" rpy="3.141592653589793 0 0"/></joint>
  <joint name="j5" type="revolute"><parent link="mid"/><child link="l5"/>
    <origin xyz="0 0 0.25"/><axis xyz="-1 0 0"/><limit effort="10" velocity="1" lower="-2" upper="2"/></joint>
  <joint name="j6" type="revolute"><parent link="l5"/><child link="flange"/>
    <origin xyz="0.08 0 0.02" rpy="0 -0.3 0.9"/><axis xyz="0.0 0.6 -0.8"/><limit effort="10" velocity="1" lower="-3" upper="3"/></joint>
  <joint name="tcp_fixed" type="fixed"><parent link="flange"/><child link="tcp"/>
    <origin xyz="0 0 0.12" rpy="0 0 -0.7853981633974483"/></joint>
</robot>
"""


def _pinocchio_reference(model, robot: Robot, tip: str):
    """(fk, jacobian) of ``robot``'s joint vector through Pinocchio (LOCAL_WORLD_ALIGNED = ours)."""
    data = model.createData()
    frame = model.getFrameId(tip)
    slots = []
    for joint in robot.joints:
        jid = model.getJointId(joint.name)
        slots.append((model.joints[jid].idx_q, model.joints[jid].nq, model.joints[jid].idx_v))

    def configuration(q):
        qp = pin.neutral(model)
        for (idx, nq, _), value in zip(slots, q):
            if nq == 2:  # continuous joints are (cos, sin) in Pinocchio
                qp[idx:idx + 2] = [math.cos(value), math.sin(value)]
            else:
                qp[idx] = value
        return qp

    def fk_jac(q):
        qp = configuration(q)
        jac = pin.computeFrameJacobian(model, data, qp, frame, pin.LOCAL_WORLD_ALIGNED)
        pin.updateFramePlacements(model, data)
        return data.oMf[frame].homogeneous.copy(), jac[:, [v for _, _, v in slots]]

    return fk_jac


def _assert_matches_pinocchio(robot: Robot, model, tip: str, samples: int = SAMPLES) -> None:
    reference = _pinocchio_reference(model, robot, tip)
    q = np.random.default_rng(SEED).uniform(robot.qmin, robot.qmax, (samples, robot.n))
    T, J = robot.fk(q), robot.jacobian(q)  # the batched path
    for k in range(samples):
        T_ref, J_ref = reference(q[k])
        assert np.abs(T[k] - T_ref).max() <= PINOCCHIO_TOL, f"FK differs at sample {k}"
        assert np.abs(J[k] - J_ref).max() <= PINOCCHIO_TOL, f"Jacobian differs at sample {k}"
    T1, J1 = robot.fk(q[0]), robot.jacobian(q[0])  # the single-sample path
    T_ref, J_ref = reference(q[0])
    assert np.abs(T1 - T_ref).max() <= PINOCCHIO_TOL and np.abs(J1 - J_ref).max() <= PINOCCHIO_TOL


@pytest.mark.parametrize("relative,tip", EXAMPLE_ARMS)
def test_example_robot_data_arms_match_pinocchio(relative, tip):
    path = _example_robot_data_dir() / relative
    robot = Robot.from_urdf(path, tip_link=tip)
    model = pin.buildModelFromUrdf(str(path))
    _assert_matches_pinocchio(robot, model, robot.urdf["tip_link"])


def test_oblique_axes_prismatic_and_continuous_match_pinocchio(tmp_path):
    path = tmp_path / "oblique.urdf"
    path.write_text(OBLIQUE_URDF)
    robot = Robot.from_urdf(path)
    assert [j.name for j in robot.joints] == ["j1", "j2", "j3", "j4", "j5", "j6"]
    assert [j.type for j in robot.joints] == ["revolute"] * 3 + ["prismatic"] + ["revolute"] * 2
    assert robot.joints[2].qlim == (-CONTINUOUS_LIMIT, CONTINUOUS_LIMIT)
    assert robot.urdf["base_link"] == "world" and robot.urdf["tip_link"] == "tcp"
    _assert_matches_pinocchio(robot, pin.buildModelFromXML(OBLIQUE_URDF), "tcp")


def test_oblique_chain_matches_the_sympy_derivation(tmp_path):
    path = tmp_path / "oblique.urdf"
    path.write_text(OBLIQUE_URDF)
    robot = Robot.from_urdf(path)
    fk_ref, jac_ref = sympy_fk_jacobian(robot)
    model = SymbolicModel(robot)
    fk, jac = model.function("fk"), model.function("jacobian")
    rng = np.random.default_rng(SEED)
    for _ in range(50):
        q = rng.uniform(robot.qmin, robot.qmax)
        assert np.abs(np.array(fk(q)) - fk_ref(q)).max() <= PINOCCHIO_TOL
        assert np.abs(np.array(jac(q)) - jac_ref(q)).max() <= PINOCCHIO_TOL


def test_panda_urdf_and_dh_panda_agree():
    """The DH frames of the bundled (modified-DH) panda coincide with the URDF link frames:
    its flange tool is panda_link8 (107 mm along joint 7's axis)."""
    urdf = Robot.from_urdf(_example_robot_data_dir() / "panda_description/urdf/panda.urdf", tip_link="panda_link8")
    dh = load_robot("panda")
    q = np.random.default_rng(SEED).uniform(dh.qmin, dh.qmax, (SAMPLES, dh.n))
    assert np.allclose(urdf.qmin, dh.qmin, rtol=0, atol=0) and np.allclose(urdf.qmax, dh.qmax, rtol=0, atol=0)
    assert np.abs(urdf.fk(q) - dh.fk(q)).max() <= PINOCCHIO_TOL
    assert np.abs(urdf.jacobian(q) - dh.jacobian(q)).max() <= PINOCCHIO_TOL


@pytest.mark.slow
def test_generated_c_of_a_urdf_robot_matches_pinocchio(tmp_path):
    from armgen.codegen.compiled import CompiledModel, build_library
    from armgen.codegen.generate import CodegenConfig, generate, write

    require_tool("gcc")
    path = tmp_path / "oblique.urdf"
    path.write_text(OBLIQUE_URDF)
    robot = Robot.from_urdf(path)
    functions = ("fk", "jacobian", "fk_jacobian", "zghal", "manipulability", "step_gpm")
    code = generate(CodegenConfig(robot, functions=functions))
    write(code, tmp_path / "gen")
    lib = build_library(tmp_path / "gen", code.prefix, "double", tmp_path)
    symbolic = SymbolicModel(robot)
    compiled = CompiledModel(lib, code.prefix, {f: symbolic.function(f) for f in functions}, "double")
    reference = _pinocchio_reference(pin.buildModelFromXML(OBLIQUE_URDF), robot, "tcp")
    rng = np.random.default_rng(SEED)
    for _ in range(200):
        q = rng.uniform(robot.qmin, robot.qmax)
        T_ref, J_ref = reference(q)
        (T,) = compiled.raw["fk"](q)
        T2, J2 = compiled.raw["fk_jacobian"](q)
        assert np.abs(T - T_ref).max() <= PINOCCHIO_TOL and np.abs(T2 - T_ref).max() <= PINOCCHIO_TOL
        assert np.abs(J2 - J_ref).max() <= PINOCCHIO_TOL
        w, grad = compiled.raw["manipulability"](q, 0.0)
        assert w[0, 0] == pytest.approx(math.sqrt(np.linalg.det(J_ref @ J_ref.T)), rel=1e-9)


# -- robot files that reference a URDF -------------------------------------------------------

def _write_robot_file(tmp_path: Path, body: str) -> Path:
    (tmp_path / "arm.urdf").write_text(OBLIQUE_URDF)
    path = tmp_path / "arm.toml"
    path.write_text(body)
    return path


def test_robot_file_referencing_a_urdf(tmp_path):
    path = _write_robot_file(tmp_path, """
name = "oblique_arm"
urdf = "arm.urdf"
base_link = "base"
tip_link = "flange"
task_rows = ["vx", "vy", "vz"]
[units]
angle = "deg"
length = "mm"
[limits]
j3 = [-170, 170]
[tool]
xyz = [0, 0, 100]
[configurations]
q0 = [10, 20, 30, 50, -40, 60]
""")
    robot = load_robot(path)
    assert robot.name == "oblique_arm" and robot.convention == "urdf" and robot.task_rows == (0, 1, 2)
    assert robot.joints[2].qlim == pytest.approx((-math.radians(170), math.radians(170)))
    assert robot.q0 == pytest.approx([math.radians(10), math.radians(20), math.radians(30), 0.05,
                                      math.radians(-40), math.radians(60)])
    # base_link "base" drops the world->base mount; the tool adds 100 mm along the flange's z.
    full = Robot.from_urdf(tmp_path / "arm.urdf", tip_link="flange")
    mount = np.eye(4)
    mount_xyz_rpy = ((0.1, -0.2, 0.05), (0.1, 0.2, 0.3))
    from armgen.robot import rpy_matrix
    mount[:3, :3], mount[:3, 3] = rpy_matrix(*mount_xyz_rpy[1]), mount_xyz_rpy[0]
    q = robot.q0
    expected = np.linalg.inv(mount) @ full.fk(q) @ np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0.1], [0, 0, 0, 1.0]])
    assert np.abs(robot.fk(q) - expected).max() <= PINOCCHIO_TOL
    assert len(robot.sha256) == 64 and robot.sha256 != full.sha256


@pytest.mark.parametrize("body,match", [
    ('urdf = "missing.urdf"\n', "not found"),
    ('urdf = "arm.urdf"\nconvention = "standard"\n', "unknown field"),
    ('urdf = "arm.urdf"\n[limits]\nnope = [0, 1]\n', "no joint named nope"),
    ('urdf = "arm.urdf"\n[limits]\nj3 = [1, -1]\n', "empty or reversed"),
    ('urdf = "arm.urdf"\n[configurations]\nq0 = [0, 0, 0, 0, 0, 9]\n', "outside its limits"),
    ('urdf = "arm.urdf"\ntip_link = "nowhere"\n', "tip_link"),
    ('urdf = "arm.urdf"\nname = "../evil"\n', "'name' = '../evil' is not a valid name"),
])
def test_bad_robot_file_referencing_a_urdf(tmp_path, body, match):
    with pytest.raises(RobotFileError, match=match):
        load_robot(_write_robot_file(tmp_path, body))


def test_short_cartesian_plan_on_a_urdf_robot(tmp_path):
    from armgen.planning.tasks import run_task

    path = _write_robot_file(tmp_path, """
urdf = "arm.urdf"
tip_link = "tcp"
[configurations]
q0 = [0.3, 0.5, -0.4, 0.1, 0.8, 0.2]
""")
    robot = load_robot(path)
    start = robot.fk(robot.q0)
    end = start[:3, 3] + np.array([0.03, -0.02, 0.01])
    task = {"planner": "cartesian", "robot": str(path), "start": "q0",
            "path": {"type": "line", "end": end.tolist()}, "timing": {"duration": 1.0},
            "integrator": {"method": "rk4", "step": 0.01}, "method": {"name": "pinv"}}
    result = run_task(task, "urdf line")
    q_end = _final_joints(result, robot)
    reached = robot.fk(q_end)[:3, 3]
    # RK4 at 10 ms on a 37 mm line: the tracking error is integration error only.
    assert np.linalg.norm(reached - end) < 1e-6


def _final_joints(result, robot: Robot) -> np.ndarray:
    names = [next(c for c in result.columns if c.startswith(f"q{i + 1}_")) for i in range(robot.n)]
    return np.array([result.column(c)[-1] for c in names])


# -- clean errors -------------------------------------------------------------------------------

def _chain(joints: str, links: str = "<link name='a'/><link name='b'/><link name='c'/>", name: str = "r") -> str:
    return f"<robot name='{name}'>{links}{joints}</robot>"


_J1 = "<joint name='j1' type='revolute'><parent link='a'/><child link='b'/><limit lower='-1' upper='1'/></joint>"
_J2 = "<joint name='j2' type='revolute'><parent link='b'/><child link='c'/><limit lower='-1' upper='1'/></joint>"

BAD_URDFS = [
    ("<robot name='r'><link name='a'>", None, "not well-formed"),
    ('<?xml version="1.0"?><!DOCTYPE r [<!ENTITY x "y">]><robot name="r"/>', None, "DOCTYPE"),
    ("<model name='r'/>", None, "expected <robot>"),
    ("<robot><link name='a'/></robot>", None, "no 'name'"),
    (_chain(_J1 + _J2.replace("revolute'>", "revolute'><mimic joint='j1'/>")), None, "joint 'j2'.*mimic"),
    (_chain(_J1 + _J2.replace("'revolute'", "'floating'")), None, "joint 'j2'.*floating"),
    (_chain(_J1 + _J2.replace("'revolute'", "'planar'")), None, "joint 'j2'.*planar"),
    (_chain(_J1 + _J2.replace("'revolute'", "'hinge'")), None, "joint 'j2'.*not a URDF joint type"),
    (_chain(_J1 + _J2.replace("link='c'", "link='ghost'")), None, "joint 'j2'.*child link 'ghost' is not defined"),
    (_chain(_J1 + _J2.replace("'b'", "'a'")), None, "link 'a': branches into joints j1, j2"),
    (_chain(_J1 + _J2 + _J2.replace("j2", "j3").replace("'b'", "'c'").replace("'c'/>", "'a'/>", 1)), None,
     "loop|already has parent joint"),
    (_chain(_J1 + _J2.replace("<limit", "<origin xyz='0 nan 0'/><limit")), None, "joint 'j2' <origin>.*finite"),
    (_chain(_J1 + _J2.replace("<limit", "<origin xyz='0 0'/><limit")), None, "must be 3 numbers"),
    (_chain(_J1 + _J2.replace("<limit lower='-1' upper='1'/>", "")), None, "joint 'j2'.*needs <limit"),
    (_chain(_J1 + _J2.replace("lower='-1'", "lower='2'")), None, "joint 'j2' <limit>.*not below"),
    (_chain(_J1 + _J2.replace("<limit", "<axis xyz='0 0 0'/><limit")), None, "zero vector"),
    (_chain(_J1 + _J2), "nowhere", "tip_link.*'nowhere' is not defined"),
    (_chain(_J1.replace("'revolute'", "'fixed'") + _J2.replace("'revolute'", "'fixed'")), None, "no revolute"),
    (_chain(_J1 + _J2, links="<link name='a'/><link name='b'/><link name='c'/><link name='b'/>"), None,
     "link 'b'.*defined twice"),
]


@pytest.mark.parametrize("text,tip,match", BAD_URDFS, ids=[case[2].split(".*")[-1][:24] for case in BAD_URDFS])
def test_bad_urdf_is_one_clean_error(tmp_path, text, tip, match):
    path = tmp_path / "bad.urdf"
    path.write_text(text)
    with pytest.raises(RobotFileError, match=match) as info:
        Robot.from_urdf(path, tip_link=tip)
    assert str(path) in str(info.value)


def test_tip_above_base_and_billion_laughs(tmp_path):
    path = tmp_path / "r.urdf"
    path.write_text(_chain(_J1 + _J2))
    with pytest.raises(RobotFileError, match="not below base link"):
        Robot.from_urdf(path, base_link="b", tip_link="a")
    laughs = ('<?xml version="1.0"?><!DOCTYPE lolz [<!ENTITY lol "lol"><!ENTITY lol2 "&lol;&lol;&lol;">]>'
              '<robot name="&lol2;"/>')
    path.write_text(laughs)
    with pytest.raises(RobotFileError, match="DOCTYPE"):
        Robot.from_urdf(path)
    with pytest.raises(RobotFileError, match="not found"):
        Robot.from_urdf(tmp_path / "absent.urdf")


_VALID = _chain(_J1 + _J2.replace("<limit", "<origin xyz='0.1 0 0.2' rpy='0 0.5 0'/><axis xyz='0 1 0'/><limit"))
_ATTRIBUTE_VALUES = st.one_of(
    st.sampled_from(["nan", "inf", "-inf", "1e400", "", " ", "1 2", "0 0 0", "1 2 3 4", "x", "fixed", "floating",
                     "planar", "continuous", "prismatic", "a", "b", "c", "ghost", "&amp;", "1,2,3"]),
    st.text(max_size=12),
)


@settings(derandomize=True, max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.data())
def test_fuzzed_urdf_loads_or_fails_cleanly(tmp_path_factory, data):
    text = _VALID
    kind = data.draw(st.sampled_from(["attribute", "cut", "delete", "garbage"]))
    if kind == "attribute":
        quoted = [i for i, ch in enumerate(text) if ch == "'"]
        k = data.draw(st.integers(0, len(quoted) // 2 - 1))
        start, stop = quoted[2 * k] + 1, quoted[2 * k + 1]
        value = data.draw(_ATTRIBUTE_VALUES).replace("'", "").replace("<", "")
        text = text[:start] + value + text[stop:]
    elif kind == "cut":
        text = text[:data.draw(st.integers(0, len(text)))]
    elif kind == "delete":
        a = data.draw(st.integers(0, len(text)))
        text = text[:a] + text[a + data.draw(st.integers(1, 40)):]
    else:
        text = data.draw(st.text(max_size=200))
    path = tmp_path_factory.mktemp("fuzz") / "f.urdf"
    path.write_text(text, encoding="utf-8", errors="surrogatepass")
    try:
        robot = Robot.from_urdf(path)
    except RobotFileError:
        return
    assert robot.n >= 1 and np.all(np.isfinite(robot.fk(robot.qmid)))


@pytest.mark.slow
def test_verify_with_firmware_replay_on_a_urdf_robot(tmp_path, monkeypatch):
    """gen → plan → verify (fresh, compile, callbacks, C-backend replay, host firmware) for a
    robot file that references a URDF, in a folder of the user's (./generated/<name>/ by default)."""
    import armgen

    require_tool("gcc")
    monkeypatch.chdir(tmp_path)
    generated = tmp_path / "generated"
    path = _write_robot_file(tmp_path, """
name = "oblique_arm"
urdf = "arm.urdf"
tip_link = "tcp"
[configurations]
q0 = [0.3, 0.5, -0.4, 0.1, 0.8, 0.2]
""")
    robot = armgen.load_robot(path)
    armgen.generate(robot, out=generated / robot.name)
    end = robot.fk(robot.q0)[:3, 3] + np.array([0.03, -0.02, 0.01])
    plan = armgen.plan({"planner": "cartesian", "robot": str(path), "start": "q0",
                        "path": {"type": "line", "end": end.tolist()}, "timing": {"duration": 1.0},
                        "integrator": {"method": "euler", "step": 0.005}, "method": {"name": "pinv"}})
    csv_path, _ = plan.save(tmp_path / "line.csv")
    report = armgen.verify(path, plan=csv_path, samples=200, precision="double")
    assert report.passed, str(report)
    assert [s.name for s in report.stages] == ["fresh", "compile", "callbacks", "replay"]
    assert any("host firmware" in str(row[0]) for row in report.stages[-1].rows)


def test_show_and_robots_cli_text_and_json(tmp_path):
    from click.testing import CliRunner

    from armgen.cli.main import cli

    path = tmp_path / "oblique.urdf"
    path.write_text(OBLIQUE_URDF)
    runner = CliRunner()
    text = runner.invoke(cli, ["show", str(path)])
    assert text.exit_code == 0, text.output
    assert "URDF chain" in text.output and "axis=[0.0, -1.0, 0.0]" in text.output
    assert "tool: xyz = [0.0, 0.0, 120.0] mm, rpy = [0.0, 0.0, -45.0] deg" in text.output
    data = json.loads(runner.invoke(cli, ["show", str(path), "--json"]).output)
    assert data["urdf"]["tip_link"] == "tcp" and len(data["joints"]) == 6
    assert data["joints"][1]["axis"] == pytest.approx(np.array([0.3, 0.5, 0.8]) / np.linalg.norm([0.3, 0.5, 0.8]))
    assert data["tool"]["rpy"] == pytest.approx([0.0, 0.0, -math.pi / 4])
    dh = json.loads(runner.invoke(cli, ["show", "panda", "--json"]).output)
    assert dh["convention"] == "modified" and dh["joints"][6]["a"] == pytest.approx(0.088)
    listing = json.loads(runner.invoke(cli, ["robots", "--json"]).output)
    assert {"panda", "planar3"} <= {r["name"] for r in listing}
    bad = runner.invoke(cli, ["show", str(tmp_path / "missing.urdf")])
    assert bad.exit_code == 2 and "not found" in bad.output


# A flange with two tool frames on fixed joints, and a camera frame hung off link b.
_FLANGE = ("<link name='a'/><link name='b'/><link name='c'/><link name='tool0'/><link name='ee_link'/>"
           "<link name='camera'/>")
_TOOLS = ("<joint name='to_tool0' type='fixed'><parent link='c'/><child link='tool0'/></joint>"
          "<joint name='to_ee' type='fixed'><parent link='c'/><child link='ee_link'/></joint>")
_CAMERA = "<joint name='to_camera' type='fixed'><parent link='b'/><child link='camera'/></joint>"


def test_branch_error_lists_the_leaf_links_and_fixed_only_branches_are_ignored(tmp_path):
    path = tmp_path / "tools.urdf"
    path.write_text(_chain(_J1 + _CAMERA + _J2 + _TOOLS, links=_FLANGE))
    # the camera branch at b leads only through a fixed joint to a leaf frame: ignored; the two
    # tool frames on c are a real choice, named in the error
    with pytest.raises(RobotFileError, match="link 'c': branches into joints to_tool0, to_ee, leading to the "
                                             "leaf links ee_link, tool0; choose the chain's end with tip_link"):
        Robot.from_urdf(path)
    robot = Robot.from_urdf(path, tip_link="tool0")
    assert [j.name for j in robot.joints] == ["j1", "j2"] and robot.urdf["tip_link"] == "tool0"
    path.write_text(_chain(_J1 + _CAMERA + _J2, links=_FLANGE.replace("<link name='tool0'/><link name='ee_link'/>",
                                                                      "")))
    assert Robot.from_urdf(path).urdf["tip_link"] == "c"
    # a moving branch at a (two arms) is a choice too, with every leaf below it listed
    path.write_text(_chain(_J1 + _J2 + _J1.replace("j1", "k1").replace("'b'", "'camera'"),
                           links=_FLANGE.replace("<link name='tool0'/><link name='ee_link'/>", "")))
    with pytest.raises(RobotFileError, match="link 'a': branches into joints j1, k1, leading to the leaf links "
                                             "c, camera"):
        Robot.from_urdf(path)


def test_show_names_continuous_joints_given_half_turn_limits(tmp_path):
    path = tmp_path / "oblique.urdf"
    path.write_text(OBLIQUE_URDF)
    robot = Robot.from_urdf(path, tip_link="tcp")
    assert robot.joints[2].qlim == (-math.pi, math.pi)
    assert "continuous in the URDF, given ±180 deg here: j3" in robot.show_text()
    (tmp_path / "oblique.toml").write_text('urdf = "oblique.urdf"\ntip_link = "tcp"\n[limits]\nj3 = [0, 6.283]\n')
    bounded = load_robot(tmp_path / "oblique.toml")
    assert bounded.joints[2].qlim == (0.0, 6.283) and "given ±180 deg" not in bounded.show_text()
