"""Inverse kinematics (armgen.symbolic.ik, Robot.ik): round trips, limits, batches, misses."""

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from armgen.robot import load_robot
from armgen.symbolic import ik

ROBOTS = ["planar3", "iiwa14", "panda", "modular8"]
POSES = 60
# The least success rate a test batch of random reachable poses must reach (the benchmark's
# bar, 99.5 % over 10 000 poses, is measured in benchmarks/bench_ik.py, not asserted here): a
# regression that breaks convergence drops far below it.
MIN_SUCCESS = 0.9


# The solver's own steps, without the collision search that Robot.ik adds for a robot with
# capsules (tests/test_ik_collision.py): a random configuration may collide with the arm itself.
PLAIN = {"collision_free": False}


def random_configurations(robot, count, seed=7):
    rng = np.random.default_rng(seed)
    return robot.qmin + (robot.qmax - robot.qmin) * rng.random((count, robot.n))


def independent_errors(robot, q, pose):
    """Position and orientation errors of the tool at q against pose, over the task rows:
    the orientation from SciPy's rotation vector of R_target R^T (not the solver's formula)."""
    reached = robot.fk(q)
    rows = np.array(robot.task_rows)
    diff = pose[..., :3, 3] - reached[..., :3, 3]
    rotvec = Rotation.from_matrix(pose[..., :3, :3] @ np.swapaxes(reached[..., :3, :3], -1, -2)).as_rotvec()
    error = np.concatenate([diff, rotvec], axis=-1)[..., rows]
    pos = np.linalg.norm(error[..., rows < 3], axis=-1)
    ori = np.linalg.norm(error[..., rows >= 3], axis=-1)
    return pos, ori


@pytest.mark.parametrize("name", ROBOTS)
def test_round_trip_of_random_reachable_poses(name):
    robot = load_robot(name)
    poses = robot.fk(random_configurations(robot, POSES))
    result = robot.ik(poses)
    assert result.q.shape == (POSES, robot.n) and result.success.shape == (POSES,)
    assert result.success.mean() >= MIN_SUCCESS
    assert robot.within_limits(result.q).all()  # the misses too
    pos, ori = independent_errors(robot, result.q, poses)
    ok = result.success
    assert np.all(pos[ok] <= ik.TOL_POSITION * 1.001) and np.all(ori[ok] <= ik.TOL_ORIENTATION * 1.001)
    # the reported errors are those of the returned q (SciPy's angle to ~1e-15 rad)
    np.testing.assert_allclose(result.position_error, pos, rtol=1e-9, atol=1e-14)
    np.testing.assert_allclose(result.orientation_error, ori, rtol=1e-6, atol=1e-12)
    assert np.all(result.iterations >= 1) and np.all(result.iterations <= ik.ITERATIONS * ik.ATTEMPTS)


def test_snake12_round_trip():
    robot = load_robot("snake12")
    poses = robot.fk(random_configurations(robot, 8))
    result = robot.ik(poses, **PLAIN)
    assert result.success.mean() >= MIN_SUCCESS * 0.85 and robot.within_limits(result.q).all()
    pos, ori = independent_errors(robot, result.q[result.success], poses[result.success])
    assert np.all(pos <= ik.TOL_POSITION * 1.001) and np.all(ori <= ik.TOL_ORIENTATION * 1.001)


@pytest.mark.parametrize("name", ["iiwa14", "planar3"])
def test_one_pose_equals_its_row_of_a_batch_and_is_deterministic(name):
    robot = load_robot(name)
    poses = robot.fk(random_configurations(robot, 40, seed=3))
    batch = robot.ik(poses)
    again = robot.ik(poses)
    np.testing.assert_array_equal(batch.q, again.q)
    for k in range(40):
        one = robot.ik(poses[k])
        assert one.q.shape == (robot.n,) and one.success.shape == ()
        # CasADi's evaluator (one pose) and the NumPy replay (a batch) run the same operations
        np.testing.assert_array_equal(one.q, batch.q[k])
        assert one.iterations == batch.iterations[k] and one.success == batch.success[k]


