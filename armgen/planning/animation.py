"""The arm moving through a plan, as a GIF (Pillow, no other install) or an MP4 (ffmpeg).

Each frame draws the arm from its own forward kinematics (``robot.frames``, DH or URDF alike, of
the robot ``plan.json`` records or ``--robot``): links as straight segments between consecutive
joint-frame origins (base, each joint's frame, the tool), the tool frame's axes (x red, y green,
z blue), the planned tool path dashed and the executed one so far, and a time stamp; for a robot
with capsules the capsules at each frame and the plan's closest approach (marked throughout,
labelled with its time), and the task's obstacles (:mod:`.collision_scene`, the drawing the
figures use). A planner
whose arm the joint frames do not show draws its own scene (its registry entry's
``animation_scene``: snake plans in top and side view with their obstacles and plate openings). Frames are plan samples picked evenly in time so that the video lasts ``duration``
seconds at ``fps`` frames per second.
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import numpy as np
from matplotlib.animation import FFMpegWriter, PillowWriter
from matplotlib.backends.backend_agg import FigureCanvasAgg

from ..errors import PlanFileError, TaskFileError, ToolchainError, excerpt
from ..fileio import atomic_open
from ..progress import progress
from ..robot import Robot
from .registry import PLANNER_NAMES, planner as planner_named
from .collision_scene import draw_approach, draw_capsules, draw_obstacles, plan_scene, scene_points
from .plotting import (FigureOutputError, FigureWriteError, new_figure, plan_joint_angles, plan_robot,
                       planned_tool_path)
from .result import PlanResult

VIDEO_FORMATS = (".gif", ".mp4")
DEFAULT_FPS = 20.0
MAX_DEFAULT_DURATION = 10.0  # s: without --duration a long plan is sped up to this, a short one plays in real time
MAX_FRAMES = 3000  # a larger request is a typo, not a video (150 s at 20 fps)
# The scene is laid out on a figure FIGURE_HEIGHT_IN tall (its width follows the aspect) and
# rendered at the DPI that gives the requested pixel size, so a larger video scales text and
# lines with it. 960 × 720 px fills half a laptop screen with 8-pt labels about 10 px tall.
DEFAULT_SIZE = (960, 720)
FIGURE_HEIGHT_IN = 4.8
SIZE_RANGE = (160, 3840)  # px per side: below, nothing reads; above, a typo (and a huge GIF)
TOOL_AXIS_FRACTION = 0.08  # tool-frame axes drawn this long, as a fraction of the scene size
SCENE_MARGIN = 0.05  # of the scene size, around the arm's sweep


def parse_size(text: str) -> tuple[int, int]:
    """``WIDTHxHEIGHT`` in pixels (even numbers: video encoders need them), e.g. ``960x720``."""
    parts = text.lower().split("x")
    lo, hi = SIZE_RANGE
    if len(parts) == 2 and all(p.strip().isdigit() for p in parts):
        width, height = (int(p) for p in parts)
        if all(lo <= v <= hi and v % 2 == 0 for v in (width, height)):
            return width, height
    raise TaskFileError(f"--size {text!r}: give WIDTHxHEIGHT in pixels, even numbers from {lo} to {hi} "
                        f"(e.g. {DEFAULT_SIZE[0]}x{DEFAULT_SIZE[1]})")


def frame_samples(t: np.ndarray, fps: float, duration: float | None) -> tuple[np.ndarray, float]:
    """Indices of the plan samples shown (one per frame, evenly spaced in plan time) and the video duration."""
    if not np.isfinite(fps) or fps <= 0:
        raise TaskFileError(f"--fps {fps}: give a positive number of frames per second (e.g. 20)")
    span = float(t[-1] - t[0])
    if duration is None:
        duration = min(span, MAX_DEFAULT_DURATION) if span > 0 else 1.0
    if not np.isfinite(duration) or duration <= 0:
        raise TaskFileError(f"--duration {duration}: give a positive video length in seconds (e.g. 5)")
    count = max(2, int(round(fps * duration)))
    if count > MAX_FRAMES:
        raise TaskFileError(f"--fps {fps:g} × --duration {duration:g} s = {count} frames, more than {MAX_FRAMES}; "
                            "lower --fps or --duration")
    wanted = np.linspace(t[0], t[-1], count)
    return np.clip(np.searchsorted(t, wanted), 0, t.size - 1), duration


def _writer(out: Path, fps: float):
    if out.suffix.lower() == ".gif":
        return PillowWriter(fps=fps)
    if shutil.which("ffmpeg") is None:
        raise ToolchainError(f"{out}: MP4 needs ffmpeg, which is not installed (apt-get install -y ffmpeg); "
                             "or write a .gif, which needs nothing else")
    return FFMpegWriter(fps=fps, codec="libx264", extra_args=["-pix_fmt", "yuv420p"])


def _check_output(out_path: str | Path) -> Path:
    text = str(out_path)
    out = Path(out_path)
    if text in ("", "-") or text.endswith(("/", "\\")) or out.is_dir():
        raise FigureOutputError(f"output {excerpt(repr(text))} is not a file name; give e.g. -o plan.gif or -o plan.mp4")
    if out.suffix.lower() not in VIDEO_FORMATS:
        raise FigureOutputError(f"output {excerpt(repr(text))}: unknown video format {excerpt(repr(out.suffix or '(no extension)'))}; "
                                f"use one of {', '.join(VIDEO_FORMATS)}")
    return out


def _serial_scene(fig, result: PlanResult, frames: np.ndarray, robot: Robot):
    q = plan_joint_angles(result, robot)
    poses = robot.frames(q[frames])
    origins = poses[:, :, :3, 3] * 1e3
    planned = planned_tool_path(result, robot) if result.metadata.get("planner") != "ptp" else None
    ax = fig.add_subplot(projection="3d")
    scene = plan_scene(result, robot, q)
    bounded = origins.reshape(-1, 3) if scene is None else np.vstack([origins.reshape(-1, 3),
                                                                      scene_points(scene, poses) * 1e3])
    lo, hi = bounded.min(axis=0), bounded.max(axis=0)
    size = float(np.max(hi - lo)) or 1.0
    centre = (lo + hi) / 2
    for k, axis in enumerate("xyz"):
        getattr(ax, f"set_{axis}lim")(centre[k] - size / 2 - SCENE_MARGIN * size, centre[k] + size / 2 + SCENE_MARGIN * size)
    ax.set_box_aspect((1, 1, 1))
    ax.set(xlabel="x [mm]", ylabel="y [mm]", zlabel="z [mm]")
    ax.tick_params(labelsize=6)
    if planned is not None:
        ax.plot(*(planned * 1e3).T, "k--", lw=0.8, label="planned tool path")
    trace, = ax.plot([], [], [], color="tab:red", lw=1.2, label="executed")
    links, = ax.plot([], [], [], "-o", color="tab:blue", lw=3, ms=4, label="links (joint frames)")
    axes = [ax.plot([], [], [], color=c, lw=2)[0] for c in ("r", "g", "b")]
    capsules: list = []
    if scene is not None:
        draw_obstacles(ax, scene.obstacles, centre / 1e3, (0.5 + SCENE_MARGIN) * size / 1e3)
        if scene.approach is not None:
            draw_approach(ax, scene.approach)
    ax.legend(fontsize=7, loc="upper left")
    length = TOOL_AXIS_FRACTION * size

    def draw(f: int) -> None:
        if scene is not None and scene.has_capsules:  # the capsules move with the arm: drawn again each frame
            for artist in capsules:
                artist.remove()
            capsules[:] = draw_capsules(ax, robot, poses[f])
        links.set_data_3d(*origins[f].T)
        trace.set_data_3d(*origins[: f + 1, -1].T)
        tool = poses[f, -1]
        for k, line in enumerate(axes):
            tip = tool[:3, 3] * 1e3 + length * tool[:3, k]
            line.set_data_3d(*np.column_stack([tool[:3, 3] * 1e3, tip]))
    return draw


def animate_plan(result: PlanResult, out_path: str | Path, fps: float = DEFAULT_FPS,
                 duration: float | None = None, size: tuple[int, int] = DEFAULT_SIZE,
                 robot: Robot | str | Path | None = None) -> Path:
    """Render the arm moving through ``result`` to ``out_path`` (.gif or .mp4), atomically.

    ``fps`` frames per second, ``duration`` seconds of video (default: the plan's duration, at
    most 10 s); the plan's samples are subsampled (or repeated) to ``fps × duration`` frames;
    ``size`` the frames' (width, height) in pixels; ``robot`` the arm drawn (a Robot, a robot
    file or a bundled name; default: the one ``plan.json`` records,
    :func:`~armgen.planning.plotting.plan_robot`). A plan without its ``plan.json`` is drawn
    only with ``robot`` (its joint columns, no planned path). Returns the path written.
    """
    out = _check_output(out_path)
    t = result.column("t_s")
    frames, duration = frame_samples(t, fps, duration)
    writer = _writer(out, fps)
    dpi = size[1] / FIGURE_HEIGHT_IN
    fig = new_figure(size[0] / dpi, FIGURE_HEIGHT_IN)
    FigureCanvasAgg(fig)
    planner = result.metadata.get("planner")
    if planner is None and robot is None:
        raise PlanFileError("the plan has no plan.json (it names the planner and the robot); keep the plan.json that "
                            "`armgen plan` wrote beside the CSV, or give the robot (--robot FILE) to draw the joint columns")
    if planner is not None and planner not in PLANNER_NAMES:
        raise PlanFileError(f"no animation for planner {excerpt(repr(planner))}; plan.json is from another armgen version: "
                            "re-run `armgen plan`")
    if not isinstance(robot, Robot):
        robot = plan_robot(result, robot=robot)
    scene = (planner_named(planner).animation_scene if planner is not None else None) or _serial_scene
    draw = scene(fig, result, frames, robot)
    name = robot.name
    planner = planner or "plan.csv"
    stamp = fig.suptitle("")
    with tempfile.TemporaryDirectory(prefix="armgen-animate-") as scratch:
        scratch_file = Path(scratch) / f"video{out.suffix.lower()}"
        with progress(len(frames), f"animating {len(frames)} frames") as bar:
            with writer.saving(fig, str(scratch_file), dpi):
                for f, k in enumerate(frames):
                    draw(f)
                    stamp.set_text(f"{name} — {planner} — t = {t[k]:7.2f} s of {t[-1]:.2f} s")
                    writer.grab_frame()
                    bar.update(1)
        try:
            with atomic_open(out, "wb") as handle:
                handle.write(scratch_file.read_bytes())
        except OSError as exc:
            raise FigureWriteError(f"cannot write {out}: {exc.strerror or exc}; choose a writable path") from None
    return out
