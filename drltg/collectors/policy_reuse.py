"""Probabilistic policy reuse: a policy mixer chained after the learner's policy.

In every episode, with probability psi_h the action comes from a past (source) policy and otherwise
from the learner's own exploration (Fernandez & Veloso 2006, pi-reuse):

    psi_h = psi * upsilon ** h,        h = steps since the episode started (``step_count``)

so the past policy guides the start of every episode and hands over to the learner as the episode
goes on. The mixer is a schedule-driven ``torch.where`` per environment, like TorchRL's
``EGreedyModule``; the schedule says how likely reuse is at step h, and, for a library of past
policies, which one an episode reuses:

- :class:`PiReuse`: psi * upsilon^h, with an optional linear decay of psi over training;
- :class:`JumpStart`: the guide acts for the first H steps, H shrinking on a curriculum that advances when
  the combined policy's evaluated return holds near its best (JSRL, Uchendu et al. 2023);
- :class:`PRQL`: a library of past policies; each episode reuses policy k with probability
  softmax(tau * W)_k, W_k being its average return when reused (Fernandez & Veloso 2006).

Off-policy learners only. The behaviour policy (past policy mixed with the learner) is not the
learner's policy, so the collected actions are not samples of pi_theta: an on-policy loss (PPO, A2C)
would weigh them with log-probabilities of a policy that did not choose them and follow a biased
gradient. Off-policy losses (SAC, TD3, soft option-critic, DQN) learn from any behaviour's
transitions in the replay buffer, which is exactly what reuse provides.
"""
from __future__ import annotations

import copy
import math
from collections.abc import Sequence

import torch
from tensordict import NestedKey, TensorDictBase
from tensordict.nn import TensorDictModuleBase
from tensordict.utils import expand_as_right
from torch import nn
from torchrl.data import Composite, TensorSpec, Unbounded
from torchrl.envs import TensorDictPrimer
from torchrl.envs.utils import ExplorationType, exploration_type, set_exploration_type

from drltg.errors import ArgumentError, UsageError

__all__ = ["PolicyReuse", "ReuseSchedule", "PiReuse", "JumpStart", "PRQL"]

NOT_CHOSEN = -1
"""``reuse_index`` of an episode whose past policy is not drawn yet (set by the primer at reset)."""


class ReuseSchedule(nn.Module):
    """When to reuse: psi_h per environment, and which past policy an episode reuses.

    Training progress (frames collected) is a buffer, so it is saved with the module's
    ``state_dict`` and a resumed run continues the same schedule.
    """

    def __init__(self) -> None:
        super().__init__()
        self.register_buffer("frames", torch.zeros((), dtype=torch.long))

    def set_progress(self, frames: int) -> None:
        """Set training progress to ``frames`` collected frames."""
        self.frames.fill_(frames)

    def probability(self, step_count: torch.Tensor) -> torch.Tensor:
        """psi_h, the probability of reusing at step ``step_count`` of the episode (same shape)."""
        raise NotImplementedError

    def attach(self, num_policies: int) -> None:
        """Called by the mixer with the size of its library of past policies."""
        if num_policies != 1:
            raise UsageError(
                f"{type(self).__name__} reuses one past policy but {num_policies} were given; "
                "use the PRQL schedule to choose among several."
            )

    def choose(self, n: int, device: torch.device, generator: torch.Generator | None = None) -> torch.Tensor:
        """Index of the past policy for ``n`` new episodes (== the library size: the learner's own)."""
        return torch.zeros(n, dtype=torch.long, device=device)

    def observe(self, index, step_count, reward, done) -> None:  # noqa: B027
        """Learn from collected transitions, time last (only schedules that learn use it)."""