def test_batch_shape_is_kept():
    robot = load_robot("planar3")
    poses = robot.fk(random_configurations(robot, 6).reshape(2, 3, robot.n))
    result = robot.ik(poses)
    assert result.q.shape == (2, 3, 3) and result.position_error.shape == (2, 3)


def test_a_solution_at_the_seed_is_found_in_one_step():
    robot = load_robot("panda")
    q = random_configurations(robot, 1, seed=11)[0]
    result = robot.ik(robot.fk(q), seed=q, **PLAIN)
    assert result.success and result.iterations == 1
    np.testing.assert_array_equal(result.q, q)


def test_q0_pulls_the_self_motion_toward_it():
    """From the same seed, the solution found with q0 given is nearer q0 than the one with
    the default (joint-limit) criterion, on most poses of a redundant arm."""
    robot = load_robot("modular8")
    q = random_configurations(robot, 20, seed=5)
    poses = robot.fk(q)
    target = robot.qmid + 0.3 * (robot.qmax - robot.qmid)
    near = robot.ik(poses, target, seed=robot.qmid)
    free = robot.ik(poses, seed=robot.qmid)
    both = near.success & free.success
    assert both.sum() >= 15
    closer = np.linalg.norm(near.q - target, axis=1) <= np.linalg.norm(free.q - target, axis=1)
    assert closer[both].mean() >= 0.7


# The closest configuration of a miss is the best of the search's iterates, not the minimiser of
# ½‖e‖²: here 0.28 m above the least distance with restarts that also move a held joint's
# neighbours (0.21 m, orientation 0.11 rad, without them; 0.11 m, orientation 0.47 rad, with
# every third restart afresh); a folded arm would be ~0.9 m above.
STRETCHED_SLACK = 0.35


def test_unreachable_pose_returns_the_closest_configuration_reached():
    robot = load_robot("iiwa14")
    pose = np.eye(4)
    pose[:3, 3] = [3.0, 0.0, 0.5]  # the iiwa reaches 1.2 m from its base
    result = robot.ik(pose)
    assert not result.success
    assert robot.within_limits(result.q)
    pos, ori = independent_errors(robot, result.q, pose)
    np.testing.assert_allclose([result.position_error, result.orientation_error], [pos, ori], rtol=1e-6)
    # closest in ½‖e‖² (m², rad²), which trades position for orientation: nearer than the seed,
    # and the arm stretched toward the target, within STRETCHED_SLACK of the least distance
    # (3 m − reach about the shoulder, the reach sampled from the workspace)
    seed_pos, seed_ori = independent_errors(robot, robot.qmid, pose)
    assert pos**2 + ori**2 < seed_pos**2 + seed_ori**2
    reach = np.linalg.norm(robot.fk(random_configurations(robot, 20000))[:, :3, 3] - [0, 0, 0.36], axis=1).max()
    assert result.position_error <= np.linalg.norm(np.array([3.0, 0, 0.5]) - [0, 0, 0.36]) - reach + STRETCHED_SLACK


def test_planar_arm_ignores_the_rows_outside_its_task():
    robot = load_robot("planar3")
    q = np.array([0.3, -0.5, 0.7])
    pose = robot.fk(q)
    pose[2, 3] += 0.25  # z is not a task row of the planar arm
    result = robot.ik(pose)
    assert result.success
    reached = robot.fk(result.q)
    np.testing.assert_allclose(reached[:2, 3], pose[:2, 3], atol=ik.TOL_POSITION)


@pytest.mark.parametrize("pose, message", [
    (np.eye(3), "shape"),
    (np.full((4, 4), np.nan), "NaN"),
    (np.diag([1.0, 1.0, 2.0, 1.0]), "rotation"),
    (np.diag([1.0, 1.0, -1.0, 1.0]), "rotation"),
    (np.array([[1.0, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 1, 1]]), "last row"),
])
def test_bad_poses_are_rejected(pose, message):
    with pytest.raises(ValueError, match=message):
        load_robot("planar3").ik(pose)


