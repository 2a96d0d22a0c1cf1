"""The layers hold: no module imports from a layer above its own.

The contract is import-linter's, in pyproject.toml (``[tool.importlinter]``), bottom to top:
errors; the utilities (schemas, fileio, progress, data); the robot description; the symbolic
core; code generation; the NumPy façade ``armgen.robot`` (which calls the compiled kernel); planning; the firmware generator;
verification; the API; the CLI. import-linter follows every import statement, at module level
and inside functions, and indirect chains through other modules. The tests of the contract add
one import that runs back up to a copy of the package and show that the check then fails.

Within a layer the contract allows any import; the graph of every import statement of the
package (module level and inside functions) must still have no circle. And the layers hold
their data apart: the description holds nothing built above it, and the version comes from
the ground floor, ``armgen._version``, not from the root package.
"""

from __future__ import annotations

import ast
import pickle
import pkgutil
import shutil
import subprocess
import sys
import types
from dataclasses import fields
from pathlib import Path

import numpy as np

import pytest

import armgen
from armgen.description import RobotDescription, load_description
from armgen.robot import Robot
from armgen.symbolic.model import SymbolicModel

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
    """The import-linter configuration, with its layers contract as ``contract``."""
    config = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["importlinter"]
    (contract,) = [c for c in config["contracts"] if c["type"] == "layers"]
    return config | {"contract": contract}


def _layer_modules(contract: dict) -> set[str]:
    """Every module a layer names (``a | b`` siblings, ``(a)`` optional)."""
    return {name.strip().strip("()") for layer in contract["layers"] for name in layer.split("|")}


def test_the_layers_hold():
    run = _lint_imports(REPO)
    assert run.returncode == 0, run.stdout
    assert f"{len(_contract()['contracts'])} kept, 0 broken" in run.stdout, run.stdout


def test_the_contract_lists_no_exception():
    config = _contract()
    contract = config["contract"]
    assert contract["type"] == "layers"
    for each in config["contracts"]:
        assert not each.get("ignore_imports"), f"no import may be exempted from {each['name']!r}"
        assert not each.get("allow_indirect_imports"), f"{each['name']!r} must follow indirect imports"
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
    # verification calling the API (what the callable package armgen.verify once did)
    ("verification/compare.py", "def _back():\n    from ..api import verify\n",
     "armgen.verification is not allowed to import armgen.api"),
    # a planner importing the CLI, for a type only
    ("planning/limits.py", "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from ..cli import main\n",
     "armgen.planning is not allowed to import armgen.cli"),
    # a planner borrowing another planner's helper (what issue 36 ended: four planners used cartesian's)
    ("planning/wgpm/planner.py", "def _back():\n    from ..fault_tolerant import config\n",
     "armgen.planning.wgpm is not allowed to import armgen.planning.fault_tolerant"),
    # the figures' shared code reaching into a planner
    ("planning/plotting.py", "def _back():\n    from .cartesian import config\n",
     "armgen.planning.plotting is not allowed to import armgen.planning.cartesian"),
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


# -- no import circle -----------------------------------------------------------------------

def _module_name(path: Path, root: Path) -> str:
    parts = path.relative_to(root).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _from_source(node: ast.ImportFrom, path: Path, root: Path) -> str:
    """The module a ``from … import`` statement in ``path`` reads from, relative ones resolved."""
    if not node.level:
        return node.module or ""
    name = _module_name(path, root).split(".")
    package = name if path.name == "__init__.py" else name[:-1]
    return ".".join(package[:len(package) - node.level + 1] + ([node.module] if node.module else []))


def _import_graph(root: Path) -> dict[str, set[str]]:
    """Every module of the package ``root/armgen`` → the package's modules its import statements
    name, at module level and inside functions alike (``ast.walk`` visits every statement):
    relative imports resolved, ``from p import m`` naming the module ``p.m`` where there is one
    and ``p`` otherwise."""
    paths = {_module_name(path, root): path for path in sorted((root / "armgen").rglob("*.py"))}
    graph = {}
    for name, path in paths.items():
        named = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            if isinstance(node, ast.Import):
                named |= {alias.name for alias in node.names}
            elif isinstance(node, ast.ImportFrom):
                source = _from_source(node, path, root)
                named |= {f"{source}.{alias.name}" if f"{source}.{alias.name}" in paths else source
                          for alias in node.names}
        graph[name] = {other for other in named if other in paths and other != name}
    return graph


