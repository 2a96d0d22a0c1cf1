"""plan.json is versioned (``format``), old files still read, newer ones refused by name, and
the plan's summary is typed."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from armgen.errors import PlanFileError
from armgen.planning.plan_schema import PLAN_FORMAT, JointSpeed, LimitViolation
from armgen.planning.result import PlanResult, read_plan, write_plan
from armgen.planning.tasks import load_task, run_task

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    task, sha = load_task(EXAMPLES / "modular8_ptp_two_segments.toml")
    result = run_task(task, "two_segments.toml", sha)
    csv_path, json_path = write_plan(result, tmp_path_factory.mktemp("plan") / "p.csv")
    return result, csv_path, json_path


def test_plan_json_states_its_format(written):
    _, _, json_path = written
    assert json.loads(json_path.read_text())["format"] == PLAN_FORMAT == 2


def test_a_plan_json_without_format_is_read_as_format_1(written, tmp_path):
    _, csv_path, json_path = written
    old = json.loads(json_path.read_text())
    del old["format"]
    (tmp_path / "old.csv").write_bytes(csv_path.read_bytes())
    (tmp_path / "old.json").write_text(json.dumps(old))
    plan = read_plan(tmp_path / "old.csv")
    assert plan.metadata["planner"] == "ptp"
    assert plan.metadata["summary"] == old["summary"]


def test_a_newer_format_is_refused_naming_the_field(written, tmp_path):
    _, csv_path, json_path = written
    newer = json.loads(json_path.read_text())
    newer["format"] = PLAN_FORMAT + 1
    (tmp_path / "new.csv").write_bytes(csv_path.read_bytes())
    (tmp_path / "new.json").write_text(json.dumps(newer))
    with pytest.raises(PlanFileError) as err:
        read_plan(tmp_path / "new.csv")
    assert "new.json: field 'format' = 3: written by a newer armgen" in str(err.value)
    assert err.value.exit_code == 2


def test_the_summary_is_typed_and_equals_plan_json(written):
    result, _, json_path = written
    summary = result.summary
    on_disk = json.loads(json_path.read_text())["summary"]
    assert isinstance(summary.joint_speed, JointSpeed)
    assert summary.joint_speed.max_speed_ratio == on_disk["joint_speed"]["max_speed_ratio"]
    assert summary.run_time_s == on_disk["run_time_s"] > 0


def test_limit_violations_are_typed(tmp_path):
    violation = {"joint": "j6", "first_t_s": 1.0, "last_t_s": 2.0, "worst_t_s": 1.5, "worst_deg": 141.0,
                 "limit_deg": 140.0, "max_abs_deg": 141.0}
    result = PlanResult(["t_s"], np.zeros((1, 1)), {"planner": "cartesian", "summary": {"limit_violations": [violation]}})
    (typed,) = result.summary.limit_violations
    assert isinstance(typed, LimitViolation) and typed.joint == "j6" and typed.worst_deg == 141.0


def test_numpy_and_non_finite_values_are_written_as_plain_json(tmp_path):
    meta = {"planner": "cartesian", "summary": {"a": np.arange(3), "inf": np.float64(np.inf), "flag": np.bool_(True),
                                                "pair": (np.int64(1), float("nan"))}}
    _, json_path = write_plan(PlanResult(["t_s"], np.zeros((2, 1)), meta), tmp_path / "p.csv")
    summary = json.loads(json_path.read_text())["summary"]
    assert summary == {"a": [0, 1, 2], "inf": "inf", "flag": True, "pair": [1, "nan"]}
