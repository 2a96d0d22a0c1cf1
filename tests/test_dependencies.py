"""Every third-party import is a declared dependency, and every declared dependency is used.

The check is deptry, configured in pyproject.toml (``[tool.deptry]``): the ``test`` and
``docs`` extras are development groups, so armgen/ may not import from them, and their
packages may be imported by tests/, benchmarks/ and docs/hooks/. The last tests run the same
check on a copy of the package with one deliberate mistake each, to show that it fails.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
# tests/data holds a module the tests import by path (make_planner_reference): a root of its own
SUPPORT_ROOTS = ("tests", "tests/data", "benchmarks", "docs/hooks")


def _deptry(cwd: Path, *args: str) -> subprocess.CompletedProcess:
    """deptry's exit status and its report (it writes the findings to stderr) as ``stdout``."""
    return subprocess.run([sys.executable, "-m", "deptry", *args, "--no-ansi"], cwd=cwd, stdout=subprocess.PIPE,
                          stderr=subprocess.STDOUT, text=True, timeout=300)


def test_the_package_declares_what_it_imports_and_imports_what_it_declares():
    run = _deptry(REPO, ".")
    assert run.returncode == 0, run.stdout


def test_tests_benchmarks_and_docs_hooks_import_only_declared_packages():
    # DEP002 (declared, unused) is the package check's; DEP004 (a test/docs extra imported) is
    # what these folders may do.
    run = _deptry(REPO, *SUPPORT_ROOTS, "--exclude", ".*/__pycache__/", "--ignore", "DEP002,DEP004")
    assert run.returncode == 0, run.stdout


@pytest.fixture
def package_copy(tmp_path) -> Path:
    """armgen/ and pyproject.toml, copied: a project deptry checks exactly as the real one."""
    shutil.copytree(REPO / "armgen", tmp_path / "armgen", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(REPO / "pyproject.toml", tmp_path / "pyproject.toml")
    assert _deptry(tmp_path, ".").returncode == 0, "the unmodified copy must pass"
    return tmp_path


def _add_import(root: Path, statement: str) -> None:
    module = root / "armgen" / "robot.py"
    module.write_text(module.read_text(encoding="utf-8") + f"\n{statement}  # the deliberate mistake\n",
                      encoding="utf-8")


@pytest.mark.parametrize("statement, codes, name", [
    # installed only as another package's dependency (mkdocs needs PyYAML): transitive (DEP003),
    # or missing (DEP001) where the docs extra is not installed
    ("import yaml", ("DEP003", "DEP001"), "'yaml'"),
    # not installed and not declared
    ("import armgen_no_such_package", ("DEP001",), "'armgen_no_such_package'"),
    # declared, but only in the test extra: a user's install would not have it
    ("import hypothesis", ("DEP004",), "'hypothesis'"),
])
def test_the_check_fails_on_an_undeclared_import(package_copy, statement, codes, name):
    _add_import(package_copy, statement)
    run = _deptry(package_copy, ".")
    assert run.returncode != 0
    finding = [line for line in run.stdout.splitlines() if any(c in line for c in codes) and name in line]
    assert finding and "armgen/robot.py" in finding[0], run.stdout


def test_the_check_fails_on_a_declared_dependency_nothing_imports(package_copy):
    pyproject = package_copy / "pyproject.toml"
    text = pyproject.read_text(encoding="utf-8")
    declared = '    "click>=8.1",\n'
    assert declared in text
    pyproject.write_text(text.replace(declared, declared + '    "tabulate>=0.9",\n'), encoding="utf-8")
    run = _deptry(package_copy, ".")
    assert run.returncode != 0
    assert any("DEP002" in line and "'tabulate'" in line for line in run.stdout.splitlines()), run.stdout
