"""Hardening (issue 11, input side): names are identifiers, schemas reject nonsense with a
suggestion, outputs appear all together or not at all with umask permissions, resource caps
before work, exit codes, and the robust axis–angle of line paths (UR5 hold-orientation line,
symbolic vs compiled C)."""

from __future__ import annotations

import errno
import fcntl
import json
import math
import multiprocessing
import os
import stat
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from armgen import fileio
from armgen.cli.main import cli
from armgen.errors import OutputError, RobotFileError, TaskFileError
from armgen.planning.toolpath.paths import LinePath, _axis_angle
from armgen.planning.result import read_plan
from armgen.planning.tasks import ResourceCaps, load_task, run_task
from armgen.robot import BUNDLED_DIR, parse_robot
from armgen.schemas import MAX_NESTING_DEPTH

EXAMPLES = Path(__file__).resolve().parents[1] / "armgen" / "data" / "examples"
PLANAR3 = (BUNDLED_DIR / "planar3.toml").read_text()
# Agreement of a plan on the CasADi interpreter and on the compiled C: the same double
# arithmetic in a different order, ~1e-15 per step over a few hundred steps (issue 11's bound).
BACKEND_AGREEMENT_RAD = 1e-9

# Standard UR5 DH parameters (Universal Robots, "DH parameters for calculations of kinematics
# and dynamics"): d1, a2, a3, d4, d5, d6 in m; alpha in deg.
UR5_TOML = """
name = "ur5"
description = "Universal Robots UR5 (standard DH)"
convention = "standard"
[units]
length = "m"
angle = "deg"
""" + "".join(f"""
[[joints]]
name = "j{i + 1}"
type = "revolute"
a = {a}
d = {d}
alpha = {alpha}
qlim = [-360, 360]
""" for i, (a, d, alpha) in enumerate([(0, 0.089159, 90), (-0.425, 0, 0), (-0.39225, 0, 0), (0, 0.10915, 90),
                                        (0, 0.09465, -90), (0, 0.0823, 0)])) + """
[configurations]
q0 = [10, -100, 80, -70, -90, 20]
"""


def run(*args: str):
    return CliRunner().invoke(cli, list(args))


# -- names ------------------------------------------------------------------------------

@pytest.mark.parametrize("name", ["../../../../elsewhere/x", "/abs/path", ".", "x */ int injected = 42; /*",
                                  "x" * 300, "1abc", "", "a-b", "naïve"])
def test_robot_and_joint_names_must_be_identifiers(name):
    with pytest.raises(RobotFileError, match=r"two\.toml: file: field 'name' .*not a valid name.*letter then"):
        parse_robot(PLANAR3.replace('name = "planar3"', f"name = {json.dumps(name)}"), "two.toml")
    with pytest.raises(RobotFileError, match=r"two\.toml: joint 1: field 'name' .*not a valid name"):
        parse_robot(PLANAR3.replace('name = "j1"', f"name = {json.dumps(name)}"), "two.toml")


def test_gen_never_writes_outside_its_folder(tmp_path):
    robot = tmp_path / "evil.toml"
    robot.write_text(PLANAR3.replace('name = "planar3"', 'name = "../../../../elsewhere/x"'))
    out = run("gen", str(robot))
    assert out.exit_code == 2 and "not a valid name" in out.output
    robot.write_text(PLANAR3.replace("a = 0.5", "a = 1e300"))
    out = run("gen", str(robot), "--out", str(tmp_path / "gen"))
    assert out.exit_code == 2 and "beyond" in out.output and "Traceback" not in out.output
    assert not (tmp_path / "gen").exists()


# -- schemas ----------------------------------------------------------------------------