def test_bad_seed_is_rejected():
    robot = load_robot("planar3")
    with pytest.raises(ValueError, match="3 finite joint values"):
        robot.ik(np.eye(4), seed=[0.0, 1.0])
    result = robot.ik(robot.fk(robot.q0), seed="q0")
    assert result.success and result.iterations == 1


# -- the generated C against its Python twin ---------------------------------------------------

# The float C solves to the float tolerances below (what single precision resolves on a
# ~1 m arm: 6e-8 relative per rounding, a chain of ~10 products); its solution, checked by the
# double FK, may miss them by the float FK's own error (≤ 2e-6, FLOAT_BOUNDS["fk"]).
FLOAT_TOL = 1e-4
FLOAT_FK_SLACK = 2e-6
# The float solver reaches that many of the poses the double one does (the benchmark measures it).
FLOAT_MIN_SUCCESS = 0.9
# The float build clamps to the float-rounded limits: at most half an ulp of the limit outside.
FLOAT_LIMIT_SLACK = 2.4e-7


@pytest.fixture(scope="module")
def compiled_ik(tmp_path_factory):
    """name -> {precision: (ctypes function, reference)} of an ik-only build."""
    import ctypes

    from armgen.codegen.compiled import build_library
    from armgen.codegen.generate import CodegenConfig, generate, write

    built = {}

    def get(name):
        if name not in built:
            robot = load_robot(name)
            out = tmp_path_factory.mktemp(name)
            write(generate(CodegenConfig(robot, functions=("ik",))), out)
            built[name] = {}
            for precision, real in (("double", ctypes.c_double), ("float", ctypes.c_float)):
                lib = ctypes.CDLL(str(build_library(out, name, precision, out)))
                fn = lib[f"{name}_ik"]
                fn.restype = ctypes.c_int
                built[name][precision] = (fn, real)
        return built[name]
    return get


def call_c(entry, robot, pose, seed, rest, use_rest, tol, cap=ik.MAX_ITERATIONS):
    import ctypes

    fn, real = entry
    dtype = np.float64 if real is ctypes.c_double else np.float32
    buffers = [np.ascontiguousarray(pose.T.reshape(16), dtype=dtype), np.asarray(seed, dtype=dtype),
               np.asarray(rest, dtype=dtype)]
    q = np.zeros(robot.n, dtype=dtype)
    scalars = [real() for _ in range(4)]
    pointer = ctypes.POINTER(real)
    status = fn(*[b.ctypes.data_as(pointer) for b in buffers], real(use_rest), real(tol), real(tol), real(cap),
                q.ctypes.data_as(pointer), *[ctypes.byref(s) for s in scalars])
    return status, q.astype(float), [s.value for s in scalars]


@pytest.mark.parametrize("name", ["planar3", "iiwa14"])
def test_double_c_is_bit_identical_to_python(name, compiled_ik):
    robot = load_robot(name)
    entry = compiled_ik(name)["double"]
    q_true = random_configurations(robot, 25, seed=13)
    poses = robot.fk(q_true)
    for k, pose in enumerate(poses):
        use_rest = k % 2
        rest = q_true[(k + 1) % 25]
        cap = [ik.MAX_ITERATIONS, 3, 1, 20][k % 4]  # also the early stop
        py = robot.ik(pose, rest if use_rest else None, seed=robot.qmid, max_iterations=cap)
        status, q, (pos, ori, iterations, success) = call_c(entry, robot, pose, robot.qmid, rest if use_rest else robot.qmid,
                                                           use_rest, ik.TOL_POSITION, cap)
        np.testing.assert_array_equal(q, py.q)
        assert (pos, ori, iterations, success) == (py.position_error, py.orientation_error, py.iterations, py.success)
        assert status == (0 if py.success else 2)


