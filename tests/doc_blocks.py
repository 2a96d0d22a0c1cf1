"""The runnable code blocks of the README and docs/*.md: the docs are the tests' script.

A fenced ``sh``/``bash``/``python`` block runs unless its first line says why not:
``# docs-test: skip (reason)``. tests/test_docs.py runs every page's blocks with this
checkout's armgen; tests/test_install.py runs the README's wheel block and the getting-started
page from an empty folder with armgen installed from its wheel.
"""

from __future__ import annotations

import re
from typing import NamedTuple

BLOCK = re.compile(r"^```(sh|bash|python)[^\n]*\n(.*?)^```", re.M | re.S)
SKIP = re.compile(r"^#\s*docs-test:\s*skip\s*\((.+)\)\s*$")


class Block(NamedTuple):
    lang: str  # "sh", "bash" or "python"
    code: str
    line: int  # of the opening fence, 1-based


def blocks(text: str, start: int = 0) -> list[Block]:
    """The code blocks of a markdown text, in order, from character ``start`` on."""
    return [Block(m.group(1), m.group(2), text[:m.start()].count("\n") + 1) for m in BLOCK.finditer(text, start)]


def skip_reason(code: str) -> str | None:
    """The reason a block is not run (its ``# docs-test: skip (…)`` first line), else None."""
    first = code.strip().splitlines()[0] if code.strip() else ""
    match = SKIP.match(first)
    return match.group(1) if match else None
