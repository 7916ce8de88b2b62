r"""The sf-gpi method: the source policy's successor features, the target's reward weights, and GPI as the
behaviour policy of an ordinary learner (Barreto et al. 2017, "Successor features for transfer in reinforcement
learning"; 2018).

For goal-reaching tasks that share their dynamics (FourRooms, grid FourRooms: only the goal moves),
:math:`\phi(s') = [\text{in source goal}, \text{in target goal}, 1]` (:class:`~drltg.modules.GoalFeatures`)
writes both rewards exactly, :math:`r = \phi^\top w`, with the target's :math:`w` from its goal and step cost
(:meth:`~drltg.modules.GoalFeatures.task_weights`). At build time the source policy acts for ``sf_frames``
frames in the source task (its exploration policy, from an env seeded apart) and
:math:`\psi^{\pi_S}` is learnt by TD on them (:class:`~drltg.losses.SuccessorFeatureLoss`, the next action
the source's deterministic one) for ``sf_updates`` = 20,000 steps, a measured count (``benchmarks/sf_psi.py``:
on FourRooms bench sources psi's value at start states agrees far better with the source's Monte Carlo return
there than after the 2,000 steps this method took before). A plateau rule is opt-in (``sf_patience`` > 0,
:class:`Plateau`): TD stops once the mean relative TD error ``loss_sf / sf_target_sq`` of each block of
``sf_block`` steps has failed to fall ``sf_tolerance`` below the lowest so far for ``sf_patience`` blocks in a
row. The error is taken relative to the target's size because the plain TD loss grows as psi does (psi starts at
0 and its constant feature's part climbs towards ``1 / (1 - gamma)``); the relative one is no reliable stop
either (on some sources it plateaus while psi still improves), which is why the rule is not the default. psi's TD
is the run's :class:`~drltg.transfer.registry.Pretraining`: a seed group learns its members' psi as one vmapped
update, and the members that would learn the same psi (a tuning grid's settings of ``sf_epsilon`` on one seed)
learn it once.

The collector then acts by GPI over the library :math:`\{\pi_S, \pi_L\}`, the source and the learner, each
valued by its own :math:`Q` (:class:`~drltg.collectors.GPIPolicy`, Barreto et al. 2017, theorem 1):

- continuous actions: :math:`a = \arg\max_{a_j \in \{\pi_S(s), a_L\}} \max(\psi^{\pi_S}(s, a_j)^\top w,
  \min_k Q^L_k(s, a_j))`, the source's action or the learner's own sampled one :math:`a_L`;
- discrete actions: :math:`a = \arg\max_a \max(\psi^{\pi_S}(s, a)^\top w, \min_k Q^L_k(s, a))`;

then epsilon-greedy, as Barreto et al.'s agents explore: with probability ``sf_epsilon`` a uniform random action
(TorchRL's ``EGreedyModule``). The learner trains on what GPI collects with its own loss, and is evaluated
alone; ``reused`` marks the steps whose action is the source's (GPI chose it and no random action replaced
it: ``train/reused_fraction``).
"""
from __future__ import annotations

import json
import math

from pydantic import Field

from drltg.config import Float, Int, Probability, RunConfig
from drltg.errors import UsageError
from drltg.transfer.registry import Pretraining, Transfer, TransferMethod

SHARED = ("goal", "step_cost")
"""The env options that set the reward alone; every other one is the dynamics, the same on both tasks."""
OWN_VALUES = "learner_action_value"


def _refusal(why: str) -> UsageError:
    return UsageError(f"sf-gpi needs source and target tasks that differ only in reward (the goal of a FourRooms "
                      f"or grid FourRooms task); {why}.")


def _check_task(task: str) -> None:
    from drltg.envs import get_task

    if not set(SHARED) <= set(get_task(task).keywords()):
        raise _refusal(f"task '{task}' has no goal to write its reward as features")


