"""The on-disk kernel store: a new process loads the fused step a former one composed, and
plans exactly what composing it afresh gives; a damaged entry or a changed robot composes anew."""

import hashlib
import json
import os
import stat
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from armgen.codegen import kernel_store
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
    kernel_store.prune(store, 400)  # at the cap: nothing to do
    assert len(list(store.iterdir())) == 4
    kernel_store.prune(store, 300)  # over it: down to 3/4 of the cap (225 bytes), oldest first
    assert sorted(p.name for p in store.iterdir()) == ["newer", "newest"]


# -- the store is code: nothing in it is loaded unless this user wrote it, whole ------------

PLANTED_CONSTRUCTOR = r"""
#include <stdio.h>
__attribute__((constructor)) static void planted(void) {
    FILE *f = fopen(MARKER, "w");
    if (f) { fputs("ran", f); fclose(f); }
}
int g(const double **arg, double **res, long long *iw, double *w, int mem) {
    (void)iw; (void)w; (void)mem; res[0][0] = arg[0][0]; return 0;
}
void armgen_kernel(const double *x, double *y) { (void)x; (void)y; }
"""


@pytest.fixture
def planted(tmp_path):
    """A shared library whose constructor writes a marker file: loading it is the finding."""
    marker = tmp_path / "constructor-ran"
    source = tmp_path / "planted.c"
    source.write_text(PLANTED_CONSTRUCTOR)
    library = tmp_path / "libplanted.so"
    subprocess.run(["gcc", "-shared", "-fPIC", f'-DMARKER="{marker}"', str(source), "-o", str(library)],
                   check=True)
    return library, marker


def entry_of(tmp_path):
    [entry] = store_entries(tmp_path, ".json")
    return entry, json.loads(entry.read_text())


def test_planted_library_under_the_expected_name_is_not_loaded(tmp_path, monkeypatch, planted):
    library, marker = planted
    composed = plan("pinv", "c")
    [stored] = store_entries(tmp_path, ".so")
    stored.unlink()  # (a new file: the mapped one stays as this process loaded it)
    stored.write_bytes(library.read_bytes())  # same name, someone else's code
    monkeypatch.setattr(backends, "_KERNELS", {})
    again = plan("pinv", "c")
    assert not marker.exists()
    np.testing.assert_array_equal(again.data, composed.data)
    assert stored.read_bytes() != library.read_bytes()  # rebuilt over the planted file


def test_entry_naming_a_library_outside_the_store_is_not_loaded(tmp_path, monkeypatch, planted):
    library, marker = planted
    composed = plan("pinv", "c")
    entry, fields = entry_of(tmp_path)
    for name in (str(library), f"../../{library.name}"):
        fields["library"] = name
        entry.write_text(json.dumps(fields))
        monkeypatch.setattr(backends, "_KERNELS", {})
        again = plan("pinv", "c")
        assert not marker.exists()
        np.testing.assert_array_equal(again.data, composed.data)
        entry, fields = entry_of(tmp_path)
        assert fields["library"] != name  # the entry was written anew


def test_stored_function_calling_an_external_is_not_deserialised(tmp_path, monkeypatch, planted):
    """The default (symbolic) backend: a .casadi whose SX function calls a CasADi `external`
    would load that library when deserialised; its digest is even made to match."""
    library, marker = planted
    composed = plan()
    entry, fields = entry_of(tmp_path)
    stored = entry.with_suffix(".casadi")
    attacker = ("import casadi as ca, sys; x = ca.SX.sym('x', 1); "
                "ca.Function('k', [x], [ca.external('g', sys.argv[1])(x) * 2]).save(sys.argv[2])")
    # in a process of its own: the library's constructor runs there
    subprocess.run([sys.executable, "-c", attacker, str(library), str(stored)], check=True)
    marker.unlink()
    fields["function_sha256"] = hashlib.sha256(stored.read_bytes()).hexdigest()
    entry.write_text(json.dumps(fields))
    monkeypatch.setattr(backends, "_KERNELS", {})
    again = plan()
    assert not marker.exists()
    np.testing.assert_array_equal(again.data, composed.data)


