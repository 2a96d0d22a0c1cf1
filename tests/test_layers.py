"""The layers hold: no module imports from a layer above its own.

The contract is import-linter's, in pyproject.toml (``[tool.importlinter]``), bottom to top:
errors; the utilities (schemas, fileio, progress, data); the robot description; the symbolic
core; the NumPy façade ``armgen.robot``; code generation; planning; the firmware generator;
verification; the API; the CLI. import-linter follows every import statement, at module level
and inside functions, and indirect chains through other modules. The last tests add one import
that runs back up to a copy of the package and show that the check then fails.
"""

from __future__ import annotations

import pkgutil
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import armgen

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

REPO = Path(__file__).resolve().parent.parent
LINT_IMPORTS = Path(sys.executable).with_name("lint-imports")


def _lint_imports(root: Path) -> subprocess.CompletedProcess:
    """``lint-imports`` on the package under ``root`` (its pyproject.toml, its armgen/)."""
    assert LINT_IMPORTS.is_file(), f"{LINT_IMPORTS} missing: pip install -e '.[test]' installs import-linter"
    env = {"PATH": str(LINT_IMPORTS.parent), "PYTHONPATH": str(root), "HOME": str(root)}
    return subprocess.run([str(LINT_IMPORTS), "--no-cache"], cwd=root, env=env, stdout=subprocess.PIPE,
                          stderr=subprocess.STDOUT, text=True, timeout=300)


def _contract() -> dict:
    config = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["importlinter"]
    (contract,) = config["contracts"]
    return config | {"contract": contract}


def _layer_modules(contract: dict) -> set[str]:
    """Every module a layer names (``a | b`` siblings, ``(a)`` optional)."""
    return {name.strip().strip("()") for layer in contract["layers"] for name in layer.split("|")}


def test_the_layers_hold():
    run = _lint_imports(REPO)
    assert run.returncode == 0, run.stdout
    assert "1 kept, 0 broken" in run.stdout, run.stdout


def test_the_contract_lists_no_exception():
    config = _contract()
    contract = config["contract"]
    assert contract["type"] == "layers"
    assert not contract.get("ignore_imports"), "no import may be exempted from the layers"
    assert not contract.get("unmatched_ignore_imports_alerting")
    assert not config.get("exclude_type_checking_imports"), "imports for type checkers count too"
    assert contract.get("exhaustive") is None and contract.get("containers") is None


def test_every_module_of_the_package_is_in_a_layer():
    # A module left out of every layer would be free to import anything, and anything to import it.
    named = _layer_modules(_contract()["contract"])
    top_level = {f"armgen.{m.name}" for m in pkgutil.iter_modules(armgen.__path__)}
    assert top_level - named == set(), "add the new module to a layer in pyproject.toml [tool.importlinter]"
    assert named - top_level <= {"armgen.firmware"}  # optional until the firmware package exists


@pytest.fixture(scope="module")
def package_copy(tmp_path_factory) -> Path:
    """armgen/ and pyproject.toml, copied: a project lint-imports checks exactly as the real one."""
    root = tmp_path_factory.mktemp("layers")
    shutil.copytree(REPO / "armgen", root / "armgen", ignore=shutil.ignore_patterns("__pycache__", "data"))
    (root / "armgen" / "data").mkdir()
    (root / "armgen" / "data" / "__init__.py").write_text("", encoding="utf-8")
    shutil.copy(REPO / "pyproject.toml", root / "pyproject.toml")
    assert _lint_imports(root).returncode == 0, "the unmodified copy must pass"
    return root


@pytest.mark.parametrize("module, statement, broken", [
    # the circle this contract ended: the symbolic core reaching the façade, inside a function
    ("symbolic/kinematics.py", "def _back():\n    from ..robot import Robot\n", "armgen.symbolic is not allowed to import armgen.robot"),
    # the description reaching the symbolic core at module level
    ("description/frames.py", "from ..symbolic import loops\n", "armgen.description is not allowed to import armgen.symbolic"),
    # verification calling the API (what armgen.verify's callable package once did)
    ("verify/compare.py", "def _back():\n    from ..api import verify\n", "armgen.verify is not allowed to import armgen.api"),
    # a planner importing the CLI, for a type only
    ("planning/limits.py", "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from ..cli import main\n",
     "armgen.planning is not allowed to import armgen.cli"),
])
def test_the_check_fails_on_an_import_back_up(package_copy, module, statement, broken):
    path = package_copy / "armgen" / module
    original = path.read_text(encoding="utf-8")
    try:
        path.write_text(original + f"\n\n{statement}", encoding="utf-8")  # the deliberate back-import
        run = _lint_imports(package_copy)
    finally:
        path.write_text(original, encoding="utf-8")
    assert run.returncode != 0
    assert broken in run.stdout, run.stdout
