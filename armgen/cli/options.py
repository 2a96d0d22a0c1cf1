"""Options several commands share. ``-o/--out`` is the one name for "where outputs go" (a
file or a folder, per command); the spellings it replaced (``--output``, ``verify
--generated``) still work for a release but are left out of ``--help``."""

from __future__ import annotations

from typing import Any

import click

# The spellings replaced by -o/--out, accepted but not shown.
OLD_OUT_SPELLINGS = ("--output", "--generated")


class HiddenAliasOption(click.Option):
    """An option whose old spellings still parse but are not listed in ``--help``."""

    def get_help_record(self, ctx: click.Context) -> tuple[str, str] | None:
        shown = [o for o in self.opts if o not in OLD_OUT_SPELLINGS]
        saved, self.opts = self.opts, shown
        try:
            return super().get_help_record(ctx)
        finally:
            self.opts = saved


def out_option(dest: str, help: str, old: tuple[str, ...] = ("--output",), **kwargs: Any):
    """``-o/--out`` stored in ``dest``; ``old`` are the spellings this command had before."""
    assert set(old) <= set(OLD_OUT_SPELLINGS)
    return click.option("-o", "--out", *old, dest, cls=HiddenAliasOption, help=help, **kwargs)


def plan_robot_option():
    """``--robot``: the arm a plan is drawn with, when ``plan.json``'s record is not found."""
    return click.option("--robot", default=None, metavar="FILE|NAME",
                        help="robot to draw (robot TOML, URDF or bundled name); default: the one plan.json records, "
                             "looked for as recorded and beside the plan")


def plan_with_metadata(plan_csv: str, robot: str | None, command: str):
    """The plan of ``plan_csv`` with its plan.json; without one, an error naming the missing
    file and the fix (``--robot`` draws a plan without it where ``command`` can)."""
    from ..api import PlanFileError, plan_metadata_path, read_plan

    plan = read_plan(plan_csv)
    if not plan.metadata and (robot is None or command == "plot"):
        fix = ", or give the arm with --robot FILE to draw its joint columns" if command == "animate" else ""
        raise PlanFileError(f"{plan_metadata_path(plan_csv)} not found: `armgen {command}` needs the plan.json that "
                            f"`armgen plan` wrote beside {plan_csv} (it names the planner and the robot); copy it "
                            f"there, or re-run `armgen plan`{fix}")
    return plan
