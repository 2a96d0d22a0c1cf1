"""`armgen firmware` (issue 37): the project of a URDF arm works as its README says (1), nothing
outside --out is written or deleted through a symbolic link (10), and only plans within the
joint limits that their recorded task reproduces are shipped (13)."""

from __future__ import annotations

import hashlib
import json
import shutil
import tomllib
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from armgen.cli.main import cli
from armgen.firmware.project import WRAPPER_COMMENT, demo_task, task_toml
from armgen.planning.result import read_plan
from armgen.robot import load_robot

REPO = Path(__file__).resolve().parent.parent
EXAMPLES = REPO / "armgen" / "data" / "examples"
URDF = REPO / "tests" / "data" / "iiwa7.urdf"  # a 7-DOF URDF arm armgen does not bundle
# A start away from the limits and from the stretched (singular) zero pose of the URDF arm.
URDF_START = [0.0, 0.6, 0.0, -1.2, 0.0, 0.9, 0.0]


def run(*args: str, cwd: Path | None = None, monkeypatch=None):
    if cwd is not None:
        monkeypatch.chdir(cwd)
    return CliRunner().invoke(cli, [str(a) for a in args])


def tree(root: Path) -> dict[str, bytes]:
    """Every file under ``root`` (not following links) with its bytes; links as their target."""
    out = {}
    for path in sorted(root.rglob("*")):
        if path.is_symlink():
            out[path.relative_to(root).as_posix()] = b"-> " + str(path.readlink()).encode()
        elif path.is_file():
            out[path.relative_to(root).as_posix()] = path.read_bytes()
    return out


# -- 1. a URDF arm's project: the README's commands ----------------------------------------------

def _wrapper(tmp_path: Path) -> Path:
    """A robot file in its own folder that references the URDF in another one (``../urdf/``)."""
    (tmp_path / "urdf").mkdir()
    shutil.copy(URDF, tmp_path / "urdf" / "iiwa7.urdf")
    (tmp_path / "robots").mkdir()
    wrapper = tmp_path / "robots" / "iiwa7.toml"
    wrapper.write_text('# my arm\nurdf = "../urdf/iiwa7.urdf"\nname = "iiwa7_job"\n'
                       'description = "a \\"quoted\\" name,\\ttab and DEL \\u007f"\n'
                       f'[configurations]\nq0 = {URDF_START}\n')
    return wrapper


def _joint_start_task(tmp_path: Path, robot_file: Path) -> Path:
    """A 5 cm line of the tool from URDF_START (a joint vector: a URDF names no configuration)."""
    robot = load_robot(robot_file)
    task = demo_task(robot, str(robot_file))
    task["start"] = URDF_START
    task["path"]["end"] = (robot.fk(np.array(URDF_START))[:3, 3] + [0.0, 0.0, 0.05]).tolist()
    path = tmp_path / "line.toml"
    path.write_text(task_toml(task, "a line of the URDF arm"))
    return path


def _readme_commands_work(project: Path, robot_file: str, monkeypatch, joints: int = 7) -> None:
    """The README's commands that need no compiler: show, plan the demo again, regenerate."""
    readme = (project / "README.md").read_text()
    for command in (f"armgen show {robot_file}", "armgen plan demo/demo.toml -o replan.csv",
                    f"armgen firmware {robot_file} --task demo/demo.toml --out .",
                    f"armgen verify {robot_file} -o generated --plan demo/plan.csv --run run.csv"):
        assert command in readme, command
    out = run("show", robot_file, cwd=project, monkeypatch=monkeypatch)
    assert out.exit_code == 0 and f"{joints} joints" in out.output, out.output
    out = run("plan", "demo/demo.toml", "-o", "replan.csv", cwd=project, monkeypatch=monkeypatch)
    assert out.exit_code == 0, out.output
    assert np.array_equal(read_plan(project / "replan.csv").data, read_plan(project / "demo" / "plan.csv").data)
    meta = json.loads((project / "demo" / "plan.json").read_text())
    robot = load_robot(project / robot_file)
    assert meta["robot"]["file"] == robot_file and meta["robot"]["sha256"] == robot.sha256
    manifest = json.loads((project / "generated" / "manifest.json").read_text())
    assert manifest["robot"]["sha256"] == robot.sha256 and manifest["robot"]["file"] == robot_file
    before = tree(project)
    out = run("firmware", robot_file, "--task", "demo/demo.toml", "--out", ".", cwd=project, monkeypatch=monkeypatch)
    assert out.exit_code == 0, out.output
    after = tree(project)
    assert after.keys() == before.keys()
    for name in (robot_file, "generated/manifest.json", "demo/plan.csv", "task/robot_fw.c"):
        assert after[name] == before[name], f"regenerating in place changed {name}"
    assert after.get("robot.urdf") == before.get("robot.urdf")


