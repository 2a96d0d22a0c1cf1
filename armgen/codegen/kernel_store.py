"""Where compiled planner kernels are kept between runs, and what makes a stored file
trustworthy enough to load: the store is code (a shared library is ``dlopen``-ed, a CasADi
function is deserialised), so it is used only when nobody but this user can write it.

- The folder (``$ARMGEN_CACHE_DIR/kernels``, else ``$XDG_CACHE_HOME/armgen/kernels``, else
  ``~/.cache/armgen/kernels``) is created ``0700``. A folder owned by another user, or writable
  by group or others, is not used: this process keeps its kernels in a private temporary
  folder instead (with a warning naming the fix).
- A file is read only when it is a regular file (no symlink), owned by this user and not
  writable by group or others, and at most :data:`MAX_STORED_FILE_BYTES` long.
- Every entry records the SHA-256 of each file it loads; a file whose digest differs is not
  loaded (the caller composes the kernel again and replaces the entry).
"""

from __future__ import annotations

import atexit
import contextlib
import hashlib
import json
import os
import re
import shutil
import stat
import tempfile
import warnings
from pathlib import Path
from typing import Any, Callable, Iterator

# The largest file the store reads back: the wgpm clamp kernel's library is ~6 MB, its
# serialised function ~20 MB; anything far larger is not an entry this code wrote.
MAX_STORED_FILE_BYTES = 256 << 20
# What a stored library may be called: the name NativeKernel gives it (kernel name, digest).
LIBRARY_NAME = re.compile(r"[A-Za-z0-9_]{1,100}-[0-9a-f]{24}\.so")
_WRITABLE_BY_OTHERS = stat.S_IWGRP | stat.S_IWOTH


def configured_dir() -> Path:
    """The store folder the environment names (ARMGEN_CACHE_DIR overrides XDG_CACHE_HOME and ~/.cache)."""
    base = os.environ.get("ARMGEN_CACHE_DIR") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache"), "armgen")
    return Path(base) / "kernels"


def _user() -> int:
    return os.geteuid()


def _untrusted(st: os.stat_result) -> str | None:
    """Why a file or folder with this status must not be trusted, or None."""
    if st.st_uid != _user():
        return f"owned by uid {st.st_uid}, not by this user (uid {_user()})"
    if st.st_mode & _WRITABLE_BY_OTHERS:
        return f"writable by group or others (mode {stat.S_IMODE(st.st_mode):o})"
    return None


_PRIVATE: list[Path] = []


def _private_dir() -> Path:
    """This process's own store, removed at exit (a library in use stays mapped)."""
    if not _PRIVATE:
        _PRIVATE.append(Path(tempfile.mkdtemp(prefix="armgen-kernels-")))
        atexit.register(shutil.rmtree, _PRIVATE[0], True)
    return _PRIVATE[0]


def store_dir() -> Path:
    """The kernel store to use: the configured folder when it is this user's alone (created
    ``0700`` when missing), else a private temporary folder for this process."""
    folder = configured_dir()
    try:
        folder.mkdir(mode=0o700, parents=True, exist_ok=True)
        st = os.stat(folder, follow_symlinks=False)
        problem = "not a folder" if not stat.S_ISDIR(st.st_mode) else _untrusted(st)
    except OSError as exc:
        problem = f"cannot be created ({exc.strerror or exc})"
    if problem is None:
        return folder
    warnings.warn(f"kernel store {folder} is {problem}: not used (kernels are composed for this process only); "
                  f"use a folder of your own (chmod go-w {folder}, or set ARMGEN_CACHE_DIR)", stacklevel=2)
    return _private_dir()


# Every armgen version or robot edit adds entries (a planner kernel's 1–6 MB with its compiled
# library, a robot's API kernel ~0.2 MB); past this size the store drops the entries used least
# recently, whenever it stores a new one.
MAX_STORE_BYTES = 1 << 30