@pytest.mark.parametrize("name", ["planar3", "iiwa14"])
def test_float_c_reaches_the_float_tolerance(name, compiled_ik):
    robot = load_robot(name)
    entry = compiled_ik(name)["float"]
    poses = robot.fk(random_configurations(robot, 40, seed=17))
    reached = 0
    for pose in poses:
        status, q, (pos, ori, iterations, success) = call_c(entry, robot, pose, robot.qmid, robot.qmid, 0, FLOAT_TOL)
        assert np.all((q >= robot.qmin - FLOAT_LIMIT_SLACK) & (q <= robot.qmax + FLOAT_LIMIT_SLACK))
        assert status == (0 if success else 2)
        if success:
            reached += 1
            true_pos, true_ori = independent_errors(robot, q, pose)
            assert true_pos <= FLOAT_TOL + FLOAT_FK_SLACK and true_ori <= FLOAT_TOL + FLOAT_FK_SLACK
    assert reached >= FLOAT_MIN_SUCCESS * len(poses)


def test_c_status_for_misses_and_nonfinite_input(compiled_ik):
    robot = load_robot("planar3")
    entry = compiled_ik("planar3")["double"]
    far = np.eye(4)
    far[0, 3] = 10.0
    status, q, (pos, ori, iterations, success) = call_c(entry, robot, far, robot.qmid, robot.qmid, 0, 1e-6)
    assert status == 2 and success == 0 and iterations == ik.ITERATIONS * ik.ATTEMPTS and robot.within_limits(q)
    bad = robot.fk(robot.qmid)
    bad[1, 3] = np.nan
    assert call_c(entry, robot, bad, robot.qmid, robot.qmid, 0, 1e-6)[0] == BAD_TARGET  # not a pose
    assert call_c(entry, robot, robot.fk(robot.qmid), [np.inf, 0, 0], robot.qmid, 0, 1e-6)[0] == 1


# -- targets that are not poses (issue 37) -------------------------------------------------------

BAD_TARGET = 3  # <P>_BAD_TARGET


def stretched(pose, defect):
    """The pose with its rotation's x column stretched: max |R^T R - I| = defect (exactly in exact
    arithmetic, (1 + e)^2 - 1; computed here by NumPy, not by the check under test)."""
    t = pose.copy()
    t[:3, 0] *= np.sqrt(1.0 + defect)
    return t


def candidate_targets(robot):
    """(name, 4x4, defect): poses, non-poses and both sides of each build's tolerance; the defect
    max(|R^T R - I|, |T(3, :) - [0 0 0 1]|) by NumPy (inf: not finite or mirrored)."""
    pose = robot.fk(robot.qmid + 0.1)
    shear = np.eye(3)
    shear[0, 1] = 0.2
    out = [("pose", pose), ("zero", np.zeros((4, 4))), ("identity", np.eye(4))]
    for name, rot in (("scaled", 2.0 * pose[:3, :3]), ("sheared", pose[:3, :3] @ shear),
                      ("mirrored", pose[:3, :3] @ np.diag([1.0, 1.0, -1.0])), ("zero_rotation", np.zeros((3, 3)))):
        t = pose.copy()
        t[:3, :3] = rot
        out.append((name, t))
    for tol in (ik.POSE_TOL, ik.FLOAT_POSE_TOL):
        for factor in (0.5, 2.0):
            out.append((f"stretched {factor} x {tol:g}", stretched(pose, factor * tol)))
            t = pose.copy()
            t[3, 2] = factor * tol
            out.append((f"last row {factor} x {tol:g}", t))
    for k in ((1, 3), (2, 2), (3, 3)):
        t = pose.copy()
        t[k] = np.nan
        out.append((f"NaN at {k}", t))
    result = []
    for name, t in out:
        rot = t[:3, :3]
        finite = np.all(np.isfinite(t))
        defect = np.inf if not finite or np.linalg.det(rot) <= 0 else max(
            np.max(np.abs(rot.T @ rot - np.eye(3))), np.max(np.abs(t[3] - [0, 0, 0, 1])))
        result.append((name, t, defect))
    return result


