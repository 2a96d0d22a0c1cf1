"""Hardening, third round (issue 27): projects and sweeps lose nothing, output sets are
all-or-nothing, URDF robots obey the robot-file bounds, caps and clean errors everywhere."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from armgen.cli.main import cli
from conftest import require_tool, terminal_sigint

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


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


# -- 3, 6, 7, 8. sweeps: Ctrl-C keeps the finished rows, caps, clean errors, resume refuses --

SWEEP_TASK = EXAMPLES / "ptp_single_joint.toml"


def sweep_args(out: Path, *extra: str) -> list[str]:
    return ["sweep", str(SWEEP_TASK), "-o", str(out), *extra]


@pytest.mark.parametrize("workers", ["1", "2"])
def test_ctrl_c_stops_the_sweep_and_keeps_the_finished_rows(tmp_path, workers):
    """SIGINT to the sweep's process (as Ctrl-C sends it to the whole process group) stops it
    promptly, writes the rows that finished and says so truthfully; --resume then skips them."""
    out = tmp_path / "s.csv"
    env = {**os.environ, "ARMGEN_NO_PROGRESS": "1"}
    values = ", ".join(str(1 + k * 1e-3) for k in range(SWEEP_RUNS))
    proc = subprocess.Popen([sys.executable, "-m", "armgen.cli.main", "sweep", str(FAULT_TASK), "-o", str(out),
                             "--set", "timing.duration=1", "--set", "fault.time=0.5", "--set", "path.turns=0.5",
                             "--grid", f"method.K=[{values}]", "--workers", workers],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, start_new_session=True,
        preexec_fn=terminal_sigint)
    time.sleep(SWEEP_INTERRUPT_AFTER_S)
    os.killpg(proc.pid, signal.SIGINT)
    try:
        stdout, stderr = proc.communicate(timeout=SWEEP_STOP_WITHIN_S)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        pytest.fail(f"the sweep still ran {SWEEP_STOP_WITHIN_S} s after Ctrl-C")
    assert proc.returncode == 130, stdout + stderr
    import pandas as pd

    if "no run finished" in stderr:
        assert not out.exists()
    else:
        rows = len(pd.read_csv(out))
        assert f"wrote the {rows} finished runs to {out}" in stderr and "--resume" in stderr, stderr
        assert 0 < rows < SWEEP_RUNS


# 2000 short fault-tolerant plans (~50 ms each: a minute or more in all). Ctrl-C comes once the
# sweep has planned for a while (imports take ~2 s); it must be over well before the sweep
# would be (the finding: it ran on for the whole sweep).
FAULT_TASK = EXAMPLES / "modular8_fault_circle_gpm.toml"
SWEEP_RUNS = 2000


def test_ctrl_c_inside_a_run_that_swallows_it_still_stops_the_sweep(tmp_path, monkeypatch):
    """A library inside a run may turn the interrupt into its own error (CasADi makes a Ctrl-C in
    its C++ a RuntimeError): the sweep then went on to its end (seen as a sweep that ignored
    Ctrl-C about half of the time). In process, Ctrl-C only sets a flag: the run in progress ends
    undisturbed, is not kept, and the sweep stops there with the runs before it written."""
    from armgen.errors import Interrupted
    from armgen.planning import sweep as sweep_module
    from armgen.planning.result import PlanResult

    calls = []

    def run_task_swallowing_ctrl_c(task, source, sha256="", backend="symbolic"):
        calls.append(task["method"]["K"])
        if len(calls) == 3:  # Ctrl-C arrives while the third run is inside a library call
            try:
                os.kill(os.getpid(), signal.SIGINT)
                time.sleep(0.05)
            except KeyboardInterrupt:
                raise RuntimeError("KeyboardInterrupt") from None  # what CasADi makes of it
        return PlanResult(["t_s"], np.zeros((1, 1)), {"summary": {"K": float(task["method"]["K"])}})

    monkeypatch.setattr(sweep_module, "run_task", run_task_swallowing_ctrl_c)
    task = {"planner": "fault_tolerant", "method": {"K": 0.0}}
    out = tmp_path / "s.csv"
    spec = sweep_module.SweepSpec(grid=[("method.K", [1.0, 2.0, 3.0, 4.0, 5.0])])
    with pytest.raises(Interrupted, match="interrupted after 2 of 5 runs"):
        sweep_module.sweep(task, "task.toml", "", spec, out)
    assert calls == [1.0, 2.0, 3.0]
    assert [row["method.K"] for row in sweep_module.read_table(out)] == [1.0, 2.0]
SWEEP_INTERRUPT_AFTER_S = 10.0
SWEEP_STOP_WITHIN_S = 15.0


@pytest.mark.parametrize("args", [["--random", "1000000000", "--range", "step=0.001:0.002"],
                                  ["--grid", f"step=[{', '.join(['0.001'] * 3000)}]",
                                   "--grid", f"compare=[{', '.join(['[]'] * 3000)}]"]])
def test_sweep_size_is_capped_before_work(tmp_path, args):
    out = tmp_path / "s.csv"
    result = run(*sweep_args(out, *args))
    assert result.exit_code == 2 and "more than the cap of 100000" in result.output, result.output
    assert not out.exists()


@pytest.mark.parametrize("table, why", [
    ("date,city\n2020-01-01,Paris\n", "not a table of `armgen sweep`"),
    ('run,step,status,exit_code,message,overrides\n0,0.001,ok,0,,"{""step"": 0.001}"\nxyz,??,garbage,,,[[\n',
     "row 3 is not a row of `armgen sweep`"),
])
def test_resume_refuses_a_table_it_did_not_write(tmp_path, table, why):
    out = tmp_path / "s.csv"
    out.write_text(table)
    result = run(*sweep_args(out, "--grid", "step=[0.001, 0.002]", "--resume", "--workers", "1"))
    assert result.exit_code == 2 and why in result.output and "drop --resume" in result.output, result.output
    assert out.read_text() == table


def test_sweep_in_which_every_run_fails_exits_3(tmp_path):
    out = tmp_path / "s.csv"
    result = run(*sweep_args(out, "--grid", "step=[-1, -2]", "--workers", "1"))
    assert result.exit_code == 3 and "every run of the sweep failed" in result.output, result.output
    assert out.exists()  # the table says why


@pytest.fixture
def nonsense_service():
    """A TCP listener on 127.0.0.1 that answers every connection with garbage."""
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen()
    stop = threading.Event()

    def serve():
        server.settimeout(0.2)
        while not stop.is_set():
            try:
                conn, _ = server.accept()
            except OSError:
                continue
            with conn:
                with contextlib.suppress(OSError):
                    conn.sendall(b"\xff" * 64 + b"HTTP/1.0 200 OK\r\n\r\nnot dask\n")
                    time.sleep(0.5)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    yield f"tcp://127.0.0.1:{server.getsockname()[1]}"
    stop.set()
    thread.join()
    server.close()


def test_scheduler_that_is_not_dask_is_a_tool_error(tmp_path, nonsense_service):
    pytest.importorskip("distributed")
    for address in (nonsense_service, "nonsense://x"):
        out = tmp_path / "s.csv"
        start = time.monotonic()
        result = run(*sweep_args(out, "--grid", "step=[0.001]", "--scheduler", address))
        assert result.exit_code == 4 and "cannot reach a Dask scheduler" in result.output, result.output
        assert time.monotonic() - start < SCHEDULER_GIVE_UP_S
        assert not out.exists()


# the connection timeout (10 s) plus Dask's import and teardown
SCHEDULER_GIVE_UP_S = 40.0


# -- 4. an output set is all-or-nothing, also when a later rename fails or the process dies --

def old_set(folder: Path) -> dict[Path, str]:
    files = {folder / "plan.csv": "old csv", folder / "plan.json": "old json"}
    for path, text in files.items():
        path.write_text(text)
    return files


def test_failing_second_rename_puts_the_first_file_back(tmp_path, monkeypatch):
    from armgen import fileio
    from armgen.errors import OutputError

    old = old_set(tmp_path)
    real = os.replace

    def replace(src, dst, *args, **kwargs):
        if Path(dst).name == "plan.json" and ".armgen-staging-" in str(src):
            raise PermissionError(13, "Permission denied", str(dst))
        return real(src, dst, *args, **kwargs)

    monkeypatch.setattr(fileio.os, "replace", replace)
    with pytest.raises(OutputError, match="nothing was written"):
        fileio.write_file_set({tmp_path / "plan.csv": "new csv", tmp_path / "plan.json": "new json"})
    assert {p: p.read_text() for p in old} == old
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plan.csv", "plan.json"]


def test_set_cut_by_a_kill_between_renames_is_rolled_back_by_the_next_write(tmp_path):
    """A child process dies (os._exit) right after the first rename; the folder then holds a
    mixed set, which the next write into the folder rolls back before writing its own."""
    from armgen import fileio

    old = old_set(tmp_path)
    new_file = tmp_path / "new.csv"  # not there before: goes away on roll-back
    pid = os.fork()
    if pid == 0:  # the child: dies between the renames
        real = os.replace
        count = []

        def replace(src, dst, *args, **kwargs):
            if ".armgen-staging-" in str(src):
                count.append(dst)
                if len(count) == 3:
                    os._exit(9)
            return real(src, dst, *args, **kwargs)

        os.replace = replace
        try:
            fileio.write_file_set({tmp_path / "new.csv": "cut", tmp_path / "plan.csv": "cut csv",
                                   tmp_path / "plan.json": "cut json"})
        finally:
            os._exit(1)
    _, status = os.waitpid(pid, 0)
    assert os.WEXITSTATUS(status) == 9
    assert (tmp_path / "plan.csv").read_text() == "cut csv" and (tmp_path / "plan.json").read_text() == "old json"
    fileio.write_file_set({tmp_path / "other.txt": "another set"})
    assert {p: p.read_text() for p in old} == old
    assert not new_file.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["other.txt", "plan.csv", "plan.json"]


# -- 5. URDF robots obey the robot-file bounds; 12. messages quote a bounded excerpt ---------

def urdf_chain(joints: int = 2, name: str = "j", xyz: str = "0 0 0.1", axis: str = "0 0 1",
               lower: str = "-1", upper: str = "1", robot: str = "arm") -> str:
    links = "".join(f'<link name="l{k}"/>' for k in range(joints + 1))
    body = "".join(f'<joint name="{name}{k}" type="revolute"><parent link="l{k}"/><child link="l{k + 1}"/>'
                   f'<origin xyz="{xyz}"/><axis xyz="{axis}"/><limit lower="{lower}" upper="{upper}"/></joint>'
                   for k in range(joints))
    return f'<robot name="{robot}">{links}{body}</robot>'


def load_urdf(tmp_path: Path, text: str):
    from armgen.robot import load_robot

    path = tmp_path / "f.urdf"
    path.write_text(text)
    return load_robot(path)


@pytest.mark.parametrize("text, match", [
    (urdf_chain(joints=200), r"200 moving joints, more than 64"),
    (urdf_chain(joints=1000), r"1000 moving joints, more than 64"),
    (urdf_chain(xyz="1e12 0 0"), r"xyz = 1e\+12 0 0 is beyond ±1000 m"),
    (urdf_chain(lower="-1e300", upper="1e300"), r"reach beyond ±12.57 rad .*URDF angles are radians"),
    (urdf_chain(axis="1e155 1e155 1e155"), r"<axis>: xyz is so long its length overflows"),
    (urdf_chain(name="not a name "), r"a moving joint's name must be a letter then"),
    (urdf_chain(name="x" * 500_000), r"name=\"x{60}… \(500001 characters\)\"> is longer than 256"),
    (urdf_chain(robot="r" * 500_000), r"is longer than 256"),
    (urdf_chain(robot="not an identifier"), r"robot name 'not an identifier' must be a letter"),
])
def test_urdf_obeys_the_robot_file_bounds(tmp_path, text, match):
    from armgen.errors import RobotFileError

    with pytest.raises(RobotFileError, match=match) as caught:
        load_urdf(tmp_path, text)
    assert len(str(caught.value)) < MAX_MESSAGE_CHARS


# An error message names the file, the place and the fix, and quotes a bounded excerpt.
MAX_MESSAGE_CHARS = 600


def test_sensible_urdf_still_loads(tmp_path):
    robot = load_urdf(tmp_path, urdf_chain(joints=64, xyz="999 0 0", lower="-12.5", upper="12.5"))  # ±2 turns
    assert robot.n == 64


@pytest.mark.parametrize("args", [
    ["plan", "{task}", "--set", "method.name=\"" + "m" * 500_000 + "\""],
    ["plan", "{task}", "--set", "k" * 500_000 + "=1"],
    ["sweep", "{task}", "--grid", "step=" + "9" * 500_000],
])
def test_error_messages_quote_a_bounded_excerpt(tmp_path, args):
    task = str(EXAMPLES / "modular8_wgpm_demo.toml")
    result = run(*[a.replace("{task}", task) for a in args])
    assert result.exit_code == 2, result.output[:300]
    assert len(result.output) < MAX_MESSAGE_CHARS and "characters)" in result.output, result.output


def test_excerpt_helper():
    from armgen.errors import EXCERPT_CHARS, excerpt

    assert excerpt("short") == "short"
    assert excerpt("y" * 1000) == "y" * EXCERPT_CHARS + "… (1000 characters)"
    assert excerpt(list(range(3))) == "[0, 1, 2]"


def test_integer_beyond_the_digit_limit_is_bad_input(tmp_path):
    from armgen.errors import RobotFileError
    from armgen.robot import BUNDLED_DIR, load_robot

    robot = tmp_path / "huge.toml"
    robot.write_text((BUNDLED_DIR / "planar3.toml").read_text().replace("a = 0.5", "a = " + "9" * 5000, 1))
    with pytest.raises(RobotFileError, match=r"huge\.toml: not valid TOML: .*digits"):
        load_robot(robot)


# -- 7. a closed pipe; 10. FIFOs and files that lie about their size --------------------------

def test_show_into_a_closed_pipe_exits_quietly():
    """`armgen show modular8 | head -1`: the reader is gone before armgen writes (closed here
    before the interpreter has even imported armgen)."""
    read, write = os.pipe()
    os.close(read)
    proc = subprocess.run([sys.executable, "-m", "armgen.cli.main", "show", "modular8"], stdout=write,
                          stderr=subprocess.PIPE, text=True, timeout=120)
    os.close(write)
    assert proc.returncode == 141 and proc.stderr == "", proc.stderr


@pytest.mark.parametrize("suffix", [".urdf", ".toml"])
def test_show_refuses_a_fifo_without_blocking(tmp_path, suffix):
    fifo = tmp_path / f"f{suffix}"
    os.mkfifo(fifo)
    proc = subprocess.run([sys.executable, "-m", "armgen.cli.main", "show", str(fifo)], capture_output=True,
                          text=True, timeout=120)  # it used to block for ever: the timeout is the finding
    assert proc.returncode == 2 and "not a regular file" in proc.stderr, proc.stderr


def test_task_file_that_is_a_fifo_is_refused(tmp_path):
    fifo = tmp_path / "t.toml"
    os.mkfifo(fifo)
    result = run("plan", str(fifo))
    assert result.exit_code == 2 and "not a regular file" in result.output, result.output


def test_input_read_is_bounded_not_sized_by_stat(tmp_path, monkeypatch):
    """A file that reports size 0 (as /proc files do) but holds more than the cap."""
    from armgen import schemas
    from armgen.errors import TaskFileError

    big = tmp_path / "big.toml"
    big.write_bytes(b"#" * (schemas.MAX_INPUT_FILE_BYTES + 10))
    real_fstat = os.fstat

    def lying_fstat(fd):
        st = real_fstat(fd)
        return os.stat_result((st.st_mode, st.st_ino, st.st_dev, st.st_nlink, st.st_uid, st.st_gid, 0,
                               st.st_atime, st.st_mtime, st.st_ctime))

    monkeypatch.setattr(schemas.os, "fstat", lying_fstat)
    monkeypatch.setattr(Path, "stat", lambda self, **kw: os.stat_result((0o100644,) + (0,) * 9))
    with pytest.raises(TaskFileError, match=r"larger than the 1048576 bytes a task file may have"):
        schemas.read_input_file(big, schemas.MAX_INPUT_FILE_BYTES, "task file", TaskFileError)
    proc = Path("/proc/self/status")  # a real one: stat says 0 bytes, it holds ~1.5 kB
    if proc.exists():
        monkeypatch.undo()
        assert os.stat(proc).st_size == 0
        with pytest.raises(TaskFileError, match=r"larger than the 100 bytes"):
            schemas.read_input_file(proc, 100, "task file", TaskFileError)
        assert b"Pid" in schemas.read_input_file(proc, schemas.MAX_INPUT_FILE_BYTES, "task file", TaskFileError)


# -- 9. a ptp task's given knot times may not make its plan absurd ----------------------------

PTP_NO_ROBOT = """
planner = "ptp"
method = "cubic"
step = 0.001
[waypoints]
t = [0, {t1}, 2]
theta = [0, 1, 2]
omega = [0, 0.5, 0]
{timing}
"""


@pytest.mark.parametrize("t1, timing, match", [
    ("1e-9", "", r"segment 1 \(A→B\), joint 'j1'.* beyond 1000 rad/s"),
    ("1e-9", "[timing]\nomega_max = [2, 2]", r"segment 1 \(A→B\), joint 'j1'"),
    ("0.2", "[timing]\nomega_max = [2, 2]", r"segment 1 \(A→B\).*over 2 times its timing.omega_max of 2 rad/s"),
])
def test_ptp_refuses_absurd_given_times(tmp_path, t1, timing, match):
    task = tmp_path / "t.toml"
    task.write_text(PTP_NO_ROBOT.format(t1=t1, timing=timing))
    result = run("plan", str(task), "-o", str(tmp_path / "p.csv"))
    assert result.exit_code == 3, result.output
    import re

    assert re.search(match, result.output), result.output
    assert not (tmp_path / "p.csv").exists()


def test_ptp_given_times_may_round_a_bound(tmp_path):
    """1 rad in 0.8 s, at rest at both ends: the cubic peaks at 3Δθ/(2T) = 1.875 rad/s, 1.875
    times the bound of 1 rad/s (< 2): recorded as a violation, planned."""
    task = tmp_path / "t.toml"
    task.write_text(PTP_NO_ROBOT.format(t1="0.8", timing="[timing]\nomega_max = [1, 2]").replace(
        "omega = [0, 0.5, 0]", "omega = [0, 0, 0]"))
    result = run("plan", str(task), "-o", str(tmp_path / "p.csv"))
    assert result.exit_code == 0, result.output
    meta = json.loads((tmp_path / "p.json").read_text())
    assert meta["summary"]["bound_violations"] >= 1


# -- 11. the firmware header generator and the controller refuse out-of-range configurations --

@pytest.fixture(scope="module")
def firmware_builder(tmp_path_factory):
    from armgen import firmware as fw

    return fw.FirmwareBuilder("modular8", tmp_path_factory.mktemp("firmware"))


@pytest.fixture(scope="module")
def line_task():
    """A 1 s line of modular8's tool (resolved rate), as firmware parameters."""
    from armgen.planning.tasks import apply_overrides, load_task
    from armgen import firmware as fw

    task, _ = load_task(EXAMPLES / "modular8_circle_combined.toml")
    apply_overrides(task, ["path.type=line", "path.end=[-450, 400, 900]", "timing.duration=1"])
    return fw.task_from_dict(task, "line")


