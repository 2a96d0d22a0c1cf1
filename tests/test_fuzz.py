"""Fuzzing of the loaders (hypothesis, derandomized): 2 000 mutated robot files and 2 000
mutated task files per run, 500 mutated URDF files, 500 sets of sweep options, 500 poses CSV
files, 1 000 Robot.ik calls and 200 `armgen ik` command lines. Each case must end in a valid
result or a clean error (an ArmgenError with the documented exit code; for Robot.ik a
TypeError/ValueError naming the argument), within its time limit; a case that is certainly
invalid must not be accepted; a failed plan writes nothing. ``benchmarks/fuzz.py`` runs
10 000+ of each."""

from __future__ import annotations

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fuzzing import (FULL_PLAN_BASES, ik_case, ik_cli_case, mutate_ik, mutate_ik_cli, mutate_poses, mutate_robot,
                     mutate_sweep, mutate_task, mutate_urdf, poses_case, robot_case, sweep_case, task_case, urdf_case)

FUZZ_SETTINGS = settings(max_examples=2000, derandomize=True, deadline=None, database=None,
                         suppress_health_check=list(HealthCheck))
# Share of task cases planned in full (and written) rather than only validated by the schema.
FULL_PLAN_SHARE = 0.03


@FUZZ_SETTINGS
@given(st.randoms(use_true_random=False))
def test_fuzzed_robot_files_end_cleanly(rng):
    text, invalid = mutate_robot(rng)
    outcome = robot_case(text)
    assert outcome.kind in ("accepted", "clean"), f"{outcome.kind}: {outcome.detail}\n--- file:\n{text}"
    assert not (invalid and outcome.kind == "accepted"), f"accepted nonsense:\n{text}"


@FUZZ_SETTINGS
@given(st.randoms(use_true_random=False))
def test_fuzzed_task_files_end_cleanly(rng):
    full = rng.random() < FULL_PLAN_SHARE
    name, task, invalid = mutate_task(rng, FULL_PLAN_BASES if full else None)
    outcome = task_case(task, full)
    assert outcome.kind in ("accepted", "clean"), f"{name}: {outcome.kind}: {outcome.detail}\n{task}"
    assert not (invalid and outcome.kind == "accepted"), f"{name}: accepted nonsense: {task}"
    assert not outcome.wrote, f"{name}: a failed plan left files behind"


SMALL_FUZZ_SETTINGS = settings(FUZZ_SETTINGS, max_examples=500)


@SMALL_FUZZ_SETTINGS
@given(st.randoms(use_true_random=False))
def test_fuzzed_urdf_files_end_cleanly(rng):
    text, invalid = mutate_urdf(rng)
    outcome = urdf_case(text)
    assert outcome.kind in ("accepted", "clean"), f"{outcome.kind}: {outcome.detail}\n--- file:\n{text[:2000]}"
    assert not (invalid and outcome.kind == "accepted"), f"accepted nonsense:\n{text[:2000]}"


@SMALL_FUZZ_SETTINGS
@given(st.randoms(use_true_random=False))
def test_fuzzed_sweep_options_end_cleanly(rng):
    options, invalid = mutate_sweep(rng)
    outcome = sweep_case(options)
    shown = {k: (v[:200] if isinstance(v, str) else [x[:200] for x in v] if isinstance(v, list) else v)
             for k, v in options.items()}
    assert outcome.kind in ("accepted", "clean"), f"{outcome.kind}: {outcome.detail}\n{shown}"
    assert not (invalid and outcome.kind == "accepted"), f"accepted nonsense: {shown}"


@SMALL_FUZZ_SETTINGS
@given(st.randoms(use_true_random=False))
def test_fuzzed_poses_files_end_cleanly(rng):
    data, invalid = mutate_poses(rng)
    outcome = poses_case(data)
    assert outcome.kind in ("accepted", "clean"), f"{outcome.kind}: {outcome.detail}\n--- file:\n{data[:2000]!r}"
    assert not (invalid and outcome.kind == "accepted"), f"accepted nonsense:\n{data[:2000]!r}"


@settings(FUZZ_SETTINGS, max_examples=1000)
@given(st.randoms(use_true_random=False))
def test_fuzzed_ik_calls_end_cleanly(rng):
    args, invalid = mutate_ik(rng)
    outcome = ik_case(args)
    assert outcome.kind in ("accepted", "clean"), f"{outcome.kind}: {outcome.detail}\n{args}"
    assert not (invalid and outcome.kind == "accepted"), f"accepted nonsense: {args}"


@settings(FUZZ_SETTINGS, max_examples=200)
@given(st.randoms(use_true_random=False))
def test_fuzzed_ik_command_lines_end_cleanly(rng):
    argv, invalid = mutate_ik_cli(rng)
    outcome = ik_cli_case(argv)
    shown = [a[:200] for a in argv]
    assert outcome.kind in ("accepted", "clean"), f"{outcome.kind}: {outcome.detail}\n{shown}"
    assert not (invalid and outcome.kind == "accepted"), f"accepted nonsense: {shown}"
