"""The compiled kernel behind the Python API (issue 41): Robot's methods on the generated C give
what the CasADi reference gives; the kernel is built once into the store and loaded from it only
when trusted and self-tested; without a C compiler the reference runs, said once."""

import dataclasses
import json
import os
import subprocess
import sys
import sysconfig
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from armgen.codegen import api_kernel
from conftest import require_tool
from armgen.errors import OptionError, ToolchainError
from armgen.robot import Robot, load_robot

ROOT = Path(__file__).resolve().parents[1]
SEED = 4141
# The bench poses of benchmarks/bench_ik.py: FK of seeded configurations inside the limits,
# solved from the middle of the limits.
IK_POSES = 30
IK_SEED = 2025


def require_python_headers() -> None:
    """The kernel is a CPython extension: Python.h. Missing locally: skip with the install
    command; missing in CI: fail (as conftest.require_tool)."""
    include = sysconfig.get_paths()["include"]
    if not Path(include, "Python.h").is_file():
        message = f"no Python.h in {include} (apt-get install -y python3-dev)"
        if os.environ.get("CI") == "true":
            pytest.fail(f"{message}: CI must install it (.ci/run)")
        pytest.skip(message)


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    """One store for the module: each robot's kernel is built once here."""
    require_tool("gcc")
    require_python_headers()
    folder = tmp_path_factory.mktemp("cache")
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("ARMGEN_CACHE_DIR", str(folder))
        patch.delenv(api_kernel.KERNEL_ENV, raising=False)
        yield folder / "kernels"


@pytest.fixture
def fresh_process(monkeypatch):
    """Nothing loaded, nothing warned: as in a new process."""
    monkeypatch.setattr(api_kernel, "_LOADED", {})
    monkeypatch.setattr(api_kernel, "_WARNED", [])


class _KernelRobots(dict):
    """(compiled, reference) robot per name, loaded once for the property tests."""

    def __missing__(self, name):
        self[name] = (compiled(name), reference(name))
        return self[name]


KERNEL_ROBOTS = _KernelRobots()


def reference(name):
    """The robot with its methods on the CasADi reference."""
    robot = load_robot(name)
    robot.__dict__["_kernel"] = None
    return robot


def compiled(name):
    robot = load_robot(name)
    assert robot._kernel is not None, "no compiled kernel was built"
    return robot


def assert_agrees(value, expected, tolerance=api_kernel.REFERENCE_AGREEMENT):
    value, expected = np.asarray(value), np.asarray(expected)
    assert value.shape == expected.shape
    np.testing.assert_allclose(value, expected, rtol=tolerance, atol=tolerance)


@pytest.mark.parametrize("name", ["planar3", "panda", "modular8"])
def test_kinematics_and_criteria_equal_the_casadi_reference(store, name):
    robot, ref = compiled(name), reference(name)
    rng = np.random.default_rng(SEED)
    batch = rng.uniform(robot.qmin, robot.qmax, (2, 3, robot.n))
    for q in (batch, batch[0, 0], batch[0, 0].tolist(), batch[:, 1]):  # batch, one sample, a list, a strided batch
        assert_agrees(robot.fk(q), ref.fk(q))
        assert_agrees(robot.jacobian(q), ref.jacobian(q))
        for value, expected in zip(robot.fk_jacobian(q), ref.fk_jacobian(q)):
            assert_agrees(value, expected)
        assert_agrees(robot.manipulability(q, delta=0.01), ref.manipulability(q, delta=0.01))
        assert_agrees(robot.manipulability_gradient(q, delta=0.01), ref.manipulability_gradient(q, delta=0.01))
        assert_agrees(robot.joint_limit_criterion(q), ref.joint_limit_criterion(q))
        assert_agrees(robot.joint_limit_gradient(q), ref.joint_limit_gradient(q))
        assert_agrees(robot.repetitive_gradient(q, robot.qmid), ref.repetitive_gradient(q, robot.qmid))
        weights = rng.uniform(0.5, 2.0, robot.n)
        for key, value in robot.joint_manipulability(q, weights, delta=0.01).items():
            assert_agrees(value, ref.joint_manipulability(q, weights, delta=0.01)[key])
    assert robot.fk(np.zeros((0, robot.n))).shape == (0, 4, 4)