def test_python_refuses_exactly_the_targets_that_are_not_poses():
    """Robot.ik and the numeric path (ik.solve) raise for a defect beyond POSE_TOL, and only then
    (the last row within it is accepted too: a pose that went through an inverse)."""
    robot = load_robot("planar3")
    seeds = robot.qmid[None]
    for name, target, defect in candidate_targets(robot):
        if defect <= ik.POSE_TOL:
            assert robot.ik(target).q.shape == (robot.n,), name
            ik.solve(robot.symbolic.ik_definition, target[None], seeds, seeds, 0.0, 1e-6, 1e-6)
        else:
            with pytest.raises(ValueError, match="NaN|rotation|last row"):
                robot.ik(target)
            with pytest.raises(ValueError, match="NaN|rotation|last row"):
                ik.solve(robot.symbolic.ik_definition, target[None], seeds, seeds, 0.0, 1e-6, 1e-6)
    batch = np.stack([target for _, target, _ in candidate_targets(robot)[:3]])
    with pytest.raises(ValueError, match="pose 1 of the batch"):
        robot.ik(batch)


@pytest.mark.parametrize("precision, tol", [("double", ik.POSE_TOL), ("float", ik.FLOAT_POSE_TOL)])
def test_c_returns_bad_target_for_the_same_targets_and_takes_no_step(compiled_ik, precision, tol):
    """The generated ik: BAD_TARGET (before: OK or NOT_CONVERGED, and a zero rotation reported
    orientation error 0) exactly where the defect exceeds the build's tolerance, 0 iterations, q
    the seed; the double build refuses what Python refuses."""
    robot = load_robot("planar3")
    entry = compiled_ik("planar3")[precision]
    seed = robot.qmid + 0.05
    for name, target, defect in candidate_targets(robot):
        status, q, (pos, ori, iterations, success) = call_c(entry, robot, target, seed, seed, 1, 1e-6)
        if defect > tol:
            assert status == BAD_TARGET and iterations == 0 and success == 0, name
            np.testing.assert_array_equal(q, seed.astype(np.float32 if precision == "float" else float), name)
        else:
            assert status in (0, 2) and iterations >= 1, name


@pytest.mark.parametrize("cap", [0, -1, -1e9])
def test_max_iterations_of_zero_or_less_takes_no_step(compiled_ik, cap):
    """C and the numeric path: NOT_CONVERGED, 0 iterations, q the seed (use_rest = 1: not turned),
    errors not evaluated (ERROR_START). Before: one step was taken."""
    robot = load_robot("planar3")
    pose = robot.fk(robot.qmid + 0.2)
    seed = robot.qmid
    status, q, (pos, ori, iterations, success) = call_c(compiled_ik("planar3")["double"], robot, pose, seed, seed, 1,
                                                       1e-6, cap)
    assert (status, iterations, success) == (2, 0, 0) and pos == ori == ik.ERROR_START
    np.testing.assert_array_equal(q, seed)
    solve = robot.symbolic.ik_definition.function
    outputs = [np.asarray(x).ravel() for x in solve(pose, seed, seed, 1, 1e-6, 1e-6, cap)]
    np.testing.assert_array_equal(outputs[0], seed)
    assert [float(x[0]) for x in outputs[1:]] == [ik.ERROR_START, ik.ERROR_START, 0.0, 0.0]


# -- command line ----------------------------------------------------------------------------------

def test_cli_prints_the_solution_and_exits_0():
    from click.testing import CliRunner

    from armgen.cli.main import cli
    from armgen.robot import matrix_rpy

    robot = load_robot("panda")
    pose = robot.fk(robot.qr + 0.1)
    roll, pitch, yaw = np.degrees(matrix_rpy(pose[:3, :3]))
    numbers = [repr(float(v)) for v in (*pose[:3, 3], roll, pitch, yaw)]
    result = CliRunner().invoke(cli, ["ik", "panda", "--xyz", *numbers[:3], "--rpy", *numbers[3:],
                                      "--units", "deg", "--seed", "qr"])
    assert result.exit_code == 0, result.output
    printed = np.radians([float(line.split()[1]) for line in result.output.splitlines()[1:1 + robot.n]])
    pos, ori = independent_errors(robot, printed, pose)
    assert pos <= 1e-6 and ori <= 1e-6  # printed to 9 digits: ~1e-9 rad per joint


