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
import re
import subprocess
import sys
from pathlib import Path

import pytest

from doc_blocks import blocks, skip_reason
from conftest import require_tool

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


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    """The site built once with ``mkdocs build --strict``."""
    missing = [name for name in DOCS_PACKAGES if importlib.util.find_spec(name) is None]
    if missing:
        pytest.skip(f"{', '.join(missing)} not installed: {DOCS_HINT}")
    site = tmp_path_factory.mktemp("docs") / "site"
    env = dict(os.environ, PYTHONPATH=str(ROOT), ARMGEN_NO_PROGRESS="1", MPLBACKEND="Agg", NO_MKDOCS_2_WARNING="1")
    run = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-f", str(ROOT / "mkdocs.yml"),
                          "-d", str(site)], cwd=ROOT, env=env, capture_output=True, text=True, timeout=900)
    assert run.returncode == 0, run.stdout + run.stderr
    return site


@pytest.mark.slow
def test_mkdocs_build_strict(site):
    from PIL import Image

    for name in ("modular8_circle_combined", "iiwa14_fault_circle_gpm", "iiwa14_fault_circle_wln",
                 "modular8_wgpm_demo", "ptp_single_joint", "snake_tank"):
        assert (site / "figures" / f"{name}.png").read_bytes().startswith(b"\x89PNG")
    with Image.open(site / "figures" / "arm.gif") as gif:
        assert gif.n_frames == 40


@pytest.mark.slow
def test_rendered_pages_hide_ci_markers_and_show_figures_early(site):
    pages = sorted(site.rglob("*.html"))
    assert pages
    for page in pages:
        assert "docs-test" not in page.read_text(encoding="utf-8"), page.relative_to(site)
    wgpm = (site / "wgpm" / "index.html").read_text(encoding="utf-8")
    body = wgpm[wgpm.index('<article'):]
    # the demo's figure comes before the page's first section heading: in its first screen
    assert body.index("figures/modular8_wgpm_demo.png") < body.index("<h2")
    assert wgpm.count("figures/modular8_wgpm_demo.png") == 1
    api = (site / "api" / "index.html").read_text(encoding="utf-8")
    toc = re.search(r'<nav class="md-nav md-nav--secondary".*?</nav>\s*</div>', api, re.S).group(0)
    entries = re.findall(r'<a href="#[^"]+" class="md-nav__link">\s*<span class="md-ellipsis">\s*(.*?)\s*</span>',
                         toc, re.S)
    twice = sorted({entry for entry in entries if entries.count(entry) > 1})
    assert entries and not twice, f"the API page's table of contents lists these twice: {twice}"


# Page width of the layout check (a laptop screen).
SCREEN_WIDTH_PX = 1280
# Run in the page: its layout width, and the code blocks and tables whose content is wider
# than their box (cut off at the right edge, or only visible by scrolling inside the box).
PROBE = """<script>
document.body.setAttribute('data-width', document.documentElement.scrollWidth);
document.body.setAttribute('data-clipped', Array.from(document.querySelectorAll(
  '.md-content pre > code, .md-content .md-typeset__table, .md-content table'))
  .filter(e => e.scrollWidth > e.clientWidth + 1)
  .map(e => e.tagName + ':' + e.textContent.slice(0, 40).replace(/[^A-Za-z0-9_.:=-]+/g, ' ')).join(' | '));
</script>"""


@pytest.mark.slow
@pytest.mark.parametrize("page", ["getting-started", "api", "cartesian", "results", "wgpm", "fault_tolerance"])
def test_pages_fit_a_1280_px_screen(site, page, tmp_path):
    """Headless Chromium lays the page out 1280 px wide: nothing (code, tables) may widen it."""

    browser = require_tool("chromium")
    html = site / page / "index.html"
    probe = html.with_name("probe.html")  # beside it, so the relative assets resolve
    probe.write_text(html.read_text(encoding="utf-8").replace("</body>", PROBE + "</body>"), encoding="utf-8")
    run = subprocess.run([browser, "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                          f"--window-size={SCREEN_WIDTH_PX},900", "--virtual-time-budget=3000", "--dump-dom",
                          probe.as_uri()], capture_output=True, text=True, timeout=120)
    width = re.search(r'data-width="(\d+)"', run.stdout)
    assert width, run.stderr[-2000:]
    assert int(width.group(1)) <= SCREEN_WIDTH_PX, f"{page}: the page is {width.group(1)} px wide"
    clipped = re.search(r'data-clipped="([^"]*)"', run.stdout).group(1)
    assert not clipped, f"{page}: content wider than its box (scrolls or is cut off): {clipped}"