def test_edited_function_is_composed_again_not_planned_with(tmp_path, monkeypatch):
    """A stored function edited to move joint 8 (a valid SXFunction, digest not updated)."""
    import casadi as ca

    composed = plan()
    entry, fields = entry_of(tmp_path)
    stored = entry.with_suffix(".casadi")
    func = ca.Function.load(str(stored))
    x = ca.SX.sym("x", func.nnz_in())
    shifted = func(x) + ca.DM([0.25 if k == 7 else 0.0 for k in range(func.nnz_out())])
    ca.Function(func.name(), [x], [shifted], ["x"], ["y"]).save(str(stored))
    monkeypatch.setattr(backends, "_KERNELS", {})
    again = plan()
    np.testing.assert_array_equal(again.data, composed.data)


@pytest.mark.parametrize("what", ["folder", "entry"])
def test_store_writable_by_others_is_not_trusted(tmp_path, monkeypatch, what):
    composed = plan()
    entry, _ = entry_of(tmp_path)
    target = entry.parent if what == "folder" else entry.with_suffix(".casadi")
    target.chmod(target.stat().st_mode | 0o002)
    monkeypatch.setattr(backends, "_KERNELS", {})
    forbid_loading(monkeypatch)
    if what == "folder":
        with pytest.warns(UserWarning, match=r"writable by group or others.*chmod go-w"):
            again = plan()
    else:
        again = plan()
    np.testing.assert_array_equal(again.data, composed.data)


def test_store_owned_by_someone_else_is_not_trusted(tmp_path, monkeypatch):
    composed = plan()
    monkeypatch.setattr(kernel_store, "_user", lambda: os.geteuid() + 1)  # every file is now another user's
    monkeypatch.setattr(backends, "_KERNELS", {})
    forbid_loading(monkeypatch)
    with pytest.warns(UserWarning, match=r"owned by uid \d+, not by this user"):
        again = plan()
    np.testing.assert_array_equal(again.data, composed.data)


def forbid_loading(monkeypatch):
    def deserialize(*_):
        raise AssertionError("an untrusted entry was deserialised")

    monkeypatch.setattr(backends.ca, "StringDeserializer", deserialize)


def test_new_store_folder_is_private(tmp_path):
    plan()
    assert stat.S_IMODE((tmp_path / "cache" / "kernels").stat().st_mode) == 0o700
    for path in (tmp_path / "cache" / "kernels").iterdir():
        assert not path.stat().st_mode & 0o022, path


def test_serialised_text_check_accepts_sx_and_refuses_others():
    import casadi as ca

    x = ca.SX.sym("x", 2)
    plain = ca.Function("f", [x], [ca.sin(x) * 2]).serialize().encode()
    assert kernel_store.sx_function_text_loads_no_code(plain)
    mx = ca.MX.sym("x", 2)
    assert not kernel_store.sx_function_text_loads_no_code(ca.Function("f", [mx], [ca.sin(mx)]).serialize().encode())
    assert not kernel_store.sx_function_text_loads_no_code(b"not casadi text")


def test_a_stored_file_is_used_only_while_its_bytes_match_its_entry(tmp_path):
    """stored_file builds once and hands the stored file back after; a file replaced by other
    bytes, or by a symlink to the same bytes, is not trusted: built again and replaced."""
    key = hashlib.sha256(b"what the file is made of").hexdigest()
    builds = []

    def build(folder: Path) -> Path:
        builds.append(folder)
        (folder / "made").write_bytes(b"the build's bytes")
        return folder / "made"

    path, built = kernel_store.stored_file("probe", key, ".bin", build)
    assert built and path.read_bytes() == b"the build's bytes" and len(builds) == 1
    assert kernel_store.stored_file("probe", key, ".bin", build) == (path, False) and len(builds) == 1

    other = tmp_path / "other"
    other.write_bytes(b"someone else's bytes!")
    other.replace(path)
    assert kernel_store.stored_file("probe", key, ".bin", build) == (path, True) and len(builds) == 2
    assert path.read_bytes() == b"the build's bytes"

    twin = tmp_path / "twin"
    twin.write_bytes(b"the build's bytes")
    path.unlink()
    path.symlink_to(twin)
    assert kernel_store.stored_file("probe", key, ".bin", build) == (path, True) and len(builds) == 3
    assert not path.is_symlink()
    assert kernel_store.stored_file("probe", key, ".bin", build, again=True)[1] and len(builds) == 4
