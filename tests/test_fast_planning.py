"""The fused-step planners against the outputs of the planners they replaced.

tests/data/planner_reference.npz holds the cartesian, fault-tolerant and weighted-GPM plans of
every example (and the variants the examples do not cover) as computed at commit 85a2322, one
interpreted call per model function (tests/data/make_planner_reference.py wrote it). The
rewrite makes one fused call per step, on either backend; its plans must match those."""

import os
from pathlib import Path

import numpy as np
import pytest

from armgen.planning.tasks import apply_overrides, load_task, run_task
from armgen.robot import load_robot
from armgen.symbolic.criteria import ZGHAL_GAP_FLOOR

HERE = Path(__file__).resolve().parent
EXAMPLES = HERE.parent / "examples"
REFERENCE = np.load(HERE / "data" / "planner_reference.npz")

import sys  # noqa: E402

sys.path.insert(0, str(HERE / "data"))
from make_planner_reference import CASES, summary_scalars  # noqa: E402

# The bar: joint angles identical to the replaced planners within 1e-12 rad.
ANGLE_TOL = 1e-12
# Every other column and summary scalar: the same sums in another order (BLAS vs the fused
# expression; bisection vs LAPACK for σ_min) differ by rounding, relative to the column's scale.
VALUE_REL_TOL = 1e-9

# σ_min is the square root of a bisection eigenvalue estimate: where the (masked) Jacobian is rank
# deficient that eigenvalue is rounding noise (~1e-16 ‖A‖), so its root is noise of ~1e-8.
SIGMA_ABS_TOL = 1e-7

# An activation whose weight penalty W_i − 1 is below this moves nothing: the base joint's
# ∂H/∂q_i is rounding noise and its WLN flag flips with the noise's sign (planner docs).
ACTIVE_MIN_PENALTY = 1e-9
# The plain WLN rule's switch count: at the lock of iiwa_wln a joint's ∂H/∂q_i falls to rounding
# noise in the same step as its weight drops by 13, so whether its flag also flips there is the
# noise's sign (the closed-form gradients of the lean criteria round differently from the
# reference's AD): one event either way, the weights and angles being equal (checked above).
SWITCH_COUNT_TOL = 1
# The σ_min index's gradient is a central difference (step 1e-6) of SVD values, so it
# amplifies the last-bit differences of the fused step's sums by ~1e6: angles to 1e-9 rad,
# the rest (velocities are differences of angles over h) to 1e-7 relative.
FD_INDEX_ANGLE_TOL = 1e-9
FD_INDEX_VALUE_TOL = 1e-7
ANGLE_TOLS = {"m8_fault_sigma": FD_INDEX_ANGLE_TOL}
VALUE_TOLS = {"m8_fault_sigma": FD_INDEX_VALUE_TOL}

# The Zghal criterion H_L is the floored form since the lean criteria (its gap (q_max − q)(q − q_min)
# floored at ZGHAL_GAP_FLOOR·range², i.e. saturated at and beyond the limits, where the
# reference's raw formula went negative): H_L is compared where every joint is inside its
# limits by more than that floor (the only change to the planners' outputs).
def _inside_limits(robot_name, got, columns):
    robot = load_robot(robot_name)
    q = np.column_stack([got[:, columns.index(f"q{i + 1}_rad")] for i in range(robot.n)])
    span = robot.qmax - robot.qmin
    return np.all((robot.qmax - q) * (q - robot.qmin) > ZGHAL_GAP_FLOOR * span ** 2, axis=1)


# Summary entries added since the reference (the sweep table reads them; copies of the verdict's).
ADDED_SUMMARY_KEYS = {"max_weight_step", "w_min_after_lock_mm3"}

CASE = {name: (example, overrides) for name, example, overrides in CASES}


def plan(name, backend):
    example, overrides = CASE[name]
    task, sha = load_task(EXAMPLES / f"{example}.toml")
    apply_overrides(task, list(overrides))
    return run_task(task, example, sha, backend)


def check_against_reference(name, result):
    value_tol = VALUE_TOLS.get(name, VALUE_REL_TOL)
    columns = list(REFERENCE[f"{name}/columns"])
    assert result.columns == columns
    assert result.data.shape[0] == int(REFERENCE[f"{name}/n_rows"])
    got = result.data[REFERENCE[f"{name}/rows"]]
    want = REFERENCE[f"{name}/samples"]
    for k, column in enumerate(columns):
        if column.startswith("q") and column.endswith("_rad"):
            np.testing.assert_allclose(got[:, k], want[:, k], rtol=0, atol=ANGLE_TOLS.get(name, ANGLE_TOL),
                                       err_msg=f"{name}: {column}")
        elif column.startswith("active"):
            weight = columns.index("W" + column[len("active"):])
            matters = (want[:, weight] - 1 > ACTIVE_MIN_PENALTY) | (got[:, weight] - 1 > ACTIVE_MIN_PENALTY)
            np.testing.assert_allclose(got[matters, k], want[matters, k], rtol=0, atol=value_tol,
                                       err_msg=f"{name}: {column}")
        elif column == "H_L_1":
            inside = _inside_limits(load_task(EXAMPLES / f"{CASE[name][0]}.toml")[0]["robot"], got, columns)
            scale = max(1.0, float(np.max(np.abs(want[inside, k]))))
            np.testing.assert_allclose(got[inside, k], want[inside, k], rtol=0, atol=value_tol * scale,
                                       err_msg=f"{name}: {column} (inside the limits)")
        elif column == "sigma_min_1":
            np.testing.assert_allclose(got[:, k], want[:, k], rtol=value_tol, atol=SIGMA_ABS_TOL,
                                       err_msg=f"{name}: {column}")
        else:
            scale = max(1.0, float(np.max(np.abs(want[:, k]))))
            np.testing.assert_allclose(got[:, k], want[:, k], rtol=0, atol=value_tol * scale,
                                       err_msg=f"{name}: {column}")
    scalars = summary_scalars(result.metadata["summary"])
    keys = list(REFERENCE[f"{name}/summary_keys"])
    assert set(keys) <= set(scalars) and set(scalars) - set(keys) <= ADDED_SUMMARY_KEYS
    for key, value in zip(keys, REFERENCE[f"{name}/summary_values"]):
        tol = SWITCH_COUNT_TOL if key.endswith("weight_switches") else value_tol
        assert scalars[key] == pytest.approx(value, rel=value_tol, abs=tol), f"{name}: summary {key}"


@pytest.fixture(autouse=True)
def _quiet(monkeypatch):
    monkeypatch.setenv("ARMGEN_NO_PROGRESS", "1")


@pytest.mark.parametrize("name", [c[0] for c in CASES])
def test_symbolic_backend_matches_reference(name):
    check_against_reference(name, plan(name, "symbolic"))


@pytest.mark.parametrize("name", ["combined", "combined_rk4", "combined_clik", "iiwa_wln", "m8_fault_wln_plain",
                                  "m8_fault_relative", "wgpm", "wgpm_pinv"])
def test_c_backend_matches_reference(name, tmp_path, monkeypatch):
    # (the clamp kernel, eight unrolled solves, takes ~90 s to compile: its logic is checked on
    # the symbolic backend, and the C is the same emitter's output of the same expression)
    monkeypatch.setenv("ARMGEN_CACHE_DIR", os.environ.get("ARMGEN_TEST_CACHE_DIR", str(tmp_path)))
    check_against_reference(name, plan(name, "c"))
