"""Write files so that a reader never sees a half-written one.

Every writer here writes to a temporary name in the target's own folder
(``.<name>.tmp-<pid>``), flushes and fsyncs it, and only then renames it over the
target with ``os.replace``. A rename within one folder is atomic, so after a crash the
target is either the complete old file, the complete new file, or absent; a leftover
temporary file starts with a dot and ends in ``.tmp-<pid>``, so it never looks like output.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, TypeVar

__all__ = [
    "TEMP_MARKER",
    "sync_to_disk",
    "atomic_open",
    "atomic_path",
    "atomic_write_bytes",
    "atomic_write_text",
    "is_temporary_name",
    "temporary_path",
]

TEMP_MARKER = ".tmp-"

StrPath = TypeVar("StrPath", str, os.PathLike)


def temporary_path(path: str | os.PathLike) -> Path:
    """The temporary name used while ``path`` is being written (same folder, hidden)."""
    return Path(_temporary_name(os.fspath(path)))


def _temporary_name(path: str) -> str:
    folder, name = os.path.split(path)
    return os.path.join(folder, f".{name}{TEMP_MARKER}{os.getpid()}")


def is_temporary_name(name: str) -> bool:
    """True for names made by :func:`temporary_path` (by any process)."""
    if not name.startswith("."):
        return False
    _, sep, pid = name.rpartition(TEMP_MARKER)
    return bool(sep) and pid.isdigit()


def _fsync_file(path: StrPath) -> None:
    fd = os.open(path, os.O_RDWR)  # Windows refuses fsync on a read-only handle
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _fsync_folder(folder: StrPath) -> None:
    # Makes the rename itself durable; folders cannot be opened this way on Windows.
    if os.name != "posix":
        return
    fd = os.open(folder, os.O_RDONLY)
    try:
        os.fsync(fd)
    except OSError:
        pass  # some file systems refuse fsync on a folder; the data itself is synced
    finally:
        os.close(fd)


# more files than this are forced to disk by one syncfs of their file system
SYNCFS_ABOVE = 8


def sync_to_disk(paths) -> None:
    """Force files written without ``fsync`` (and their folders' renames) to disk.

    Many files (a run's frames since its last checkpoint) go by one ``syncfs`` of each
    file system they are on, where the system has it (Linux): an fsync costs 0.1–5 ms
    each, which for a frame per step was a tenth of a small scene's run; a few go by
    one fsync each (``syncfs`` also waits for whatever else is unwritten there). Paths
    stay strings: a ``Path`` and its parent for each of a run's 200 frames took a
    millisecond."""
    paths = [os.fspath(path) for path in paths]
    if len(paths) > SYNCFS_ABOVE and _syncfs({os.path.dirname(p) or "." for p in paths}):
        return
    folders = set()
    for path in paths:
        if os.path.isfile(path):
            _fsync_file(path)
            folders.add(os.path.dirname(path) or ".")
    for folder in folders:
        _fsync_folder(folder)


def _syncfs(folders) -> bool:
    """``syncfs`` the file system of each folder; False where that cannot be done."""
    if not sys.platform.startswith("linux"):
        return False
    import ctypes

    try:
        syncfs = ctypes.CDLL(None, use_errno=True).syncfs
    except (OSError, AttributeError):
        return False
    done = set()
    for folder in folders:
        try:
            fd = os.open(folder, os.O_RDONLY)
        except OSError:
            return False
        try:
            device = os.fstat(fd).st_dev
            if device not in done:
                if syncfs(fd) != 0:
                    return False
                done.add(device)
        finally:
            os.close(fd)
    return True


def _discard(tmp: Path) -> None:
    try:
        tmp.unlink()
    except FileNotFoundError:
        pass


@contextmanager
def atomic_path(path: str | os.PathLike, *, fsync: bool = True) -> Iterator[Path]:
    """Yield a temporary path for a writer that wants a file name (e.g. a library's
    ``write(filename, ...)``); on success it becomes ``path``.

    If the body raises, the temporary file is removed, ``path`` keeps its old content
    (or stays absent) and the exception propagates.
    """
    path = Path(path)
    tmp = temporary_path(path)
    try:
        yield tmp
        if not tmp.exists():
            raise FileNotFoundError(f"the writer did not create {tmp}")
        if fsync:
            _fsync_file(tmp)
        os.replace(tmp, path)
    except BaseException:
        _discard(tmp)
        raise
    if fsync:
        _fsync_folder(path.parent)


@contextmanager
def atomic_open(
    path: str | os.PathLike,
    mode: str = "w",
    *,
    encoding: str | None = None,
    newline: str | None = None,
    fsync: bool = True,
) -> Iterator[IO]:
    """Like ``open(path, mode)`` for writing, but ``path`` appears only when the block
    finishes without an exception. ``mode`` is ``"w"`` or ``"wb"``."""
    if mode not in ("w", "wb"):
        raise ValueError(f"atomic_open supports modes 'w' and 'wb', not {mode!r}")
    if mode == "w" and encoding is None:
        encoding = "utf-8"
    with atomic_path(path, fsync=False) as tmp:
        with open(tmp, mode, encoding=encoding, newline=newline) as f:
            yield f
            f.flush()
            if fsync:
                os.fsync(f.fileno())
    if fsync:
        _fsync_folder(Path(path).parent)


def atomic_write_bytes(path: StrPath, data: bytes, *, fsync: bool = True) -> StrPath:
    """Replace ``path`` with ``data`` atomically; returns ``path`` (the object given). A
    run writes a frame a step with this, so it keeps to strings and plain system calls:
    ``atomic_open``'s file object, ``atomic_path``'s context manager and the parsing of
    paths were half of a small frame's cost."""
    name = os.fspath(path)
    tmp = _temporary_name(name)
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | getattr(os, "O_BINARY", 0),
                     0o666)
        try:
            view = memoryview(data)
            while view:  # a write may take only part of it
                view = view[os.write(fd, view):]
            if fsync:
                os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, name)
    except BaseException:
        _discard(Path(tmp))
        raise
    if fsync:
        _fsync_folder(os.path.dirname(name) or ".")
    return path


def atomic_write_text(
    path: str | os.PathLike, text: str, *, encoding: str = "utf-8", fsync: bool = True
) -> Path:
    """Replace ``path`` with ``text`` atomically; returns ``path``. Newlines are written
    as ``\\n`` on every platform so output files compare equal across machines."""
    with atomic_open(path, "w", encoding=encoding, newline="\n", fsync=fsync) as f:
        f.write(text)
    return Path(path)