def test_urdf_project_holds_the_urdf_byte_for_byte(tmp_path, monkeypatch):
    task = _joint_start_task(tmp_path, URDF)
    out = run("firmware", URDF, "--task", task, "--out", tmp_path / "fw")
    assert out.exit_code == 0, out.output
    project = tmp_path / "fw"
    assert (project / "robot.urdf").read_bytes() == URDF.read_bytes() and not (project / "robot.toml").exists()
    assert tomllib.loads((project / "demo" / "demo.toml").read_text())["robot"] == "../robot.urdf"
    _readme_commands_work(project, "robot.urdf", monkeypatch)


def test_urdf_wrapper_project_copies_the_urdf_it_references(tmp_path, monkeypatch):
    wrapper = _wrapper(tmp_path)
    out = run("firmware", wrapper, "--out", tmp_path / "fw")
    assert out.exit_code == 0, out.output
    project = tmp_path / "fw"
    assert (project / "robot.urdf").read_bytes() == URDF.read_bytes()
    text = (project / "robot.toml").read_text()
    assert text.startswith(WRAPPER_COMMENT + "\n")
    expected = dict(tomllib.loads(wrapper.read_text()), urdf="robot.urdf")
    assert tomllib.loads(text) == expected  # every field as written, quotes, tab and DEL included
    mine, theirs = load_robot(wrapper), load_robot(project / "robot.toml")
    assert theirs.name == mine.name == "iiwa7_job"
    q = np.array(URDF_START)
    assert np.array_equal(theirs.fk(q), mine.fk(q)) and np.array_equal(theirs.qmax, mine.qmax)
    _readme_commands_work(project, "robot.toml", monkeypatch)


def test_dh_project_readme_commands_work_alike(tmp_path, monkeypatch):
    """The same README commands for a DH robot file (robot.toml, byte for byte)."""
    out = run("firmware", REPO / "tests" / "data" / "baxter_arm.toml", "--out", tmp_path / "fw")
    assert out.exit_code == 0, out.output
    project = tmp_path / "fw"
    assert (project / "robot.toml").read_bytes() == (REPO / "tests" / "data" / "baxter_arm.toml").read_bytes()
    assert not (project / "robot.urdf").exists()
    _readme_commands_work(project, "robot.toml", monkeypatch)


def test_demo_of_a_urdf_without_a_start_names_the_wrapper_fix(tmp_path):
    """The URDF arm's middle of the limits is its stretched, singular pose: no demo line; the
    message says how to give a q0, which a URDF cannot hold."""
    out = run("firmware", URDF, "--out", tmp_path / "fw")
    assert out.exit_code == 3, out.output
    assert 'urdf = "iiwa7.urdf"' in out.output and "[configurations] q0" in out.output
    assert not (tmp_path / "fw").exists()


# -- 10. nothing outside --out: no writing or deleting through a link ---------------------------

@pytest.fixture(scope="module")
def project(tmp_path_factory):
    out = tmp_path_factory.mktemp("fw") / "project"
    result = run("firmware", "planar3", "--out", out)
    assert result.exit_code == 0, result.output
    return out


def _copy(project: Path, tmp_path: Path) -> Path:
    return Path(shutil.copytree(project, tmp_path / "project"))


def _refused(out: Path, tmp_path: Path, link: Path, outside: Path) -> None:
    """A re-run refuses (exit 4, naming the link) and leaves both folders as they were."""
    before_project, before_outside = tree(out), tree(outside)
    result = run("firmware", "planar3", "--out", out)
    assert result.exit_code == 4, result.output
    assert str(link) in result.output and "symbolic link" in result.output and "nothing was written" in result.output
    assert tree(outside) == before_outside, "armgen wrote or deleted outside --out"
    assert tree(out) == before_project
    assert not [p for p in out.parent.iterdir() if p.name.startswith(".armgen-firmware-")], "staging folder left"


@pytest.mark.parametrize("folder", ["controller", "generated", "demo", "task"])
def test_a_linked_sub_folder_is_refused(project, tmp_path, folder):
    out = _copy(project, tmp_path)
    outside = tmp_path / "elsewhere"
    shutil.move(out / folder, outside)  # the same files, digests and all, now outside the project
    (out / folder).symlink_to(outside, target_is_directory=True)
    (outside / "mine.txt").write_text("keep")
    _refused(out, tmp_path, out / folder, outside)


def test_a_manifest_entry_through_a_link_deletes_nothing(project, tmp_path):
    """The audit's case: ``link → DIR`` and a manifest entry ``link/x`` with x's SHA-256: the old
    code deleted DIR/x (an owned file the new project no longer has)."""
    out = _copy(project, tmp_path)
    outside = tmp_path / "DIR"
    outside.mkdir()
    (outside / "x").write_text("the user's file")
    (out / "link").symlink_to(outside, target_is_directory=True)
    manifest = json.loads((out / ".armgen-firmware").read_text())
    manifest["files"]["link/x"] = hashlib.sha256(b"the user's file").hexdigest()
    (out / ".armgen-firmware").write_text(json.dumps(manifest))
    _refused(out, tmp_path, out / "link", outside)
    assert (outside / "x").read_text() == "the user's file"