def test_dynamics_equal_the_casadi_reference(store):
    robot, ref = compiled("panda"), reference("panda")
    assert robot.has_dynamics and {"gravity", "rnea", "mass_matrix", "coriolis"} <= set(robot._kernel.functions)
    rng = np.random.default_rng(SEED)
    q, dq, ddq = (rng.uniform(-1.0, 1.0, (5, robot.n)) for _ in range(3))
    for sample in (slice(None), 0):
        assert_agrees(robot.gravity_torques(q[sample]), ref.gravity_torques(q[sample]))
        assert_agrees(robot.rnea(q[sample], dq[sample], ddq[sample]), ref.rnea(q[sample], dq[sample], ddq[sample]))
        assert_agrees(robot.mass_matrix(q[sample]), ref.mass_matrix(q[sample]))
        assert_agrees(robot.coriolis(q[sample], dq[sample]), ref.coriolis(q[sample], dq[sample]))
    assert_agrees(robot.rnea(q, dq[0], 0.0 * ddq[0]), ref.rnea(q, dq[0], 0.0 * ddq[0]))  # rates broadcast


def test_ik_has_the_reference_success_and_residuals_on_the_bench_poses(store):
    robot, ref = compiled("panda"), reference("panda")
    rng = np.random.default_rng(IK_SEED)
    poses = ref.fk(robot.qmin + (robot.qmax - robot.qmin) * rng.random((IK_POSES, robot.n)))
    solved, expected = robot.ik(poses, seed=robot.qmid), ref.ik(poses, seed=robot.qmid)
    np.testing.assert_array_equal(solved.success, expected.success)
    assert solved.success.mean() >= expected.success.mean()
    for field in ("q", "position_error", "orientation_error"):
        assert_agrees(getattr(solved, field), getattr(expected, field), api_kernel.IK_REFERENCE_AGREEMENT)
    for pose, q in zip(poses[:3], expected.q[:3]):  # one pose per call, and with q0 (the self-motion toward it)
        assert_agrees(robot.ik(pose, seed=robot.qmid).q, ref.ik(pose, seed=robot.qmid).q,
                      api_kernel.IK_REFERENCE_AGREEMENT)
        assert_agrees(robot.ik(pose, q0=q).q, ref.ik(pose, q0=q).q, api_kernel.IK_REFERENCE_AGREEMENT)
    # the C takes no step for a target that is not a pose; the reference's check then names what is wrong
    with pytest.raises(ValueError, match="not a rotation"):
        robot.ik(np.diag([2.0, 1.0, 1.0, 1.0]))
    with pytest.raises(ValueError, match="pose 1 of the batch holds NaN or inf"):
        robot.ik(np.stack([poses[0], np.full((4, 4), np.nan)]))


def test_results_are_independent_arrays(store):
    robot = compiled("planar3")
    first = robot.fk(robot.qmid)
    second = robot.fk(robot.qmin)
    assert not np.shares_memory(first, second) and not np.allclose(first, second)


def test_wrong_shapes_and_buffers_are_errors_not_crashes(store):
    robot = compiled("planar3")
    with pytest.raises(ValueError, match=r"q must have shape \(3,\) or \(\.\.\., 3\) for robot 'planar3'"):
        robot.fk(np.zeros(4))
    module = robot._kernel._module
    with pytest.raises(ValueError, match="argument 2: a contiguous float64 buffer of 1 samples of 16 values"):
        module.fk(1, np.zeros(3), np.zeros(15))
    with pytest.raises(ValueError, match="argument 1"):
        module.fk(2, np.zeros(3, dtype=np.float32), np.zeros(32))
    with pytest.raises(ValueError, match="argument 2"):
        module.fk(2, np.zeros(3), np.zeros(16))  # an output holds every sample
    with pytest.raises(TypeError, match="fk takes count and 2 buffers"):
        module.fk(1, np.zeros(3))
    with pytest.raises(ValueError, match="count must be at least 0"):
        module.fk(-1, np.zeros(3), np.zeros(16))
    with pytest.raises(ValueError, match="not C-contiguous"):  # a Fortran-ordered batch: samples interleaved
        module.fk(2, np.zeros((3, 2), order="F"), np.zeros(32))


def test_kernel_is_loaded_from_the_store_not_built_again(store, fresh_process, monkeypatch):
    compiled("planar3")
    monkeypatch.setattr(api_kernel, "_LOADED", {})
    monkeypatch.setattr(api_kernel, "compile_shared", lambda *_, **__: pytest.fail("compiled again"))
    monkeypatch.setattr(api_kernel, "reference_cases", lambda *_: pytest.fail("self-test values evaluated again"))
    robot = load_robot("planar3")
    assert robot._kernel is not None
    [entry] = store.glob("planar3_api-*.json")
    [library] = store.glob("kernel_planar3_double-*.so")  # armgen gen's C of planar3, the build verify shares
    assert json.loads(entry.read_text())["library"] == library.name