def test_cli_exit_3_prints_the_closest_and_exit_2_for_a_bad_seed():
    from click.testing import CliRunner

    from armgen.cli.main import cli

    miss = CliRunner().invoke(cli, ["ik", "iiwa14", "--xyz", "3", "0", "0.5"])
    assert miss.exit_code == 3 and "closest reached" in miss.output and "no configuration" in miss.output
    assert len(miss.output.splitlines()) >= 8  # the 7 joints of the closest configuration
    bad = CliRunner().invoke(cli, ["ik", "iiwa14", "--xyz", "0.5", "0", "0.5", "--seed", "1,2"])
    assert bad.exit_code == 2 and "--seed" in bad.output


# -- PTP through tool poses --------------------------------------------------------------------------

def ptp_pose_task(robot, configurations, **waypoints):
    from armgen.robot import matrix_rpy

    poses = robot.fk(configurations)
    return {"planner": "ptp", "robot": robot.name, "units": {"angle": "deg"},
            "waypoints": {"xyz": poses[:, :3, 3].tolist(),
                          "rpy": [np.degrees(matrix_rpy(p[:3, :3])).tolist() for p in poses],
                          "t": [2.0 * k for k in range(len(poses))], **waypoints}}, poses


def test_ptp_waypoints_as_poses_are_solved_nearest_and_recorded():
    import armgen

    robot = load_robot("panda")
    # a short walk: each waypoint a small joint move from the one before (the branch to keep)
    walk = robot.qr + np.cumsum(np.tile([0.15, -0.1, 0.1, 0.2, -0.1, 0.15, 0.1], (4, 1)), axis=0)
    task, poses = ptp_pose_task(robot, walk, seed="qr")
    plan = armgen.plan(task)
    record = plan.metadata["ik"]
    solved = np.array(record["waypoints"])
    assert solved.shape == (4, robot.n) and robot.within_limits(solved).all()
    pos, ori = independent_errors(robot, solved, poses)
    assert np.all(pos <= ik.TOL_POSITION * 1.001) and np.all(ori <= ik.TOL_ORIENTATION * 1.001)
    # nearest in joint space: each solution is no farther from the one before than the walk's
    # own configuration of that pose (another solution of it); a branch flip would be radians
    previous = np.vstack([robot.qr, solved[:-1]])
    assert np.all(np.linalg.norm(solved - previous, axis=1) <= np.linalg.norm(walk - previous, axis=1))
    # the joint splines pass through the solved configurations at the knots, at rest there
    knots = plan.metadata["knot_times_s"]
    data = plan.to_pandas()
    for k, t in enumerate(knots):
        row = data.iloc[int(np.argmin(np.abs(data["t_s"] - t)))]
        got = [row[f"theta_{j.name}_rad"] for j in robot.joints]
        np.testing.assert_allclose(got, solved[k], atol=1e-9)
        assert max(abs(row[f"omega_{j.name}_rad_s"]) for j in robot.joints) < 1e-9


def test_ptp_unreachable_pose_is_infeasible_and_bad_fields_are_named():
    import armgen
    from armgen.errors import PlanningError, TaskFileError

    robot = load_robot("panda")
    task, _ = ptp_pose_task(robot, np.array([robot.qr, robot.qr + 0.2]))
    task["waypoints"]["xyz"][1] = [3.0, 0.0, 0.5]
    with pytest.raises(PlanningError, match="waypoint 1"):
        armgen.plan(task)
    task, _ = ptp_pose_task(robot, np.array([robot.qr, robot.qr + 0.2]))
    task["waypoints"]["theta"] = {j.name: [0.0, 0.0] for j in robot.joints}
    with pytest.raises(TaskFileError, match="either theta"):
        armgen.plan(task)


