"""Files written whole or not at all: a temporary file (or folder) beside the target, then a rename.

A reader never sees half a file, a failed write leaves the previous version, and an ``OSError`` (a full disk,
a read-only folder) is one :class:`~drltg.errors.UsageError` sentence. Outputs are regular files: a device,
a FIFO or a socket in the way is refused (:func:`refuse_special`)."""
from __future__ import annotations

import contextlib
import glob
import os
import tempfile
from pathlib import Path
from typing import Iterator

from drltg.errors import UsageError


def _umask() -> int:
    """The process's umask, read without changing it where the system allows (other threads may be
    creating files)."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except OSError:
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_path(path: str | Path) -> Iterator[str]:
    """Yield a temporary path beside ``path``; once the block has written it, rename it to ``path``.

    The file gets the mode the umask gives any new file (``mkstemp`` makes it 0600). On any failure
    the temporary file is removed and ``path`` is left as it was; an ``OSError`` (a full disk, a
    read-only folder) becomes one :class:`UsageError` sentence.
    """
    path = Path(path)
    refuse_special(path, "output")
    tmp = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
        os.close(fd)
        yield tmp
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException as err:
        if tmp is not None:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(tmp)
        if isinstance(err, OSError):
            raise UsageError(f"cannot write '{path}' ({err.strerror or err}).") from None
        raise


def refuse_special(path: str | Path, option: str) -> None:
    """Refuse an output path that exists as something other than a regular file or folder (a device, a
    FIFO, a socket): drltg writes regular files only, and a rename would replace the special file."""
    import stat

    try:
        mode = os.stat(path).st_mode
    except (FileNotFoundError, NotADirectoryError):
        return
    except OSError as err:
        raise UsageError(f"{option} '{path}' cannot be read ({err.strerror or err}).") from None
    if not (stat.S_ISREG(mode) or stat.S_ISDIR(mode)):
        kind = "a FIFO" if stat.S_ISFIFO(mode) else "a socket" if stat.S_ISSOCK(mode) else "a device"
        raise UsageError(f"{option} '{path}' is {kind}; drltg writes only regular files and folders, so choose "
                         "another path.")


def atomic_write(path: str | Path, data: str | bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file and a rename: readers never see half a file."""
    data = data.encode() if isinstance(data, str) else data
    with atomic_path(path) as tmp:
        fd = os.open(tmp, os.O_WRONLY)
        try:
            view = memoryview(data)
            while view:
                view = view[os.write(fd, view):]
            os.fsync(fd)
        finally:
            os.close(fd)


def write_files(directory: str | Path, files: dict[str, bytes | str]) -> None:
    """Create ``directory`` and write every file atomically."""
    for name, data in files.items():
        atomic_write(Path(directory) / name, data)


def _exchange(a: Path, b: Path) -> bool:
    """Swap two paths in one step (Linux ``renameat2(RENAME_EXCHANGE)``); False where the system cannot."""
    import ctypes
    import errno

    try:
        renameat2 = ctypes.CDLL(None, use_errno=True).renameat2
    except (OSError, AttributeError):
        return False
    at_fdcwd, rename_exchange = -100, 2
    if renameat2(at_fdcwd, os.fsencode(a), at_fdcwd, os.fsencode(b), rename_exchange) == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.ENOSYS, errno.EINVAL, errno.ENOTSUP):
        return False
    raise OSError(err, os.strerror(err), str(b))


def _recover(directory: Path) -> None:
    """Undo what a killed :func:`write_directory` left: its previous version put aside (``.NAME.*.old``)
    while ``directory`` is missing is put back; its unfinished temporary folders are removed."""
    import shutil

    if not directory.parent.is_dir():
        return
    left = sorted(directory.parent.glob(f".{glob.escape(directory.name)}.*.old"), key=lambda p: p.stat().st_mtime)
    if left and not directory.exists():
        os.rename(left.pop(), directory)
    for stale in [*left, *directory.parent.glob(f".{glob.escape(directory.name)}.*.tmp")]:
        if stale.is_dir() and not stale.is_symlink():
            shutil.rmtree(stale, ignore_errors=True)


def write_directory(directory: str | Path, files: dict[str, bytes | str]) -> None:
    """Make ``directory`` hold ``files``, all of them or, on any failure, its previous content whole.

    The files are written into a temporary sibling folder that is then swapped with ``directory`` in one
    step where the system can (Linux), else renamed over it after the old one is put aside; a kill between
    those two renames leaves the old version beside, which the next write puts back first. A folder that
    holds other files than these (a user's own folder given as ``--out``) is never replaced: its files are
    then written one by one, each atomically."""
    import shutil

    directory = Path(directory)
    _recover(directory)
    if directory.is_dir() and any(p.name not in files for p in directory.iterdir()):
        write_files(directory, files)
        return
    tmp = None
    try:
        directory.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(dir=directory.parent, prefix=f".{directory.name}.", suffix=".tmp"))
        try:
            write_files(tmp, files)
        except UsageError as err:  # name the folder the user gave, not the temporary one
            raise UsageError(str(err).replace(str(tmp), str(directory))) from None
        os.chmod(tmp, 0o777 & ~_umask())
        if directory.exists() and _exchange(tmp, directory):
            shutil.rmtree(tmp, ignore_errors=True)  # it holds the previous version now
        elif directory.exists():
            old = tmp.with_suffix(".old")
            os.rename(directory, old)
            os.rename(tmp, directory)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.rename(tmp, directory)
    except BaseException as err:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
        if isinstance(err, OSError):
            raise UsageError(f"cannot write '{directory}' ({err.strerror or err}).") from None
        raise
