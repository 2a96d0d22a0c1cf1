"""MkDocs hook: the parts of the site that are generated from the code during the build.

- ``cli.md``: the ``--help`` of every ``armgen`` command, rendered from click;
- ``task-files.md``: the task-file reference, from the JSON Schemas of ``armgen schema`` when
  that command exists, else from the bundled example files (every field they use);
- ``figures/*.png`` and ``figures/arm.gif``: every planner's figure, planned from the bundled
  examples at build time and appended to the planner's method page (a "Figures" section);
- the tables of ``results.md`` (markers ``<!-- armgen:NAME -->``), measured on the example plans.

Two edits to every page: the ``# docs-test: …`` first lines of code blocks (for
tests/test_docs.py, not for readers) are left out of the rendered page, and a page's figures go
where ``<!-- armgen:figures -->`` stands (in the first screen of the weighted-GPM page), else
at its end.

Nothing here is checked in as an image: a stale figure cannot survive a build.
"""

from __future__ import annotations

import json
import logging
import os
import re
import tempfile
import time
from importlib.resources import files as package_files
from pathlib import Path

import numpy as np

log = logging.getLogger("mkdocs.plugins.armgen")
os.environ.setdefault("ARMGEN_NO_PROGRESS", "1")

# (example, page it illustrates, caption) — one plan each, the full example (all under ~6 s)
FIGURES = [
    ("modular8_circle_combined", "cartesian.md", "spec 20 combined method on modular8: closed circle, 250 s"),
    ("iiwa14_fault_circle_wln", "fault_tolerance.md", "iiwa14, WLN, joint a4 locked at t = 2 s"),
    ("iiwa14_fault_circle_gpm", "fault_tolerance.md", "iiwa14, GPM, joint a4 locked at t = 2 s"),
    ("modular8_wgpm_demo", "wgpm.md", "modular8, weighted GPM demo"),
    ("ptp_single_joint", "ptp.md", "the paper's worked example: cubic, 3-4 and 3-5-3 on the paper's knot times"),
    ("snake_tank", "snake.md", "snake12 through the tank's plate openings, tip driven, exact solver"),
    ("iiwa14_weld_seam_program", "programs.md", "iiwa14 weld seam: lines and an arc, corners rounded (10 mm), start pose"),
    ("panda_polish_contour_program", "programs.md", "panda polishing contour from a 181-row CSV, approach and retract"),
    ("iiwa14_weld_seam_pillar", "collision.md", "the weld seam beside a pillar: the collision criterion keeps the arm 57 mm clear"),
    ("iiwa14_pick_table", "collision.md", "a pick from the table the arm stands on: the wrist 33.7 mm above it"),
]
FAULT_EXAMPLES = [("iiwa14", "iiwa14_fault_circle_gpm", "iiwa14_fault_circle_wln"),
                  ("modular8", "modular8_fault_circle_gpm", "modular8_fault_circle_wln")]
ANIMATION = ("modular8_circle_combined", 10.0, 4.0)  # example, fps, seconds: 40 frames on the home page

# The first line of a code block that tells tests/test_docs.py what it needs or why it is
# skipped (tests/doc_blocks.py's NEEDS and SKIP patterns, as a line).
DOCS_TEST_MARKER = re.compile(r"^[ \t]*#\s*docs-test:\s*(skip|needs)\b.*\n", re.M)
FIGURES_MARKER = "<!-- armgen:figures -->"
SAME_AT_DISPLAY_PRECISION = 0.05  # deg/s or deg/s²: the tables print one decimal
_plans: dict = {}
_generated: dict[str, bytes] = {}


def _plan(name: str):
    from armgen.planning.tasks import load_task, run_task

    if name not in _plans:
        path = package_files("armgen.data").joinpath("examples", f"{name}.toml")
        task, sha = load_task(path)
        _plans[name] = run_task(task, str(path), sha)  # the real path: a poses CSV is relative to it
    return _plans[name]


def _figure_png(name: str) -> bytes:
    from armgen.planning.plotting import save_figure
    from armgen.planning.tasks import plot_plan

    with tempfile.TemporaryDirectory() as scratch:
        out = save_figure(plot_plan(_plan(name), name), Path(scratch) / f"{name}.png")
        return out.read_bytes()