def test_max_iterations_bounds_the_steps():
    robot = load_robot("panda")
    poses = robot.fk(random_configurations(robot, 30, seed=21))
    full = robot.ik(poses, **PLAIN)
    for cap in (1, 4, 40):
        capped = robot.ik(poses, max_iterations=cap, **PLAIN)
        assert np.all(capped.iterations <= cap)
        # the same steps up to the cap: a pose solved within it is solved identically
        early = full.iterations <= cap
        np.testing.assert_array_equal(capped.q[early], full.q[early])
        assert np.all(capped.success[early]) and not np.any(capped.success[~early & ~full.success])
    with pytest.raises(ValueError, match="max_iterations"):
        robot.ik(poses[0], max_iterations=0)


@settings(max_examples=40, deadline=None, derandomize=True)
@given(name=st.sampled_from(["planar3", "iiwa14", "modular8"]),
       fractions=st.lists(st.floats(0.0, 1.0), min_size=8, max_size=8))
def test_a_pose_solved_from_its_own_configuration_is_that_configuration(name, fractions):
    """Invariant: started at a configuration that already reaches the pose, the solver stops
    at its first step and returns that configuration unchanged (also at a limit)."""
    robot = load_robot(name)
    q = robot.qmin + (robot.qmax - robot.qmin) * np.array(fractions[:robot.n])
    result = robot.ik(robot.fk(q), seed=q, **PLAIN)
    assert result.success and result.iterations == 1
    np.testing.assert_array_equal(result.q, q)


# Closed-form references agree with the SX to rounding: a few ulps of 1 m or 1 rad.
REFERENCE_TOL = 1e-12


def _symbolic(expression_builder, *shapes):
    symbols = [ca.SX.sym(f"x{k}", *shape) for k, shape in enumerate(shapes)]
    return ca.Function("f", symbols, [expression_builder(*symbols)])


def _azimuth(point):
    return np.arctan2(point[1], point[0])  # about the base z: both arms' first axis


@pytest.mark.parametrize("name", ["panda", "iiwa14"])
def test_the_seed_turns_about_the_first_axis_toward_the_target(name):
    """The turned seed's tool point has the target's azimuth about the (vertical) first axis,
    by the NumPy FK; the other joints are unchanged; with use_rest = 1 the seed is kept, and so
    is a seed whose tool point lies on that axis (iiwa14 stretched upright)."""
    robot = load_robot(name)
    definition = robot.symbolic.ik_definition
    turn = _symbolic(definition.aligned_seed, (robot.n, 1), (4, 4), (1, 1))
    upright = np.zeros(robot.n)
    if name == "iiwa14":
        np.testing.assert_array_equal(np.asarray(turn(upright, robot.fk(robot.qmid + 0.5), 0.0)).ravel(), upright)
    seed = robot.qmid + 0.8 * np.eye(robot.n)[1]  # the shoulder bent: the tool point off the axis
    checked = 0
    for target_q in random_configurations(robot, 40, seed=3):
        target = robot.fk(target_q)
        turned = np.asarray(turn(seed, target, 0.0)).ravel()
        np.testing.assert_array_equal(turned[1:], seed[1:])
        np.testing.assert_array_equal(np.asarray(turn(seed, target, 1.0)).ravel(), seed)
        assert robot.qmin[0] <= turned[0] <= robot.qmax[0]
        goal = target[:3, 3]  # both arms: the first axis is the base z through the origin
        if np.hypot(goal[0], goal[1]) <= ik.AZIMUTH_MIN_SINE * np.linalg.norm(goal):  # near the axis: kept
            assert turned[0] == seed[0]
        elif robot.qmin[0] < turned[0] < robot.qmax[0]:  # not clamped: the azimuths agree
            gap = _azimuth(robot.fk(turned)[:3, 3]) - _azimuth(target[:3, 3])
            assert abs((gap + np.pi) % (2 * np.pi) - np.pi) < REFERENCE_TOL
            checked += 1
    assert checked >= 20


