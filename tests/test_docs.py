"""The documentation: the MkDocs site builds with warnings as errors (figures, animation, CLI
and file references generated from the code), and every ``sh``/``python`` block in README.md
and docs/*.md runs.

A block that is not meant to run (it installs packages, builds inside the source tree, or runs
for minutes) says so on its first line: ``# docs-test: skip (reason)``; it is reported as
skipped with that reason, never as passed. The blocks of one page run in order in one scratch
directory that holds the repository's examples, robots, firmware stub and benchmarks, with an
``armgen`` on PATH that runs this checkout.
"""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import pytest

from doc_blocks import blocks, skip_reason

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md"] + sorted((ROOT / "docs").glob("*.md"))
LINKED = ("examples", "robots", "firmware_stub", "benchmarks")
BLOCK_TIMEOUT_S = 600  # a block that runs longer is marked skip (CI machines are 2-core)
DOCS_PACKAGES = ("mkdocs", "material", "mkdocstrings", "mkdocstrings_handlers")
DOCS_HINT = "pip install '.[docs]' (mkdocs, mkdocs-material, mkdocstrings[python])"


def _blocks():
    for page in PAGES:
        for k, block in enumerate(blocks(page.read_text(encoding="utf-8"))):
            yield pytest.param(page, k, block.lang, block.code, id=f"{page.relative_to(ROOT)}:{block.line}")


_sandboxes: dict[Path, tuple[Path, list[int]]] = {}


def _sandbox(page: Path, tmp_path_factory) -> tuple[Path, list[int]]:
    if page not in _sandboxes:
        work = tmp_path_factory.mktemp(page.stem.replace(".", "_"))
        for name in LINKED:
            (work / name).symlink_to(ROOT / name)
        bin_dir = work / ".bin"
        bin_dir.mkdir()
        shim = bin_dir / "armgen"
        shim.write_text(f'#!/bin/sh\nexec "{sys.executable}" -m armgen.cli.main "$@"\n')
        shim.chmod(0o755)
        _sandboxes[page] = (work, [])
    return _sandboxes[page]


def _run(work: Path, lang: str, code: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(ROOT), ARMGEN_NO_PROGRESS="1", MPLBACKEND="Agg",
               PATH=f"{work / '.bin'}{os.pathsep}{os.environ.get('PATH', '')}")
    if lang == "python":
        command = [sys.executable, "-c", code]
    else:
        command = ["bash", "-e", "-o", "pipefail", "-c", code]
    return subprocess.run(command, cwd=work, env=env, capture_output=True, text=True, timeout=BLOCK_TIMEOUT_S)


@pytest.mark.slow
@pytest.mark.parametrize("page, index, lang, code", list(_blocks()))
def test_code_block_runs(page, index, lang, code, tmp_path_factory):
    reason = skip_reason(code)
    if reason:
        pytest.skip(f"marked not to run: {reason}")
    work, done = _sandbox(page, tmp_path_factory)
    # earlier blocks of the page first (they write the files later ones use), once per worker
    for k, (_, _, earlier_lang, earlier) in enumerate(b.values for b in _blocks() if b.values[0] == page):
        if k >= index:
            break
        if k not in done and not skip_reason(earlier):
            run = _run(work, earlier_lang, earlier)
            assert run.returncode == 0, f"earlier block {k} of {page.name} failed:\n{run.stdout}\n{run.stderr}"
            done.append(k)
    run = _run(work, lang, code)
    assert run.returncode == 0, f"{page.name} block {index} failed (exit {run.returncode}):\n{run.stdout}\n{run.stderr}"
    done.append(index)


@pytest.mark.slow
def test_mkdocs_build_strict(tmp_path):
    missing = [name for name in DOCS_PACKAGES if importlib.util.find_spec(name) is None]
    if missing:
        pytest.skip(f"{', '.join(missing)} not installed: {DOCS_HINT}")
    site = tmp_path / "site"
    env = dict(os.environ, PYTHONPATH=str(ROOT), ARMGEN_NO_PROGRESS="1", MPLBACKEND="Agg", NO_MKDOCS_2_WARNING="1")
    run = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-f", str(ROOT / "mkdocs.yml"),
                          "-d", str(site)], cwd=ROOT, env=env, capture_output=True, text=True, timeout=900)
    assert run.returncode == 0, run.stdout + run.stderr
    from PIL import Image

    for name in ("modular8_circle_combined", "iiwa14_fault_circle_gpm", "iiwa14_fault_circle_wln",
                 "modular8_wgpm_demo", "ptp_single_joint", "snake_tank"):
        assert (site / "figures" / f"{name}.png").read_bytes().startswith(b"\x89PNG")
    with Image.open(site / "figures" / "arm.gif") as gif:
        assert gif.n_frames == 40
    # each method page shows its figures; the references and results are generated, not placeholders
    assert 'src="../figures/modular8_circle_combined.png"' in (site / "cartesian" / "index.html").read_text()
    assert 'src="../figures/snake_tank.png"' in (site / "snake" / "index.html").read_text()
    cli_page = (site / "cli" / "index.html").read_text()
    for command in ("plan", "plot", "animate", "gen", "verify"):
        assert f"armgen {command}" in cli_page
    results = (site / "results" / "index.html").read_text()
    assert "armgen:" not in results and results.count("<table>") == 2
    assert "ptp_single_joint.toml" in (site / "task-files" / "index.html").read_text()
