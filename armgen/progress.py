"""A progress bar for long work, on stderr so it never mixes with data on stdout.
Silent when stderr is not a terminal (CI logs, tests) or when ARMGEN_NO_PROGRESS is set."""

from __future__ import annotations

import contextlib
import os
import sys
from typing import Iterator

import click


class _Silent:
    def update(self, n: int) -> None:
        pass


@contextlib.contextmanager
def progress(total: int, label: str) -> Iterator:
    if os.environ.get("ARMGEN_NO_PROGRESS") or not sys.stderr.isatty():
        yield _Silent()
        return
    with click.progressbar(length=total, label=label, file=sys.stderr, show_eta=True) as bar:
        yield bar
