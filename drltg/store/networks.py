"""A run's networks alone, ``checkpoints/last.safetensors`` beside ``last.pt`` (``best.safetensors`` beside
``best.pt``): what reusing the run as a source reads.

A training checkpoint holds the optimiser, the replay buffer and the random state besides the networks, so
it is large (the buffer dominates) and read only to resume. Each time a checkpoint is saved, the learner's
loss state dict (actor, critics, target networks, temperature: every tensor ``load_state_dict`` restores)
is saved with it in the safetensors format: a JSON header naming each tensor's dtype, shape and byte range,
then the raw bytes. Reading it parses that header and copies bytes, so nothing in the file can run code;
the header's metadata records the checkpoint's ``frames`` and ``updates``, which tell whether the file
holds the same networks as its checkpoint (:func:`drltg.store.rundir.sync_networks`). The config that
rebuilds the networks is the run's ``config.yaml``. The file's SHA-256 is in the run's manifest, as every
file's is.
"""
from __future__ import annotations

import json
import struct
from pathlib import Path

from drltg.errors import UsageError
from drltg.regular import open_regular, read_bytes
from drltg.store import manifest

NETWORKS = {"last": Path("checkpoints") / "last.safetensors", "best": Path("checkpoints") / "best.safetensors"}
"""The networks file of each checkpoint, by the name ``transfer.source_checkpoint`` gives it."""
FORMAT = "drltg networks"
MAX_NETWORKS_BYTES = 4 * 2**30
"""Networks of drltg's learners are megabytes; a file above this is no networks file."""


def encode(loss_state: dict, frames: int, updates: int) -> bytes:
    """The safetensors bytes of a loss state dict (each tensor copied: safetensors stores no tensor twice,
    and a target network may share its parameters' storage)."""
    from safetensors.torch import save

    tensors = {name: value.detach().to("cpu", copy=True).contiguous() for name, value in loss_state.items()}
    info = json.dumps({"format": FORMAT, "frames": frames, "updates": updates}, sort_keys=True)
    return save(tensors, metadata={"drltg": info})  # one entry: safetensors writes a mapping in no fixed order


def header(data: bytes, path: Path) -> dict:
    """The metadata of a networks file (``frames``, ``updates`` as numbers); a file of another kind is one
    :class:`UsageError` sentence."""
    try:
        (size,) = struct.unpack("<Q", data[:8])
        meta = json.loads(json.loads(data[8:8 + size])["__metadata__"]["drltg"])
        if meta["format"] != FORMAT or not all(type(meta[k]) is int for k in ("frames", "updates")):
            raise ValueError
        return {"frames": meta["frames"], "updates": meta["updates"]}
    except (struct.error, ValueError, KeyError, TypeError):
        raise UsageError(f"'{path}' is not a drltg networks file (safetensors with drltg's header).") from None


def read_header(run_dir: str | Path, name: str) -> dict | None:
    """The metadata of a run's networks file ``name`` (``last``/``best``), unchecked (for a message or a
    comparison, never for the tensors); ``None`` where the file is missing or unreadable."""
    path = Path(run_dir) / NETWORKS[name]
    try:
        with open_regular(path) as f:
            start = f.read(8)
            size = struct.unpack("<Q", start)[0] if len(start) == 8 else 0
            return header(start + f.read(min(size, 2**20)), path)
    except (OSError, UsageError):
        return None


def listed(run_dir: str | Path, name: str) -> bool:
    """Whether the run's manifest names the networks file ``name`` (a run written before drltg kept one does
    not)."""
    return NETWORKS[name].as_posix() in manifest.read(run_dir)


def load(run_dir: str | Path, name: str, map_location="cpu") -> tuple[dict, dict]:
    """``(loss state dict, {"frames", "updates"})`` from the run's networks file ``name``, its bytes checked
    against the manifest's SHA-256 before they are parsed."""
    from safetensors.torch import load as parse

    path = Path(run_dir) / NETWORKS[name]
    data = read_bytes(path, MAX_NETWORKS_BYTES, "a networks file")
    accepted = manifest.read(run_dir).get(NETWORKS[name].as_posix())
    if accepted and manifest.digest(data) not in accepted:
        raise UsageError(f"cannot read '{path}': it does not match its SHA-256 in {Path(run_dir) / manifest.MANIFEST}, "
                         "so it was damaged or changed after it was written; restore it or train the run again.")
    info = header(data, path)
    try:
        state = parse(data)
    except Exception as err:  # safetensors reports a damaged body as its own error type
        raise UsageError(f"cannot read '{path}' ({type(err).__name__}); is it truncated?") from None
    return {k: v.to(map_location) for k, v in state.items()}, info
