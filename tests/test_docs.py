"""The documentation: the MkDocs site builds with warnings as errors (figures, animation, CLI
and file references generated from the code), and every ``sh``/``python`` block in README.md
and docs/*.md runs.

A block that calls an external tool says so on its first line, ``# docs-test: needs TOOL …``:
it runs wherever the tools are, is skipped with the install command where they are missing,
and fails where they are missing in CI (which installs them all, .ci/run). A block that cannot
run in a test at all says why, ``# docs-test: skip (reason)``; it is reported as skipped with
that reason, never as passed, and only the blocks in SKIPPED_BLOCKS may say so. The blocks of
one page run in order, in one test, as one reader types them into one terminal (a ``cd``
carries over to the next block), in a scratch directory laid out as the repository: its
examples, robots, benchmarks and generated code, a copy of the firmware stub (its Makefile
builds in place), and ``armgen``/``python`` on PATH that run this checkout.
"""

from __future__ import annotations

import importlib.util
import os
import re
import resource
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

from doc_blocks import Block, blocks, command, needed_tools, next_cwd, skip_reason
from conftest import require_tool

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md"] + sorted((ROOT / "docs").glob("*.md"))
# The blocks that cannot run in a test (page, the start of the block's first command), and why
# that is so; every other block runs.
SKIPPED_BLOCKS = {
    # it installs armgen into the running environment and runs the whole test suite, this test included
    ("README.md", "pip install -e '.[test,docs]'"),
    # pip and apt-get install into the system; tests/test_install.py installs the wheel itself
    ("getting-started.md", "pip install armgen-*.whl"),
}
LINKED = ("examples", "robots", "benchmarks", "generated")  # read-only in the scratch directory
BLOCK_TIMEOUT_S = 900  # the longest block (firmware.md: a project built, run, verified) takes ~3 min on 2 busy cores
DOCS_PACKAGES = ("mkdocs", "material", "mkdocstrings", "mkdocstrings_handlers")
DOCS_HINT = "pip install '.[docs]' (mkdocs, mkdocs-material, mkdocstrings[python])"


def _page_blocks(page: Path) -> list[Block]:
    return blocks(page.read_text(encoding="utf-8"))


def _first_command(code: str) -> str:
    return next(line.strip() for line in code.splitlines() if line.strip() and not line.lstrip().startswith("#"))


def _scratch(work: Path) -> None:
    """The repository's layout: firmware_stub/ is armgen/data/firmware_stub (its Makefile finds
    the generated code at ../../../generated), examples/ and robots/ beside it."""
    data = work / "armgen" / "data"
    data.mkdir(parents=True)
    shutil.copytree(ROOT / "armgen" / "data" / "firmware_stub", data / "firmware_stub",
                    ignore=shutil.ignore_patterns("build"))
    for name in ("examples", "robots"):
        (data / name).symlink_to(ROOT / "armgen" / "data" / name)
    (work / "firmware_stub").symlink_to(Path("armgen") / "data" / "firmware_stub")
    for name in LINKED:
        if not (work / name).exists():
            (work / name).symlink_to(ROOT / name)
    bin_dir = work / ".bin"
    bin_dir.mkdir()
    for name, run in (("armgen", f'"{sys.executable}" -m armgen.cli.main'), ("python", f'"{sys.executable}"'),
                      ("python3", f'"{sys.executable}"')):
        shim = bin_dir / name
        shim.write_text(f'#!/bin/sh\nexec {run} "$@"\n')
        shim.chmod(0o755)