def test_a_linked_file_is_refused(project, tmp_path):
    out = _copy(project, tmp_path)
    outside = tmp_path / "notes"
    outside.mkdir()
    shutil.move(out / "README.md", outside / "README.md")
    (out / "README.md").symlink_to(outside / "README.md")
    _refused(out, tmp_path, out / "README.md", outside)


def test_a_linked_manifest_is_refused(project, tmp_path):
    out = _copy(project, tmp_path)
    outside = tmp_path / "meta"
    outside.mkdir()
    shutil.move(out / ".armgen-firmware", outside / "m.json")
    (out / ".armgen-firmware").symlink_to(outside / "m.json")
    _refused(out, tmp_path, out / ".armgen-firmware", outside)


def test_out_itself_may_be_a_link(project, tmp_path):
    """--out is the user's own choice of folder: a link to it is followed (docs/firmware.md)."""
    real = _copy(project, tmp_path)
    alias = tmp_path / "alias"
    alias.symlink_to(real, target_is_directory=True)
    result = run("firmware", "planar3", "--out", alias)
    assert result.exit_code == 0, result.output
    assert (real / "generated" / "planar3.c").is_file()


# -- 13. the firmware ships only plans within the limits that their task reproduces -------------

def test_a_task_that_leaves_the_limits_is_refused_even_when_reported(tmp_path):
    """The pinv circle leaves joint j6's limit at 17.84 s; its task writes such plans
    (limits = "report"): the firmware refuses it (exit 3) and writes nothing."""
    text = (EXAMPLES / "modular8_circle_pinv.toml").read_text()
    assert 'limits = "report"' in text
    task = tmp_path / "circle.toml"
    task.write_text(text.replace("duration = 250", "duration = 40"))
    out = run("firmware", "modular8", "--task", task, "--out", tmp_path / "fw")
    assert out.exit_code == 3, out.output
    assert "leaves the joint limits" in out.output and "j6" in out.output and "never to run it" in out.output
    assert not (tmp_path / "fw").exists()


def _plan(tmp_path: Path, task: Path, name: str) -> Path:
    plan = tmp_path / name
    out = run("plan", task, "-o", plan)
    assert out.exit_code == 0, out.output
    return plan


def _line_task(tmp_path: Path) -> Path:
    """The built-in demo's line of planar3 as a task file (a cartesian plan: Euler steps)."""
    task = tmp_path / "line.toml"
    task.write_text(task_toml(demo_task(load_robot("planar3"), "planar3"), "a line"))
    return task


def test_a_hand_edited_sample_of_a_sampled_plan_is_refused(tmp_path):
    plan = _plan(tmp_path, EXAMPLES / "snake_planar.toml", "snake.csv")
    lines = plan.read_text().splitlines()
    header, row = lines[0].split(","), lines[5].split(",")
    column = next(k for k, name in enumerate(header) if name.endswith("_rad"))
    row[column] = repr(float(row[column]) + 10.0)  # +10 rad: it would land in the flash table
    lines[5] = ",".join(row)
    plan.write_text("\n".join(lines) + "\n")
    out = run("firmware", "snake12", "--plan", plan, "--out", tmp_path / "fw")
    assert out.exit_code == 5, out.output
    assert f"line 6, column '{header[column]}'" in out.output and "edited" in out.output
    assert not (tmp_path / "fw").exists()


def test_a_doubled_integrator_step_in_plan_json_is_refused(tmp_path):
    plan = _plan(tmp_path, _line_task(tmp_path), "line.csv")
    meta_path = plan.with_suffix(".json")
    meta = json.loads(meta_path.read_text())
    meta["task"]["integrator"]["step"] *= 2
    meta_path.write_text(json.dumps(meta))
    out = run("firmware", "planar3", "--plan", plan, "--out", tmp_path / "fw")
    assert out.exit_code == 5, out.output
    assert "does not give this plan" in out.output and "samples" in out.output
    assert not (tmp_path / "fw").exists()


def test_the_project_uses_the_replanned_plan_not_the_files_metadata(tmp_path):
    """An edit of plan.json outside its task changes nothing the firmware runs: the project's
    plan is the task planned again."""
    plan = _plan(tmp_path, _line_task(tmp_path), "line.csv")
    meta_path = plan.with_suffix(".json")
    meta = json.loads(meta_path.read_text())
    meta["integrator"]["step_s"] *= 2
    meta_path.write_text(json.dumps(meta))
    out = run("firmware", "planar3", "--plan", plan, "--out", tmp_path / "fw")
    assert out.exit_code == 0, out.output
    shipped = json.loads((tmp_path / "fw" / "demo" / "plan.json").read_text())
    assert shipped["integrator"]["step_s"] == meta["task"]["integrator"]["step"]
    assert np.array_equal(read_plan(tmp_path / "fw" / "demo" / "plan.csv").data, read_plan(plan).data)
