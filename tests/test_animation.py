"""``armgen animate``: the requested number of frames, GIF without ffmpeg, MP4 with it, clear errors,
a URDF arm drawn through its own kinematics (against Pinocchio)."""

from __future__ import annotations

from importlib.resources import files

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

from armgen.cli.main import cli
from armgen.planning import animation
from armgen.planning.animation import animate_plan, frame_samples
from armgen.planning.result import write_plan
from armgen.planning.tasks import load_task, run_task
from conftest import require_tool
from test_plots import PINOCCHIO_TOL, pinocchio_frames, urdf_plan  # noqa: F401 (urdf_plan: the shared fixture)


def _plan(tmp_path_factory, name):
    path = files("armgen.data").joinpath("examples", f"{name}.toml")
    task, sha = load_task(path)
    result = run_task(task, str(path), sha)
    csv, _ = write_plan(result, tmp_path_factory.mktemp(name) / "plan.csv")
    return result, csv


@pytest.fixture(scope="module")
def short_plan(tmp_path_factory):
    return _plan(tmp_path_factory, "iiwa14_fault_circle_gpm")  # 4 s, 201 samples


@pytest.mark.parametrize("fps, duration", [(10, 1.2), (5, 2.0)])
def test_gif_has_the_requested_frame_count(short_plan, tmp_path, fps, duration):
    result, _ = short_plan
    out = animate_plan(result, tmp_path / "arm.gif", fps=fps, duration=duration)
    with Image.open(out) as gif:
        assert gif.format == "GIF"
        assert gif.n_frames == round(fps * duration)
        assert gif.info["duration"] == pytest.approx(1000 / fps, abs=10)  # ms per frame (GIF stores 10 ms units)


def test_cli_animate_gif_and_snake(tmp_path_factory, tmp_path):
    _, csv = _plan(tmp_path_factory, "snake_planar")
    out = tmp_path / "snake.gif"
    run = CliRunner().invoke(cli, ["animate", str(csv), "-o", str(out), "--fps", "4", "--duration", "1"])
    assert run.exit_code == 0, run.output
    with Image.open(out) as gif:
        assert gif.n_frames == 4
    assert list(tmp_path.iterdir()) == [out]


def test_mp4_with_ffmpeg(short_plan, tmp_path):
    require_tool("ffmpeg")
    out = animate_plan(short_plan[0], tmp_path / "arm.mp4", fps=5, duration=1)
    assert out.read_bytes()[4:8] == b"ftyp"  # ISO base media file


def test_mp4_without_ffmpeg_is_a_clear_error(short_plan, tmp_path, monkeypatch):
    monkeypatch.setattr(animation.shutil, "which", lambda name: None)
    run = CliRunner().invoke(cli, ["animate", str(short_plan[1]), "-o", str(tmp_path / "arm.mp4")])
    assert run.exit_code == 4 and "ffmpeg" in run.output and ".gif" in run.output
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize("args", [["-o", "-"], ["-o", "arm.avi"], ["-o", "arm.gif", "--fps", "0"],
                                  ["-o", "arm.gif", "--duration", "-1"], ["-o", "arm.gif", "--fps", "1e6"],
                                  ["--size", "960"], ["--size", "961x720"], ["--size", "8x8"], ["--size", "axb"]])
def test_bad_options_exit_2_and_write_nothing(short_plan, tmp_path, monkeypatch, args):
    monkeypatch.chdir(tmp_path)
    run = CliRunner().invoke(cli, ["animate", str(short_plan[1]), *args])
    assert run.exit_code == 2, run.output
    assert not any(tmp_path.iterdir())


def test_frames_are_evenly_spaced_plan_samples():
    t = np.linspace(0.0, 10.0, 1001)
    idx, duration = frame_samples(t, fps=4, duration=2.5)
    assert duration == 2.5 and idx.size == 10
    assert idx[0] == 0 and idx[-1] == t.size - 1
    np.testing.assert_allclose(np.diff(t[idx]), 10.0 / 9, atol=0.011)  # one sample step
    idx, duration = frame_samples(t, fps=20, duration=None)  # default: plan length capped at 10 s
    assert duration == 10.0 and idx.size == 200


def test_size_option_sets_the_frame_size_default_laptop_readable(short_plan, tmp_path):
    """--size WxH gives frames of exactly that size; the default is 960×720 (was 512×384)."""
    _, csv = short_plan
    for args, expected in (([], (960, 720)), (["--size", "640x360"], (640, 360))):
        out = tmp_path / f"arm{len(args)}.gif"
        run = CliRunner().invoke(cli, ["animate", str(csv), "-o", str(out), "--fps", "2", "--duration", "1", *args])
        assert run.exit_code == 0, run.output
        with Image.open(out) as gif:
            assert gif.size == expected


# -- a URDF arm moves as its own kinematics say; a CSV without plan.json (issue 37 items 2, 16) --


def test_urdf_arm_links_are_the_joint_origins_of_pinocchio(urdf_plan):
    """Each frame's drawn links pass through the URDF arm's joint origins (Pinocchio) and end at
    its tool; the old DH-only chain drew every joint at the base (a still stick)."""
    from armgen.planning.plotting import new_figure, plan_robot
    from armgen.planning.result import read_plan

    _, csv, model = urdf_plan
    result = read_plan(csv)
    robot = plan_robot(result, csv)
    frames, _ = frame_samples(result.column("t_s"), fps=4, duration=1.0)
    fig = new_figure(6, 4.8)
    draw = animation._serial_scene(fig, result, frames, robot)
    q = np.column_stack([result.column(f"q{i + 1}_rad") for i in range(robot.n)])[frames]
    origins, tools = pinocchio_frames(model, robot, q)
    links = next(line for line in fig.axes[0].get_lines() if line.get_label() == "links (joint frames)")
    drawn = []
    for f in range(len(frames)):
        draw(f)
        drawn.append(np.column_stack(links.get_data_3d()))
    drawn = np.array(drawn) / 1e3  # mm → m
    np.testing.assert_allclose(drawn[:, 1:-1], origins, atol=PINOCCHIO_TOL, rtol=0)
    np.testing.assert_allclose(drawn[:, -1], tools[:, :3, 3], atol=PINOCCHIO_TOL, rtol=0)
    assert np.ptp(drawn[:, -1], axis=0).max() > 0.05  # the tool moves between the frames


def test_animate_without_plan_json_is_a_clear_error_or_drawn_with_robot(urdf_plan, tmp_path):
    project, csv, _ = urdf_plan
    alone = tmp_path / "plan.csv"
    alone.write_bytes(csv.read_bytes())
    run = CliRunner().invoke(cli, ["animate", str(alone), "-o", str(tmp_path / "arm.gif")])
    assert run.exit_code == 2, run.output
    assert f"{tmp_path / 'plan.json'} not found" in run.output and "--robot" in run.output
    assert "Traceback" not in run.output and list(tmp_path.iterdir()) == [alone]
    run = CliRunner().invoke(cli, ["animate", str(alone), "-o", str(tmp_path / "arm.gif"), "--fps", "2",
                                   "--duration", "1", "--robot", str(project / "job" / "arm.toml")])
    assert run.exit_code == 0, run.output
    with Image.open(tmp_path / "arm.gif") as gif:
        assert gif.n_frames == 2
    run = CliRunner().invoke(cli, ["plot", str(alone), "-o", str(tmp_path / "arm.png")])
    assert run.exit_code == 2 and "plan.json not found" in run.output