def rewrite(task, field: str, value: str):
    import dataclasses
    import re

    header, count = re.subn(rf"\.{field} = (\{{[^}}]*\}}|[^,]+),", f".{field} = {value},", task.header, count=1)
    assert count == 1, field
    return dataclasses.replace(task, header="#include <math.h>\n" + header)


@pytest.mark.parametrize("field, value", [
    ("qdot_max", "{" + ", ".join(["CTRL_LIT(3.0)"] * 7 + ["CTRL_LIT(1e300)"]) + "}"),  # one joint's guard
    ("qdot_max", "{" + ", ".join(["CTRL_LIT(3.0)"] * 7 + ["CTRL_LIT(0.0)"]) + "}"), ("residual_rel", "CTRL_LIT(1e300)"), ("residual_abs", "CTRL_LIT(1e300)"),
    ("pos_err_max", "CTRL_LIT(1e300)"), ("blend", "CTRL_LIT(NAN)"), ("blend", "CTRL_LIT(0.75)"),
])
def test_controller_refuses_guards_out_of_range(firmware_builder, line_task, field, value):
    from armgen import firmware as fw

    variant = fw.Variant("host", "double")
    assert fw.run_host(firmware_builder.executable(variant, line_task, "line")).state == "DONE"  # as written
    run_ = fw.run_host(firmware_builder.executable(variant, rewrite(line_task, field, value), f"bad_{field}"))
    assert (run_.summary["init"], run_.fault) == ("BAD_CONFIG", "BAD_CONFIG"), field


