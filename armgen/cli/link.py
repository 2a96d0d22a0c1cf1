"""``armgen link PORT status | move-to … | stream plan.csv | servo twists.csv | watch``: talk to a board running the
firmware's link (docs/link.md). PORT is a serial device (``/dev/ttyUSB0``, ``COM3``), the host
firmware's pseudo-terminal (``/dev/pts/N``) or ``socket://host:port``. Exit 4 when nothing
answers (or in another protocol version), 3 when the board refuses a command, 2 for bad options."""

from __future__ import annotations

import math

import click

from .handling import handle_errors

# SERVO_SETUP's criteria (armgen/link/protocol.py CRITERIA), as the command line spells them
CRITERION_NAMES = ("task", "none", "joint_limits", "manipulability", "joint_manipulability", "rest")


def _describe(reply) -> str:
    q = " ".join(f"{v:.6g}" for v in reply.q)
    tool = reply["tool"]
    return (f"tick {reply['tick']}  state {reply.state_name}  fault {reply.fault_name}  "
            f"flags {','.join(reply.flags) or '-'}\n"
            f"  q [rad|m]   {q}\n"
            f"  tool [m]    {tool[0]:.6g} {tool[1]:.6g} {tool[2]:.6g}\n"
            f"  frames      valid {reply['rx_frames']}, bad CRC {reply['bad_crc']}, malformed {reply['malformed']}, "
            f"oversized {reply['oversized']}, out of order {reply['out_of_order']}, "
            f"other version {reply['wrong_version']}, refused {reply['rejected']}")


@click.group("link")
@click.argument("port")
@click.option("--timeout", type=click.FloatRange(0.01, 60), default=2.0, show_default=True,
              help="seconds to wait for each reply")
@click.pass_context
def link_cmd(ctx: click.Context, port: str, timeout: float) -> None:
    """Talk to a board over the link: status, move-to, stream, servo, watch."""
    ctx.obj = {"port": port, "timeout": timeout}


@link_cmd.command("status")
@click.pass_obj
@handle_errors
def status_cmd(obj: dict) -> None:
    """The board's state, fault, joints, tool position and frame counters."""
    from ..api import link_status

    click.echo(_describe(link_status(obj["port"], obj["timeout"])))


@link_cmd.command("move-to")
@click.option("--joints", default=None, help="joint target: one value per joint, separated by commas (--units)")
@click.option("--xyz", nargs=3, type=float, default=None, help="tool position in the base frame [m]")
@click.option("--rpy", nargs=3, type=float, default=None, help="tool orientation R = Rz(yaw) Ry(pitch) Rx(roll) "
                                                               "[--units] (default 0 0 0)")
@click.option("--units", type=click.Choice(["rad", "deg"]), default="rad", show_default=True)
@click.option("--no-wait", is_flag=True, help="return when the board accepts the move")
@click.pass_obj
@handle_errors
def move_to_cmd(obj: dict, joints: str | None, xyz, rpy, units: str, no_wait: bool) -> None:
    """Move to a joint target (--joints) or a tool pose (--xyz, --rpy): planned on the board."""
    import numpy as np

    from ..api import OptionError, link_move_to
    from ..description import rpy_matrix

    scale = math.pi / 180 if units == "deg" else 1.0
    if (joints is None) == (xyz is None):
        raise OptionError("move-to: give --joints or --xyz (with an optional --rpy)")
    if joints is not None:
        try:
            values = [float(v) * scale for v in joints.replace(",", " ").split()]
        except ValueError:
            values = []
        if not values or not all(math.isfinite(v) for v in values):
            raise OptionError(f"--joints {joints!r}: give one finite number per joint, separated by commas")
        reply = link_move_to(obj["port"], joints=values, wait=not no_wait, timeout=obj["timeout"])
    else:
        pose = np.eye(4)
        pose[:3, :3] = rpy_matrix(*(v * scale for v in (rpy or (0.0, 0.0, 0.0))))
        pose[:3, 3] = xyz
        reply = link_move_to(obj["port"], pose=pose, wait=not no_wait, timeout=obj["timeout"])
    click.echo(_describe(reply))


@link_cmd.command("stream")
@click.argument("plan_csv", type=click.Path(dir_okay=False))
@click.option("--rate", type=click.FloatRange(0.1, 1000), default=50.0, show_default=True,
              help="waypoints per second (the plan's samples on this grid)")
@click.option("--lead", type=click.FloatRange(0.0, 10), default=0.1, show_default=True,
              help="seconds each waypoint is sent ahead of its time")
@click.option("--poses", is_flag=True, help="stream the plan's tool poses (x_m y_m z_m roll_rad pitch_rad yaw_rad) "
                                            "instead of its joints; a pose file (t_s and those columns) always is")
@click.option("--ack", is_flag=True, help="the board answers each waypoint with a 16-byte ACK instead of the full "
                                          "telemetry (no deviation measured)")
@click.pass_obj
@handle_errors
def stream_cmd(obj: dict, plan_csv: str, rate: float, lead: float, poses: bool, ack: bool) -> None:
    """Stream a plan's joint samples (or its tool poses, or a pose file's) as timed waypoints; the
    board interpolates them at its tick (poses in task space, followed by its resolved-rate step)."""
    from ..api import link_stream

    report = link_stream(obj["port"], plan_csv, rate, lead, obj["timeout"], poses=poses,
                         replies="ACK" if ack else "TELEMETRY")
    what, unit = ("tool poses", "m (tool position)") if report.poses else ("waypoints", "rad|m")
    click.echo(f"streamed {report.waypoints} {what} at {rate:g} Hz; largest difference from the plan at the "
               f"replies' ticks {report.max_deviation:.3g} {unit}")
    click.echo(_describe(report.end))


@link_cmd.command("servo")
@click.argument("twists_csv", type=click.Path(dir_okay=False))
@click.option("--rate", type=click.FloatRange(0.1, 1000), default=50.0, show_default=True, help="twists per second")
@click.option("--criterion", type=click.Choice(CRITERION_NAMES, case_sensitive=False), default="task",
              show_default=True, help="the self-motion of a redundant arm (task: the compiled-in task's choice)")
@click.option("--gain", type=click.FloatRange(0.0, 1e3), default=0.0, show_default=True,
              help="the criterion's gain, 1/s (0: its default)")
@click.pass_obj
@handle_errors
def servo_cmd(obj: dict, twists_csv: str, rate: float, criterion: str, gain: float) -> None:
    """Servo the tool through a twist trace (CSV: vx_m_s vy_m_s vz_m_s wx_rad_s wy_rad_s wz_rad_s per row)."""
    from ..api import link_servo, read_twists

    twists = read_twists(twists_csv)
    click.echo(f"sent {len(twists)} twists at {rate:g} Hz")
    click.echo(_describe(link_servo(obj["port"], twists, 1.0 / rate, obj["timeout"], criterion.upper(), gain)))


@link_cmd.command("watch")
@click.option("--period", type=click.FloatRange(0.001, 60), default=0.1, show_default=True, help="seconds")
@click.option("--count", type=click.IntRange(1, None), default=None, help="stop after this many (default: Ctrl-C)")
@click.pass_obj
@handle_errors
def watch_cmd(obj: dict, period: float, count: int | None) -> None:
    """Telemetry every --period seconds (its requests keep the watchdog fed)."""
    from ..api import link_watch

    for reply in link_watch(obj["port"], period, count, obj["timeout"]):
        click.echo(_describe(reply))