def _check_shared(source_task: str, source_env: dict, task: str, env: dict) -> None:
    """Refuse a source task of another factory, or with other env options than the reward's."""
    from drltg.envs import get_task

    _check_task(source_task)
    if get_task(source_task).entry != get_task(task).entry:
        raise _refusal(f"the source task '{source_task}' and the target task '{task}' are different environments")
    mine, theirs = ({k: v for k, v in {**get_task(name).keywords(), **opts}.items() if k not in SHARED}
                    for name, opts in ((source_task, source_env), (task, env)))
    differ = sorted(k for k in {*mine, *theirs} if mine.get(k) != theirs.get(k))
    if differ:
        raise _refusal(f"the source task '{source_task}' and '{task}' differ in env.{', env.'.join(differ)}")


def _check(cfg: RunConfig) -> None:
    """The target must be a goal task; a source run already there must be one of the same dynamics."""
    from pathlib import Path

    from drltg import safe_yaml
    from drltg.store.rundir import CONFIG

    _check_task(cfg.task)
    saved = Path(str(cfg.transfer.source or "")).expanduser() / CONFIG
    if cfg.transfer.source and saved.is_file():
        data = safe_yaml.load_file(saved)
        if isinstance(data, dict) and isinstance(data.get("task"), str):
            _check_shared(data["task"], data.get("env") or {}, cfg.task, cfg.env)


class Plateau:
    """When TD learning of psi stops: its relative TD error averaged over each block of ``block`` steps, ``L_j``; a
    block falls if ``L_j < (1 - tolerance) * min_{i<j} L_i`` (the first always does), and TD stops after
    ``patience`` blocks in a row that do not fall. :meth:`push` takes one step's value and says whether to stop;
    ``means`` keeps the blocks' means. "Falls" is torch's ``ReduceLROnPlateau`` comparison (mode ``min``,
    threshold mode ``rel``)."""

    def __init__(self, block: int, patience: int, tolerance: float) -> None:
        self.block, self.patience, self.tolerance = block, patience, tolerance
        self.best, self.flat, self.means = math.inf, 0, []
        self._sum, self._count = 0.0, 0

    def push(self, loss) -> bool:
        self._sum, self._count = self._sum + loss, self._count + 1
        if self._count < self.block:
            return False
        mean = float(self._sum) / self._count
        self._sum, self._count = 0.0, 0
        self.means.append(mean)
        if mean < (1.0 - self.tolerance) * self.best:
            self.best, self.flat = mean, 0
        else:
            self.flat += 1
        return self.flat >= self.patience


