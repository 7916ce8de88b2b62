"""Agent builders: TorchRL actors, critics and losses for each algorithm, sized from the config.

An algorithm is a function ``make_<algo>_agent(env, cfg) -> Agent`` registered in ``ALGOS``. The
training loop only sees the ``Agent`` fields, so a new learner (e.g. soft option-critic) plugs in by
adding one builder.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import torch
from tensordict.nn import NormalParamExtractor, TensorDictModule, TensorDictSequential
from torch import nn
from torchrl.data import OneHot
from torchrl.envs import EnvBase, Transform
from torchrl.modules import (
    MLP,
    AdditiveGaussianModule,
    OneHotCategorical,
    ProbabilisticActor,
    TanhModule,
    TanhNormal,
    ValueOperator,
)
from torchrl.objectives import DiscreteSACLoss, LossModule, SACLoss, SoftUpdate, TD3Loss

from drltg.errors import UsageError
from drltg.losses.soc import make_soc_agent


@dataclass
class Agent:
    """What the training loop needs from an algorithm.

    ``actor`` acts deterministically under ``ExplorationType.DETERMINISTIC`` (evaluation); ``policy``
    is the exploration policy the collector runs (the actor itself for SAC, actor + noise for TD3);
    ``actor_delay`` is how many critic updates pass per actor/target update (TD3's policy delay).
    """

    actor: TensorDictModule
    policy: TensorDictModule
    loss: LossModule
    target_updater: SoftUpdate
    optimizer: torch.optim.Optimizer
    actor_delay: int = 1
    env_transforms: list[Transform] = field(default_factory=list)


def _mlp(out_features: int, cfg: dict) -> MLP:
    return MLP(out_features=out_features, num_cells=list(cfg["network"]["hidden"]), activation_class=nn.ReLU)


def _optimizer(loss: LossModule, cfg: dict) -> torch.optim.Optimizer:
    return torch.optim.Adam(loss.parameters(), lr=cfg["optim"]["lr"], foreach=True)  # = the for-loop Adam, bit for bit


def _action_spec(env: EnvBase):
    return env.full_action_spec_unbatched["action"]


def make_sac_agent(env: EnvBase, cfg: dict) -> Agent:
    """SAC (Haarnoja et al. 2018): tanh-Gaussian actor, twin Q critics, learned temperature.
    On a discrete (one-hot) action space it builds discrete SAC (Christodoulou 2019)."""
    spec = _action_spec(env)
    if isinstance(spec, OneHot):
        return make_discrete_sac_agent(env, cfg)
    n_act = spec.shape[-1]
    actor = ProbabilisticActor(
        TensorDictModule(
            nn.Sequential(_mlp(2 * n_act, cfg), NormalParamExtractor()),
            in_keys=["observation"],
            out_keys=["loc", "scale"],
        ),
        in_keys=["loc", "scale"],
        spec=spec,
        distribution_class=TanhNormal,
        distribution_kwargs={"low": spec.space.low, "high": spec.space.high},
        return_log_prob=False,
    )
    qvalue = ValueOperator(_mlp(1, cfg), in_keys=["observation", "action"])
    _init_lazy(env, actor, qvalue)
    loss = SACLoss(
        actor,
        qvalue,
        num_qvalue_nets=2,
        loss_function="l2",
        alpha_init=cfg["sac"]["alpha_init"],
        fixed_alpha=cfg["sac"]["fixed_alpha"],
        target_entropy=cfg["sac"]["target_entropy"],
        action_spec=spec,
    )
    loss.make_value_estimator(gamma=cfg["optim"]["gamma"])
    return Agent(actor, actor, loss, SoftUpdate(loss, tau=cfg["optim"]["tau"]), _optimizer(loss, cfg))


def make_discrete_sac_agent(env: EnvBase, cfg: dict) -> Agent:
    """Discrete SAC: a categorical actor over one-hot actions; exact soft expectations over actions."""
    spec = _action_spec(env)
    n = spec.space.n
    actor = ProbabilisticActor(
        TensorDictModule(_mlp(n, cfg), in_keys=["observation"], out_keys=["logits"]),
        in_keys=["logits"],
        spec=spec,
        distribution_class=OneHotCategorical,
        return_log_prob=False,
    )
    qvalue = TensorDictModule(_mlp(n, cfg), in_keys=["observation"], out_keys=["action_value"])
    _init_lazy(env, actor, qvalue)
    loss = DiscreteSACLoss(
        actor,
        qvalue,
        action_space=spec,
        num_actions=n,
        num_qvalue_nets=2,
        loss_function="l2",
        alpha_init=cfg["sac"]["alpha_init"],
        fixed_alpha=cfg["sac"]["fixed_alpha"],
        target_entropy=cfg["sac"]["target_entropy"],
    )
    loss.make_value_estimator(gamma=cfg["optim"]["gamma"])
    return Agent(actor, actor, loss, SoftUpdate(loss, tau=cfg["optim"]["tau"]), _optimizer(loss, cfg))


def make_td3_agent(env: EnvBase, cfg: dict) -> Agent:
    """TD3 (Fujimoto et al. 2018): deterministic actor, twin critics, target smoothing, policy delay;
    the collector explores with additive Gaussian noise, clipped to the action box."""
    spec = _action_spec(env)
    if isinstance(spec, OneHot):
        raise UsageError(f"TD3 needs continuous actions; task '{cfg['task']}' has discrete actions (use --algo sac).")
    n_act = spec.shape[-1]
    actor = TensorDictSequential(
        TensorDictModule(_mlp(n_act, cfg), in_keys=["observation"], out_keys=["param"]),
        TanhModule(in_keys=["param"], out_keys=["action"], spec=spec),
    )
    qvalue = ValueOperator(_mlp(1, cfg), in_keys=["observation", "action"])
    _init_lazy(env, actor, qvalue)
    td3 = cfg["td3"]
    sigma = td3["exploration_noise"]
    noise = AdditiveGaussianModule(spec=spec, sigma_init=sigma, sigma_end=sigma, annealing_num_steps=1)
    loss = TD3Loss(
        actor,
        qvalue,
        action_spec=spec,
        num_qvalue_nets=2,
        policy_noise=td3["policy_noise"],
        noise_clip=td3["noise_clip"],
        loss_function="l2",
    )
    loss.make_value_estimator(gamma=cfg["optim"]["gamma"])
    return Agent(
        actor,
        TensorDictSequential(actor, noise),
        loss,
        SoftUpdate(loss, tau=cfg["optim"]["tau"]),
        _optimizer(loss, cfg),
        actor_delay=td3["policy_delay"],
    )


def _init_lazy(env: EnvBase, actor: nn.Module, qvalue: nn.Module) -> None:
    """Materialise lazy layers with one fake step so the loss can copy target parameters."""
    td = env.fake_tensordict()
    td = td.reshape(-1)[:1] if td.batch_dims else td.unsqueeze(0)
    with torch.no_grad():
        actor(td)
        qvalue(td)


ALGOS: dict[str, Callable[[EnvBase, dict], Agent]] = {
    "sac": make_sac_agent,
    "td3": make_td3_agent,
    "soc": make_soc_agent,
}


def make_agent(env: EnvBase, cfg: dict) -> Agent:
    algo = cfg["algo"]
    if algo not in ALGOS:
        raise UsageError(f"unknown algorithm '{algo}'; choose one of: {', '.join(sorted(ALGOS))}.")
    return ALGOS[algo](env, cfg)
