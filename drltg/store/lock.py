"""The owner lock of a run, experiment or sweep folder: ``.drltg.lock``, created with ``O_CREAT | O_EXCL``,
holding the owner's pid, host and start time; a lock whose owner no longer runs on this host is taken over."""
from __future__ import annotations

import contextlib
import os
import socket
import time
import uuid
from pathlib import Path
from typing import Iterator

from drltg.errors import UsageError

LOCK = ".drltg.lock"


def _stat(pid: int) -> list[str]:
    """The fields of ``/proc/<pid>/stat`` after the command name (state first); empty if unknown."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()
    except (OSError, IndexError):
        return []


def _started(pid: int) -> str | None:
    """When process ``pid`` started (clock ticks since boot); ``None`` if unknown."""
    fields = _stat(pid)
    return fields[19] if len(fields) > 19 else None


def _alive(pid: int, host: str, started: str | None = None) -> bool:
    """Whether the lock's owner still runs: its pid exists and, where the lock records it, started when
    the owner did (a pid reused by an unrelated process after a crash does not hold the lock)."""
    if host != socket.gethostname():
        return True  # cannot tell from here
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        pass
    if _stat(pid)[:1] == ["Z"]:  # exited, not yet reaped (an orphan's zombie where nothing reaps)
        return False
    return started is None or _started(pid) in (None, started)


def _holder(path: Path) -> tuple[str, int, str, str | None] | None:
    """(text, pid, host, start time) of the lock file, ``None`` if it is gone; pid 0 while it is being written."""
    try:
        text = path.read_text()
    except FileNotFoundError:
        return None
    except (IsADirectoryError, UnicodeDecodeError):
        raise UsageError(f"'{path}' is not drltg's lock file (a folder, or not text); remove it if no drltg process "
                         f"is writing '{path.parent}'.") from None
    parts = text.split()
    try:
        return text, int(parts[0]), parts[1], parts[3] if len(parts) > 3 else None
    except (IndexError, ValueError):
        return text, 0, "", None


def _break_stale(path: Path, seen: str) -> None:
    """Remove a dead owner's lock, unless another process replaced it in the meantime."""
    grave = path.with_name(f"{path.name}.{os.getpid()}.{uuid.uuid4().hex}.stale")
    try:
        os.rename(path, grave)
    except FileNotFoundError:
        return
    if grave.read_text() != seen:  # a live lock, taken over by another process: put it back
        with contextlib.suppress(FileExistsError):
            os.link(grave, path)
    os.unlink(grave)


def _acquire(directory: Path, what: str) -> str:
    path = directory / LOCK
    token = f"{os.getpid()} {socket.gethostname()} {uuid.uuid4().hex} {_started(os.getpid()) or '-'}\n"
    for _ in range(10):
        try:
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        except FileExistsError:
            held = _holder(path)
            if held is None:
                continue
            text, pid, host, started = held
            if pid == 0:  # written right now, or left empty by a crash
                with contextlib.suppress(FileNotFoundError):
                    if time.time() - path.stat().st_mtime > 10:
                        _break_stale(path, text)
                time.sleep(0.05)
                continue
            if _alive(pid, host, None if started == "-" else started):
                raise UsageError(
                    f"{what} '{directory}' is in use by process {pid} on {host}; wait for it to end, or "
                    f"delete '{path}' if that process is gone."
                ) from None
            _break_stale(path, text)
            continue
        except OSError as err:
            raise UsageError(f"cannot write to {what} '{directory}' ({err.strerror}).") from None
        with os.fdopen(fd, "w") as f:
            f.write(token)
        return token
    raise UsageError(f"cannot take the lock of {what} '{directory}'; another process keeps changing '{path}'.")


@contextlib.contextmanager
def lock(directory: str | Path, what: str = "run directory") -> Iterator[None]:
    """Own ``directory`` (it must exist) while the block runs; a second owner is refused in one sentence.

    The lock file is created with ``O_CREAT | O_EXCL``, so of two processes exactly one gets it; it
    holds the owner's pid and host and is removed on exit. A lock left by a process that no longer
    runs on this host is taken over.
    """
    directory = Path(directory)
    token = _acquire(directory, what)
    try:
        yield
    finally:
        path = directory / LOCK
        held = _holder(path)
        if held is not None and held[0] == token:
            with contextlib.suppress(FileNotFoundError):
                path.unlink()
