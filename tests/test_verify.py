"""armgen verify: passes on the bundled code, and each stage fails where it should."""

import json
import shutil

import pytest
from click.testing import CliRunner

from armgen.cli.main import cli
from armgen.codegen import generate as generate_module
from armgen.robot import load_robot
from armgen.verify import pipeline
from armgen.verify.pipeline import VerifyConfig, stage_fresh, stage_replay

from test_cartesian import EXAMPLES


def test_verify_passes_with_a_replayed_plan(tmp_path):
    plan = tmp_path / "plan.csv"
    out = CliRunner().invoke(cli, ["plan", str(EXAMPLES / "modular8_circle_combined.toml"), "-o", str(plan),
                                   "--set", "path.type=line", "--set", "path.end=[-450, 400, 900]",
                                   "--set", "timing.duration=5"])
    assert out.exit_code == 0, out.output
    report = tmp_path / "verify.json"
    out = CliRunner().invoke(cli, ["verify", "modular8", "--plan", str(plan), "--samples", "300",
                                   "--report", str(report)])
    assert out.exit_code == 0, out.output
    data = json.loads(report.read_text())
    assert data["passed"] and [s["name"] for s in data["stages"]] == ["fresh", "compile", "callbacks", "replay"]
    replay = next(s for s in data["stages"] if s["name"] == "replay")
    assert replay["rows"], "the replay stage compared something"


def test_fresh_stage_names_stale_files(tmp_path, monkeypatch):
    copy = tmp_path / "generated"
    shutil.copytree(generate_module.REPO_GENERATED_DIR / "planar3", copy / "planar3")
    source = copy / "planar3" / "planar3.c"
    source.write_text(source.read_text().replace("w0", "w_0", 1))
    monkeypatch.setattr(pipeline, "REPO_GENERATED_DIR", copy)
    stage = stage_fresh(VerifyConfig(load_robot("planar3")), tmp_path)
    assert not stage.passed
    assert ["planar3.c", "stale", False] in stage.rows
    assert "armgen gen planar3" in stage.message


def test_replay_detects_a_tampered_plan(tmp_path):
    plan = tmp_path / "plan.csv"
    out = CliRunner().invoke(cli, ["plan", str(EXAMPLES / "modular8_circle_pinv.toml"), "-o", str(plan),
                                   "--set", "path.type=line", "--set", "path.end=[-450, 400, 900]",
                                   "--set", "timing.duration=2"])
    assert out.exit_code == 0, out.output
    lines = plan.read_text().splitlines()
    cells = lines[-1].split(",")
    cells[1] = repr(float(cells[1]) + 1e-6)  # q1 of the last sample, off by 1 µrad
    lines[-1] = ",".join(cells)
    plan.write_text("\n".join(lines) + "\n")
    stage = stage_replay(VerifyConfig(load_robot("modular8"), plan))
    assert not stage.passed


def test_verify_exit_code_on_failure(tmp_path, monkeypatch):
    copy = tmp_path / "generated"
    shutil.copytree(generate_module.REPO_GENERATED_DIR / "planar3", copy / "planar3")
    (copy / "planar3" / "manifest.json").write_text("{}")
    monkeypatch.setattr(pipeline, "REPO_GENERATED_DIR", copy)
    out = CliRunner().invoke(cli, ["verify", "planar3", "--samples", "50", "--precision", "double"])
    assert out.exit_code == 5 and "FAIL" in out.output
