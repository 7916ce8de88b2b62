"""The demonstrations method: source episodes in their own buffer, a share of every batch, behaviour cloning.

The buffer and the share are DDPGfD's (Vecerik et al. 2017); the cloning term is Nair et al. (2018)'s, with
its Q filter on by default (``bc_q_filter``: clone a demonstrated action only where the critic rates it above
the actor's own, which is what keeps demonstrations of a source task's behaviour from being copied where the
target task pays for something else), and its weight scaled to the critic's size as TD3+BC scales it
(Fujimoto & Gu 2021): ``bc_weight * mean|Q| / bc_alpha``, ``bc_alpha`` = 2.5 as in TD3+BC
(:func:`drltg.losses.behaviour_cloning`).
"""
from __future__ import annotations

from typing import Annotated, Optional

from pydantic import Field

from drltg.config import DEMO_SEED_OFFSET, Bool, Float, Int, Probability, RunConfig
from drltg.errors import UsageError
from drltg.transfer.registry import Transfer, TransferMethod


def _check_env(cfg: RunConfig, env) -> None:
    """Behaviour cloning and demonstration noise act on continuous actions."""
    from torchrl.data import OneHot

    for key, value in (("bc_weight", cfg.transfer.bc_weight), ("demo_noise", cfg.transfer.demo_noise)):
        if value > 0 and isinstance(env.full_action_spec_unbatched["action"], OneHot):
            raise UsageError(f"transfer.{key} works on continuous actions; task '{cfg.task}' has discrete actions "
                             f"(set -o transfer.{key}=0).")


def _build(cfg: RunConfig, agent, env, *, resuming: bool) -> Transfer:
    """``transfer.demo_episodes`` episodes of the source policy on the training task, from an env
    seeded apart from the training and evaluation envs, kept in a buffer of their own; a resumed run
    collects the same episodes again. For the soft option-critic each sampled demonstration is credited
    to an option drawn from the learner's policy over options (:func:`drltg.losses.option_labels`)."""
    from torchrl.envs import TransformedEnv

    from drltg.collectors import collect_demonstrations, demonstration_buffer, mixed_batches
    from drltg.envs import make_env
    from drltg.losses import SoftOptionCriticLoss, behaviour_cloning, option_labels
    from drltg.transfer.source import source_actor

    t = cfg.transfer
    _check_env(cfg, env)
    policy = source_actor(cfg, env)
    demo_env = TransformedEnv(make_env(cfg.task, batch_size=(cfg.collector.num_envs,), device=cfg.device,
                                       seed=cfg.seed + DEMO_SEED_OFFSET, **cfg.env))
    for transform in agent.env_transforms:
        demo_env.append_transform(transform.clone())
    try:
        data = collect_demonstrations(demo_env, policy, t.demo_episodes, noise=t.demo_noise)
    finally:
        demo_env.close()
    demos = demonstration_buffer(data, agent.loss.in_keys)
    count = round(t.demo_ratio * cfg.buffer.batch_size)
    weight = [t.bc_weight]

    def anneal(frames: int) -> None:  # w_f = w * max(0, 1 - f / bc_anneal_frames)
        weight[0] = t.bc_weight * max(0.0, 1.0 - frames / t.bc_anneal_frames)

    bc = behaviour_cloning(agent.loss, count, lambda: weight[0], q_filter=t.bc_q_filter, alpha=t.bc_alpha)
    label = option_labels(agent.loss, count) if isinstance(agent.loss, SoftOptionCriticLoss) and count else None

    def batches(own, n):  # a generator: each batch's options are drawn just before its update
        mixed = mixed_batches(own, demos, n, t.demo_ratio)
        return mixed if label is None else (label(batch) for batch in mixed)

    return Transfer(batches=batches,
                    loss_terms=bc if t.bc_weight > 0 and count > 0 else None,
                    on_frames=anneal if t.bc_anneal_frames > 0 else None,
                    summary={"demonstration_frames": data.numel()})


DEMONSTRATIONS = TransferMethod(
    "demonstrations",
    "episodes of the source policy in a buffer of their own, a fixed share of every batch",
    _build,
    source="policy",
    takes=("batches",),
    check_env=_check_env,
    algos=("sac", "td3", "soc"),
    grouped=True,
    options={
        "demo_episodes": (Int, Field(50, ge=1, description="demonstrations: episodes of the source policy collected")),
        "demo_ratio": (Probability, Field(0.25, description="demonstrations: share of every batch drawn from them")),
        "bc_weight": (Float, Field(1.0, ge=0, description="demonstrations: weight of the behaviour-cloning term, "
                                                          "times mean(abs(Q)) / bc_alpha (0: none)")),
        "bc_alpha": (Optional[Annotated[Float, Field(gt=0)]],
                     Field(2.5, description="demonstrations: TD3+BC's alpha, the cloning weight bc_weight * "
                                            "mean(abs(Q)) / bc_alpha; null: bc_weight alone",
                           json_schema_extra={"absent": None})),  # runs saved before it cloned at bc_weight alone
        "bc_q_filter": (Bool, Field(True, description="demonstrations: clone only where Q(s, a_demo) > Q(s, mu(s)) "
                                                      "(Nair et al.'s Q filter)")),
        "bc_anneal_frames": (Int, Field(0, ge=0, description="demonstrations: frames over which bc_weight falls "
                                                             "linearly to 0 (0: constant)")),
        "demo_noise": (Float, Field(0.0, ge=0, description="demonstrations: std of the Gaussian noise added to every "
                                                           "demonstrated action, clipped (0: none)")),
    },
    search={"bc_alpha": (2.5, 1.0, 5.0, 10.0)},  # TD3+BC's alpha and its neighbours
    member_options=("bc_alpha",),  # a buffer of each seed's cloning term
)
