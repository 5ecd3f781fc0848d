"""Reading a file a user named without ever blocking on it.

Opening a FIFO for reading waits for a writer, and reading a device such as /dev/zero
never ends: :func:`read_regular_file` opens without blocking (``O_NONBLOCK``), asks the
open file what it is, and reads only a regular file. Every reader of a file that a user
names or that an earlier run left (scene and study files, a run's series, run.json,
golden references) goes through it, so the rule is written once.
"""

from __future__ import annotations

import errno
import os
import stat

__all__ = ["NotRegularFileError", "open_regular", "read_regular_file", "read_regular_text"]


class NotRegularFileError(OSError):
    """The path is a device, a pipe or a socket, not a file that can be read whole."""

    def __init__(self, path):
        super().__init__(errno.EINVAL, "not a regular file (a device, a pipe or a socket)",
                         os.fspath(path))


def open_regular(path):
    """``path`` opened for reading in binary, once it is known to be a regular file.
    Raises ``FileNotFoundError``, ``IsADirectoryError``, :class:`NotRegularFileError` or
    another ``OSError``; never blocks on a FIFO or a device."""
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
    fd = os.open(path, flags)
    try:
        mode = os.fstat(fd).st_mode
        if stat.S_ISDIR(mode):
            raise IsADirectoryError(errno.EISDIR, "is a folder", os.fspath(path))
        if not stat.S_ISREG(mode):
            raise NotRegularFileError(path)
        return os.fdopen(fd, "rb", closefd=True)
    except BaseException:
        os.close(fd)
        raise


def read_regular_file(path, max_bytes: int | None = None) -> bytes:
    """The bytes of ``path`` (at most ``max_bytes``, where given): :func:`open_regular`."""
    with open_regular(path) as f:
        return f.read() if max_bytes is None else f.read(max_bytes)


def read_regular_text(path, encoding: str = "utf-8") -> str:
    """:func:`read_regular_file` decoded; a decoding error is a ``UnicodeDecodeError``."""
    return read_regular_file(path).decode(encoding)