class PiReuse(ReuseSchedule):
    """psi_h = psi_t * upsilon^h (Fernandez & Veloso 2006).

    psi_t goes linearly from ``psi`` to ``psi_end`` over the first ``annealing_frames`` training
    frames (no decay across training by default).

    Args:
        psi: probability of reusing at the first step of an episode. Default 1.
        upsilon: decay of psi within an episode, in [0, 1]. Default 0.95.
        psi_end: psi after ``annealing_frames`` frames. Default ``psi`` (no decay).
        annealing_frames: frames over which psi decays to ``psi_end``.
    """

    def __init__(
        self,
        psi: float = 1.0,
        upsilon: float = 0.95,
        *,
        psi_end: float | None = None,
        annealing_frames: int = 0,
    ) -> None:
        super().__init__()
        psi_end = psi if psi_end is None else psi_end
        for name, value in (("psi", psi), ("upsilon", upsilon), ("psi_end", psi_end)):
            if not 0.0 <= value <= 1.0:
                raise ArgumentError(name, f"must lie in [0, 1], got {value}.")
        if psi_end != psi and annealing_frames <= 0:
            raise ArgumentError("psi_end", "needs annealing_frames > 0, the frames over which psi decays.")
        self.psi_init, self.psi_end, self.upsilon = psi, psi_end, upsilon
        self.annealing_frames = annealing_frames

    @property
    def psi(self) -> torch.Tensor:
        """psi at the current training progress."""
        if self.annealing_frames <= 0:
            return torch.tensor(self.psi_init, device=self.frames.device)
        fraction = (self.frames / self.annealing_frames).clamp(max=1.0)
        return self.psi_init + (self.psi_end - self.psi_init) * fraction

    def probability(self, step_count: torch.Tensor) -> torch.Tensor:
        upsilon = torch.tensor(self.upsilon, device=step_count.device)
        return self.psi * upsilon.pow(step_count)


