"""Checks of a run's config against the task and the machine, made before its first frame.

A config can be valid key by key and still fail hours later, or worse, run as something else: a
replay buffer or networks larger than the machine's memory fail on their first allocation, and a task
factory that ignores the batch size it is given trains on 1 env and evaluates 1 episode while
``config.yaml`` says ``collector.num_envs: 8`` and ``eval.episodes: 16``. Each check here is one
:class:`UsageError` sentence naming the key.
"""
from __future__ import annotations

import os
import sys
from typing import Callable

import torch
from torchrl.envs import EnvBase

from drltg.config import RunConfig
from drltg.errors import UsageError

FLOAT_BYTES = 4


def device_memory(device: str) -> int | None:
    """Bytes of memory of ``device`` (a CPU's physical memory, a GPU's own); ``None`` if unknown."""
    dev = torch.device(device)
    if dev.type == "cuda":
        return torch.cuda.get_device_properties(dev.index or 0).total_memory
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (OSError, ValueError):
        return None


def _gib(n: float) -> str:
    return f"{n / 2**30:,.1f} GiB"


def budget_warnings(cfg: RunConfig) -> list[str]:
    """Why a budget cannot learn or cannot be followed, one sentence each: every frame within the random
    warm-up (no update at all), or fewer than two evaluations after frame 0."""
    col = cfg.collector
    warm_up = col.warm_up_frames
    if cfg.frames < warm_up:
        return [f"{cfg.frames:,} frames lie within the {warm_up:,} random warm-up frames "
                "(collector.init_random_frames): the run will make no update, so it learns nothing."]
    if cfg.frames < 2 * cfg.eval.interval(cfg.frames):
        return [f"{cfg.frames:,} frames with {every_text(cfg)} give evaluations at frame 0 and "
                f"{cfg.frames:,} only: no learning curve to speak of; lower eval.every."]
    return []


def every_text(cfg: RunConfig) -> str:
    """``eval.every=5,000``, or ``eval.every=auto (1,000 frames)``: the interval as set and as it is."""
    every = cfg.eval.every
    return f"eval.every={every:,}" if every != "auto" else f"eval.every=auto ({cfg.eval.interval(cfg.frames):,} frames)"


def warn_budget(cfg: RunConfig) -> None:
    """Print :func:`budget_warnings` on stderr, before training."""
    for sentence in budget_warnings(cfg):
        print(f"warning: {sentence}", file=sys.stderr)


def check_task(cfg: RunConfig, env: EnvBase, fresh: Callable[[], EnvBase] | None = None) -> None:
    """The observation drltg's learners read, as they read it: a float32 ``observation`` (the networks'
    dtype; a float64 one fails inside the first matrix product); and, with ``fresh`` (a builder of a
    throwaway env of the task: a user's task, not one of drltg's, which the suite checks), one step."""
    obs = env.full_observation_spec.get("observation", None)
    if obs is None:
        raise UsageError(f"task '{cfg.task}' reports no 'observation' entry; drltg's learners read it.")
    if obs.dtype != torch.float32:
        raise UsageError(f"task '{cfg.task}' reports its observation as {obs.dtype}; drltg's networks take "
                         "torch.float32 (append torchrl.envs.DoubleToFloat() in the task's factory).")
    if fresh is None:
        return
    trial = fresh()  # not the probe, which methods reuse: stepping it would change what they draw
    try:
        trial.step(trial.reset().set("action", trial.full_action_spec["action"].zero()))
    except Exception as err:  # a user's env fails inside TorchRL or itself: name the task and the cause
        cause = (str(err).strip().splitlines() or [""])[0]
        raise UsageError(f"task '{cfg.task}' cannot take a step ({type(err).__name__}: {cause}); check its "
                         "_reset and _step against its specs (torchrl.envs.utils.check_env_specs).") from None
    finally:
        trial.close()


def check_network(cfg: RunConfig, env: EnvBase) -> None:
    """Refuse ``network.hidden`` widths whose weights alone exceed the device's memory.

    The lower bound counted: 3 MLPs (an actor and two critics) of ``obs -> hidden... -> action`` float32
    weights, ``3 * 4 * sum_i w_i w_{i+1}`` bytes; targets, gradients and Adam's moments come on top."""
    obs = sum(spec.shape.numel() for spec in env.observation_spec.values(True, True))
    act = env.action_spec.shape.numel()
    widths = [max(obs, 1), *cfg.network.hidden, max(act, 1)]
    need = 3 * FLOAT_BYTES * sum(a * b for a, b in zip(widths, widths[1:]))
    have = device_memory(cfg.device)
    if have is not None and need > have:
        raise UsageError(f"network.hidden={cfg.network.hidden} needs at least {_gib(need)} for its weights, "
                         f"more than the {_gib(have)} of device '{cfg.device}'; use smaller widths.")


def check_buffer(cfg: RunConfig, env: EnvBase, in_keys) -> None:
    """Refuse a ``buffer.size`` whose transitions (the keys the loss reads, from the env's specs) exceed
    the device's memory: the buffer allocates all of them at its first write."""
    fake = env.fake_tensordict().select(*in_keys, strict=False)
    per = sum(v.numel() * v.element_size() for v in fake.values(True, True))
    need = per * cfg.buffer.size
    have = device_memory(cfg.device)
    if have is not None and need > have:
        raise UsageError(f"buffer.size={cfg.buffer.size} needs {_gib(need)} ({per} bytes a transition), more "
                         f"than the {_gib(have)} of device '{cfg.device}'; use a smaller buffer.size.")


def check_batch(cfg: RunConfig, train_env: EnvBase, eval_env: EnvBase) -> None:
    """Refuse a task whose envs do not have the batch size asked for: its factory ignored
    ``batch_size``, and the run would train on fewer envs and evaluate fewer episodes than its config says."""
    for env, key, n in ((train_env, "collector.num_envs", cfg.collector.num_envs),
                        (eval_env, "eval.episodes", cfg.eval.episodes)):
        if tuple(env.batch_size) != (n,):
            raise UsageError(f"task '{cfg.task}' built an env of batch size {tuple(env.batch_size)} when asked for "
                             f"({n},) ({key}={n}); its factory must pass batch_size on to the env.")
