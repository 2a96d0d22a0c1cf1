"""armgen.fileio without fcntl (Windows): the module imports, and the output-folder lock falls
back to filelock on a hidden lock file, still keeping concurrent writers' sets whole."""

from __future__ import annotations

import multiprocessing
import subprocess
import sys
from pathlib import Path

from filelock import FileLock

from armgen import fileio

REPO = Path(__file__).resolve().parent.parent
WRITES_PER_WRITER = 20


def test_fileio_imports_and_writes_where_fcntl_is_missing(tmp_path):
    # sys.modules["fcntl"] = None makes every `import fcntl` fail, armgen's and filelock's
    script = ("import sys; sys.modules['fcntl'] = None\n"
              "from armgen import fileio\n"
              "assert fileio.fcntl is None\n"
              f"fileio.write_file_set({{{str(tmp_path / 'p.csv')!r}: 'a\\n', {str(tmp_path / 'p.json')!r}: '{{}}\\n'}})\n")
    run = subprocess.run([sys.executable, "-c", script], cwd=tmp_path, capture_output=True, text=True, timeout=120,
                         env={"PYTHONPATH": str(REPO), "PATH": "/usr/bin:/bin"})
    assert run.returncode == 0, run.stderr
    assert (tmp_path / "p.csv").read_text() == "a\n" and (tmp_path / "p.json").read_text() == "{}\n"


def _write_set_many(args: tuple[str, int]) -> None:
    folder, tag = args
    fileio.fcntl = None  # this forked writer takes the fallback lock
    for _ in range(WRITES_PER_WRITER):
        fileio.write_file_set({Path(folder) / "p.csv": f"{tag}\n" * 2000, Path(folder) / "p.json": f"{tag}\n"})


def _read_set_under_fallback_lock(folder: Path) -> tuple[str, str] | None:
    with FileLock(folder / fileio.FALLBACK_LOCK_NAME):
        try:
            return (folder / "p.csv").read_text()[:1], (folder / "p.json").read_text()[:1]
        except FileNotFoundError:
            return None


def test_fallback_lock_keeps_concurrent_sets_whole(tmp_path):
    ctx = multiprocessing.get_context("fork")
    with ctx.Pool(2) as pool:
        writers = pool.map_async(_write_set_many, [(str(tmp_path), 1), (str(tmp_path), 2)])
        while not writers.ready():
            tags = _read_set_under_fallback_lock(tmp_path)
            assert tags is None or tags[0] == tags[1]
        writers.get()
    assert _read_set_under_fallback_lock(tmp_path) in (("1", "1"), ("2", "2"))
    # on POSIX filelock keeps its lock file (Windows' removes it on release); no staging is left
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([fileio.FALLBACK_LOCK_NAME, "p.csv", "p.json"])
