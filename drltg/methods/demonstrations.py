"""Learning from demonstrations: transitions of a demonstrator kept apart and sampled by every update.

As in DQfD and DDPGfD (Hester et al. 2018; Vecerik et al. 2017; Nair et al. 2018), demonstrations
live in their own buffer, never overwritten by the agent's experience, and every gradient step draws
a fixed share of its batch from them:

    batch = [ k = round(ratio * B) demonstration transitions | B - k own transitions ]

so the critic keeps seeing demonstrated successes for the whole run instead of until the replay
buffer has cycled past them. On top, the actor is pulled towards the demonstrated actions by a
behaviour-cloning term (Nair et al. 2018, :func:`behaviour_cloning`), optionally only where the critic
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
from torchrl.collectors import Collector
from torchrl.data import LazyTensorStorage, OneHot, ReplayBuffer
from torchrl.envs import EnvBase, ExplorationType, TransformedEnv, set_exploration_type

from drltg.config import Field, builtin_options
from drltg.errors import UsageError
from drltg.methods.registry import Transfer, TransferMethod, register_method

__all__ = ["behaviour_cloning", "collect_demonstrations", "demonstration_buffer", "mixed_batches"]


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


def _min_q(loss, td: TensorDictBase) -> torch.Tensor:
    """The smaller of ``loss``'s critics at ``td``'s (observation, action), without gradients."""
    values = []
    for params in loss.qvalue_network_params.detach().unbind(0):
        with params.to_module(loss.qvalue_network):
            values.append(loss.qvalue_network(td.clone(False))["state_action_value"])
    return torch.stack(values).amin(0).squeeze(-1)


def behaviour_cloning(loss, count: int, weight: float, *, q_filter: bool = False):
    """Nair et al. (2018)'s behaviour-cloning term on the first ``count`` transitions of each batch (the
    demonstrations, as :func:`mixed_batches` lays them out), for a SAC or TD3 loss module:

        loss_actor_bc = weight * mean_i ||mu(s_i) - a_i||^2 * 1[Q(s_i, a_i) > Q(s_i, mu(s_i))]

    ``mu`` the actor's deterministic action, ``Q`` the smaller of the current critics. The Q filter
    clones a demonstrated action only while the critic rates it above the actor's own, so the term fades
    where the learner has become better than its demonstrator. Returns ``loss_terms(batch)`` for
    :class:`~drltg.learners.UpdateStep`, with ``bc_accepted``, the share of demonstrations kept."""
    actor, actor_params = loss.actor_network, loss.actor_network_params
    obs_keys = list(actor.in_keys)

    def loss_terms(batch: TensorDictBase) -> dict[str, torch.Tensor]:
        demo = batch[:count]
        with set_exploration_type(ExplorationType.DETERMINISTIC), actor_params.to_module(actor):
            action = actor(demo.select(*obs_keys).clone(False))["action"]
        error = (action - demo["action"]).pow(2).sum(-1)
        accepted = torch.ones_like(error)
        if q_filter:
            pair = demo.select(*obs_keys, "action")
            accepted = (_min_q(loss, pair) > _min_q(loss, pair.clone(False).set("action", action.detach()))).float()
        return {"loss_actor_bc": weight * (error * accepted).mean(), "bc_accepted": accepted.mean()}

    return loss_terms


def _build(cfg: dict, agent, env, *, resuming: bool) -> Transfer:
    """``transfer.demo_episodes`` episodes of the source policy on the training task, from an env
    seeded apart from the training and evaluation envs, kept in a buffer of their own; a resumed run
    collects the same episodes again."""
    from drltg.envs import make_env
    from drltg.methods.source import source_actor

    t = cfg["transfer"]
    if t["bc_weight"] > 0 and isinstance(env.full_action_spec_unbatched["action"], OneHot):
        raise UsageError(
            f"transfer.bc_weight clones continuous actions; task '{cfg['task']}' has discrete actions "
            f"(set -o transfer.bc_weight=0)."
        )
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
    count = round(t["demo_ratio"] * cfg["buffer"]["batch_size"])
    bc = behaviour_cloning(agent.loss, count, t["bc_weight"], q_filter=t["bc_q_filter"])
    return Transfer(batches=lambda own, n: mixed_batches(own, demos, n, t["demo_ratio"]),
                    loss_terms=bc if t["bc_weight"] > 0 and count > 0 else None,
                    summary={"demonstration_frames": data.numel()})


DEMONSTRATIONS = register_method(TransferMethod(
    "demonstrations",
    "episodes of the source policy in a buffer of their own, a fixed share of every batch",
    _build,
    source="policy",
    algos=("sac", "td3"),
    options=builtin_options("demonstrations", {
        "demo_episodes": Field(int, "demonstrations: episodes of the source policy collected", low=1),
        "demo_ratio": Field(float, "demonstrations: share of every batch drawn from them", low=0.0, high=1.0),
        "bc_weight": Field(float, "demonstrations: weight of the behaviour-cloning term (0: none)", low=0.0),
        "bc_q_filter": Field(bool, "demonstrations: clone only where Q(s, a_demo) > Q(s, mu(s))"),
    }),
))
