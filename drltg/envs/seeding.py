"""Per-seed random streams in one batched env: the env of a seed group.

A seed group steps N seeds' envs as one env of batch ``N * E``. Block ``k`` (flat elements ``k*E`` to
``(k+1)*E - 1``) draws its starts and noise from its own generator, seeded ``seeds[k]``, with the same
calls as an env of batch ``E`` seeded ``seeds[k]``: each block sees the random numbers of its seed's
env alone, whatever the other blocks do.
"""
from __future__ import annotations

from typing import Iterator, Sequence

import torch

from drltg.errors import UsageError

__all__ = ["block_generators", "blocks", "set_block_seeds"]


def block_generators(batch_size: torch.Size, seeds: Sequence[int]) -> list[torch.Generator]:
    """One CPU generator per seed; the flat batch must split into ``len(seeds)`` equal blocks."""
    if not seeds or batch_size.numel() % len(seeds):
        raise UsageError(f"a batch of {batch_size.numel()} envs does not split into {len(seeds)} equal seed blocks.")
    return [torch.Generator().manual_seed(int(seed)) for seed in seeds]


def blocks(env, mask: torch.Tensor) -> Iterator[tuple[torch.Tensor, torch.Generator]]:
    """``(block's part of the flat mask, block's generator)`` for each block of ``env`` (one block, the
    env's own generator, when no block seeds are set)."""
    if env.block_rngs is None:
        yield mask, env.rng
        return
    yield from zip(mask.reshape(len(env.block_rngs), -1), env.block_rngs)


def set_block_seeds(env, seeds: Sequence[int]) -> None:
    """Give ``env`` (a drltg grid or FourRooms env, possibly inside a ``TransformedEnv``) one random
    stream per seed; an env without block streams is one :class:`UsageError` sentence."""
    base = getattr(env, "base_env", env)
    if not hasattr(base, "set_block_seeds"):
        raise UsageError(f"{type(base).__name__} has no per-seed random streams; train its seeds one by one.")
    base.set_block_seeds(seeds)
