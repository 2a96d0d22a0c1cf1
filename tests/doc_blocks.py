"""The runnable code blocks of the README and docs/*.md: the docs are the tests' script.

A fenced ``sh``/``bash``/``python`` block runs. Its first line may say what it needs or why it
cannot run (tests only; the site leaves that line out, docs/hooks/armgen_docs.py):

- ``# docs-test: needs TOOL …``: the external tools it calls (as tests/conftest.py's
  ``require_tool`` names them); missing locally the block is skipped with the install command,
  missing in CI (``CI=true``) it fails;
- ``# docs-test: skip (reason)``: a block that cannot run in a test at all (it installs into the
  environment, or it would run the test suite itself).

The blocks of one page run in order, as a reader types them into one terminal: a block starts
in the folder where the previous one ended (a ``cd`` carries over). tests/test_docs.py runs
every page's blocks with this checkout's armgen; tests/test_install.py runs the README's wheel
block and the getting-started page from an empty folder with armgen installed from its wheel.
"""

from __future__ import annotations

import re
import shlex
from pathlib import Path
from typing import NamedTuple

BLOCK = re.compile(r"^```(sh|bash|python)[^\n]*\n(.*?)^```", re.M | re.S)
SKIP = re.compile(r"^#\s*docs-test:\s*skip\s*\((.+)\)\s*$")
NEEDS = re.compile(r"^#\s*docs-test:\s*needs\s+(\S.*?)\s*$")


class Block(NamedTuple):
    lang: str  # "sh", "bash" or "python"
    code: str
    line: int  # of the opening fence, 1-based


def blocks(text: str, start: int = 0) -> list[Block]:
    """The code blocks of a markdown text, in order, from character ``start`` on."""
    return [Block(m.group(1), m.group(2), text[:m.start()].count("\n") + 1) for m in BLOCK.finditer(text, start)]


def _first_line(code: str) -> str:
    return code.strip().splitlines()[0] if code.strip() else ""


def skip_reason(code: str) -> str | None:
    """The reason a block is not run (its ``# docs-test: skip (…)`` first line), else None."""
    match = SKIP.match(_first_line(code))
    return match.group(1) if match else None


def needed_tools(code: str) -> list[str]:
    """The external tools a block calls (its ``# docs-test: needs …`` first line), else []."""
    match = NEEDS.match(_first_line(code))
    return match.group(1).split() if match else []


def command(lang: str, code: str, python: str, cwd_record: Path, trace: bool = False) -> list[str]:
    """The command that runs a block as a reader would: bash stops at the first command that
    fails (``-e -o pipefail``; ``trace``: each command echoed, so a report names it), and the
    folder the block ends in is written to ``cwd_record`` for the next block of the page."""
    if lang == "python":
        return [python, "-c", code]
    record = f'trap "pwd > {shlex.quote(str(cwd_record))}" EXIT\n'
    return ["bash", "-e", "-o", "pipefail", *(["-x"] if trace else []), "-c", record + code]


def next_cwd(cwd: Path, cwd_record: Path) -> Path:
    """Where the next block of the page starts: where this one ended (``cwd`` for python)."""
    if cwd_record.is_file():
        ended = Path(cwd_record.read_text(encoding="utf-8").strip())
        cwd_record.unlink()
        return ended
    return cwd