def _children_cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _run(work: Path, cwd: Path, block: Block) -> tuple[subprocess.CompletedProcess, Path]:
    """One block, from ``cwd``; and the folder the next block starts in."""
    env = dict(os.environ, PYTHONPATH=str(ROOT), ARMGEN_NO_PROGRESS="1", MPLBACKEND="Agg",
               PATH=f"{work / '.bin'}{os.pathsep}{os.environ.get('PATH', '')}")
    record = work / ".cwd"
    started, cpu = time.perf_counter(), _children_cpu_s()
    run = subprocess.run(command(block.lang, block.code, sys.executable, record), cwd=cwd, env=env,
                         capture_output=True, text=True, timeout=BLOCK_TIMEOUT_S)
    print(f"line {block.line}: {time.perf_counter() - started:.1f} s wall, {_children_cpu_s() - cpu:.1f} s CPU, "
          f"exit {run.returncode}")
    return run, next_cwd(cwd, record)


@pytest.mark.slow
@pytest.mark.parametrize("page", PAGES, ids=lambda page: str(page.relative_to(ROOT)))
def test_page_blocks_run(page, tmp_path):
    """Every block of the page not marked skip, in order, in one scratch directory."""
    work = tmp_path / "work"
    work.mkdir()
    _scratch(work)
    cwd = work
    for block in _page_blocks(page):
        if skip_reason(block.code):
            continue  # reported by test_marked_block_is_skipped; later blocks do not use it
        for tool in needed_tools(block.code):
            require_tool(tool)  # missing here: the rest of the page (which may use it) is skipped
        run, cwd = _run(work, cwd, block)
        assert run.returncode == 0, \
            f"{page.name}:{block.line} failed (exit {run.returncode}):\n{run.stdout[-4000:]}\n{run.stderr[-6000:]}"


def _marked_skip():
    for page in PAGES:
        for block in _page_blocks(page):
            if skip_reason(block.code):
                yield pytest.param(page, block, id=f"{page.relative_to(ROOT)}:{block.line}")


@pytest.mark.parametrize("page, block", list(_marked_skip()))
def test_marked_block_is_skipped(page, block):
    pytest.skip(f"marked not to run: {skip_reason(block.code)}")


def test_only_blocks_that_cannot_run_are_skipped():
    """A block is skipped only when no test can run it (SKIPPED_BLOCKS says why for each);
    one that needs a tool says which (``needs``), so CI runs it."""
    skipped = [(page.name, block.line, _first_command(block.code)) for page in PAGES for block in _page_blocks(page)
               if skip_reason(block.code)]
    unexplained = [(name, line) for name, line, first in skipped
                   if not any(name == page and first.startswith(start) for page, start in SKIPPED_BLOCKS)]
    assert not unexplained, f"skipped blocks that a test can run (remove their skip marker): {unexplained}"
    assert len(skipped) == len(SKIPPED_BLOCKS), f"SKIPPED_BLOCKS lists blocks that are gone or run: {skipped}"


# What a block calls that needs the ARM toolchain and QEMU (so it must say ``needs`` them).
CALLS_THE_ARM_TOOLS = ("arm-none-eabi", "--target qemu", "--target cortex-m4", "make -C firmware_stub")


def test_blocks_that_call_the_arm_tools_say_so():
    """Without its ``needs`` line a block that builds for the M4 would fail where the toolchain
    is missing instead of being skipped with the install command."""
    for page in PAGES:
        for block in _page_blocks(page):
            if skip_reason(block.code) or not any(call in block.code for call in CALLS_THE_ARM_TOOLS):
                continue
            assert {"arm-none-eabi-gcc", "qemu-system-arm"} <= set(needed_tools(block.code)), \
                f"{page.name}:{block.line}: add '# docs-test: needs arm-none-eabi-gcc qemu-system-arm …'"


def test_no_block_takes_a_build_log_for_a_run_csv():
    """The firmware project's ``qemu`` target writes the run's CSV to build-m4/run-m4.csv itself;
    the getting-started page redirected the target's output (the build's lines) to run-m4.csv,
    and `armgen verify --run` of that file failed."""
    for page in PAGES:
        for block in _page_blocks(page):
            for line in block.code.splitlines():
                assert not re.search(r"--target\s+qemu\b[^#]*>", line), f"{page.name}:{block.line}: {line.strip()}"


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