def _animation_gif(name: str, fps: float, seconds: float) -> bytes:
    from armgen.planning.animation import animate_plan

    with tempfile.TemporaryDirectory() as scratch:
        return animate_plan(_plan(name), Path(scratch) / "arm.gif", fps, seconds).read_bytes()


def _cli_reference() -> str:
    import click

    from armgen.cli.main import cli

    lines = ["# Command line reference", "",
             "Generated from the click definitions during the docs build (`armgen COMMAND --help`).", ""]
    root = click.Context(cli, info_name="armgen")
    lines += ["## armgen", "", "```text", cli.get_help(root), "```", ""]
    for name in sorted(cli.commands):
        command = cli.commands[name]
        ctx = click.Context(command, info_name=name, parent=root)
        lines += [f"## armgen {name}", "", "```text", command.get_help(ctx), "```", ""]
    return "\n".join(lines)


def _schema_tables(title: str, schema: dict) -> list[str]:
    """A JSON Schema's models as field tables (name, type, default, description)."""
    out = []
    models = [(title, schema)] + sorted((schema.get("$defs") or {}).items())
    for model_name, model in models:
        props = model.get("properties") or {}
        if not props:
            continue
        required = set(model.get("required", []))
        out += [f"### {model_name}", "", model.get("description", "").strip(), "",
                "| field | type | default | description |", "|---|---|---|---|"]
        for field, spec in props.items():
            kind = spec.get("type") or spec.get("$ref", "").split("/")[-1] or " / ".join(
                s.get("type") or s.get("$ref", "").split("/")[-1] for s in spec.get("anyOf", []))
            default = "required" if field in required else json.dumps(spec.get("default", ""))
            text = " ".join(str(spec.get("description", "")).split()).replace("|", "\\|")
            out.append(f"| `{field}` | {kind} | {default} | {text} |")
        out.append("")
    return out


def _task_reference() -> str:
    from click.testing import CliRunner

    from armgen.cli.main import cli

    lines = ["# Task files", "",
             "A task file is TOML; its `planner` field picks the planner, whose page explains the method. ",
             "This page is generated during the docs build.", ""]
    if "schema" in cli.commands:
        for kind in ("task", "robot"):
            run = CliRunner().invoke(cli, ["schema", kind])
            if run.exit_code == 0:
                lines += [f"## Schema: {kind} files (from `armgen schema {kind}`)", ""]
                lines += _schema_tables(kind, json.loads(run.output))
    lines += ["## The bundled examples", "",
              "Every example under `examples/`, complete; copy one and change it "
              "(`armgen plan FILE --set key=value` overrides a field from the command line).", ""]
    for example in sorted(package_files("armgen.data").joinpath("examples").iterdir(), key=lambda p: p.name):
        if example.name.endswith(".toml"):
            lines += [f"### `{example.name}`", "", "```toml", example.read_text(encoding="utf-8").rstrip(), "```", ""]
    return "\n".join(lines)


def _compare(a: float, b: float) -> str:
    """'lower' / 'higher' / 'equal' for a against b, equal when they agree to the table's 0.1."""
    if abs(a - b) < SAME_AT_DISPLAY_PRECISION:
        return "equal"
    return "lower" if a < b else "higher"


