"""Atomic file output.

:func:`write_file_set` writes a SET of files (a plan's CSV and JSON, a robot's C header,
source and manifest) so that they appear together or not at all: every file is staged in a
hidden temporary folder inside the target folder, flushed to disk, and only then renamed into
place. On any exception (a planner error, disk full, SIGINT) the staging folder is removed and
the previous files stay untouched; a failing rename puts back the files already renamed, and a
journal lets the next write roll back a set a kill or power loss cut between two renames.
Concurrent runs writing the same set serialise on a lock of the output folder, so two runs never
leave a mix of their files: on POSIX ``fcntl.flock`` on the folder itself (no lock file; a reader
may take ``LOCK_SH`` on it to see only whole sets); where ``fcntl`` is missing (Windows),
:mod:`filelock` on a hidden ``.armgen.lock`` file in the folder (Windows removes it on release).
New files get the permissions the umask gives (0644 under umask 022), also when they replace
older files.

Every OS failure (the target is a directory, a read-only folder, a full disk) becomes an
:class:`~armgen.errors.OutputError` (exit 4) that names the path.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import shutil
import tempfile
from pathlib import Path
from typing import Iterator, Mapping

from .errors import OutputError

try:
    import fcntl
except ImportError:  # not POSIX: the folder lock falls back to filelock (see the module docstring)
    fcntl = None

FALLBACK_LOCK_NAME = ".armgen.lock"


def _umask_mode() -> int:
    """0666 less the process umask (read without changing it for other threads)."""
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


def _check_targets(targets: list[Path]) -> None:
    for target in targets:
        if target.is_dir():
            raise OutputError(f"{target}: the output name is a directory; give a file name (e.g. -o {target / 'plan.csv'})")


@contextlib.contextmanager
def _folder_lock(folder: Path) -> Iterator[None]:
    """An exclusive lock on the output folder itself (flock on its descriptor), held while one
    set is written: it leaves no lock file behind in the output. Without fcntl, a filelock on
    ``FALLBACK_LOCK_NAME`` in the folder."""
    if fcntl is None:
        from filelock import FileLock

        with FileLock(folder / FALLBACK_LOCK_NAME):
            yield
        return
    fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        fcntl.flock(fd, fcntl.LOCK_UN)
        os.close(fd)


def _write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        written = os.write(fd, view)
        view = view[written:]


def write_file_set(files: Mapping[str | os.PathLike, str | bytes]) -> list[Path]:
    """Write every ``path -> content`` (text is written as UTF-8 with the newlines given) so
    the files appear together or not at all. All paths must be in one folder.

    The renames are made all-or-nothing: each file it replaces is first hard-linked (else
    copied) into the staging folder, and a journal listing the set is written (and synced)
    there before the first rename. A rename that fails puts back the files already replaced.
    A kill or power loss between two renames leaves the staging folder with its journal: the
    next set written into that folder (under the same lock) rolls it back first, so the
    folder holds the old set again (see :func:`_roll_back`). The journal is removed once
    every file is in place: that is the commit."""
    targets = [Path(p) for p in files]
    folders = {t.parent for t in targets}
    if len(folders) != 1:
        raise ValueError(f"write_file_set writes into one folder, got {sorted(map(str, folders))}")
    folder = folders.pop()
    _check_targets(targets)
    mode = _umask_mode()
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with _folder_lock(folder):
            for stale in folder.glob(".armgen-staging-*"):  # a set interrupted by a kill or power loss
                _roll_back(stale, folder)
            staging = Path(tempfile.mkdtemp(prefix=".armgen-staging-", dir=folder))
            try:
                staged = []
                for target, content in zip(targets, files.values()):
                    data = content.encode("utf-8") if isinstance(content, str) else bytes(content)
                    path = staging / target.name
                    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
                    try:
                        _write_all(fd, data)
                        os.fchmod(fd, mode)
                        os.fsync(fd)
                    finally:
                        os.close(fd)
                    staged.append((path, target))
                _check_targets(targets)  # a directory created since the first check
                journal = []
                for path, target in staged:
                    old = staging / (".old-" + target.name)
                    if target.exists():
                        try:
                            os.link(target, old)
                        except OSError:  # no hard links here: a copy is as good a backup
                            shutil.copy2(target, old)
                    journal.append({"name": target.name, "old": target.exists(), "inode": os.stat(path).st_ino})
                _write_journal(staging, journal)
                try:
                    for path, target in staged:
                        os.replace(path, target)
                except BaseException:
                    _roll_back(staging, folder)
                    raise
                os.unlink(staging / _JOURNAL)  # the commit: every file is in place
                _sync_folder(folder)
            finally:
                shutil.rmtree(staging, ignore_errors=True)
    except OSError as exc:
        where = exc.filename or folder
        raise OutputError(f"cannot write {', '.join(t.name for t in targets)} in {folder}: {exc.strerror or exc} "
                          f"({where}); choose a writable folder with free space (nothing was written)") from None
    return targets


# The journal of a set being renamed into place, in its staging folder: one entry per file
# (its name, whether an older version was kept beside as ".old-<name>", the new file's inode).
_JOURNAL = ".journal.json"


def _write_journal(staging: Path, entries: list[dict]) -> None:
    fd = os.open(staging / _JOURNAL, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    try:
        _write_all(fd, json.dumps(entries).encode())
        os.fsync(fd)
    finally:
        os.close(fd)
    _sync_folder(staging)


def _roll_back(staging: Path, folder: Path) -> None:
    """Undo the renames of the set staged in ``staging`` (the journal says which files), then
    remove it. A staging folder without a journal never renamed anything: it is removed."""
    try:
        entries = json.loads((staging / _JOURNAL).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        entries = []
    for entry in entries if isinstance(entries, list) else []:
        try:
            target = folder / Path(str(entry["name"])).name
            renamed = target.exists() and os.stat(target).st_ino == entry["inode"]  # the new file is in place
            if entry["old"] and (renamed or not target.exists()):
                os.replace(staging / (".old-" + target.name), target)
            elif renamed:
                os.unlink(target)
        except (OSError, KeyError, TypeError):
            continue  # that file was not renamed yet, or is someone else's now
    _sync_folder(folder)
    shutil.rmtree(staging, ignore_errors=True)


def _sync_folder(folder: Path) -> None:
    with contextlib.suppress(OSError):  # the folder entry itself (not all filesystems allow it)
        dir_fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(dir_fd)
        finally:
            os.close(dir_fd)


def write_text_atomic(path: str | os.PathLike, text: str) -> None:
    """One file, atomically (a set of one)."""
    write_file_set({path: text})


@contextlib.contextmanager
def atomic_open(path: str | os.PathLike, mode: str = "w", newline: str | None = None) -> Iterator:
    """A file handle whose content is written (as a set of one) only when the block ends
    without an exception, e.g. for ``figure.savefig(handle)``."""
    buffer: io.BytesIO | io.StringIO = io.BytesIO() if "b" in mode else io.StringIO(newline=newline)
    yield buffer
    write_file_set({path: buffer.getvalue()})
