"""The bench's reads of files it is given: bounded, and only of regular files.

A path a user gives (a scenario, a record, a run's summary) may be a symlink to ``/dev/zero``, a
FIFO or a multi-gigabyte file by mistake; reading it whole would exhaust memory or block forever.
Every such read goes through :func:`read_bounded`, which refuses anything but a regular file
(after following symlinks: a link to a real file is fine) and reads at most a stated number of
bytes.

Owns: bounded reads of input files. Boundaries: no parsing; callers word the error for their
file kind (:class:`FileRefused` carries the reason only).
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