def test_an_entry_whose_recorded_reference_was_edited_is_made_again(store, fresh_process):
    """The self-test on load compares with the values the entry recorded: a kernel that does
    not reproduce them (here: the values moved, the library intact) is not used; the entry is
    made again from the reference evaluated anew (the build, whose bytes match, is kept)."""
    compiled("planar3")
    [entry] = store.glob("planar3_api-*.json")
    fields = json.loads(entry.read_text())
    recorded = fields["self_test"]["fk"][0]["outputs"][0][12]
    fields["self_test"]["fk"][0]["outputs"][0][12] += 1e-6  # the x of the first case's pose
    entry.write_text(json.dumps(fields))
    api_kernel._LOADED.clear()
    assert load_robot("planar3")._kernel is not None
    assert json.loads(entry.read_text())["self_test"]["fk"][0]["outputs"][0][12] == recorded


PLANTED = r"""
#include <stdio.h>
__attribute__((constructor)) static void planted(void) {
    FILE *f = fopen(MARKER, "w");
    if (f) { fputs("ran", f); fclose(f); }
}
"""


def test_a_library_that_is_not_the_stored_one_is_not_loaded(store, fresh_process, tmp_path):
    compiled("planar3")
    [library] = store.glob("kernel_planar3_double-*.so")
    marker, source = tmp_path / "constructor-ran", tmp_path / "planted.c"
    source.write_text(PLANTED)
    subprocess.run(["gcc", "-shared", "-fPIC", f'-DMARKER="{marker}"', str(source), "-o", str(tmp_path / "p.so")],
                   check=True)
    library.unlink()  # (a new file: the one this process mapped stays as it was)
    library.write_bytes((tmp_path / "p.so").read_bytes())  # same name, someone else's code
    api_kernel._LOADED.clear()
    robot, ref = load_robot("planar3"), reference("planar3")
    assert robot._kernel is not None
    assert not marker.exists()
    assert_agrees(robot.fk(robot.qmin), ref.fk(robot.qmin))
    assert library.read_bytes() != (tmp_path / "p.so").read_bytes()  # built again over it


def test_a_kernel_failing_its_self_test_is_not_used(store, fresh_process, monkeypatch):
    compiled("planar3")
    api_kernel._LOADED.clear()
    monkeypatch.setattr(api_kernel, "_reproduces", lambda *_: False)
    with pytest.warns(RuntimeWarning, match="disagrees with the CasADi reference"):
        robot = load_robot("planar3")
        assert robot._kernel is None
    assert_agrees(robot.fk(robot.qmid), reference("planar3").fk(robot.qmid))


def test_without_a_compiler_the_reference_runs_and_one_line_says_so(store, fresh_process, monkeypatch):
    def no_compiler():
        raise ToolchainError("'gcc' not found on PATH; install a C compiler (apt-get install -y gcc)")

    monkeypatch.setattr(api_kernel, "host_cc", no_compiler)
    api_kernel._toolchain_identity.cache_clear()
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            robots = [load_robot("planar3"), load_robot("panda")]
            for robot in robots:
                assert robot._kernel is None
                assert_agrees(robot.fk_jacobian(robot.qmid)[1], reference(robot.name).jacobian(robot.qmid))
    finally:
        api_kernel._toolchain_identity.cache_clear()
    [line] = [str(w.message) for w in caught if issubclass(w.category, RuntimeWarning)]
    assert line == ("armgen: the Robot methods run on the CasADi reference (slower), no compiled kernel: "
                    "'gcc' not found on PATH; install a C compiler (apt-get install -y gcc)")


def test_the_environment_forces_the_reference(store, fresh_process, monkeypatch):
    monkeypatch.setenv(api_kernel.KERNEL_ENV, "reference")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a choice, not a fallback: no warning
        assert load_robot("planar3")._kernel is None
    monkeypatch.setenv(api_kernel.KERNEL_ENV, "fast")
    with pytest.raises(OptionError, match="ARMGEN_KERNEL='fast': set it to one of compiled, reference"):
        load_robot("planar3").fk(np.zeros(3))


BUILD = """
import armgen.codegen.api_kernel as api_kernel
from armgen.robot import load_robot
build = api_kernel._built
def counted(*args):
    print('built')
    return build(*args)
api_kernel._built = counted
robot = load_robot('planar3')
assert robot._kernel is not None, 'no kernel'
print(robot.fk([0.1, 0.2, 0.3])[0, 3])
"""


