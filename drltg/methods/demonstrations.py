"""Learning from demonstrations: transitions of a demonstrator kept apart and sampled by every update.

As in DQfD and DDPGfD (Hester et al. 2018; Vecerik et al. 2017; Nair et al. 2018), demonstrations
live in their own buffer, never overwritten by the agent's experience, and every gradient step draws
a fixed share of its batch from them:

    batch = [ k = round(ratio * B) demonstration transitions | B - k own transitions ]

so the critic keeps seeing demonstrated successes for the whole run instead of until the replay
buffer has cycled past them. The demonstrator needs no source training, but its environment steps
are a cost: :func:`collect_demonstrations` says how many it took. Off-policy learners only: the
demonstrator's actions are not the learner's.
"""
from __future__ import annotations

import warnings

import torch
from tensordict import TensorDictBase
from torchrl.collectors import Collector
from torchrl.data import LazyTensorStorage, ReplayBuffer
from torchrl.envs import EnvBase, ExplorationType, TransformedEnv

from drltg.config import Field
from drltg.methods.registry import Transfer, TransferMethod, register_method

__all__ = ["collect_demonstrations", "demonstration_buffer", "mixed_batches"]


@torch.no_grad()
def collect_demonstrations(env: EnvBase, policy, episodes: int, *, steps_per_batch: int = 50) -> TensorDictBase:
    """Runs ``policy`` on the batched ``env`` until at least ``episodes`` episodes have ended and
    returns every transition collected, flat (``[frames]``), in the collector's layout (``"next"``
    entries included). A learned policy acts deterministically (its mode), as a demonstrator would.
    Batches of ``steps_per_batch`` steps per environment are collected until the count is reached, so a few
    transitions of unfinished episodes may follow the last ended one."""
    if episodes < 1:
        raise ValueError(f"demonstrations need at least one episode, got {episodes}.")
    n_envs = max(env.batch_size.numel(), 1)
    collector = Collector(
        env,
        policy,
        frames_per_batch=n_envs * steps_per_batch,
        total_frames=-1,
        exploration_type=ExplorationType.DETERMINISTIC,
        auto_register_policy_transforms=False,
    )
    parts, ended = [], 0
    try:
        for data in collector:
            data = data.reshape(-1)
            parts.append(data)
            ended += int(data["next", "done"].sum())
            if ended >= episodes:
                break
    finally:
        collector.shutdown(close_env=False)  # the env is the caller's
    return torch.cat(parts)


def demonstration_buffer(demonstrations: TensorDictBase, keys) -> ReplayBuffer:
    """A replay buffer holding exactly the ``keys`` of ``demonstrations`` (the loss's inputs)."""
    device = demonstrations.device or "cpu"
    buffer = ReplayBuffer(storage=LazyTensorStorage(demonstrations.numel(), device=device))
    buffer.extend(demonstrations.select(*keys))
    return buffer


def mixed_batches(own: ReplayBuffer, demonstrations: ReplayBuffer, count: int, ratio: float) -> list[TensorDictBase]:
    """``count`` batches of ``own.batch_size`` transitions, each with ``round(ratio * batch_size)``
    demonstration transitions first and the rest drawn from ``own``; one ``sample`` call per buffer."""
    size = own.batch_size
    k = round(ratio * size)
    with warnings.catch_warnings():  # sample sizes other than the buffer's batch size are intended
        warnings.filterwarnings("ignore", message="Got conflicting batch_sizes")
        demo = demonstrations.sample(k * count).split(k) if k else [None] * count
        mine = own.sample((size - k) * count).split(size - k) if k < size else [None] * count
    return [d if m is None else m if d is None else torch.cat([d, m]) for d, m in zip(demo, mine)]


def _build(cfg: dict, agent, env, *, resuming: bool) -> Transfer:
    """``transfer.demo_episodes`` episodes of the source policy on the training task, from an env
    seeded apart from the training and evaluation envs, kept in a buffer of their own; a resumed run
    collects the same episodes again."""
    from drltg.envs import make_env
    from drltg.methods.source import source_actor

    t = cfg["transfer"]
    policy = source_actor(cfg, env)
    demo_env = TransformedEnv(make_env(cfg["task"], batch_size=(cfg["collector"]["num_envs"],), device=cfg["device"],
                                       seed=cfg["seed"] + 20_000, **cfg["env"]))
    for transform in agent.env_transforms:
        demo_env.append_transform(transform.clone())
    try:
        data = collect_demonstrations(demo_env, policy, t["demo_episodes"])
    finally:
        demo_env.close()
    demos = demonstration_buffer(data, agent.loss.in_keys)
    return Transfer(batches=lambda own, n: mixed_batches(own, demos, n, t["demo_ratio"]),
                    summary={"demonstration_frames": data.numel()})


DEMONSTRATIONS = register_method(TransferMethod(
    "demonstrations",
    "episodes of the source policy in a buffer of their own, a fixed share of every batch",
    _build,
    source="policy",
    algos=("sac", "td3"),
    options={
        "demo_episodes": (10, Field(int, "demonstrations: episodes of the source policy collected", low=1)),
        "demo_ratio": (0.25, Field(float, "demonstrations: share of every batch drawn from them", low=0.0, high=1.0)),
    },
))
