"""A run's networks alone, ``checkpoints/last.safetensors`` beside ``last.pt`` (``best.safetensors``: those of
the best evaluation, :mod:`drltg.training.best`): what reusing the run as a source reads.

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
import re
import struct
from itertools import accumulate
from pathlib import Path

from drltg.errors import UsageError
from drltg.regular import read_bytes
from drltg.store import manifest

NETWORKS = {"last": Path("checkpoints") / "last.safetensors", "best": Path("checkpoints") / "best.safetensors"}
"""The networks file of each checkpoint, by the name ``transfer.source_checkpoint`` gives it."""
FORMAT = "drltg networks"
MAX_NETWORKS_BYTES = 4 * 2**30
"""Networks of drltg's learners are megabytes; a file above this is no networks file."""
MAX_HEADER_BYTES = 16 * 2**20
"""A header names each tensor in about 100 bytes: one above this is no networks file's."""
MAX_DEPTH = 8
"""A safetensors header nests three deep (the header, a tensor's entry, its shape): parsing a deeper one
would only spend the stack."""
_STRING = re.compile(r'"(?:[^"\\]|\\.)*"', re.DOTALL)
_DEPTH = {"[": 1, "{": 1, "]": -1, "}": -1}


def encode(loss_state: dict, frames: int, updates: int) -> bytes:
    """The safetensors bytes of a loss state dict (each tensor copied: safetensors stores no tensor twice,
    and a target network may share its parameters' storage)."""
    from safetensors.torch import save

    tensors = {name: value.detach().to("cpu", copy=True).contiguous() for name, value in loss_state.items()}
    info = json.dumps({"format": FORMAT, "frames": frames, "updates": updates}, sort_keys=True)
    return save(tensors, metadata={"drltg": info})  # one entry: safetensors writes a mapping in no fixed order


def _shallow_json(text: str):
    """``json.loads(text)``, refused (``ValueError``) when it nests deeper than :data:`MAX_DEPTH`: the depth is
    counted over the brackets outside strings, without recursion, before the parser sees the text."""
    brackets = re.sub(r"[^\[\]{}]", "", _STRING.sub("", text))
    if brackets and max(accumulate(_DEPTH[c] for c in brackets)) > MAX_DEPTH:
        raise ValueError("nested too deep")
    return json.loads(text)


def header(data: bytes, path: Path, most_frames: int | None = None) -> dict:
    """The metadata of a networks file (``frames`` from 0 to ``most_frames``, the run's budget where it is known,
    ``updates`` from 0), read from a
    header of at most :data:`MAX_HEADER_BYTES` nested at most :data:`MAX_DEPTH` deep; a file of another kind is
    one :class:`UsageError` sentence."""
    not_ours = f"'{path}' is not a drltg networks file (safetensors with drltg's header)"
    if len(data) < 8:
        raise UsageError(f"{not_ours}: it is {len(data)} bytes long, too short for the header's length.")
    (size,) = struct.unpack("<Q", data[:8])
    if size > min(MAX_HEADER_BYTES, len(data) - 8):
        raise UsageError(f"{not_ours}: its header would be {size:,} bytes, more than the file holds or the "
                         f"{MAX_HEADER_BYTES // 2**20} MB a networks header may take.")
    try:
        entries = _shallow_json(data[8:8 + size].decode("utf-8"))
        meta = _shallow_json(entries["__metadata__"]["drltg"])
        if not isinstance(meta, dict) or meta.get("format") != FORMAT:
            raise ValueError("another format")
        counts = {k: meta[k] for k in ("frames", "updates")}
    except (ValueError, KeyError, TypeError, UnicodeDecodeError):
        raise UsageError(f"{not_ours}.") from None
    for name, value in counts.items():
        most = most_frames if name == "frames" else None
        if type(value) is not int or value < 0 or (most is not None and value > most):
            bound = f"0 to the run's budget of {most}" if most is not None else "0 or more"
            raise UsageError(f"'{path}' gives its {name} as {value!r}, not a whole number from {bound}; it holds "
                             "no checkpoint of this run.")
    return counts