def prune(store: Path, max_bytes: int = MAX_STORE_BYTES) -> None:
    """Drop the least recently used entries (and compiled libraries) until the store holds at
    most three quarters of ``max_bytes``; nothing happens below ``max_bytes``."""
    files = [(f.stat().st_mtime, f.stat().st_size, f) for f in store.iterdir() if f.is_file()]
    total = sum(size for _, size, _ in files)
    if total <= max_bytes:
        return
    for _, size, path in sorted(files, key=lambda item: item[0]):
        if total <= max_bytes * 3 // 4:
            break
        path.unlink(missing_ok=True)  # a library in use stays mapped; its entry compiles it again
        total -= size


def read_trusted(path: Path) -> bytes | None:
    """The bytes of a stored file, or None when it is missing, not a regular file (a symlink,
    a FIFO), not this user's alone, or too long to be an entry."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except OSError:
        return None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode) or _untrusted(st) or st.st_size > MAX_STORED_FILE_BYTES:
            return None
        with os.fdopen(os.dup(fd), "rb") as handle:
            data = handle.read(MAX_STORED_FILE_BYTES + 1)
        return data if len(data) <= MAX_STORED_FILE_BYTES else None
    except OSError:
        return None
    finally:
        os.close(fd)


def digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


@contextlib.contextmanager
def build_lock(path: Path) -> Iterator[None]:
    """Processes building the same entry take turns (``flock`` on ``path``): the second then
    finds it stored rather than building it too (a sweep's workers, pytest's). Where ``fcntl`` is
    missing each builds; ``os.replace`` keeps the store whole either way."""
    try:
        import fcntl
    except ImportError:
        yield
        return
    fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | getattr(os, "O_CLOEXEC", 0), 0o600)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        fcntl.flock(fd, fcntl.LOCK_UN)
        os.close(fd)


def _entry_paths(stem: str, key: str, suffix: str) -> tuple[Path, Path]:
    """(entry, file) of the entry ``stem``-``key``: the JSON entry and the file it vouches for,
    named by the stem (letters, digits and _, for whoever lists the store) and the first 24 hex
    digits of the key (what identifies the content)."""
    if not re.fullmatch(r"[0-9a-f]{24,64}", key):
        raise ValueError(f"not a store key: {key!r}")
    stem = re.sub(r"[^A-Za-z0-9_]", "_", stem)[:80]
    store = store_dir()
    return store / f"{stem}-{key[:24]}.json", store / f"{stem}-{key[:24]}{suffix}"


def stored_file(stem: str, key: str, suffix: str, build: Callable[[Path], Path],
                again: bool = False) -> tuple[Path, bool]:
    """A file made from what ``key`` digests (a compiled library or program): the stored one when
    its entry is trusted and the file's bytes match the SHA-256 the entry records, else the one
    ``build(folder)`` writes into a private folder of the store, sealed and moved into place (the
    entry last). Returns (path, whether it was built now). A file that does not match its entry
    (edited, truncated, replaced) is never used: it is built again and replaced; ``again``
    builds and replaces it whatever the store holds."""
    entry_path, path = _entry_paths(stem, key, suffix)
    stored = None if again else _matching(entry_path, path, key)
    if stored is not None:
        return stored, False
    with build_lock(entry_path.with_suffix(".lock")):
        stored = None if again else _matching(entry_path, path, key)  # (another process's, meanwhile)
        if stored is not None:
            return stored, False
        with tempfile.TemporaryDirectory(prefix=f"{stem}-", dir=path.parent) as tmp:
            built = build(Path(tmp))
            sha256 = seal(built)
            os.replace(built, path)  # atomic: a reader sees the old file or the whole new one
            entry = Path(tmp) / "entry.json"
            entry.write_text(json.dumps({"key": key, "file": path.name, "sha256": sha256}), encoding="utf-8")
            seal(entry)
            os.replace(entry, entry_path)  # last: the entry vouches only for a whole file
        prune(path.parent)
    return path, True


def _matching(entry_path: Path, path: Path, key: str) -> Path | None:
    """``path`` when the trusted entry names it for ``key`` and its bytes have the recorded SHA-256."""
    entry = read_record_file(entry_path)
    if entry is None or entry.get("key") != key or entry.get("file") != path.name:
        return None
    data = read_trusted(path)
    if data is None or digest(data) != entry.get("sha256"):
        return None
    os.utime(entry_path)  # used now: pruned last
    os.utime(path)
    return path


def read_record_file(path: Path) -> dict[str, Any] | None:
    """A JSON object the store holds at ``path``, or None (missing, untrusted, not an object)."""
    text = read_trusted(path)
    try:
        value = json.loads(text) if text is not None else None
    except ValueError:
        return None
    return value if isinstance(value, dict) else None


def read_record(stem: str, key: str) -> dict[str, Any] | None:
    """The record stored for ``key`` (:func:`write_record`), or None. It applies only to what
    ``key`` digests: the caller composes the key from the content hashes of every input."""
    path, _ = _entry_paths(stem, key, "")
    record = read_record_file(path)
    if record is None or record.get("key") != key:
        return None
    os.utime(path)
    return record.get("value")


def _plain(value: Any) -> Any:
    """A NumPy scalar (a verdict's bool, an error's float) as the Python value JSON writes."""
    if hasattr(value, "item"):
        return value.item()
    raise TypeError(f"{type(value).__name__} is not JSON")


def write_record(stem: str, key: str, value: Any) -> None:
    """Store ``value`` (JSON) for ``key``, replacing any record there whole (``os.replace``);
    an unwritable store only means the work is done again next time."""
    path, _ = _entry_paths(stem, key, "")
    try:
        fd, name = tempfile.mkstemp(prefix=f".{stem}-", suffix=".json", dir=path.parent)
    except OSError:
        return
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as handle:
            json.dump({"key": key, "value": value}, handle, default=_plain)
        seal(Path(name))
        os.replace(name, path)
    except OSError:
        Path(name).unlink(missing_ok=True)


def seal(path: Path) -> str:
    """Make a file this process wrote unwritable by others (whatever the umask gave), and return
    its SHA-256 for the entry that lists it."""
    os.chmod(path, stat.S_IMODE(os.stat(path).st_mode) & ~_WRITABLE_BY_OTHERS)
    data = read_trusted(path)
    if data is None:
        raise OSError(f"{path}: the file just written is not trusted")
    return digest(data)


# CasADi's serialised text spells each byte as two letters 'a'..'p' (low nibble first) and
# each class name as its 4-byte little-endian length and its characters. A kernel is an
# SXFunction (calling MXFunction folds of SX steps, see armgen.symbolic.loops); these classes
# load a library when deserialised (External and its importers, CasADi's plugins by name,
# JIT and FMU functions), so text naming one is refused before CasADi reads it.
CODE_LOADING_CASADI_CLASSES = (
    "External", "GenericExternal", "DllLibrary", "JitLibrary", "Importer", "ImporterInternal", "JitFunction",
    "FmuFunction", "Fmu", "Fmu2", "Fmu3", "Nlpsol", "Conic", "Integrator", "Rootfinder", "Interpolant",
    "Linsol", "Dple", "Expm", "BlazingSplineFunction", "CallbackInternal")
_CASADI_TEXT = re.compile(rb"(?:[a-p]{2})*")


def casadi_bytes(text: bytes) -> bytes | None:
    """The bytes CasADi's serialised ``text`` stands for, or None when it is not such text."""
    text = text.strip()
    if len(text) % 2 or not _CASADI_TEXT.fullmatch(text):
        return None
    nibbles = bytes(c - 97 for c in text)
    return bytes(lo | hi << 4 for lo, hi in zip(nibbles[::2], nibbles[1::2]))


def _class_tag(name: str) -> bytes:
    return len(name).to_bytes(4, "little") + name.encode()


def sx_function_text_loads_no_code(text: bytes) -> bool:
    """Whether serialised CasADi ``text`` holds an SXFunction and no class that loads code when
    deserialised (checked before deserialising: loading an External runs its library)."""
    raw = casadi_bytes(text)
    return (raw is not None and _class_tag("SXFunction") in raw[:64]
            and not any(_class_tag(name) in raw for name in CODE_LOADING_CASADI_CLASSES))
