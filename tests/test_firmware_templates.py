"""The C text of the controller's task (task_params.h, a program's table) lives in
armgen/data/templates/firmware/ (issue 36): Python supplies the values only. Every template is
one armgen.firmware renders, and a template filled with a value missing, or with one it has no
place for, is refused."""

from __future__ import annotations

import re
from importlib import resources
from pathlib import Path

import pytest

from armgen.firmware.configuration import template

FIRMWARE_TEMPLATES = resources.files("armgen.data") / "templates" / "firmware"
FIRMWARE_SOURCES = Path(__file__).resolve().parent.parent / "armgen" / "firmware"


def test_every_template_is_used_and_ends_with_one_line_break():
    python = "\n".join(p.read_text() for p in FIRMWARE_SOURCES.rglob("*.py"))
    names = sorted(t.name for t in FIRMWARE_TEMPLATES.iterdir() if t.is_file())
    assert "task_params.h" in names
    for name in names:
        row = name.startswith("program_") and name.endswith(".c")  # a program table's row: _row("<kind>", ...)
        used = f'_row("{name[len("program_"):-len(".c")]}"' in python if row else f'{name}"' in python
        assert used, f"nothing in armgen/firmware renders {name}"
        text = (FIRMWARE_TEMPLATES / name).read_text(encoding="utf-8")
        assert text.endswith("\n") and not text.endswith("\n\n"), name
        assert not re.search(r"\$(?![A-Za-z_{]|\$)", text), f"{name}: a stray $"


def test_a_missing_or_an_unused_value_is_refused():
    with pytest.raises(KeyError, match="lock_tick"):
        template("task_lock.h", lock_mask=0)
    with pytest.raises(TypeError, match="extra"):
        template("task_lock.h", lock_mask=0, lock_tick=-1, extra=1)
    lines = template("task_lock.h", lock_mask=3, lock_tick=7)
    assert lines.endswith("fw_lock_mask = 3u;\nconst int32_t fw_lock_tick = 7;")