def test_header_generator_refuses_non_increasing_knots(tmp_path):
    from armgen.planning.result import read_plan
    from armgen import firmware as fw

    out = tmp_path / "p.csv"
    assert run("plan", str(EXAMPLES / "modular8_ptp_two_segments.toml"), "-o", str(out)).exit_code == 0
    meta = json.loads((tmp_path / "p.json").read_text())
    for knots in ([0.0, 2.0, 2.0], [0.0, 3.0, 1.0], [0.0, float("nan"), 3.0]):
        meta["knot_times_s"] = knots[:len(meta["knot_times_s"])]
        plan = read_plan(out)
        plan.metadata["knot_times_s"] = meta["knot_times_s"]
        with pytest.raises(fw.FirmwareError, match=r"knot_times_s = .* strictly increasing"):
            fw.task_from_plan(plan, "p.csv")


def test_header_generator_names_a_bad_blend():
    from armgen.planning.tasks import apply_overrides, load_task
    from armgen import firmware as fw

    task, _ = load_task(EXAMPLES / "modular8_circle_combined.toml")
    apply_overrides(task, ["timing.law=\"cubic\"", "timing.blend=0.75"])  # unused by the cubic law
    with pytest.raises(fw.FirmwareError, match=r"timing.blend = 0.75 must be in \[0, 0.5\]"):
        fw.task_from_dict(task, "t.toml")