def _circles(graph: dict[str, set[str]]) -> list[tuple[str, ...]]:
    """The import circles: each set of modules that all reach one another (sorted), sorted."""
    def reachable(start: str) -> set[str]:
        seen, todo = set(), list(graph[start])
        while todo:
            module = todo.pop()
            if module not in seen:
                seen.add(module)
                todo.extend(graph[module])
        return seen

    reach = {module: reachable(module) for module in graph}
    return sorted({tuple(sorted(other for other in reach[module] if module in reach[other]))
                   for module in graph if module in reach[module]})


def test_no_import_circle():
    graph = _import_graph(REPO)
    assert len(graph) > 100 and "armgen.symbolic.numeric" in graph["armgen.robot"]  # deferred imports seen
    circles = _circles(graph)
    assert circles == [], "import circles (each set of modules reaches one another): " + "; ".join(
        " <-> ".join(circle) for circle in circles)


def test_the_circle_check_sees_a_deferred_import(tmp_path):
    # the circle this package had: the IK's NumPy replay imported inside a method from
    # numeric, which imports model, which imports ik
    shutil.copytree(REPO / "armgen", tmp_path / "armgen", ignore=shutil.ignore_patterns("__pycache__", "data"))
    ik = tmp_path / "armgen" / "symbolic" / "ik.py"
    ik.write_text(ik.read_text(encoding="utf-8") + "\n\ndef _back():\n    from .numeric import BatchFunction\n",
                  encoding="utf-8")
    assert _circles(_import_graph(tmp_path)) == [("armgen.symbolic.ik", "armgen.symbolic.model",
                                                  "armgen.symbolic.numeric")]


# -- model and data apart ------------------------------------------------------------------

def test_the_description_holds_no_model():
    assert "_cache" not in {f.name for f in fields(RobotDescription)}
    description = load_description("planar3")
    model = SymbolicModel(description)
    model.function("ik"), model.function("fk")
    assert set(vars(description)) == {f.name for f in fields(RobotDescription)}  # nothing written onto it
    # the Robot holds its models, in its own attributes, and a pickle carries the description only
    robot = armgen.load_robot("planar3")
    pose = robot.fk(robot.qmid)
    assert robot.ik(pose).success and robot.frames(np.stack([robot.qmid] * 2)).shape == (2, robot.n + 2, 4, 4)
    derived = set(vars(robot)) - {f.name for f in fields(Robot)}
    assert derived and all(name in vars(Robot) for name in derived), derived
    clone = pickle.loads(pickle.dumps(robot))
    assert set(vars(clone)) == {f.name for f in fields(Robot)}
    np.testing.assert_array_equal(clone.ik(pose).q, robot.ik(pose).q)


def test_the_version_comes_from_the_ground_floor():
    from armgen._version import __version__

    assert armgen.__version__ == __version__
    config = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))
    assert "version" in config["project"]["dynamic"] and "version" not in config["project"]
    assert config["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "armgen._version.__version__"}
    from_root = []
    for path in sorted((REPO / "armgen").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            if (isinstance(node, ast.ImportFrom) and any(alias.name == "__version__" for alias in node.names)
                    and _from_source(node, path, REPO) != "armgen._version"):
                from_root.append(f"{path.relative_to(REPO)}:{node.lineno}")
    assert from_root == [], f"{from_root}: import __version__ from armgen._version"


def test_no_module_class_swapping():
    # armgen.verify is the API function; the verification layer is armgen.verification
    import armgen.api
    import armgen.verification.pipeline

    assert type(armgen) is types.ModuleType and type(armgen.verification) is types.ModuleType
    assert armgen.verify is armgen.api.verify
