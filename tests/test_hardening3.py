"""Hardening, third round (issue 27): projects and sweeps lose nothing, output sets are
all-or-nothing, URDF robots obey the robot-file bounds, caps and clean errors everywhere."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from armgen.cli.main import cli


def run(*args: str):
    return CliRunner().invoke(cli, list(args))


def tree(root: Path) -> dict[str, bytes]:
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


# -- 2. `armgen firmware` over its own project keeps the user's files --------------------------

@pytest.fixture(scope="module")
def project(tmp_path_factory):
    out = tmp_path_factory.mktemp("fw") / "project"
    result = run("firmware", "planar3", "--out", str(out))
    assert result.exit_code == 0, result.output
    return out


def copy_project(project: Path, tmp_path: Path) -> Path:
    import shutil

    return Path(shutil.copytree(project, tmp_path / "project"))


def test_firmware_update_keeps_user_files_and_build(project, tmp_path):
    out = copy_project(project, tmp_path)
    (out / "NOTES.md").write_text("my notes")
    (out / "build").mkdir()
    (out / "build" / "CMakeCache.txt").write_text("cache")
    (out / "controller" / "my_filter.c").write_text("int my_filter;")
    stale = out / "generated" / "planar3.c"
    stale.unlink()  # an owned file the user deleted is simply written again
    result = run("firmware", "planar3", "--out", str(out))
    assert result.exit_code == 0, result.output
    assert (out / "NOTES.md").read_text() == "my notes"
    assert (out / "build" / "CMakeCache.txt").read_text() == "cache"
    assert (out / "controller" / "my_filter.c").read_text() == "int my_filter;"
    assert stale.is_file()
    manifest = json.loads((out / ".armgen-firmware").read_text())
    assert "NOTES.md" not in manifest["files"] and "generated/planar3.c" in manifest["files"]


def test_firmware_refuses_to_overwrite_an_edited_file(project, tmp_path):
    out = copy_project(project, tmp_path)
    (out / "README.md").write_text("my edits")
    (out / "demo" / "demo.toml").write_text("# mine")
    before = tree(out)
    result = run("firmware", "planar3", "--out", str(out))
    assert result.exit_code == 4, result.output
    assert "README.md" in result.output and "demo/demo.toml" in result.output
    assert tree(out) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["project"], "no staging folder left"


def test_firmware_refuses_a_user_file_where_it_would_write(project, tmp_path):
    out = copy_project(project, tmp_path)
    manifest = json.loads((out / ".armgen-firmware").read_text())
    del manifest["files"]["controller/fw_csv.c"]  # as if the user had added the file
    (out / ".armgen-firmware").write_text(json.dumps(manifest))
    result = run("firmware", "planar3", "--out", str(out))
    assert result.exit_code == 4 and "controller/fw_csv.c" in result.output, result.output


def test_firmware_other_robot_replaces_only_its_own_files(project, tmp_path):
    out = copy_project(project, tmp_path)
    (out / "NOTES.md").write_text("my notes")
    result = run("firmware", "modular8", "--out", str(out))
    assert result.exit_code == 0, result.output
    assert not (out / "generated" / "planar3.c").exists(), "the old robot's generated code is the command's own"
    assert (out / "generated" / "modular8.c").is_file() and (out / "NOTES.md").read_text() == "my notes"
