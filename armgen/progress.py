"""A progress bar for long work, on stderr so it never mixes with data on stdout.
Silent when stderr is not a terminal (CI logs, tests) or when ARMGEN_NO_PROGRESS is set."""

from __future__ import annotations

import contextlib
import os
import sys
from typing import Iterator

import click


# click renders the whole bar on every update (~20 µs, twice a planner step): pass updates on
# in this many chunks over the run, enough for a smooth bar and a live ETA.
RENDERS = 200


class _Silent:
    def update(self, n: int) -> None:
        pass


class _Throttled:
    """Collects updates and hands them to the bar every ``total / RENDERS`` steps."""

    def __init__(self, bar, total: int):
        self._bar, self._every, self._pending = bar, max(1, -(-total // RENDERS)), 0

    def update(self, n: int) -> None:
        self._pending += n
        if self._pending >= self._every:
            self._bar.update(self._pending)
            self._pending = 0

    def flush(self) -> None:
        if self._pending:
            self._bar.update(self._pending)
            self._pending = 0


@contextlib.contextmanager
def progress(total: int, label: str) -> Iterator:
    if os.environ.get("ARMGEN_NO_PROGRESS") or not sys.stderr.isatty():
        yield _Silent()
        return
    with click.progressbar(length=total, label=label, file=sys.stderr, show_eta=True) as bar:
        throttled = _Throttled(bar, total)
        yield throttled
        throttled.flush()
