"""The bench's file access at its edge: bounded reads of the files it is given, and writes that
never follow a symlink.

A path a user gives (a scenario, a record, a run's summary) may be a symlink to ``/dev/zero``, a
FIFO or a multi-gigabyte file by mistake; reading it whole would exhaust memory or block forever.
Every such read goes through :func:`read_bounded`, which refuses anything but a regular file
(after following symlinks: a link to a real file is fine) and reads at most a stated number of
bytes.

Owns: bounded reads of input files and link-safe writes of the bench's own files. Boundaries: no
parsing or formats; callers word the error for their file kind (:class:`FileRefused` carries the
reason only).
"""
from __future__ import annotations

import os
import stat
from pathlib import Path

#: Bytes read at most from a file of each kind (each is a few kB in practice).
SCENARIO_BYTES = 1_000_000
SUMMARY_BYTES = 50_000_000
RECORD_BYTES = 200_000_000


class FileRefused(ValueError):
    """A file was not read: not a regular file, or larger than the limit (the message says which)."""


def _kind(mode: int) -> str:
    for test, name in ((stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
                       (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
                       (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return name
    return "not a regular file"


def read_bounded(path, max_bytes: int) -> bytes:
    """The bytes of the regular file ``path`` (symlinks followed), at most ``max_bytes`` of them.

    Raises :class:`FileRefused` for a device, FIFO, socket or folder (checked before opening, so a
    FIFO never blocks) and for a file over the limit (checked on its size and again on what is
    read, for a file that grows); ``FileNotFoundError`` and other ``OSError`` pass through."""
    info = os.stat(Path(path))
    if not stat.S_ISREG(info.st_mode):
        raise FileRefused(f"is {_kind(info.st_mode)}, not a regular file")
    if info.st_size > max_bytes:
        raise FileRefused(f"is {info.st_size:,} bytes, over the {max_bytes:,} bytes such a file may have")
    with open(path, "rb") as fh:
        data = fh.read(max_bytes + 1)
    if len(data) > max_bytes:
        raise FileRefused(f"grew past the {max_bytes:,} bytes such a file may have while it was read")
    return data


def read_text_bounded(path, max_bytes: int) -> str:
    """:func:`read_bounded` decoded as UTF-8 (a byte-order mark dropped); ``UnicodeDecodeError``
    passes through."""
    return read_bounded(path, max_bytes).decode("utf-8-sig")


# -- writes -------------------------------------------------------------------------------------
# A run folder may be one the user gave (--out) with something planted in it: a symlink named
# like a file the bench writes would send the write to its target. The bench writes only files
# it creates: a symlink in the way is removed (its target is never touched) and files are opened
# with O_NOFOLLOW, so a link planted between the two raises instead of being followed.
_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)


def clear_link(path) -> Path:
    """``path``, with a symlink at it removed (never its target), ready for a writer that opens
    files itself (matplotlib, pyarrow, rerun)."""
    path = Path(path)
    if path.is_symlink():
        path.unlink()
    return path


def open_new(path, mode: str = "w", **kwargs):
    """``open(path, mode)`` for writing a file of the bench's own: a symlink at ``path`` is
    removed first and the file is opened without following links; ``kwargs`` as for ``open``."""
    path = clear_link(path)
    flags = os.O_WRONLY | os.O_CREAT | _NOFOLLOW | (os.O_APPEND if "a" in mode else os.O_TRUNC)
    fd = os.open(path, flags, 0o644)
    try:
        return os.fdopen(fd, mode, **kwargs)
    except BaseException:
        os.close(fd)
        raise


def write_atomic(path, data: str | bytes, encoding: str = "utf-8") -> Path:
    """Write ``data`` to ``path`` through a temporary file renamed over it: a crash never leaves
    half a file, and neither a link at ``path`` nor one at the temporary name is followed (the
    rename replaces a link itself)."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    binary = isinstance(data, bytes)
    with open_new(tmp, "wb" if binary else "w", **({} if binary else {"encoding": encoding})) as fh:
        fh.write(data)
    os.replace(tmp, path)
    return path


def create_new(path, data: str | bytes, encoding: str = "utf-8") -> Path:
    """Write a file that must not exist yet: ``FileExistsError`` when anything is at ``path``, a
    dangling symlink included (``Path.exists`` is False for one, and a write would create its
    target wherever it points)."""
    path = Path(path)
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | _NOFOLLOW, 0o644)
    with os.fdopen(fd, "wb") as fh:
        fh.write(data if isinstance(data, bytes) else data.encode(encoding))
    return path
