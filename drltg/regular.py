"""Opening a file that must be a regular one: a FIFO would block the read, a device never end it.

A file a run or a log names is opened without blocking and checked by ``fstat`` on the descriptor it
was opened as (no window between the check and the read); anything but a regular file, or one larger
than the reader's limit, is one :class:`UsageError` sentence before a byte is read. A log drltg appends
to is opened the same way, and never through a link (``O_NOFOLLOW``)."""
from __future__ import annotations

import errno
import os
import stat
from pathlib import Path
from typing import BinaryIO, TextIO

from drltg.errors import UsageError

MAX_META_BYTES = 16 * 2**20
"""A manifest, summary or config: none is near this."""
MAX_LOG_BYTES = 256 * 2**20
"""A log of evaluations (eval.csv, a CSV or event file): 10^6 rows of 40 columns are about 250 MB."""


def open_regular(path: str | Path) -> BinaryIO:
    """``path`` opened for binary reading, refused unless it is a regular file (``FileNotFoundError``
    passes through: whether a missing file is an error is the caller's to say)."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except FileNotFoundError:
        raise
    except OSError as err:  # a socket cannot be opened (ENXIO)
        raise UsageError(f"cannot read '{path}' ({err.strerror or err}); drltg reads regular files only.") from None
    if not stat.S_ISREG(os.fstat(fd).st_mode):
        os.close(fd)
        raise UsageError(f"'{path}' is not a regular file (a FIFO, a device or a socket); drltg reads regular "
                         "files only.")
    os.set_blocking(fd, True)
    return os.fdopen(fd, "rb")


def read_bytes(path: str | Path, limit: int, what: str = "a file drltg reads") -> bytes:
    """The bytes of the regular file ``path``, refused above ``limit`` bytes (``what`` it would be, in the
    sentence) before it is read."""
    with open_regular(path) as f:
        size = os.fstat(f.fileno()).st_size
        if size > limit:
            raise UsageError(f"'{path}' holds {size / 2**20:,.0f} MB, more than the {limit // 2**20} MB {what} takes; "
                             "is it one?")
        return f.read(limit + 1)


def append_regular(path: str | Path) -> TextIO:
    """``path`` opened for appending text line by line, created if missing, refused in one sentence where it
    is a link (its lines would land in the link's target) or not a regular file (a FIFO would block)."""
    try:
        fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK, 0o666)
    except OSError as err:
        why = {errno.ELOOP: "it is a link, and drltg appends to no file through one",
               errno.ENXIO: "it is a FIFO or a socket; drltg appends to regular files only"}
        raise UsageError(f"cannot append to '{path}' ({why.get(err.errno, err.strerror or err)}); move it "
                         "away.") from None
    if not stat.S_ISREG(os.fstat(fd).st_mode):
        os.close(fd)
        raise UsageError(f"'{path}' is not a regular file (a FIFO, a device or a socket); drltg appends to regular "
                         "files only, so move it away.")
    os.set_blocking(fd, True)
    return os.fdopen(fd, "a", buffering=1, encoding="utf-8")
