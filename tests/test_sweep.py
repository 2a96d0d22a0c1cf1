"""``armgen sweep``: grids and random draws, failing runs as rows, --resume, CSV and Parquet,
and the same table from one process, local worker processes and a Dask cluster."""

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from armgen.cli.main import cli
from armgen.errors import TaskFileError
from armgen.planning.sweep import SweepSpec, parse_grid, parse_range, sweep
from armgen.planning.tasks import apply_overrides, load_task, run_task

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
# A short fault-tolerant task (1 s, 50 steps): the sweep machinery, not the planner, is under test.
SHORT = ["timing.duration=1", "fault.time=0.5", "path.turns=0.5"]


@pytest.fixture(autouse=True)
def _quiet(monkeypatch):
    monkeypatch.setenv("ARMGEN_NO_PROGRESS", "1")


def short_task(name="modular8_fault_circle_gpm"):
    task, sha = load_task(EXAMPLES / f"{name}.toml")
    apply_overrides(task, SHORT)
    return task, sha


def invoke(*args):
    return CliRunner().invoke(cli, ["sweep", *map(str, args)], catch_exceptions=False)


def test_grid_rows_match_single_plans(tmp_path):
    """Every grid combination is a row holding its values and the plan's summary, which is the
    summary `armgen plan --set` gives for the same fields."""
    out = tmp_path / "grid.csv"
    result = invoke(EXAMPLES / "modular8_fault_circle_gpm.toml", *sum((["--set", s] for s in SHORT), []),
                    "--grid", "method.K=[0, 4]", "--grid", "fault.joints=[[1], [4]]", "--workers", "1", "-o", out)
    assert result.exit_code == 0, result.output
    table = pd.read_csv(out)
    assert list(table["run"]) == [0, 1, 2, 3]
    assert list(table["method.K"]) == [0, 0, 4, 4]
    assert list(table["fault.joints"]) == ["[1]", "[4]", "[1]", "[4]"]
    assert set(table["status"]) == {"ok"}
    task, sha = short_task()
    apply_overrides(task, ["method.K=4", "fault.joints=[4]"])
    single = run_task(task, "x", sha).metadata["summary"]
    row = table.iloc[3]
    for key in ("max_pos_error_mm", "H_M_before_lock", "peak_ddq_deg_s2", "damped_steps"):
        assert row[key] == pytest.approx(single[key], rel=1e-15), key
    assert bool(row["task_completed"]) == single["task_completed"]
    assert "run_time_s" not in table.columns and "plan_seconds" not in table.columns


def test_failing_run_is_a_row(tmp_path):
    """A bad value (K < 0: exit 2) and an infeasible plan do not end the sweep."""
    out = tmp_path / "fail.csv"
    result = invoke(EXAMPLES / "modular8_fault_circle_gpm.toml", *sum((["--set", s] for s in SHORT), []),
                    "--grid", "method.K=[-1, 1]", "--workers", "1", "-o", out)
    assert result.exit_code == 0, result.output
    table = pd.read_csv(out, keep_default_na=False)
    bad, good = table.iloc[0], table.iloc[1]
    assert (bad["status"], int(bad["exit_code"])) == ("error", 2)
    assert "method.K" in bad["message"] and "≥ 0" in bad["message"]
    assert (good["status"], int(good["exit_code"]), good["message"]) == ("ok", 0, "")
    assert "1 failed" in result.output


def test_random_draws_are_seeded_and_within_range():
    spec = SweepSpec([("method.name", ["a", "b"])], [parse_range("method.K=0.5:4"),
                                                     parse_range("path.via=[-1, 0, 2]:[1, 0, 3]")], 5, seed=7)
    runs = spec.runs()
    assert len(runs) == 10 and runs == SweepSpec(spec.grid, spec.ranges, 5, seed=7).runs()
    assert runs != SweepSpec(spec.grid, spec.ranges, 5, seed=8).runs()
    assert [r["method.name"] for r in runs] == ["a"] * 5 + ["b"] * 5
    assert [r["method.K"] for r in runs[:5]] == [r["method.K"] for r in runs[5:]]  # the same draws per combination
    ks = np.array([r["method.K"] for r in runs])
    via = np.array([r["path.via"] for r in runs])
    assert np.all((0.5 <= ks) & (ks <= 4)) and np.all((via[:, 0] >= -1) & (via[:, 0] <= 1))
    assert np.all(via[:, 1] == 0) and np.all((via[:, 2] >= 2) & (via[:, 2] <= 3))


