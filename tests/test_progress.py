"""The progress bar: shown on a terminal, in at most RENDERS redraws, and complete at the end."""

import io
import sys

import click

from armgen import progress as progress_module


class Terminal(io.StringIO):
    def isatty(self):
        return True


def test_updates_reach_the_bar_in_chunks_and_complete(monkeypatch):
    monkeypatch.delenv("ARMGEN_NO_PROGRESS", raising=False)
    monkeypatch.setattr(sys, "stderr", Terminal())
    forwarded = []
    real = click.progressbar

    def recording(**kwargs):
        bar = real(**kwargs)
        original = bar.update
        bar.update = lambda n, *a: (forwarded.append(n), original(n, *a))
        return bar

    monkeypatch.setattr(progress_module.click, "progressbar", recording)
    total = 12_345
    with progress_module.progress(total, "steps") as bar:
        for _ in range(total):
            bar.update(1)
    assert sum(forwarded) == total
    assert len(forwarded) <= progress_module.RENDERS + 1
    assert "steps" in sys.stderr.getvalue()


def test_silent_without_a_terminal(monkeypatch):
    monkeypatch.delenv("ARMGEN_NO_PROGRESS", raising=False)
    monkeypatch.setattr(sys, "stderr", io.StringIO())
    with progress_module.progress(10, "steps") as bar:
        bar.update(10)
    assert sys.stderr.getvalue() == ""