def _successor_feature_problem(cfg: RunConfig, source, features, discrete: bool):
    """psi of the source's deterministic policy as a TD problem (:class:`Pretraining`) on ``sf_frames`` frames its
    exploration policy collects in the source task: Adam at ``optim.lr``, ``optim.gamma``, a soft target at
    ``optim.tau``, ``sf_updates`` steps or until its relative TD error stops falling (:class:`Plateau`, with
    ``sf_patience`` > 0). Returns the critic, the frames, the problem (its ``finish`` is the caller's) and the
    plateau rule that watches it."""
    import torch
    from torchrl.data import LazyTensorStorage, ReplayBuffer
    from torchrl.envs import TransformedEnv
    from torchrl.objectives import SoftUpdate

    from drltg.envs import make_env
    from drltg.learners import Agent
    from drltg.losses import SuccessorFeatureLoss
    from drltg.modules import make_sf_critic

    t, n = cfg.transfer, cfg.collector.num_envs
    env = TransformedEnv(make_env(source.cfg.task, batch_size=(n,), device=cfg.device, seed=cfg.seed + 30_000,
                                  **source.cfg.env))
    for transform in source.agent.env_transforms:
        env.append_transform(transform.clone())
    try:
        with torch.no_grad():
            data = env.rollout(-(-t.sf_frames // n), source.agent.policy, break_when_any_done=False)
    finally:
        env.close()
    data = features(data.reshape(-1))
    obs = env.full_observation_spec_unbatched["observation"].shape[-1]
    action = env.full_action_spec_unbatched["action"].shape[-1]
    critic = make_sf_critic(obs, features.num_features, num_cells=cfg.network.hidden,
                            **({"num_actions": action} if discrete else {"action_dim": action})).to(cfg.device)
    loss = SuccessorFeatureLoss(critic, policy=source.agent.actor)
    loss.make_value_estimator(gamma=cfg.optim.gamma)
    buffer = ReplayBuffer(storage=LazyTensorStorage(data.numel(), device=cfg.device),
                          batch_size=cfg.buffer.batch_size)
    buffer.extend(data.select(*loss.in_keys))
    agent = Agent(source.agent.actor, source.agent.actor, loss, SoftUpdate(loss, tau=cfg.optim.tau),
                  torch.optim.Adam(loss.parameters(), lr=cfg.optim.lr))
    plateau = Plateau(t.sf_block, max(t.sf_patience, 1), t.sf_tolerance)

    def stop(losses) -> bool:
        return plateau.push(losses["loss_sf"] / losses["sf_target_sq"].clamp_min(1e-12))

    problem = Pretraining(agent, buffer, t.sf_updates, torch.get_rng_state(), finish=None, stop=stop,
                          can_stop=t.sf_patience > 0)
    return critic, data.numel(), problem, plateau


def _learnt_key(cfg: RunConfig) -> str:
    """All that psi's learning reads: the run's config but ``sf_epsilon`` (used after it), the SHA-256 of the
    source's networks and config, and the random state it starts from."""
    import hashlib

    import torch

    from drltg.transfer.source import record

    settings = cfg.model_dump(mode="json")
    settings["transfer"].pop("sf_epsilon")
    state = hashlib.sha256(torch.random.get_rng_state().numpy().tobytes()).hexdigest()
    return json.dumps([settings, record(cfg), state], sort_keys=True, default=str)


def _learner_candidate_values(loss):
    """``(td, candidates [*, J, A]) -> min_k Q_k(s, a_j)`` ``[*, J]``, the live twin critics of a SAC learner at
    each candidate action: GPI's own values of the continuous candidates."""
    from tensordict import TensorDict

    from drltg.modules.critics import min_over_critics

    def values(td, candidates):
        obs = td.get("observation")
        n = candidates.shape[-2]
        pairs = TensorDict({"observation": obs.unsqueeze(-2).expand(*obs.shape[:-1], n, obs.shape[-1]),
                            "action": candidates}, batch_size=candidates.shape[:-1])
        return min_over_critics(loss.qvalue_network, loss.qvalue_network_params, pairs).squeeze(-1)

    return values


def _learner_values(loss):
    """``observation -> min_k Q_k(s, .)``, the live twin critics of a discrete-SAC learner: GPI's own values."""
    from tensordict import TensorDict

    from drltg.modules.critics import min_over_critics

    def values(observation):
        td = TensorDict({"observation": observation}, batch_size=observation.shape[:-1])
        return min_over_critics(loss.qvalue_network, loss.qvalue_network_params, td, "action_value")

    return values


def _chose_source(index, action, gpi_action):
    """``reused``: the source's value (discrete) or action (continuous) won, index 0 (the learner's is the last),
    and the epsilon-greedy step kept GPI's action."""
    return (index == 0) & (action == gpi_action).all(-1, keepdim=True)


def _build(cfg: RunConfig, agent, env, *, resuming: bool) -> Transfer:
    """The source's psi set up as a TD problem (under a forked random state: the learner draws what it would
    draw without transfer) that the run solves before it trains, GPI after the learner's policy in the
    collector."""
    import torch
    from tensordict import TensorDict
    from tensordict.nn import TensorDictModule, TensorDictSequential
    from torchrl.data import OneHot
    from torchrl.modules import EGreedyModule

    from drltg.collectors import GPIPolicy
    from drltg.losses import SoftOptionCriticLoss
    from drltg.modules import GoalFeatures
    from drltg.transfer.source import check_same_spaces, rebuild

    t = cfg.transfer
    key = _learnt_key(cfg)
    with torch.random.fork_rng(devices=[]):
        source = rebuild(t.source, cfg.device, t.source_checkpoint)
        _check_shared(source.cfg.task, source.cfg.env, cfg.task, cfg.env)
        if isinstance(source.agent.loss, SoftOptionCriticLoss):
            raise UsageError(f"sf-gpi evaluates a SAC or TD3 source's actor; transfer.source '{t.source}' is a soft "
                             "option-critic run, whose policy acts through its options.")
        check_same_spaces(source.env, env, f"transfer.source '{t.source}' ({source.cfg.task})", f"task '{cfg.task}'")
        target_env = getattr(env, "base_env", env)
        source_goal, goal = source.env.goal.tolist(), target_env.goal.tolist()
        features = GoalFeatures.for_env(target_env, [source_goal] + ([goal] if goal != source_goal else []))
        discrete = isinstance(env.full_action_spec_unbatched["action"], OneHot)
        critic, frames, problem, plateau = _successor_feature_problem(cfg, source, features, discrete)
    problem.key = key
    w = features.task_weights(goal, target_env.step_cost)
    if discrete:
        own = [TensorDictModule(_learner_values(agent.loss), in_keys=["observation"], out_keys=[OWN_VALUES])]
        gpi = GPIPolicy([critic], w, own_value_key=OWN_VALUES)
    else:
        own = []
        gpi = GPIPolicy([critic], w, policies=[source.agent.actor], include_action=True,
                        own_values=_learner_candidate_values(agent.loss))
    explore = EGreedyModule(env.full_action_spec_unbatched["action"], eps_init=float(t.sf_epsilon),
                            eps_end=float(t.sf_epsilon), device=cfg.device)
    keep = TensorDictModule(lambda action: action.clone(), in_keys=["action"], out_keys=["gpi_action"])
    mixer = TensorDictSequential(*own, gpi, keep, explore,
                                 TensorDictModule(_chose_source, in_keys=["gpi_index", "action", "gpi_action"],
                                                  out_keys=["reused"]))
    def finish(steps: int, stopped: bool) -> dict:
        """psi as TD left it, into GPI's copy of the critic; what TD did, for the summary."""
        with torch.no_grad():
            TensorDict.from_module(gpi.critics[0]).update_(TensorDict.from_module(critic))
        return {"successor_feature_td": {"updates": steps, "stopped": "plateau" if stopped else "sf_updates",
                                         "block_means": [float(f"{m:.4g}") for m in plateau.means]}}

    problem.finish = finish
    return Transfer(mixer=mixer, mixer_reads_learner=True, pretraining=problem,
                    summary={"successor_feature_frames": frames, "gpi_weights": [round(x, 6) for x in w.tolist()]})


SF_GPI = TransferMethod(
    "sf-gpi",
    "successor features of the source policy valued on the target's reward; the collector acts by GPI",
    _build,
    source="run",
    algos=("sac",),
    takes=("policy",),
    grouped=True,  # seed k's GPI over its own source's psi and its own live critics, on its own envs
    check=_check,
    options={
        "sf_frames": (Int, Field(10_000, ge=1, description="sf-gpi: frames the source policy acts in the source "
                                                           "task to learn its successor features")),
        "sf_updates": (Int, Field(20_000, ge=1, description="sf-gpi: TD steps on them (fewer if sf_patience stops "
                                                            "TD first)")),
        "sf_block": (Int, Field(500, ge=1, description="sf-gpi: TD steps over which the relative TD error is "
                                                       "averaged for the plateau rule")),
        "sf_patience": (Int, Field(0, ge=0, description="sf-gpi: blocks in a row whose relative TD error does not "
                                                        "fall that stop TD (0: no plateau rule)")),
        "sf_tolerance": (Float, Field(0.01, ge=0, lt=1, description="sf-gpi: the share below the lowest block "
                                                                    "mean so far a block must fall to")),
        "sf_epsilon": (Probability, Field(0.1, description="sf-gpi: probability of a uniform random action in "
                                                           "place of GPI's (epsilon-greedy)",
                                json_schema_extra={"absent": 0.0})),  # runs saved before it acted greedily
    },
    search={"sf_epsilon": (0.1, 0.05, 0.2)},
    member_options=("sf_frames", "sf_updates", "sf_block", "sf_patience", "sf_tolerance", "sf_epsilon"),
)