@pytest.mark.parametrize("item, match", [
    ("method.K", "KEY=ARRAY"), ("method.K=3", "non-empty TOML array"), ("method.K=[]", "non-empty TOML array"),
])
def test_bad_grid(item, match):
    with pytest.raises(TaskFileError, match=match):
        parse_grid(item)


@pytest.mark.parametrize("item, match", [
    ("method.K=1", "KEY=LO:HI"), ("method.K=a:b", "finite numbers"), ("method.K=3:1", "LO exceeds HI"),
    ("path.via=[1, 2]:[3]", "one length"), ("method.K=0:nan", "finite numbers"),
])
def test_bad_range(item, match):
    with pytest.raises(TaskFileError, match=match):
        parse_range(item)


def test_bad_command_lines(tmp_path):
    task = EXAMPLES / "modular8_fault_circle_gpm.toml"
    for args, match in ((["--range", "method.K=0:1"], "needs --random"), (["--random", "3"], "needs at least one"),
                        ([], "nothing to sweep"), (["--grid", "method.K=[1]", "-o", tmp_path / "t.txt"], ".csv or "
                                                                                                         ".parquet")):
        result = CliRunner().invoke(cli, ["sweep", str(task), *map(str, args)])
        assert result.exit_code == 2 and match in result.output, result.output
    assert not (tmp_path / "t.txt").exists()


def test_resume_skips_finished_runs_and_parquet_round_trips(tmp_path, monkeypatch):
    task, sha = short_task()
    out = tmp_path / "r.parquet"
    first = sweep(task, "t", sha, SweepSpec([("method.K", [0, 4])]), out)
    assert [r["run"] for r in first] == [0, 1]
    calls = []
    import armgen.planning.sweep as module

    real = module.run_one
    monkeypatch.setattr(module, "run_one", lambda *a: calls.append(a[3]) or real(*a))
    rows = sweep(task, "t", sha, SweepSpec([("method.K", [0, 4, 2])]), out, resume=True)
    assert calls == [2]  # only the new run
    table = pd.read_parquet(out)
    assert list(table["run"]) == [0, 1, 2] and list(table["method.K"]) == [0, 4, 2]
    assert [json.loads(o) for o in table["overrides"]] == [{"method.K": 0}, {"method.K": 4}, {"method.K": 2}]
    assert table.iloc[1]["H_M_before_lock"] == first[1]["H_M_before_lock"]
    assert len(rows) == 3


def test_same_table_serial_workers_and_dask(tmp_path):
    """The table does not depend on where it ran: one process, two local worker processes and
    a two-worker Dask LocalCluster (processes) give identical tables."""
    distributed = pytest.importorskip("distributed")
    task, sha = short_task("modular8_fault_circle_wln")
    spec = SweepSpec([("method.b", [0.25, 1.0]), ("fault.joints", [[2], [5]])])
    tables = {}
    tables["serial"] = sweep(task, "t", sha, spec, tmp_path / "serial.csv", workers=1)
    tables["workers"] = sweep(task, "t", sha, spec, tmp_path / "workers.csv", workers=2)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        tables["dask"] = sweep(task, "t", sha, spec, tmp_path / "dask.csv", scheduler=cluster.scheduler_address)
    assert len(tables["serial"]) == 4 and all(r["status"] == "ok" for r in tables["serial"])
    assert tables["workers"] == tables["serial"] and tables["dask"] == tables["serial"]
    texts = {k: (tmp_path / f"{k}.csv").read_text() for k in tables}
    assert texts["workers"] == texts["serial"] and texts["dask"] == texts["serial"]


def test_unreachable_scheduler_is_a_tool_error(tmp_path):
    result = CliRunner().invoke(cli, ["sweep", str(EXAMPLES / "modular8_fault_circle_gpm.toml"), "--grid",
                                      "method.K=[1]", "--scheduler", "tcp://127.0.0.1:9", "-o", str(tmp_path / "x.csv")])
    assert result.exit_code == 4 and "Dask scheduler" in result.output, result.output
    assert not (tmp_path / "x.csv").exists()
