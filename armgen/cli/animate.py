"""``armgen animate``: the arm moving through a plan, as a GIF or an MP4."""

from __future__ import annotations

from pathlib import Path

import click

from .handling import handle_errors
from .options import out_option, plan_robot_option, plan_with_metadata


@click.command("animate")
@click.argument("plan_csv", type=click.Path(exists=True, dir_okay=False))
@out_option("output", "video to write: .gif (Pillow) or .mp4 (needs ffmpeg); default: the CSV's name with .gif",
            default=None)
@click.option("--fps", type=float, default=20.0, show_default=True, help="frames per second")
@click.option("--duration", type=float, default=None,
              help="video length in seconds (default: the plan's duration, at most 10 s)")
@click.option("--size", default="960x720", show_default=True, metavar="WxH",
              help="frame size in pixels (text and lines scale with it)")
@plan_robot_option()
@handle_errors
def animate_cmd(plan_csv: str, output: str | None, fps: float, duration: float | None, size: str,
                robot: str | None) -> None:
    """Draw the arm moving through a plan: links between the joint frames (the arm's own forward
    kinematics), the tool frame, the planned path, the arm's capsules, the task's obstacles and the
    closest approach, snake obstacles, and a time stamp."""
    from ..api import animate_plan, parse_frame_size

    pixels = parse_frame_size(size)  # a bad --size fails before any work
    out = Path(output) if output is not None else Path(plan_csv).with_suffix(".gif")
    plan = plan_with_metadata(plan_csv, robot, "animate")
    animate_plan(plan, output if output is not None else out, fps, duration, pixels, robot, plan_csv)
    click.echo(f"wrote {out}")
