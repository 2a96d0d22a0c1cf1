"""Atomic file output.

:func:`write_file_set` writes a SET of files (a plan's CSV and JSON, a robot's C header,
source and manifest) so that they appear together or not at all: every file is staged in a
hidden temporary folder inside the target folder, flushed to disk, and only then renamed into
place. On any exception (a planner error, disk full, SIGINT) the staging folder is removed and
the previous files stay untouched. Concurrent runs writing the same set serialise on a lock of
the output folder, so two runs never leave a mix of their files: on POSIX ``fcntl.flock`` on the
folder itself (no lock file; a reader may take ``LOCK_SH`` on it to see only whole sets); where
``fcntl`` is missing (Windows), :mod:`filelock` on a hidden ``.armgen.lock`` file in the folder
(Windows removes it on release). New files get the permissions the umask gives (0644 under
umask 022), also when they replace older files.

Every OS failure (the target is a directory, a read-only folder, a full disk) becomes an
:class:`~armgen.errors.OutputError` (exit 4) that names the path.
"""

from __future__ import annotations

import contextlib
import io
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
    the files appear together or not at all. All paths must be in one folder."""
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
                for path, target in staged:
                    os.replace(path, target)
                with contextlib.suppress(OSError):  # the folder entry itself (not all filesystems allow it)
                    dir_fd = os.open(folder, os.O_RDONLY)
                    try:
                        os.fsync(dir_fd)
                    finally:
                        os.close(dir_fd)
            finally:
                shutil.rmtree(staging, ignore_errors=True)
    except OSError as exc:
        where = exc.filename or folder
        raise OutputError(f"cannot write {', '.join(t.name for t in targets)} in {folder}: {exc.strerror or exc} "
                          f"({where}); choose a writable folder with free space (nothing was written)") from None
    return targets


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
