"""Learning from demonstrations: transitions of a demonstrator kept apart and sampled by every update.

As in DQfD and DDPGfD (Hester et al. 2018; Vecerik et al. 2017; Nair et al. 2018), demonstrations
live in their own buffer, never overwritten by the agent's experience, and every gradient step draws
a fixed share of its batch from them:

    batch = [ k = round(ratio * B) demonstration transitions | B - k own transitions ]

so the critic keeps seeing demonstrated successes for the whole run instead of until the replay
buffer has cycled past them. On top, the actor is pulled towards the demonstrated actions by a
behaviour-cloning term (Nair et al. 2018, :func:`drltg.losses.behaviour_cloning`), optionally only where the critic
rates them higher than its own (their Q filter). The filter is off by default: on Lift's sparse reward
the young critic overrates the actor's own actions, the filter kept 1% of the demonstrations by 17k
frames and the policy, which had started to lift the cube, forgot it (seed 0: success 0.2 at 7.5k
frames, 0.1 at 30k; without the filter and with weight 10, 0.8 at 17.5k, but 0.0 at 30k). With 10
episodes the cloned policy has seen 10 cube positions and its success swings (0.1 to 0.8 from 15k
frames on, 3 seeds); with 50 (the default) every seed reached 0.8 by 17.5k frames, mostly 0.9-1.0
after, though two of three ended lower (0.4, 0.7). The demonstrator needs no source training, but its
environment steps are a cost (50 Lift episodes: 25k frames): :func:`collect_demonstrations` says how
many it took. Off-policy learners only: the demonstrator's actions are not the learner's.
"""
from __future__ import annotations

import warnings

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModule, TensorDictSequential
from torchrl.collectors import Collector
from torchrl.data import Bounded, LazyTensorStorage, ReplayBuffer
from torchrl.envs import EnvBase, ExplorationType

__all__ = ["collect_demonstrations", "demonstration_buffer", "mixed_batches"]


@torch.no_grad()
def collect_demonstrations(env: EnvBase, policy, episodes: int, *, steps_per_batch: int = 50,
                           noise: float = 0.0) -> TensorDictBase:
    """Runs ``policy`` on the batched ``env`` until at least ``episodes`` episodes have ended and
    returns every transition collected, flat (``[frames]``), in the collector's layout (``"next"``
    entries included). A learned policy acts deterministically (its mode), as a demonstrator would.
    Batches of ``steps_per_batch`` steps per environment are collected until the count is reached, so a few
    transitions of unfinished episodes may follow the last ended one.

    ``noise > 0`` executes ``clip(a + noise * N(0, I))`` in place of each action ``a`` (a continuous
    action box only), from torch's global generator: the demonstrator then also shows how it recovers
    from states off its own path (DART, Laskey et al. 2017). The executed action is stored, so the
    critic learns the transition that happened, and cloning it still targets ``a`` in expectation."""
    if episodes < 1:
        raise ValueError(f"demonstrations need at least one episode, got {episodes}.")
    if noise < 0:
        raise ValueError(f"demonstration noise is a standard deviation, got {noise}.")
    if noise > 0:
        policy = perturbed(policy, env.full_action_spec_unbatched["action"], noise)
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


def perturbed(policy, spec, noise: float) -> TensorDictSequential:
    """``policy`` followed by ``a <- clip(a + noise * N(0, I), low, high)`` on its ``"action"``."""
    if not isinstance(spec, Bounded) or not spec.dtype.is_floating_point:
        raise ValueError(f"demonstration noise perturbs a continuous action box, not a {type(spec).__name__} spec.")
    low, high = spec.space.low, spec.space.high

    def perturb(action: torch.Tensor) -> torch.Tensor:
        return (action + noise * torch.randn_like(action)).clamp(low, high)

    return TensorDictSequential(policy, TensorDictModule(perturb, in_keys=["action"], out_keys=["action"]))


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
