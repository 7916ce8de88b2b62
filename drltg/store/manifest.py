"""Checksums of a run's files in ``manifest.json``: a changed or damaged file is refused, not read.

Atomic writes protect against a file half written, not against one altered afterwards: a flipped bit
in ``checkpoints/last.pt`` still loads and resumes, a hand-edited ``eval.csv`` still reports. Each
tracked file's SHA-256 is recorded in ``manifest.json``. While a run replaces a file the manifest
accepts both the old and the new digest (written before the rename, narrowed after it), so a kill at
any moment leaves a file the manifest accepts; when the run ends, the manifest is written last and
covers every file of the run, its logs included. A run without a manifest (written before drltg
kept one) is read as it is. The writing is :func:`drltg.store.rundir.write_tracked` and
:func:`~drltg.store.rundir.finalize_manifest`; this module only reads and checks.
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

from drltg.errors import UsageError
from drltg.regular import MAX_META_BYTES, open_regular, read_bytes

MANIFEST = "manifest.json"


def digest(path_or_bytes: Path | bytes) -> str:
    h = hashlib.sha256()
    if isinstance(path_or_bytes, (bytes, bytearray, memoryview)):
        h.update(path_or_bytes)
    else:
        with open_regular(path_or_bytes) as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
    return h.hexdigest()


def read(run_dir: str | Path) -> dict[str, list[str]]:
    """``{relative path: [accepted digests]}``; empty without a manifest."""
    path = Path(run_dir) / MANIFEST
    try:
        data = json.loads(read_bytes(path, MAX_META_BYTES, "a manifest"))
    except FileNotFoundError:
        return {}
    except (OSError, ValueError):
        raise UsageError(f"'{path}' is not readable JSON; restore it or delete it to read the run unchecked.") from None
    files = data.get("sha256") if isinstance(data, dict) else None
    if not isinstance(files, dict):
        raise UsageError(f"'{path}' holds no 'sha256' mapping; restore it or delete it to read the run unchecked.")
    for name, digests in files.items():
        if not isinstance(digests, list) or not all(isinstance(d, str) for d in digests):
            raise UsageError(f"'{path}' gives '{name}' digests {digests!r}, not a list of SHA-256 strings; restore it "
                             "or delete it to read the run unchecked.")
    return files


def dumps(files: dict[str, list[str]]) -> str:
    """The manifest's text for ``{relative path: [accepted digests]}`` (written by :mod:`drltg.store.rundir`)."""
    return json.dumps({"sha256": files}, indent=1, sort_keys=True) + "\n"


def verify(run_dir: str | Path, name: str) -> None:
    """Refuse ``run_dir/name`` if the manifest lists it with other digests, or it is no regular file (a file
    it lacks is not checked)."""
    accepted = read(run_dir).get(name)
    path = Path(run_dir) / name
    if accepted and path.exists() and digest(path) not in accepted:
        raise UsageError(f"cannot read '{path}': it does not match its SHA-256 in {Path(run_dir) / MANIFEST}, so it "
                         "was damaged or changed after it was written; restore it or train the run again.")
