"""The preamble stamped on every generated file: who generated it, from what, and that it
must not be edited. Deterministic: no timestamps, no absolute paths.

User text (a robot name, a file name) reaches the C comment only through
:func:`comment_safe`: printable ASCII letters, digits and ``._-+/ ``, everything else becomes
``_``, bounded length — so no ``*`` (hence no ``*/``), no line break, no trigraph or backslash can end the
comment or splice a line. The exact text lives in ``manifest.json``."""

from __future__ import annotations

import re

from .._version import __version__
from ..data import render_template

# Longest user string copied into a comment (the manifest keeps the full text).
COMMENT_TEXT_MAX = 80


def comment_safe(text: str) -> str:
    safe = re.sub(r"[^A-Za-z0-9._+/ -]", "_", text)[:COMMENT_TEXT_MAX]
    return safe or "_"


def c_preamble(source_name: str, source_sha256: str, what: str, regenerate: str = "armgen gen") -> str:
    """The stamp comment (templates/codegen/preamble.c), a block of lines for :func:`c_file`."""
    return render_template("codegen/preamble.c", what=what, version=__version__, source=comment_safe(source_name),
                           sha256=source_sha256, regenerate=regenerate)


def c_file(preamble: str, body: str) -> str:
    """A generated file's text: the preamble, a blank line, the body and the file's last line break."""
    return render_template("codegen/file.c", preamble=preamble, body=body) + "\n"
