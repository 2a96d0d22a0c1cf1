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
