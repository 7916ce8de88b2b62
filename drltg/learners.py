"""Learners: the agent of every algorithm, sized from the config, and the one update step that trains them.

An algorithm is a function ``make_<algo>_agent(env, cfg) -> Agent`` registered in ``ALGOS`` (the config's
registry of learners, :data:`drltg.config.LEARNERS`: ``ALGOS["my-algo"] = make_my_agent``, or an entry point
of the group ``drltg.learners``, as the built-in ones are, makes ``algo=my-algo`` valid): SAC and
discrete SAC (``SACLoss``, ``DiscreteSACLoss``), TD3 (``TD3Loss``) and soft option-critic
(:class:`~drltg.losses.SoftOptionCriticLoss`). Every learner is stepped by the same
:class:`UpdateStep` over the same public TorchRL interface (the loss's ``forward``, ``SoftUpdate.step``)
and built the same way: ReLU MLPs, twin critics evaluated one copy after the other
(``deactivate_vmap=True``, see ``benchmarks/README.md``), one ``Adam(foreach=True)`` over all
parameters, so a comparison between learners compares algorithms, not code paths.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Callable

import torch
from tensordict import TensorDictBase
from tensordict.nn import NormalParamExtractor, TensorDictModule, TensorDictSequential
from torch import nn
from torchrl.data import OneHot, ReplayBuffer
from torchrl.envs import EnvBase, Transform
from torchrl.modules import (
    MLP,
    AdditiveGaussianModule,
    OneHotCategorical,
    ProbabilisticActor,
    TanhModule,
    ValueOperator,
)
from torchrl.objectives import DiscreteSACLoss, LossModule, SACLoss, SoftUpdate, TD3Loss

from drltg import config
from drltg.config import RunConfig
from drltg.errors import UsageError
from drltg.losses import SoftOptionCriticLoss
from drltg.modules import (
    TanhNormal,
    make_option_actor,
    make_option_policy,
    make_option_qvalue,
    make_termination,
    option_transforms,
)

DEACTIVATE_VMAP = True
"""Passed to every loss: the critic copies run in a plain loop instead of under ``torch.vmap``. Same values;
on a CPU level with ``torch.vmap`` for SAC, discrete SAC and TD3 and faster for SOC (``benchmarks/README.md``)."""


@dataclass
class Agent:
    """What the training loop needs from an algorithm.

    ``actor`` acts deterministically under ``ExplorationType.DETERMINISTIC`` (evaluation); ``policy``
    is the exploration policy the collector runs (the actor itself for SAC, actor + noise for TD3);
    ``actor_delay`` is how many critic updates pass per actor/target update (TD3's policy delay);
    ``env_transforms`` are what the environment must carry for the policy (SOC's option).
    """

    actor: TensorDictModule
    policy: TensorDictModule
    loss: LossModule
    target_updater: SoftUpdate
    optimizer: torch.optim.Optimizer
    actor_delay: int = 1
    env_transforms: list[Transform] = field(default_factory=list)


def _mlp(out_features: int, cfg: RunConfig, *, critic: bool = False) -> MLP:
    """A ReLU MLP; with ``network.layer_norm`` (``critics`` or ``all``) each hidden layer is Linear ->
    LayerNorm -> ReLU, which keeps critics from over-estimating on out-of-distribution actions when
    offline data share the batches (Ball et al. 2023)."""
    hidden, norm = list(cfg.network.hidden), cfg.network.layer_norm
    kwargs = {}
    if norm == "all" or (norm == "critics" and critic):
        kwargs = {"norm_class": nn.LayerNorm, "norm_kwargs": [{"normalized_shape": w} for w in hidden]}
    return MLP(out_features=out_features, num_cells=hidden, activation_class=nn.ReLU, **kwargs)


def _action_spec(env: EnvBase):
    return env.full_action_spec_unbatched["action"]


def _init_lazy(env: EnvBase, *modules: nn.Module, option: bool = False) -> None:
    """Put the networks on the env's device and materialise their lazy layers there with one fake step,
    before the loss copies them into target parameters."""
    td = env.fake_tensordict()
    td = td.reshape(-1)[:1] if td.batch_dims else td.unsqueeze(0)
    if option:
        td.set("option", torch.zeros(*td.batch_size, 1, dtype=torch.int64, device=td.device))
    with torch.no_grad():
        for module in modules:
            module.to(td.device)(td)


def _agent(loss: LossModule, policy: TensorDictModule, cfg: RunConfig, *, actor=None, **fields) -> Agent:
    """The loss with its value estimator, target updater and optimiser: the same for every learner."""
    loss.make_value_estimator(gamma=cfg.optim.gamma)
    optimizer = torch.optim.Adam(loss.parameters(), lr=cfg.optim.lr, foreach=True)  # = for-loop Adam, bit for bit
    actor = policy if actor is None else actor
    return Agent(actor, policy, loss, SoftUpdate(loss, tau=cfg.optim.tau), optimizer, **fields)


def _sac_options(cfg: RunConfig) -> dict:
    """The loss options continuous and discrete SAC share: twin critics, L2, the temperature settings."""
    return dict(num_qvalue_nets=2, loss_function="l2", alpha_init=cfg.sac.alpha_init, fixed_alpha=cfg.sac.fixed_alpha,
                target_entropy=cfg.sac.target_entropy, deactivate_vmap=DEACTIVATE_VMAP)


def make_sac_agent(env: EnvBase, cfg: RunConfig) -> Agent:
    """SAC (Haarnoja et al. 2018): tanh-Gaussian actor, twin Q critics, learned temperature.
    On a discrete (one-hot) action space it builds discrete SAC (Christodoulou 2019)."""
    spec = _action_spec(env)
    if isinstance(spec, OneHot):
        return make_discrete_sac_agent(env, cfg)
    actor = ProbabilisticActor(
        TensorDictModule(
            nn.Sequential(_mlp(2 * spec.shape[-1], cfg), NormalParamExtractor()),
            in_keys=["observation"],
            out_keys=["loc", "scale"],
        ),
        in_keys=["loc", "scale"],
        spec=spec,
        distribution_class=TanhNormal,
        distribution_kwargs={"low": spec.space.low, "high": spec.space.high},
        return_log_prob=False,
    )
    qvalue = ValueOperator(_mlp(1, cfg, critic=True), in_keys=["observation", "action"])
    _init_lazy(env, actor, qvalue)
    loss = SACLoss(
        actor,
        qvalue,
        action_spec=spec,
        **_sac_options(cfg),
    )
    return _agent(loss, actor, cfg)


def make_discrete_sac_agent(env: EnvBase, cfg: RunConfig) -> Agent:
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
    qvalue = TensorDictModule(_mlp(n, cfg, critic=True), in_keys=["observation"], out_keys=["action_value"])
    _init_lazy(env, actor, qvalue)
    loss = DiscreteSACLoss(
        actor,
        qvalue,
        action_space=spec,
        num_actions=n,
        **_sac_options(cfg),
    )
    return _agent(loss, actor, cfg)


def make_td3_agent(env: EnvBase, cfg: RunConfig) -> Agent:
    """TD3 (Fujimoto et al. 2018): deterministic actor, twin critics, target smoothing, policy delay;
    the collector explores with additive Gaussian noise, clipped to the action box."""
    spec = _action_spec(env)
    if isinstance(spec, OneHot):
        raise UsageError(f"TD3 needs continuous actions; task '{cfg.task}' has discrete actions (use --algo sac).")
    actor = TensorDictSequential(
        TensorDictModule(_mlp(spec.shape[-1], cfg), in_keys=["observation"], out_keys=["param"]),
        TanhModule(in_keys=["param"], out_keys=["action"], spec=spec),
    )
    qvalue = ValueOperator(_mlp(1, cfg, critic=True), in_keys=["observation", "action"])
    _init_lazy(env, actor, qvalue)
    td3 = cfg.td3
    sigma = td3.exploration_noise
    noise = AdditiveGaussianModule(spec=spec, sigma_init=sigma, sigma_end=sigma, annealing_num_steps=1)
    loss = TD3Loss(
        actor,
        qvalue,
        action_spec=spec,
        num_qvalue_nets=2,
        policy_noise=td3.policy_noise,
        noise_clip=td3.noise_clip,
        loss_function="l2",
        deactivate_vmap=DEACTIVATE_VMAP,
    )
    return _agent(loss, TensorDictSequential(actor, noise), cfg, actor=actor, actor_delay=td3.policy_delay)


def make_soc_agent(env: EnvBase, cfg: RunConfig) -> Agent:
    """Soft option-critic (``cfg.soc``, :class:`drltg.config.SOCConfig`) with SAC's networks, temperature and
    optimiser settings, so ``num_options=1`` is the SAC agent. The option-carrying policy both explores
    and evaluates (greedy options, mean actions under ``ExplorationType.DETERMINISTIC``)."""
    spec = _action_spec(env)
    if isinstance(spec, OneHot):
        raise UsageError(
            f"soft option-critic needs continuous actions; task '{cfg.task}' has discrete actions (use --algo sac)."
        )
    soc = cfg.soc
    num_options, hidden = soc.num_options, list(cfg.network.hidden)
    actor = make_option_actor(spec, num_options, hidden)
    qvalue = make_option_qvalue(num_options, hidden)
    termination = make_termination(num_options, hidden)
    _init_lazy(env, actor, qvalue, termination, option=True)
    loss = SoftOptionCriticLoss(
        actor,
        qvalue,
        termination,
        num_options=num_options,
        loss_function="l2",
        alpha_init=cfg.sac.alpha_init,
        fixed_alpha=cfg.sac.fixed_alpha,
        target_entropy=cfg.sac.target_entropy,
        action_spec=spec,
        option_policy=soc.option_policy,
        option_alpha_init=soc.option_alpha_init or cfg.sac.alpha_init,
        fixed_option_alpha=soc.fixed_option_alpha,
        option_target_entropy=soc.option_target_entropy,
        option_epsilon=soc.option_epsilon,
        deliberation_cost=soc.deliberation_cost,
        option_entropy_bonus=soc.option_entropy_bonus,
        deactivate_vmap=DEACTIVATE_VMAP,
    )
    return _agent(loss, make_option_policy(loss), cfg, env_transforms=option_transforms(num_options))


ALGOS = config.LEARNERS
"""``algo`` -> ``make_<algo>_agent(env, cfg)``: ``sac``, ``td3``, ``soc`` (entry points) and those added here."""


def make_agent(env: EnvBase, cfg: RunConfig | dict) -> Agent:
    """The learner ``cfg.algo`` for ``env``; a mapping of config keys is resolved first
    (:func:`drltg.config.as_config`)."""
    cfg = config.as_config(cfg)
    return ALGOS[cfg.algo](env, cfg)


# ----------------------------------------------------------------------------- the update step
def loss_total(losses: TensorDictBase, update_actor: bool = True) -> torch.Tensor:
    """Sum of the ``loss_*`` entries; the actor's terms (``loss_actor*``) are left out when ``update_actor``
    is False."""
    kept = [k for k in losses.keys() if k.startswith("loss_") and (update_actor or not k.startswith("loss_actor"))]
    return sum(losses[k] for k in kept)


class UpdateStep:
    """One gradient step of ``agent``: ``step(batch, update_actor) -> detached losses``.

    ``loss(batch) -> backward(sum of loss_* terms) -> optimizer.step() -> target_updater.step()``, the
    sequence of TorchRL's sota SAC loop, for every learner alike, and for a seed group's stacked loss
    (:class:`~drltg.training.seeds.StackedLoss`), whose terms have a leading seed dimension and are summed
    over it too: seeds share no parameter, so d/d theta_k of the sum is seed k's gradient. ``update_actor=False``
    leaves out the actor's loss terms and the target update (TD3's policy delay).

    Args:
        agent: the :class:`Agent` whose ``loss``, ``optimizer`` and ``target_updater`` are stepped.
        loss_terms: ``loss_terms(batch) -> {"loss_<name>": scalar}``, extra terms added to the loss's
            (a transfer method's, e.g. behaviour cloning on demonstrations).
        cudagraphs: capture the step in a CUDA graph with tensordict's ``CudaGraphModule`` (every
            tensor on one CUDA device, a fixed batch shape; Adam is switched to ``capturable``).
        threads: torch CPU threads the step runs in, torch's setting restored after it (``None``: torch's
            own setting). drltg's networks are small: each operation is too short to share between
            threads, and a parallel region waits for its slowest thread, so with torch's default of one
            thread per core a single busy core (another run, env workers) makes every step wait
            (``python -m benchmarks threads``).
    """

    def __init__(self, agent: Agent, *, loss_terms=None, cudagraphs: bool = False, threads: int | None = 1):
        self.agent = agent
        self.loss_terms = loss_terms
        self.cudagraphs = cudagraphs
        self.threads = threads
        if cudagraphs:
            for group in agent.optimizer.param_groups:
                group["capturable"] = True
        self.steps: dict[bool, Callable[[TensorDictBase], TensorDictBase]] = {}

    def _build(self, update_actor: bool) -> Callable[[TensorDictBase], TensorDictBase]:
        loss, optimizer, target_updater = self.agent.loss, self.agent.optimizer, self.agent.target_updater
        loss_terms = self.loss_terms

        def step(batch: TensorDictBase) -> TensorDictBase:
            losses = loss(batch)
            if loss_terms is not None:
                losses.update(loss_terms(batch))
            optimizer.zero_grad(set_to_none=True)
            loss_total(losses, update_actor).sum().backward()
            optimizer.step()
            if update_actor:
                target_updater.step()
            return losses.detach()

        if self.cudagraphs:
            from tensordict.nn import CudaGraphModule

            step = CudaGraphModule(step, warmup=3, in_keys=[], out_keys=[])
        return step

    def __call__(self, batch: TensorDictBase, update_actor: bool = True) -> TensorDictBase:
        if update_actor not in self.steps:
            self.steps[update_actor] = self._build(update_actor)
        before = torch.get_num_threads()
        if self.threads is None or self.threads == before:
            losses = self.steps[update_actor](batch)
        else:
            torch.set_num_threads(self.threads)
            try:
                losses = self.steps[update_actor](batch)
            finally:
                torch.set_num_threads(before)
        return losses.clone() if self.cudagraphs else losses


def sample_batches(buffer: ReplayBuffer, count: int) -> list[TensorDictBase]:
    """``count`` batches of ``buffer.batch_size`` transitions drawn with one ``sample`` call.

    Equal, draw for draw, to ``count`` calls of ``buffer.sample()`` for a buffer whose sampler
    draws indices independently and uniformly (TorchRL's default ``RandomSampler``).
    """
    size = buffer.batch_size
    if count == 1:
        return [buffer.sample()]
    with warnings.catch_warnings():  # a batch size given to sample() differs from the buffer's: intended
        warnings.filterwarnings("ignore", message="Got conflicting batch_sizes")
        return list(buffer.sample(size * count).split(size))
