"""One front door (issue 36): the command line calls the API and the robot description's
listing, nothing deeper. Every import in ``armgen/cli/*.py`` — at module level, inside
functions, under ``TYPE_CHECKING``, and ``importlib.import_module("armgen…")`` with a literal
name — resolves to ``armgen.api``, ``armgen.description[.…]``, ``armgen.cli[.…]``,
``armgen._version`` or a module outside armgen (the standard library, click, NumPy …).

The layer contract (``tests/test_layers.py``) lets the CLI import every layer below it; this
test narrows that to the API, so that whatever the CLI can do is also one documented call.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import armgen.cli

CLI_DIR = Path(armgen.cli.__file__).parent
CLI_PACKAGE = "armgen.cli"
# armgen modules the CLI may import: the façade, the robot description (the robot listing,
# describe, frames, the bounds of a pose), its own helpers, and the version string.
ALLOWED_MODULES = ("armgen.api",)
ALLOWED_PACKAGES = ("armgen.description", "armgen.cli", "armgen._version")
DYNAMIC_IMPORTERS = ("import_module", "__import__")


def _absolute(node: ast.ImportFrom, package: str) -> list[str]:
    """The modules ``from … import …`` reaches, relative levels resolved against ``package``.
    ``from .. import api`` names the module ``armgen.api``, so each imported name counts
    as a module when the statement gives no module of its own."""
    if node.level:
        parts = package.split(".")
        base = ".".join(parts[:len(parts) - node.level + 1])
        stem = f"{base}.{node.module}" if node.module else base
    else:
        stem = node.module or ""
    if node.module:
        return [stem]
    return [f"{stem}.{alias.name}" for alias in node.names]


def imports_of(source: str, package: str = CLI_PACKAGE) -> list[tuple[int, str]]:
    """(line, absolute module name) of every import in ``source``, wherever it stands."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            found += [(node.lineno, name) for name in _absolute(node, package)]
        elif isinstance(node, ast.Call) and node.args and isinstance(node.args[0], ast.Constant):
            func = node.func
            name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")
            if name in DYNAMIC_IMPORTERS and isinstance(node.args[0].value, str):
                found.append((node.lineno, node.args[0].value))
    return found


def allowed(module: str) -> bool:
    """True for the API, the description, the CLI's own modules, the version, and anything
    outside armgen."""
    if module != "armgen" and not module.startswith("armgen."):
        return True
    return module in ALLOWED_MODULES or any(module == p or module.startswith(p + ".") for p in ALLOWED_PACKAGES)


CLI_MODULES = sorted(CLI_DIR.glob("*.py"))


def test_the_cli_modules_are_found():
    names = {p.name for p in CLI_MODULES}
    assert {"main.py", "options.py", "handling.py", "ik.py", "sweep.py", "animate.py"} <= names


@pytest.mark.parametrize("path", CLI_MODULES, ids=lambda p: p.name)
def test_the_cli_imports_only_the_api_and_the_description(path):
    deeper = [f"{path.name}:{line}: {module}" for line, module in imports_of(path.read_text(encoding="utf-8"))
              if not allowed(module)]
    assert not deeper, "the CLI reaches past armgen.api; add a function to armgen/api.py instead:\n" + "\n".join(deeper)


@pytest.mark.parametrize("statement, module, ok", [
    ("from ..api import plan", "armgen.api", True),
    ("from .. import api", "armgen.api", True),
    ("from ..description import describe", "armgen.description", True),
    ("from ..description.model import TASK_ROWS", "armgen.description.model", True),
    ("from .handling import handle_errors", "armgen.cli.handling", True),
    ("from .._version import __version__", "armgen._version", True),
    ("import click", "click", True),
    ("def f():\n    from ..planning.tasks import load_task", "armgen.planning.tasks", False),
    ("from .. import robot", "armgen.robot", False),
    ("import armgen.errors", "armgen.errors", False),
    ("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from ..planning.result import PlanResult",
     "armgen.planning.result", False),
    ("import importlib\nimportlib.import_module('armgen.symbolic.ik')", "armgen.symbolic.ik", False),
    ("from armgen.api import plan", "armgen.api", True),
])
def test_the_check_sees_every_kind_of_import(statement, module, ok):
    # the checker itself: relative levels, function bodies, TYPE_CHECKING blocks, import_module
    modules = [m for _, m in imports_of(statement)]
    assert module in modules
    assert allowed(module) is ok


def test_solve_ik_reports_the_rows_a_planar_arm_does_not_control():
    # planar3 moves in the plane z = 0 (base and tool frames identity, joints about z): the
    # rows it controls are x, y and the rotation about z, so a target 0.3 m above the plane is
    # reached there and missed by exactly 0.3 m in z, and a target tilted about x by 0.2 rad is
    # missed by 0.2 rad in that rotation, which counts only when an orientation was asked for.
    import numpy as np

    from armgen import api

    above = np.eye(4)
    above[:3, 3] = [0.5, 0.2, 0.3]
    solution = api.solve_ik("planar3", above)
    assert solution.converged and not solution.solved
    assert solution.free_rows == ("vz", "wx", "wy")
    assert solution.free_position_error == pytest.approx(0.3, abs=1e-9)
    assert solution.free_orientation_error == pytest.approx(0.0, abs=1e-9)
    tilted = np.eye(4)
    tilted[:3, :3] = [[1, 0, 0], [0, np.cos(0.2), -np.sin(0.2)], [0, np.sin(0.2), np.cos(0.2)]]
    tilted[:3, 3] = [0.5, 0.2, 0.0]
    given = api.solve_ik("planar3", tilted)
    assert given.converged and not given.solved and given.free_orientation_error == pytest.approx(0.2, abs=1e-6)
    assert api.solve_ik("planar3", tilted, orientation_given=False).solved