class JumpStart(ReuseSchedule):
    """The guide acts for the first H steps of each episode, H shrinking on a curriculum (JSRL, Uchendu et al.
    2023, "Jump-Start Reinforcement Learning", JSRL-Curriculum).

    H takes ``stages`` equal steps down to 0, the learner alone: H_k = guide_steps * (stages - k) // stages,
    k = 0 .. stages. JSRL moves to the next stage when the combined policy (the guide for H steps, then the
    learner) performs as well as it ever did: after every evaluation of it, with R the mean of its last
    ``window`` evaluated returns at this stage and B the best such mean before (of any stage),

        k <- k + 1    if  R >= B - tolerance * |B|,          B <- max(B, R)

    (the first evaluation only sets B; a stage's window starts empty, so a stage lasts ``window`` evaluations at
    least). Tell it each evaluation with :meth:`evaluated`; evaluate the combined policy by chaining the learner's
    actor and a :class:`PolicyReuse` built with ``mix_deterministic=True``.

    ``frames_per_stage`` instead advances on a fixed clock, one stage every ``frames_per_stage`` training
    frames (k = min(frames // frames_per_stage, stages)), whatever the returns.

    The stage, B and the window are buffers: a checkpoint of the module's ``state_dict`` resumes the curriculum.
    """

    def __init__(self, guide_steps: int, *, stages: int = 10, tolerance: float = 0.05, window: int = 1,
                 frames_per_stage: int | None = None) -> None:
        super().__init__()
        if guide_steps < 0 or stages < 1 or window < 1 or tolerance < 0 or (
                frames_per_stage is not None and frames_per_stage < 1):
            raise UsageError("JumpStart needs guide_steps >= 0, stages >= 1, window >= 1, tolerance >= 0 and "
                             "frames_per_stage >= 1 (or None).")
        self.guide_steps, self.stages, self.frames_per_stage = guide_steps, stages, frames_per_stage
        self.tolerance, self.window = tolerance, window
        self.register_buffer("stage", torch.zeros((), dtype=torch.long))
        self.register_buffer("best", torch.tensor(-math.inf, dtype=torch.float64))
        self.register_buffer("returns", torch.full((window,), math.nan, dtype=torch.float64))

    @property
    def current_stage(self) -> int:
        """k, the stage reached (of 0 .. ``stages``)."""
        if self.frames_per_stage is not None:
            return min(int(self.frames) // self.frames_per_stage, self.stages)
        return int(self.stage)

    @property
    def horizon(self) -> int:
        """H, the number of guided steps at the current stage."""
        return self.guide_steps * (self.stages - self.current_stage) // self.stages

    def evaluated(self, value: float) -> bool:
        """Take the combined policy's mean evaluated return at the current stage; returns whether the curriculum
        moved to the next stage. A clock-driven curriculum (``frames_per_stage``) ignores it."""
        if self.frames_per_stage is not None or int(self.stage) >= self.stages:
            return False
        self.returns.copy_(torch.cat([self.returns[1:], self.returns.new_tensor([float(value)])]))
        if self.returns.isnan().any():  # fewer than ``window`` evaluations at this stage
            return False
        mean, best = self.returns.mean(), self.best.clone()
        advance = bool(torch.isfinite(best)) and bool(mean >= best - self.tolerance * best.abs())
        self.best.copy_(torch.maximum(best, mean))
        if advance:
            self.stage += 1
            self.returns.fill_(math.nan)
        return advance

    def probability(self, step_count: torch.Tensor) -> torch.Tensor:
        return (step_count < self.horizon).to(torch.get_default_dtype())


class PRQL(ReuseSchedule):
    """Choose, per episode, which past policy to reuse (Fernandez & Veloso 2006, PRQL).

    The choices are the K past policies and the learner itself (index K). Episode choice:

        P(k) = exp(tau * W_k) / sum_j exp(tau * W_j)

    where W_k is the average discounted return sum_h gamma^h r_h of the episodes that chose k
    (W_k <- (W_k * U_k + R) / (U_k + 1), U_k <- U_k + 1), and tau grows by ``tau_step`` after every
    episode, so the choice turns greedy as the estimates firm up. Within an episode that reuses k,
    ``schedule`` (default :class:`PiReuse`) gives psi_h; an episode that chose the learner never reuses.
    Feed collected batches to :meth:`PolicyReuse.observe` so W is learnt.
    """

    def __init__(
        self,
        schedule: ReuseSchedule | None = None,
        *,
        tau: float = 0.0,
        tau_step: float = 0.05,
        gamma: float = 0.99,
    ) -> None:
        super().__init__()
        self.schedule = PiReuse() if schedule is None else schedule
        self.tau_step, self.gamma = tau_step, gamma
        self.register_buffer("tau", torch.tensor(float(tau)))
        self.register_buffer("gain", torch.zeros(0))
        self.register_buffer("uses", torch.zeros(0, dtype=torch.long))
        self._returns: torch.Tensor | None = None

    def attach(self, num_policies: int) -> None:
        self.gain = torch.zeros(num_policies + 1, device=self.tau.device)
        self.uses = torch.zeros(num_policies + 1, dtype=torch.long, device=self.tau.device)

    def set_progress(self, frames: int) -> None:
        super().set_progress(frames)
        self.schedule.set_progress(frames)

    def probability(self, step_count: torch.Tensor) -> torch.Tensor:
        return self.schedule.probability(step_count)

    def choice_probabilities(self) -> torch.Tensor:
        """P(k) for k = 0..K (the last one is the learner's own policy)."""
        return torch.softmax(self.tau * self.gain, dim=0)

    def choose(self, n: int, device: torch.device, generator: torch.Generator | None = None) -> torch.Tensor:
        return torch.multinomial(self.choice_probabilities(), n, replacement=True, generator=generator).to(device)

    def update(self, index: torch.Tensor, returns: torch.Tensor) -> None:
        """Add finished episodes, in order: the policy each chose and its discounted return."""
        for k, ret in zip(index.tolist(), returns.tolist()):
            self.gain[k] = (self.gain[k] * self.uses[k] + ret) / (self.uses[k] + 1)
            self.uses[k] += 1
            self.tau += self.tau_step

    def observe(self, index, step_count, reward, done) -> None:
        if self._returns is None or self._returns.shape != reward.shape[:-1]:
            self._returns = torch.zeros(reward.shape[:-1], device=reward.device)
        for t in range(reward.shape[-1]):
            self._returns += self.gamma ** step_count[..., t].to(reward.dtype) * reward[..., t]
            finished = done[..., t]
            if finished.any():
                self.update(index[..., t][finished], self._returns[finished])
                self._returns[finished] = 0.0


class PolicyReuse(TensorDictModuleBase):
    """Mixes the learner's action with a past policy's action, per environment.

    Chain it after the learner's exploration policy, add its primer to the environment, and give the
    result to a ``Collector``::

        reuse = PolicyReuse(source_actor, spec=env.action_spec_unbatched)
        env = env.append_transform(reuse.primer())
        policy = TensorDictSequential(actor, reuse)

    Per environment, with probability psi_h (from ``schedule``) the action is the past policy's
    deterministic action (its mean/greedy action, under ``ExplorationType.DETERMINISTIC``);
    otherwise it is the learner's action, itself replaced with probability ``epsilon`` by an action
    drawn uniformly from ``spec`` (epsilon-greedy, for a deterministic learner). ``h`` is read from
    ``step_count`` (drltg environments and TorchRL's ``StepCounter`` write it), so psi_h restarts at
    every episode start, per environment. Under any exploration type other than RANDOM (e.g.
    evaluation under DETERMINISTIC) the learner's action passes through unchanged, unless
    ``mix_deterministic``: then the mixer mixes there too, without ``epsilon`` (the combined policy of the
    learner's and the past policy's deterministic actions, which JSRL evaluates).

    The episode's choice of past policy is environment state, not module state: ``reuse_index``
    (int64 [*, 1]) is declared by :meth:`primer`, which sets it to -1 ("not chosen yet") at every
    reset, partial resets included; the first step of an episode draws it from the schedule and the
    environment carries it to the next step, as soft option-critic's option. The module itself holds
    only training progress and what schedules learn (buffers, synchronised with the weights), so a
    copy in every collector worker acts exactly like the original. Every call writes ``reused`` (bool
    [*, 1]: the past policy acted) and ``reuse_index`` (K, the library size, when :class:`PRQL` chose
    the learner).

    The past policies are copied, frozen (no gradient) and never trained; they are not parameters
    of the learner, whose loss module is built from ``actor`` alone.

    Args:
        past_policy: a past policy, or a sequence of them (a library, for :class:`PRQL`).
        spec: the action spec, needed when ``epsilon > 0``.
        schedule: the reuse schedule. Default ``PiReuse(psi=1, upsilon=0.95)``.
        epsilon: probability of a uniform random action when the learner acts. Default 0 (the
            learner's stochastic action is its exploration).
        generator: the random generator of the episode choices (default: torch's global one).
        mix_deterministic: also mix under a DETERMINISTIC exploration type (evaluating the combined policy).

    Call :meth:`set_progress` with the frames collected so far after each batch (schedules that decay
    over training), and :meth:`observe` with the batch as collected, before flattening (schedules that
    learn from returns). A ``Collector``'s ``init_random_frames`` replace the whole policy by random
    actions, so the past policy only starts acting after them.

    Only for off-policy learners: see the module docstring.
    """

    def __init__(
        self,
        past_policy: TensorDictModuleBase | Sequence[TensorDictModuleBase],
        *,
        spec: TensorSpec | None = None,
        schedule: ReuseSchedule | None = None,
        epsilon: float = 0.0,
        generator: torch.Generator | None = None,
        mix_deterministic: bool = False,
        action_key: NestedKey = "action",
        step_count_key: NestedKey = "step_count",
        reused_key: NestedKey = "reused",
        reuse_index_key: NestedKey = "reuse_index",
    ) -> None:
        super().__init__()
        policies = list(past_policy) if isinstance(past_policy, (list, tuple, nn.ModuleList)) else [past_policy]
        if not policies:
            raise UsageError("PolicyReuse needs at least one past policy.")
        for p in policies:
            if not isinstance(p, TensorDictModuleBase):
                raise UsageError(
                    f"a past policy must be a TensorDict module writing {action_key!r} (e.g. "
                    f"drltg.transfer.load_actor(run_dir)), not a {type(p).__name__}."
                )
        if not 0.0 <= epsilon <= 1.0:
            raise UsageError(f"epsilon must lie in [0, 1], got {epsilon}.")
        if epsilon > 0 and spec is None:
            raise UsageError("epsilon > 0 draws random actions from the action spec: pass spec=.")
        self.past_policies = nn.ModuleList(copy.deepcopy(p).requires_grad_(False).eval() for p in policies)
        self.schedule = PiReuse() if schedule is None else schedule
        self.schedule.attach(len(policies))
        self.spec = spec[action_key] if isinstance(spec, Composite) else spec
        self.epsilon = epsilon
        self.generator = generator
        self.mix_deterministic = mix_deterministic
        self.action_key, self.step_count_key = action_key, step_count_key
        self.reused_key, self.reuse_index_key = reused_key, reuse_index_key
        past_in_keys = [k for p in self.past_policies for k in p.in_keys]
        self.in_keys = list(dict.fromkeys([*past_in_keys, step_count_key, reuse_index_key, action_key]))
        self.out_keys = [action_key, reused_key, reuse_index_key]

    def primer(self) -> TensorDictPrimer:
        """The environment transform that declares ``reuse_index`` and sets it to -1 at every reset."""
        spec = Unbounded(shape=(1,), dtype=torch.int64)
        return TensorDictPrimer({self.reuse_index_key: spec}, default_value=NOT_CHOSEN, expand_specs=True)

    def set_progress(self, frames: int) -> None:
        """Set the schedule's training progress to ``frames`` collected frames."""
        self.schedule.set_progress(frames)

    def step(self, frames: int = 1) -> None:
        """Advance the schedule by ``frames`` newly collected frames, as TorchRL's exploration modules
        (``EGreedyModule.step``) are advanced after each collected batch."""
        self.schedule.set_progress(int(self.schedule.frames) + frames)

    def observe(self, batch: TensorDictBase) -> None:
        """Learn from a collected batch (time is its last dimension), e.g. PRQL's reuse gains."""
        self.schedule.observe(
            batch.get(self.reuse_index_key).squeeze(-1),
            batch.get(self.step_count_key).squeeze(-1),
            batch.get(("next", "reward")).squeeze(-1),
            batch.get(("next", "done")).squeeze(-1),
        )

    def _episode_choice(self, tensordict: TensorDictBase) -> torch.Tensor:
        choice = tensordict.get(self.reuse_index_key, None)
        if choice is None:
            raise KeyError(
                f"PolicyReuse needs {self.reuse_index_key!r} in the tensordict: append its primer() to the "
                "environment, e.g. env = env.append_transform(reuse.primer())."
            )
        choice = choice.squeeze(-1)
        new = choice == NOT_CHOSEN
        if new.any():
            drawn = self.schedule.choose(int(new.sum()), choice.device, self.generator)
            choice = choice.masked_scatter(new, drawn)
        return choice

    def _random_action(self, action: torch.Tensor) -> torch.Tensor:
        return self.spec.rand(action.shape[: action.ndim - self.spec.ndim]).to(action.device)

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        action = tensordict.get(self.action_key)
        shape = tensordict.batch_size
        exploring = exploration_type() in (ExplorationType.RANDOM, None)
        if not exploring and not self.mix_deterministic:
            return tensordict.set(self.reused_key, torch.zeros(*shape, 1, dtype=torch.bool, device=action.device))

        choice = self._episode_choice(tensordict)
        step_count = tensordict.get(self.step_count_key).squeeze(-1)
        psi = self.schedule.probability(step_count)
        reused = (torch.rand(shape, device=action.device) < psi) & (choice < len(self.past_policies))

        if self.epsilon > 0 and exploring:
            explore = torch.rand(shape, device=action.device) < self.epsilon
            action = torch.where(expand_as_right(explore, action), self._random_action(action), action)
        for k, past in enumerate(self.past_policies):
            acts = reused & (choice == k)
            if acts.any():
                with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
                    past_action = past(tensordict.select(*past.in_keys)).get(self.action_key)
                action = torch.where(expand_as_right(acts, action), past_action.to(action.dtype), action)
        return tensordict.update(
            {
                self.action_key: action,
                self.reused_key: reused.unsqueeze(-1),
                self.reuse_index_key: choice.unsqueeze(-1),
            }
        )
