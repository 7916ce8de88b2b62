"""A run's health: non-finite losses or parameters end it as ``diverged``, a result in its own right.

A loss that becomes NaN or infinite poisons every later update: the weights turn NaN, the greedy
policy picks a fixed action and the curve looks like an ordinary bad seed. :func:`check_losses` (every
update) and :func:`check_parameters` (before every checkpoint) raise :class:`Diverged`; the run then
writes ``summary.json`` with ``status: diverged`` (it is finished: resuming would diverge again) and
exits non-zero, and the report and sweep summaries list it apart and leave it out of their metrics.
"""
from __future__ import annotations

import contextlib
import json
from pathlib import Path

import torch

from drltg.config import RunConfig
from drltg.errors import RunFailed
from drltg.store import rundir


class Diverged(RunFailed):
    """A loss or a parameter became non-finite; in a seed group, ``seeds`` holds the positions of the
    seeds that diverged (``None``: all of them)."""

    def __init__(self, message: str, seeds: tuple[int, ...] | None = None):
        super().__init__(message)
        self.seeds = seeds


def check_losses(losses: dict, frames: int, seeds: int = 1) -> None:
    """Raise :class:`Diverged` naming the first loss term that is not finite; with ``seeds`` > 1 (a seed
    group, one loss per seed), it names the seeds whose loss it is."""
    for key, value in losses.items():
        if isinstance(value, torch.Tensor) and value.is_floating_point() and not torch.isfinite(value).all():
            bad = value[~torch.isfinite(value)].flatten()[0].item()
            which = None
            if seeds > 1 and value.numel() % seeds == 0:
                per_seed = ~torch.isfinite(value.reshape(seeds, -1)).all(-1)
                which = tuple(per_seed.nonzero().flatten().tolist())
            raise Diverged(f"the run diverged: the loss term '{key}' became {bad} at frame {frames}", which)


def check_parameters(module: torch.nn.Module, frames: int) -> None:
    """Raise :class:`Diverged` naming the first parameter that holds a non-finite value."""
    for name, p in module.named_parameters():
        if not torch.isfinite(p).all():
            raise Diverged(f"the run diverged: the parameter '{name}' holds non-finite values at frame {frames}")


def check_state(state: dict, frames: int, seed: int | None = None) -> None:
    """:func:`check_parameters` on a module's ``state_dict`` (the one at position ``seed`` in a seed group)."""
    for name, value in state.items():
        if isinstance(value, torch.Tensor) and value.is_floating_point() and not torch.isfinite(value).all():
            raise Diverged(f"the run diverged: the parameter '{name}' holds non-finite values at frame {frames}",
                           None if seed is None else (seed,))


def write_diverged(run_dir: str | Path, cfg: RunConfig, err: Diverged) -> None:
    """``summary.json`` of a diverged run: its status and why; the run is finished, not resumable."""
    summary = {"status": rundir.DIVERGED, "reason": str(err), "task": cfg.task, "algo": cfg.algo,
               "seed": cfg.seed}
    rundir.atomic_write(Path(run_dir) / rundir.SUMMARY, json.dumps(summary, indent=2) + "\n")
    rundir.finalize_manifest(run_dir)


@contextlib.contextmanager
def on_divergence(run_dir: str | Path, cfg: RunConfig):
    """Write the diverged summary when the block raises :class:`Diverged` (which goes on up)."""
    try:
        yield
    except Diverged as err:
        write_diverged(run_dir, cfg, err)
        raise