def _refusal(run_dir: str | Path, name: str, data: bytes) -> str | None:
    """Why the bytes of networks file ``name`` are not to be read, in one sentence; ``None`` where the run's
    manifest lists the file with their SHA-256, or the run has no manifest (one written before drltg kept
    one is read as it is, as every file of it is)."""
    run, rel = Path(run_dir), NETWORKS[name].as_posix()
    files = manifest.read(run)
    if not (run / manifest.MANIFEST).is_file():
        return None
    if rel not in files:
        return (f"cannot read '{run / rel}': {run / manifest.MANIFEST} does not list it, so nothing says it holds "
                "the run's networks; resume the run to write it again, or train the run again.")
    if manifest.digest(data) not in files[rel]:
        return (f"cannot read '{run / rel}': it does not match its SHA-256 in {run / manifest.MANIFEST}, so it was "
                "damaged or changed after it was written; restore it or train the run again.")
    return None


def read_header(run_dir: str | Path, name: str) -> dict | None:
    """The metadata of a run's networks file ``name`` (``last``/``best``), for a comparison with its
    checkpoint; ``None`` where the file is missing, unreadable, not the one the manifest lists, or no
    networks file (each of which the caller answers by writing it again)."""
    path = Path(run_dir) / NETWORKS[name]
    try:
        data = read_bytes(path, MAX_NETWORKS_BYTES, "a networks file")
        return None if _refusal(run_dir, name, data) else header(data, path)
    except (OSError, UsageError):
        return None


def listed(run_dir: str | Path, name: str) -> bool:
    """Whether the run's manifest names the networks file ``name`` (a run written before drltg kept one does
    not)."""
    return NETWORKS[name].as_posix() in manifest.read(run_dir)


def load(run_dir: str | Path, name: str, map_location="cpu", most_frames: int | None = None) -> tuple[dict, dict]:
    """``(loss state dict, {"frames", "updates"})`` from the run's networks file ``name``: read only where the
    manifest lists it, its bytes checked against the manifest's SHA-256 before any is parsed, its header
    bounded (:func:`header`, ``frames`` at most ``most_frames``) and every floating tensor finite, so weights
    that would act as NaN are refused here rather than evaluated."""
    import torch
    from safetensors.torch import load as parse

    path = Path(run_dir) / NETWORKS[name]
    data = read_bytes(path, MAX_NETWORKS_BYTES, "a networks file")
    refusal = _refusal(run_dir, name, data)
    if refusal:
        raise UsageError(refusal)
    info = header(data, path, most_frames)
    try:
        state = parse(data)
    except Exception as err:  # safetensors reports a damaged body as its own error type
        raise UsageError(f"cannot read '{path}' ({type(err).__name__}); is it truncated?") from None
    for key, value in state.items():
        if (value.is_floating_point() or value.is_complex()) and not bool(torch.isfinite(value).all()):
            raise UsageError(f"'{path}' holds NaN or infinite values in {key}; no trained network holds them, so "
                             "it is not read.")
    return {k: v.to(map_location) for k, v in state.items()}, info


def mismatch(expected: dict, saved: dict) -> str | None:
    """How ``saved`` differs from ``expected``, the state dict it is loaded into, in words (``None``: it holds
    exactly its entries, each in its shape and dtype). ``load_state_dict`` would crash on an entry too many or
    of another shape, and cast one of another dtype (an int64 weight, a bool one) without a word."""
    missing, extra = sorted(set(expected) - set(saved)), sorted(set(saved) - set(expected))
    if missing or extra:
        return " and ".join([f"it lacks {_some(missing)}"] * bool(missing) + [f"it holds {_some(extra)} besides"] *
                            bool(extra))
    for key, value in expected.items():
        shape, dtype = tuple(getattr(value, "shape", ())), getattr(value, "dtype", None)
        theirs = tuple(getattr(saved[key], "shape", ())), getattr(saved[key], "dtype", None)
        if theirs != (shape, dtype):
            return f"{key} is {_kind(*theirs)} there, {_kind(shape, dtype)} here"
    return None


def _some(keys: list[str]) -> str:
    return ", ".join(keys[:3]) + (f" and {len(keys) - 3} more" if len(keys) > 3 else "")


def _kind(shape: tuple, dtype) -> str:
    return f"{str(dtype).removeprefix('torch.')} {list(shape)}"
