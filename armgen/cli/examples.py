"""``armgen examples``: list the bundled task files and copy them out, so a wheel install can
run every example of the README and the docs (``armgen plan <copied file>``)."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

import click

from ..api import OptionError, OutputError, write_text_atomic
from .handling import handle_errors


def bundled_examples() -> dict[str, str]:
    """File name -> text of every bundled task file."""
    folder = resources.files("armgen.data") / "examples"
    return {entry.name: entry.read_text(encoding="utf-8")
            for entry in sorted(folder.iterdir(), key=lambda e: e.name) if entry.name.endswith(".toml")}


def _data_files(chosen: dict[str, str]) -> dict[str, str]:
    """The bundled files the chosen task files read (a program's ``poses`` CSVs, relative to the
    task file), so that a copied example plans where it was copied to."""
    import tomllib

    folder = resources.files("armgen.data") / "examples"
    out = {}
    for text in chosen.values():
        path = tomllib.loads(text).get("path", {})
        for move in path.get("moves", []) if isinstance(path, dict) else []:
            name = move.get("file") if isinstance(move, dict) else None
            if isinstance(name, str) and (folder / name).is_file():
                out[name] = (folder / name).read_text(encoding="utf-8")
    return out


def _summary(text: str) -> tuple[str, str, str]:
    """(planner, robot, first comment line) of a task file, read without planning it."""
    fields = {"planner": "?", "robot": "?"}
    for line in text.splitlines():
        key, _, value = line.partition("=")
        if key.strip() in fields and fields[key.strip()] == "?":
            fields[key.strip()] = value.strip().strip('"')
    comment = next((line.lstrip("# ").strip() for line in text.splitlines() if line.startswith("#")), "")
    return fields["planner"], fields["robot"], comment


def copy_examples(names: tuple[str, ...], folder: Path, force: bool) -> list[Path]:
    """Copy the named (default: all) examples into ``folder``; refuses to overwrite a file
    that differs unless ``force``; checks everything before writing anything."""
    examples = bundled_examples()
    unknown = [n for n in names if n not in examples and f"{n}.toml" not in examples]
    if unknown:
        raise OptionError(f"unknown example(s) {', '.join(unknown)}; `armgen examples` lists them")
    chosen = {n: t for n, t in examples.items() if not names or n in names or n[:-5] in names}
    chosen |= _data_files(chosen)
    if folder.exists() and not folder.is_dir():
        raise OutputError(f"--copy {folder}: is a file; give a folder (it is created when missing)")
    clashes = [folder / n for n, t in chosen.items()
               if (folder / n).exists() and (not (folder / n).is_file() or (folder / n).read_bytes() != t.encode())]
    if clashes and not force:
        raise OptionError(f"{clashes[0]}: exists and differs from the bundled example; "
                          "copy into another folder or pass --force to overwrite")
    paths = []
    for name, text in chosen.items():
        write_text_atomic(folder / name, text)
        paths.append(folder / name)
    return paths


@click.command("examples")
@click.argument("names", nargs=-1)
@click.option("--copy", "copy_to", type=click.Path(), default=None,
              help="copy the examples (all, or the NAMES given) into this folder")
@click.option("--force", is_flag=True, help="overwrite copies that differ from the bundled files")
@handle_errors
def examples_cmd(names: tuple[str, ...], copy_to: str | None, force: bool) -> None:
    """List the bundled example task files, or copy them out with --copy DIR."""
    if copy_to is None:
        for name, text in bundled_examples().items():
            planner, robot, comment = _summary(text)
            click.echo(f"{name:38s} {planner:15s} {robot:10s} {comment}")
        click.echo("copy them with `armgen examples --copy DIR`, then `armgen plan DIR/<file>`")
        return
    for path in copy_examples(names, Path(copy_to), force):
        click.echo(f"wrote {path}")