@pytest.mark.parametrize("override, message", [
    ("integrator.stepp=0.5", r"'integrator' has unknown field\(s\) stepp \(integrator.stepp; did you mean `step`\?\)"),
    ("clik_gian=10", r"unknown field\(s\) clik_gian \(did you mean `integrator.clik_gain`\?\)"),
    ("method.rho_RR=1", r"did you mean `rho_R`"),
    ('planner=["ptp"]', r"field 'planner' = \['ptp'\] is not one of"),
    ('units.length=["mm"]', r"field 'units.length' = \['mm'\] is not one of m, mm"),
    ("integrator.output_every=0.5", r"'integrator.output_every' must be an integer, got float 0.5"),
    ("integrator.when=1979-05-27", r"unknown field\(s\) when"),
    ("timing.duration=-1", r"'timing.duration' = -1 must be > 0"),
    ("path.end=[1, 2]", r"'path.end' must have at least 3 entries, got 2"),
    ("timing.duration=nan", r"'timing.duration' is nan; give a finite number"),
])
def test_task_schema_errors_name_file_field_and_fix(override, message, tmp_path):
    out = run("plan", str(EXAMPLES / "modular8_circle_pinv.toml"), "-o", str(tmp_path / "p.csv"), "--set", override)
    assert out.exit_code == 2, out.output
    assert "modular8_circle_pinv.toml" in out.output
    assert __import__("re").search(message, out.output), out.output
    assert list(tmp_path.iterdir()) == []


def test_sub_table_typos_are_caught_in_every_planner():
    for example, override in [("modular8_fault_circle_gpm.toml", "fault.tme=1"),
                              ("modular8_wgpm_demo.toml", "method.criteria.zghal.k_hii=1"),
                              ("ptp_single_joint.toml", "timing.omega_maxx=1"),
                              ("snake_planar.toml", "motion.vv=1")]:
        task, _ = load_task(EXAMPLES / example)
        key, value = override.split("=")
        *parents, leaf = key.split(".")
        node = task
        for part in parents:
            node = node[part]
        node[leaf] = float(value)
        with pytest.raises(TaskFileError, match=r"unknown field\(s\) .*did you mean"):
            run_task(task, example)


def test_toml_nesting_and_size_are_bounded(tmp_path):
    deep = tmp_path / "deep.toml"
    deep.write_text("a = " + "[" * 500 + "]" * 500)
    out = run("plan", str(deep))
    assert out.exit_code == 2 and f"deeper than {MAX_NESTING_DEPTH}" in out.output
    out = run("show", str(deep))
    assert out.exit_code == 2 and f"deeper than {MAX_NESTING_DEPTH}" in out.output
    big = tmp_path / "big.toml"
    big.write_text("# " + "x" * (2 << 20))
    out = run("plan", str(big))
    assert out.exit_code == 2 and "larger than" in out.output


def test_schema_command_prints_json_schema():
    out = run("schema", "robot")
    assert out.exit_code == 0
    robot = json.loads(out.output)
    dh, urdf = (robot["$defs"][ref["$ref"].rsplit("/", 1)[1]] for ref in robot["anyOf"])
    assert set(dh["required"]) == {"name", "convention", "joints"} and urdf["required"] == ["urdf"]
    assert dh["properties"]["name"]["pattern"].startswith("^[A-Za-z]")
    assert dh["additionalProperties"] is False and urdf["additionalProperties"] is False
    out = run("schema", "task", "--planner", "cartesian")
    task = json.loads(out.output)
    assert set(task["properties"]) >= {"planner", "robot", "path", "timing", "integrator"}
    assert task["$defs"]["Integrator"]["additionalProperties"] is False
    out = run("schema", "task")
    assert out.exit_code == 0 and len(json.loads(out.output)["oneOf"]) == 5


# -- resource caps and infeasible plans --------------------------------------------------

def test_step_cap_fails_before_work_and_names_the_option(tmp_path):
    out = run("plan", str(EXAMPLES / "modular8_circle_pinv.toml"), "-o", str(tmp_path / "p.csv"),
              "--set", "integrator.step=1e-5")
    assert out.exit_code == 2 and "cap" in out.output and "--max-steps" in out.output
    out = run("plan", str(EXAMPLES / "modular8_circle_pinv.toml"), "-o", str(tmp_path / "p.csv"),
              "--set", "timing.duration=1e308", "--set", "integrator.step=1e-10")
    assert out.exit_code == 2 and "'timing.duration' = 1e+308 is beyond" in out.output
    out = run("plan", str(EXAMPLES / "modular8_circle_pinv.toml"), "-o", str(tmp_path / "p.csv"),
              "--set", "timing.duration=1e6", "--set", "integrator.step=5e-324")
    assert out.exit_code == 2 and "--max-steps" in out.output
    task, _ = load_task(EXAMPLES / "ptp_single_joint.toml")
    with pytest.raises(TaskFileError, match="--max-samples"):
        run_task(task, "ptp.toml", caps=ResourceCaps(max_samples=1000))
    assert list(tmp_path.iterdir()) == []