def test_held_joint_step_is_the_reduced_least_squares_step():
    """held_joint_step against NumPy: the held joint moves to its limit, and the others take
    α_F + J_Fᵀ (J_F J_Fᵀ + λI)⁻¹ (e − u δ − J α_F) from a dense solve with its column removed."""
    from armgen.symbolic.steps import ldl_factor, ldl_solve
    rng = np.random.default_rng(5)
    n, m = 7, 6
    qmin, qmax = -np.ones(n), np.ones(n)
    for _ in range(20):
        jac, e, alpha = rng.normal(size=(m, n)), rng.normal(size=m), 0.1 * rng.normal(size=n)
        q = rng.uniform(-0.9, 0.9, n)
        lam = 0.05
        J, E, A, Q = ca.SX.sym("J", m, n), ca.SX.sym("e", m), ca.SX.sym("a", n), ca.SX.sym("q", n)
        factor = ldl_factor(J @ J.T + lam * ca.SX.eye(m))
        solved = ldl_solve(factor, E - J @ A)
        trial = Q + A + J.T @ solved
        step = ca.Function("s", [J, E, A, Q], [ik.held_joint_step(J, factor, Q, trial, A, solved, qmin, qmax), trial])
        got, trial_value = (np.asarray(x).ravel() for x in step(jac, e, alpha, q))
        excess = np.maximum(trial_value - qmax, qmin - trial_value) / (qmax - qmin)
        if excess.max() <= 0:
            np.testing.assert_allclose(got, trial_value - q, atol=REFERENCE_TOL)
            continue
        h = int(np.argmax(excess))
        move = np.clip(trial_value[h], qmin[h], qmax[h]) - q[h]
        free = np.arange(n) != h
        jf, af = jac[:, free], alpha[free]
        expected = np.empty(n)
        expected[h] = move
        expected[free] = af + jf.T @ np.linalg.solve(jf @ jf.T + lam * np.eye(m), e - jac[:, h] * move - jf @ af)
        np.testing.assert_allclose(got, expected, atol=1e-10)


def test_a_restart_steps_from_its_configuration_turned_toward_the_target():
    """The restart turn's identity (IKDefinition.step): the pose error of the configuration
    turned by δ about the first axis equals this configuration's error toward the target turned
    back by δ (``_turned_back``), rotated by δ (SciPy's rotation), position and orientation
    rows alike; J rotates the same way, so one J and factor serve the turned configuration."""
    from armgen.symbolic.kinematics import chain
    robot = load_robot("panda")
    q_sym, target_sym, angle_sym = ca.SX.sym("q", robot.n), ca.SX.sym("T", 4, 4), ca.SX.sym("angle")
    frames, _, tool = chain(robot, q_sym)
    error = ca.Function("e", [q_sym, target_sym], [ik.pose_error(tool, target_sym)])
    turned_back = ca.Function("t", [q_sym, target_sym, angle_sym],
                              [ik._turned_back(target_sym, frames[0], angle_sym), frames[0]])
    rng = np.random.default_rng(17)
    for q, goal in zip(random_configurations(robot, 20, seed=3), random_configurations(robot, 20, seed=4)):
        target, angle = robot.fk(goal), rng.uniform(-2.5, 2.5)
        back, frame = (np.asarray(x) for x in turned_back(q, target, angle))
        rotation = Rotation.from_rotvec(frame[:3, 2] * angle).as_matrix()
        turned = q.copy()
        turned[0] += angle
        expected = np.asarray(error(turned, target)).ravel()
        got = np.asarray(error(q, back)).ravel()
        np.testing.assert_allclose(np.concatenate([rotation @ got[:3], rotation @ got[3:]]), expected, atol=1e-11)