def _fault_smoothness() -> str:
    """Total joint-velocity variation before the lock and peak |q̈| (before, after, at the lock)."""
    rows, verdicts = [], []
    for robot, gpm, wln in FAULT_EXAMPLES:
        measured = {}
        for method, name in (("GPM", gpm), ("WLN", wln)):
            result = _plan(name)
            meta = result.metadata
            n = len(meta["robot"]["qlim_rad"])
            qd = np.column_stack([result.column(f"dq{i + 1}_rad_s") for i in range(n)])
            h = meta["integrator"]["step_s"]
            lock = int(meta["fault"]["first_locked_step"])
            jumps = np.degrees(np.abs(np.diff(qd, axis=0)))  # deg/s per step, per joint
            m = {"tv": float(jumps[:lock - 1].sum()), "before": float(jumps[:lock - 1].max() / h),
                 "after": float(jumps[lock:].max() / h), "at": float(jumps[lock - 1].max() / h),
                 "done": meta["verdict"]["completed"], "why": meta["verdict"].get("why_not") or "",
                 "weights": float(meta["verdict"].get("weight_total_variation", 0.0))}
            measured[method] = m
            rows.append(f"| {robot} | {method} ({meta['verdict']['method']}) | {m['tv']:.1f} | {m['before']:.1f} | "
                        f"{m['after']:.1f} | {m['at']:.0f} | {m['weights']:.3g} | {'yes' if m['done'] else 'no: ' + m['why']} |")
        g, w = measured["GPM"], measured["WLN"]
        verdicts.append(
            f"- **{robot}**, GPM against WLN: total variation before the lock {_compare(g['tv'], w['tv'])} "
            f"({g['tv']:.1f} vs {w['tv']:.1f} deg/s); peak |q̈| before the lock {_compare(g['before'], w['before'])} "
            f"({g['before']:.1f} vs {w['before']:.1f} deg/s²), after it {_compare(g['after'], w['after'])} "
            f"({g['after']:.1f} vs {w['after']:.1f} deg/s²); the velocity jump at the lock "
            f"{_compare(g['at'], w['at'])} ({g['at']:.0f} vs {w['at']:.0f} deg/s²).")
    table = ["| robot | method | Σ\\|Δq̇\\| before the lock [deg/s] | peak \\|q̈\\| before [deg/s²] | "
             "peak \\|q̈\\| after [deg/s²] | \\|Δq̇\\|/h at the lock [deg/s²] | Σ\\|ΔW\\| (weights) | task completed |",
             "|---|---|---|---|---|---|---|---|"] + rows
    return "\n".join(table + [""] + verdicts)


def _ptp_bounds() -> str:
    result = _plan("ptp_single_joint")
    checks = result.metadata["timing"]["bound_check"]
    lines = ["| segment | peak \\|ω\\| [deg/s] | bound [deg/s] | within |", "|---|---|---|---|"]
    for c in checks:
        lines.append(f"| {c['segment']} | {np.degrees(c['peak_omega_rad_s']):.3f} | "
                     f"{np.degrees(c['omega_max_rad_s']):.3f} | {'yes' if c['within_bounds'] else '**no**'} |")
    return "\n".join(lines)


MARKERS = {"fault-smoothness": _fault_smoothness, "ptp-bounds": _ptp_bounds}


def generated_files() -> dict[str, object]:
    """Site path -> the function that renders it: every file the build adds to the site (the
    link checker of the tests reads the paths without building)."""
    files: dict[str, object] = {"cli.md": _cli_reference, "task-files.md": _task_reference}
    for name, _, _ in FIGURES:
        files[f"figures/{name}.png"] = lambda name=name: _figure_png(name)
    files["figures/arm.gif"] = lambda: _animation_gif(*ANIMATION)
    return files


def on_pre_build(config, **kwargs) -> None:
    started = time.perf_counter()
    _generated.clear()
    for uri, render in generated_files().items():
        content = render()
        _generated[uri] = content.encode() if isinstance(content, str) else content
    log.info("armgen docs hook: generated %d files in %.1f s", len(_generated), time.perf_counter() - started)


def on_files(files, config, **kwargs):
    from mkdocs.structure.files import File

    for uri, content in _generated.items():
        existing = files.get_file_from_path(uri)
        if existing is not None:
            files.remove(existing)
        files.append(File.generated(config, uri, content=content))
    return files


def on_page_markdown(markdown: str, page, config, files, **kwargs) -> str:
    markdown = DOCS_TEST_MARKER.sub("", markdown)
    for marker, render in MARKERS.items():
        tag = f"<!-- armgen:{marker} -->"
        if tag in markdown:
            markdown = markdown.replace(tag, render())
    figures = [(name, caption) for name, uri, caption in FIGURES if uri == page.file.src_uri]
    if figures:
        depth = page.file.src_uri.count("/")
        prefix = "../" * depth
        images = []
        for name, caption in figures:
            images += [f"![{caption}]({prefix}figures/{name}.png)", "", f"*`examples/{name}.toml`: {caption}.*", ""]
        if FIGURES_MARKER in markdown:  # where the page wants them (e.g. in its first screen)
            markdown = markdown.replace(FIGURES_MARKER, "\n".join(images))
        else:
            markdown += "\n".join(["", "## Figures", "",
                                   "Drawn by `armgen plot` from the bundled examples during this documentation build.",
                                   "", *images])
    return markdown