def test_non_finite_plan_is_infeasible_and_writes_nothing(tmp_path):
    out = run("plan", str(EXAMPLES / "ptp_single_joint.toml"), "-o", str(tmp_path / "p.csv"),
              "--set", "waypoints.t=[0,5e-324,13,22,35]")
    assert out.exit_code == 3, out.output
    assert "not feasible" in out.output and list(tmp_path.iterdir()) == []


# -- garbage plans to plot -----------------------------------------------------------------

@pytest.mark.parametrize("text, message", [
    ("t_s,q1_rad\n0,1\n1,x\n", r"line 3: 'x' is not a number"),
    ("t_s,q1_rad\n0,1\n1\n", r"line 3: 1 values for 2 columns"),
    ("", r"empty plan file"),
    ("a,b\n1,2\n", r"line 1: the header"),
    ("t_s,q1_rad\n0,1\n1,nan\n", r"line 3: column 'q1_rad' is nan"),
    ("t_s,clearance_min_m\n0,-inf\n", r"line 2: column 'clearance_min_m' is -inf"),
    (b"\xff\xfe garbage", r"not UTF-8"),
])
def test_garbage_plan_csv_is_a_clean_error_with_the_line(text, message, tmp_path):
    path = tmp_path / "plan.csv"
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    out = run("plot", str(path), "-o", str(tmp_path / "x.png"))
    assert out.exit_code == 2, out.output
    assert __import__("re").search(message, out.output), out.output
    assert not (tmp_path / "x.png").exists()


def test_infinite_clearance_is_a_value_not_a_failure(tmp_path):
    """A snake task without obstacles has clearance +inf: written, read back and plotted."""
    path = tmp_path / "plan.csv"
    path.write_text("t_s,feed_m,clearance_min_m\n0,0,inf\n1,0.1,inf\n")
    assert np.isinf(read_plan(path).column("clearance_min_m")).all()


def test_garbage_plan_json_is_a_clean_error(tmp_path):
    (tmp_path / "plan.csv").write_text("t_s,q1_rad\n0,1\n1,2\n")
    for meta in ('{"planner": 5}', "[1, 2]", "{", '{"planner": "ptp", "csv": {"file": "plan.csv", "columns": ["t_s"], '
                 '"samples": 2, "angle_units": "rad"}}'):
        (tmp_path / "plan.json").write_text(meta)
        out = run("plot", str(tmp_path / "plan.csv"), "-o", str(tmp_path / "x.png"))
        assert out.exit_code == 2, (meta, out.output)
        assert "plan.json" in out.output or "plan.csv" in out.output
        assert not (tmp_path / "x.png").exists()


# -- all-or-nothing outputs ----------------------------------------------------------------

def test_file_set_appears_with_umask_permissions_also_when_regenerating(tmp_path):
    old = os.umask(0o022)
    try:
        a, b = tmp_path / "x.csv", tmp_path / "x.json"
        a.write_text("old")
        os.chmod(a, 0o600)
        fileio.write_file_set({a: "1\n", b: "{}\n"})
        assert a.read_text() == "1\n" and b.read_text() == "{}\n"
        assert stat.S_IMODE(a.stat().st_mode) == 0o644 and stat.S_IMODE(b.stat().st_mode) == 0o644
        assert sorted(p.name for p in tmp_path.iterdir()) == ["x.csv", "x.json"]  # no staging or lock left
    finally:
        os.umask(old)