def test_processes_building_the_same_kernel_at_once_build_it_once(store, tmp_path):
    env = dict(os.environ, ARMGEN_CACHE_DIR=str(tmp_path / "cache"), PYTHONPATH=str(ROOT))
    env.pop(api_kernel.KERNEL_ENV, None)
    runs = [subprocess.Popen([sys.executable, "-W", "error::RuntimeWarning", "-c", BUILD], env=env,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for _ in range(2)]
    outputs = [run.communicate(timeout=600) for run in runs]
    assert [run.returncode for run in runs] == [0, 0], outputs
    assert outputs[0][0].splitlines()[-1] == outputs[1][0].splitlines()[-1]
    assert sum(out.count("built") for out, _ in outputs) == 1  # one built it; the other waited and loaded it
    store = tmp_path / "cache" / "kernels"
    [entry] = store.glob("planar3_api-*.json")
    assert [p.name for p in store.glob("*.so")] == [json.loads(entry.read_text())["library"]]
    assert not [p for p in store.iterdir() if p.is_dir()]  # no build folder left behind
    # builds are reproducible, so the entry's digest is the library's whichever process wrote last:
    # a third process loads them (a mismatch would build again, replacing the file)
    library = store / json.loads(entry.read_text())["library"]
    before = library.stat()
    third = subprocess.run([sys.executable, "-W", "error::RuntimeWarning", "-c", BUILD], env=env,
                           capture_output=True, text=True, timeout=600)
    assert third.returncode == 0, third.stderr
    assert "built" not in third.stdout
    assert library.stat().st_ino == before.st_ino  # the same file (a build replaces it by os.replace)


def test_the_c_planning_backend_calls_the_same_library(store, monkeypatch):
    """`make_backend(robot, "c", functions)` (the snake planner's fk cross-check) takes the
    functions from the robot's kernel: no second build per process."""
    from armgen.planning import backends

    robot = compiled("modular8")
    monkeypatch.setattr(backends, "build_library", lambda *_, **__: pytest.fail("compiled for the backend"))
    backend = backends.make_backend(robot, "c", ("fk", "jacobian"))
    q = np.random.default_rng(SEED).uniform(robot.qmin, robot.qmax, robot.n)
    (T,) = backend.call("fk", q)
    (J,) = backend.call("jacobian", q)
    assert_agrees(T, reference("modular8").fk(q))
    assert_agrees(J, reference("modular8").jacobian(q))
    np.testing.assert_array_equal(np.array(backend.functions["fk"](q)), T)  # as a casadi.Function


@settings(max_examples=60, deadline=None, derandomize=True)
@given(shape=st.lists(st.integers(0, 3), max_size=3), dtype=st.sampled_from(["float64", "float32", "int64"]),
       layout=st.sampled_from(["contiguous", "fortran", "strided"]), scale=st.sampled_from([1.0, 1e3, 1e-3]))
def test_any_batch_layout_and_dtype_gives_the_reference(store, shape, dtype, layout, scale):
    """Whatever the batch shape (empty batches included), dtype and memory layout of q, the
    kernel returns the reference's values and shapes: the extension reads only contiguous
    float64 buffers of the expected size, and the Python side converts anything else first."""
    robot, ref = KERNEL_ROBOTS["planar3"]
    rng = np.random.default_rng(len(shape) * 7 + sum(shape))
    q = (rng.uniform(-2.0, 2.0, (*shape, 2 * robot.n)) * scale).astype(dtype)
    q = {"contiguous": q[..., : robot.n], "fortran": np.asfortranarray(q[..., : robot.n]),
         "strided": q[..., ::2]}[layout]
    for value, expected in zip(robot.fk_jacobian(q), ref.fk_jacobian(q)):
        assert_agrees(value, expected)
    assert_agrees(robot.joint_limit_gradient(q), ref.joint_limit_gradient(q))


def test_a_robot_whose_name_is_no_c_prefix_gets_a_kernel(store, tmp_path):
    """Its kernel is built with the fallback prefix: a robot called 'r' (whose R_OK would be
    <unistd.h>'s) or 'nan' is evaluated by the compiled kernel, with the reference's values."""
    from armgen.description import BUNDLED_DIR

    text = (BUNDLED_DIR / "planar3.toml").read_text()
    for name in ("r", "nan"):
        path = tmp_path / f"{name}.toml"
        path.write_text(text.replace('name = "planar3"', f'name = "{name}"'))
        robot = load_robot(path)
        assert robot.name == name
        with warnings.catch_warnings():
            warnings.simplefilter("error", RuntimeWarning)
            assert robot._kernel is not None
        assert_agrees(robot.fk(robot.qmid), reference("planar3").fk(robot.qmid))


def test_the_digest_names_what_the_kernel_computes_not_where_the_robot_was_read(tmp_path):
    from armgen.description import BUNDLED_DIR

    def digest(robot):
        return api_kernel._kernel_digest(robot.symbolic)

    base = digest(load_robot("panda"))
    (tmp_path / "copy.toml").write_text((BUNDLED_DIR / "panda.toml").read_text())
    assert digest(load_robot(tmp_path / "copy.toml")) == base  # another file, the same arm
    moved_tool = load_robot("panda")
    moved_tool.tool[2, 3] += 1e-3
    assert digest(moved_tool) != base
    panda = load_robot("panda")
    narrowed = dataclasses.replace(panda, joints=(dataclasses.replace(panda.joints[0], qlim=(-1.0, 1.0)),
                                                  *panda.joints[1:]))
    assert digest(Robot.from_description(narrowed)) != base
