"""The on-disk kernel store: a new process loads the fused step a former one composed, and
plans exactly what composing it afresh gives; a damaged entry or a changed robot composes anew."""

from pathlib import Path

import numpy as np
import pytest

from armgen.planning import backends
from armgen.planning.tasks import apply_overrides, load_task, run_task

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
# A 2 s weighted-GPM plan (200 steps): the store, not the planner, is under test.
SHORT = ["timing.duration=2", "method.ramp_time=0.5"]


@pytest.fixture(autouse=True)
def _store(tmp_path, monkeypatch):
    monkeypatch.setenv("ARMGEN_NO_PROGRESS", "1")
    monkeypatch.setenv("ARMGEN_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setattr(backends, "_KERNELS", {})  # a "new process": nothing composed yet


def plan(method="wgpm", backend="symbolic"):
    task, sha = load_task(EXAMPLES / "modular8_wgpm_demo.toml")
    # pinv leaves the limits on the demo circle: plan it anyway (by default that is exit 3)
    apply_overrides(task, SHORT + [f"method.name={method!r}".replace("'", '"'), "check.limits=report"])
    return run_task(task, "demo", sha, backend)


def forbid_composing(monkeypatch):
    def compose(*_):
        raise AssertionError("the kernel was composed although it is stored")

    monkeypatch.setattr(backends.Packing, "add", compose)


def store_entries(tmp_path, suffix):
    return sorted((tmp_path / "cache" / "kernels").glob(f"*{suffix}"))


def test_stored_kernel_plans_what_a_composed_one_does(tmp_path, monkeypatch):
    composed = plan()
    assert len(store_entries(tmp_path, ".json")) == 1 and len(store_entries(tmp_path, ".casadi")) == 1
    monkeypatch.setattr(backends, "_KERNELS", {})
    forbid_composing(monkeypatch)
    loaded = plan()
    np.testing.assert_array_equal(loaded.data, composed.data)


def test_c_kernel_loads_its_compiled_library(tmp_path, monkeypatch):
    composed = plan("pinv", "c")
    [library] = store_entries(tmp_path, ".so")
    monkeypatch.setattr(backends, "_KERNELS", {})
    forbid_composing(monkeypatch)
    monkeypatch.setattr(backends.NativeKernel, "__init__", lambda *_: pytest.fail("compiled again"))
    loaded = plan("pinv", "c")
    np.testing.assert_array_equal(loaded.data, composed.data)
    assert store_entries(tmp_path, ".so") == [library]


def test_damaged_entry_is_composed_again(tmp_path, monkeypatch):
    composed = plan()
    for entry in store_entries(tmp_path, ".casadi"):
        entry.write_bytes(b"not a CasADi function")
    monkeypatch.setattr(backends, "_KERNELS", {})
    again = plan()
    np.testing.assert_array_equal(again.data, composed.data)
    [entry] = store_entries(tmp_path, ".casadi")
    assert entry.read_bytes() != b"not a CasADi function"  # stored whole again


def test_digest_names_robot_backend_key_and_code(monkeypatch):
    from armgen.robot import load_robot

    robot = load_robot("modular8")
    base = backends._kernel_digest(robot, "c", ("wgpm", "wgpm"))
    moved_tool = load_robot("modular8")
    moved_tool.tool[2, 3] += 1e-3
    assert backends._kernel_digest(moved_tool, "c", ("wgpm", "wgpm")) != base
    assert backends._kernel_digest(robot, "symbolic", ("wgpm", "wgpm")) != base
    assert backends._kernel_digest(robot, "c", ("wgpm", "pinv")) != base
    assert backends._kernel_digest(load_robot("modular8"), "c", ("wgpm", "wgpm")) == base
    monkeypatch.setattr(backends, "_code_fingerprint", lambda: "edited planner")
    assert backends._kernel_digest(robot, "c", ("wgpm", "wgpm")) != base


def test_prune_drops_least_recently_used_files_past_the_cap(tmp_path):
    store = tmp_path / "kernels"
    store.mkdir()
    import os

    for age, name in enumerate(["newest", "newer", "older", "oldest"]):
        path = store / name
        path.write_bytes(b"x" * 100)
        os.utime(path, (1e9 - age * 100, 1e9 - age * 100))
    backends._prune(store, 400)  # at the cap: nothing to do
    assert len(list(store.iterdir())) == 4
    backends._prune(store, 300)  # over it: down to 3/4 of the cap (225 bytes), oldest first
    assert sorted(p.name for p in store.iterdir()) == ["newer", "newest"]