def test_file_set_failures_leave_previous_files_untouched(tmp_path, monkeypatch):
    a, b = tmp_path / "x.csv", tmp_path / "x.json"
    fileio.write_file_set({a: "old csv", b: "old json"})
    calls = {"n": 0}
    real_write = os.write

    def full_disk(fd, data):
        calls["n"] += 1
        if calls["n"] == 2:  # the second file of the set hits a full disk
            raise OSError(errno.ENOSPC, "No space left on device")
        return real_write(fd, data)

    monkeypatch.setattr(fileio.os, "write", full_disk)
    with pytest.raises(OutputError, match="No space left on device.*nothing was written"):
        fileio.write_file_set({a: "new csv", b: "new json"})
    monkeypatch.undo()
    assert a.read_text() == "old csv" and b.read_text() == "old json"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.csv", "x.json"]

    def interrupted(fd, data):
        raise KeyboardInterrupt

    monkeypatch.setattr(fileio.os, "write", interrupted)
    with pytest.raises(KeyboardInterrupt):
        fileio.write_file_set({a: "new csv", b: "new json"})
    monkeypatch.undo()
    assert a.read_text() == "old csv" and sorted(p.name for p in tmp_path.iterdir()) == ["x.csv", "x.json"]


def test_plan_to_directory_read_only_folder_or_full_disk_is_exit_4(tmp_path, monkeypatch):
    task = str(EXAMPLES / "ptp_single_joint.toml")
    (tmp_path / "d.csv").mkdir()
    out = run("plan", task, "-o", str(tmp_path / "d.csv"))
    assert out.exit_code == 4 and "is a directory" in out.output
    (tmp_path / "p.csv").write_text("t_s,q1_rad\n0,1\n1,2\n")
    (tmp_path / "p.json").write_text('{"planner": "ptp"}')
    (tmp_path / "d.png").mkdir()
    out = run("plot", str(tmp_path / "p.csv"), "-o", str(tmp_path / "d.png"))
    assert out.exit_code == 4 and "is a directory" in out.output
    assert not (tmp_path / "d.json").exists()
    if os.geteuid() != 0:  # root writes into read-only folders anyway
        ro = tmp_path / "ro"
        ro.mkdir()
        ro.chmod(0o500)
        out = run("plan", task, "-o", str(ro / "p.csv"))
        assert out.exit_code == 4 and list(ro.iterdir()) == []
    def read_only(*args, **kwargs):
        raise OSError(errno.EROFS, "Read-only file system")

    with monkeypatch.context() as patch:  # as root a chmod'ed folder is still writable: simulate
        patch.setattr(fileio.tempfile, "mkdtemp", read_only)
        out = run("plan", task, "-o", str(tmp_path / "ro.csv"))
    assert out.exit_code == 4 and "Read-only file system" in out.output
    assert not (tmp_path / "ro.csv").exists()
    monkeypatch.setattr(fileio.os, "write", lambda fd, data: (_ for _ in ()).throw(OSError(errno.ENOSPC, "No space")))
    out = run("plan", task, "-o", str(tmp_path / "full.csv"))
    assert out.exit_code == 4 and "No space" in out.output
    assert not (tmp_path / "full.csv").exists() and not (tmp_path / "full.json").exists()


def _write_set_many(args: tuple[str, int]) -> None:
    folder, tag = args
    for _ in range(20):
        fileio.write_file_set({Path(folder) / "p.csv": f"{tag}\n" * 2000, Path(folder) / "p.json": f"{tag}\n"})


def _read_set_under_lock(folder: Path) -> tuple[str, str] | None:
    """The set's tags, read while holding the folder lock as a reader (no writer mid-set)."""
    fd = os.open(folder, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_SH)
        try:
            return (folder / "p.csv").read_text()[:1], (folder / "p.json").read_text()[:1]
        except FileNotFoundError:
            return None
    finally:
        os.close(fd)  # closing releases the lock


