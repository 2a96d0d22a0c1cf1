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
import hashlib
import os
import re
import shutil
import stat
import tempfile
import warnings
from pathlib import Path

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
