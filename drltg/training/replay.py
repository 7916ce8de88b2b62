"""The replay buffer as a checkpoint holds it: the rows written so far, not the whole capacity.

TorchRL's ``LazyTensorStorage.state_dict`` holds every row of the allocated storage, written or not: a Lift
run's 1e6-transition buffer is 437 MB in every checkpoint, at 1k frames as at 1M. :func:`buffer_state`
keeps the ``len(buffer)`` rows written; :func:`load_buffer_state` allocates the capacity again and writes
them back, so that the resumed buffer is the saved one, row for row, cursor for cursor. A checkpoint that
holds the whole storage (any earlier one) loads as it always did.
"""
from __future__ import annotations

import torch
from tensordict import TensorDict
from torchrl.data import LazyTensorStorage, ReplayBuffer


def replay_buffer(cfg) -> ReplayBuffer:
    """A run's replay buffer: ``buffer.size`` transitions on the run's device, ``buffer.batch_size`` a sample."""
    return ReplayBuffer(storage=LazyTensorStorage(cfg.buffer.size, device=cfg.device), batch_size=cfg.buffer.batch_size)


def buffer_state(buffer: ReplayBuffer) -> dict:
    """``buffer.state_dict()`` with the storage cut to its ``len(buffer)`` written rows."""
    state = buffer.state_dict()
    written = len(buffer)
    if 0 < written < buffer.storage.max_size:
        rows = buffer.storage[:written].clone()  # a slice would save the whole storage under it
        state["_storage"] = {**state["_storage"], "_storage": rows.state_dict()}
    return state


def load_buffer_state(buffer: ReplayBuffer, state: dict) -> None:
    """Load a state from :func:`buffer_state` (or a whole ``buffer.state_dict()``) into ``buffer``,
    whose storage has not been written yet."""
    stored = state["_storage"]
    if stored["initialized"]:
        rows = TensorDict().load_state_dict(stored["_storage"], strict=False)
        if rows.shape[0] < buffer.storage.max_size:
            buffer.storage.set(torch.arange(rows.shape[0]), rows, set_cursor=False)  # allocates the capacity
            state = {**state, "_storage": {**stored, "_storage": buffer.storage.state_dict()["_storage"]}}
    buffer.load_state_dict(state)