def test_concurrent_writers_never_mix_a_set(tmp_path):
    ctx = multiprocessing.get_context("fork")
    with ctx.Pool(2) as pool:
        writers = pool.map_async(_write_set_many, [(str(tmp_path), 1), (str(tmp_path), 2)])
        while not writers.ready():
            tags = _read_set_under_lock(tmp_path)
            assert tags is None or tags[0] == tags[1]
        writers.get()
    assert _read_set_under_lock(tmp_path) in (("1", "1"), ("2", "2"))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.csv", "p.json"]


# -- robust axis-angle -------------------------------------------------------------------

def test_axis_angle_matches_rodrigues_at_every_angle():
    rng = np.random.default_rng(11)
    for angle in [0.0, 1e-12, 1e-8, 0.3, 2.0, math.pi - 1e-9, math.pi]:
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        rot = np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * (k @ k)  # closed form
        got_axis, got_angle = _axis_angle(rot)
        assert got_angle == pytest.approx(angle, abs=1e-15)
        if 1e-8 <= angle < math.pi:
            np.testing.assert_allclose(got_axis, axis, atol=1e-9)


def _dh_fk(table: list[tuple[float, float, float]], q: np.ndarray) -> np.ndarray:
    """Standard-DH forward kinematics in NumPy, independent of armgen's symbolic model."""
    pose = np.eye(4)
    for (a, d, alpha), theta in zip(table, q):
        ct, st, ca, sa = math.cos(theta), math.sin(theta), math.cos(alpha), math.sin(alpha)
        pose = pose @ np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st],
                                [0, sa, ca, d], [0, 0, 0, 1]])
    return pose


def test_ur5_hold_orientation_line_is_zero_rotation_and_c_matches_symbolic(tmp_path):
    pytest.importorskip("casadi")
    from conftest import require_tool

    require_tool("gcc")
    robot_file = tmp_path / "ur5.toml"
    robot_file.write_text(UR5_TOML)
    q0 = np.radians([10, -100, 80, -70, -90, 20])
    table = [(0, 0.089159, math.pi / 2), (-0.425, 0, 0), (-0.39225, 0, 0), (0, 0.10915, math.pi / 2),
             (0, 0.09465, -math.pi / 2), (0, 0.0823, 0)]
    start = _dh_fk(table, q0)
    r0 = start[:3, :3]
    # the case issue 11 found: R0ᵀR0 is the identity only to rounding, and acos of its trace
    # is a rotation of ~1e-8 rad, far beyond the replay bound
    assert math.acos(min(1.0, (np.trace(r0.T @ r0) - 1) / 2)) > BACKEND_AGREEMENT_RAD
    line = LinePath(start[:3, 3], start[:3, 3] + [0.05, -0.05, 0.05], r0, r0)
    assert line.angle == 0.0
    for s in np.linspace(0, 1, 11):
        _, _, rot, omega = line(s)
        assert np.array_equal(rot, r0) and not omega.any()

    end = (start[:3, 3] + [0.05, -0.05, 0.05]).tolist()
    task = {"planner": "cartesian", "robot": str(robot_file), "start": "q0",
            "path": {"type": "line", "end": end, "orientation": "hold"},
            "timing": {"duration": 2.0, "law": "cubic"}, "integrator": {"step": 0.01}}
    plans = {backend: run_task(json.loads(json.dumps(task)), "ur5_line.toml", backend=backend)
             for backend in ("symbolic", "c")}
    q_cols = [c for c in plans["symbolic"].columns if c.startswith("q") and c.endswith("_rad")]
    q_sym = np.column_stack([plans["symbolic"].column(c) for c in q_cols])
    q_c = np.column_stack([plans["c"].column(c) for c in q_cols])
    assert q_sym.shape == (201, 6)
    np.testing.assert_allclose(q_sym[0], q0, atol=1e-15)
    assert np.max(np.abs(q_sym - q_c)) <= BACKEND_AGREEMENT_RAD
    # the plan holds the orientation: the final FK (NumPy) has the start rotation
    np.testing.assert_allclose(_dh_fk(table, q_sym[-1])[:3, :3], r0, atol=1e-6)
    np.testing.assert_allclose(_dh_fk(table, q_sym[-1])[:3, 3], end, atol=1e-4)