# -- 13. MISRA: the generated code's findings are the documented deviations -------------------

REPO = Path(__file__).resolve().parents[1]
GENERATED_MISRA_HEADING = "## MISRA C:2012 deviations (generated code)"


def generated_code_deviations() -> list[tuple[set[str], set[str]]]:
    """(rules, files) per row of the generated code's table in docs/firmware.md."""
    import re

    text = (REPO / "docs" / "firmware.md").read_text(encoding="utf-8")
    section = text.split(GENERATED_MISRA_HEADING, 1)[1].split("\n## ", 1)[0]
    rows = []
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 3 and re.fullmatch(r"[\d.]+(, [\d.]+)*", cells[0]):
            rows.append(({r.strip() for r in cells[0].split(",")}, {f.strip() for f in cells[1].split(",")}))
    return rows


def test_generated_code_misra_findings_are_documented():
    import re

    cppcheck = require_tool("cppcheck")
    rows = generated_code_deviations()
    assert rows, "the generated code's deviation table is missing from docs/firmware.md"
    folder = REPO / "generated" / "modular8"
    proc = subprocess.run([cppcheck, "--addon=misra", "--std=c99", "--enable=style", "-q",
                           "--template={file}:{line}:{id}", f"-I{folder}", str(folder / "modular8.c")],
                          capture_output=True, text=True, timeout=1800)
    output = proc.stdout + proc.stderr
    findings = {(Path(f).name.replace("modular8", "<robot>"), int(line), rule) for f, line, rule in
                re.findall(r"^(.+?):(\d+):misra-c2012-([\d.]+)$", output, re.M)}
    assert findings, "cppcheck's MISRA addon reported nothing: is the addon installed?"
    dead = re.findall(r"^.+?:\d+:(?:redundantAssignment|unreadVariable|unusedVariable)$", output, re.M)
    assert not dead, f"dead stores in the generated code: {dead[:5]}"
    undocumented = sorted(f"{name}:{line} rule {rule}" for name, line, rule in findings
                          if not any(rule in rules and name in files for rules, files in rows))
    assert not undocumented, "MISRA findings outside the generated code's deviation list:\n" + "\n".join(undocumented)
    stale = [sorted(rules) for rules, files in rows
             if not any(rule in rules and name in files for name, _, rule in findings)]
    assert not stale, f"deviation rows that no finding needs any more: {stale}"
