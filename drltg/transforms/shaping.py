"""Potential-based reward shaping as a TorchRL transform (Ng, Harada & Russell 1999).

Adding ``F(s, s') = gamma * Phi(s') - Phi(s)`` to every reward leaves the optimal policy unchanged for
any potential ``Phi``, while a potential that grows towards the goal gives a dense learning signal on a
sparse task. A terminal state's potential is zero (an episode that ends at the goal must not be charged
``-Phi(s)`` for leaving a non-zero potential behind); a truncated episode keeps ``Phi(s')`` because the
learner still bootstraps from ``s'``.

Dynamic potentials (Devlin & Kudenko 2012) ``Phi(s, t)`` keep the guarantee with
``F = gamma * Phi(s', t') - Phi(s, t)``, where each potential is evaluated once, at the time its state is
reached. The transform does exactly that: it stores ``Phi(s')`` in the TensorDict when ``s'`` is reached
and reads it back as ``Phi(s)`` on the next step, so a potential that reads ``step_count``, or one whose
parameters change during training, is never re-evaluated later with another ``t``.
"""
from __future__ import annotations

from typing import Callable, Sequence

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModuleBase
from tensordict.utils import NestedKey
from torchrl.data import Composite, Unbounded
from torchrl.envs import Transform

Potential = Callable[..., torch.Tensor]


class PotentialShaping(Transform):
    """Adds ``gamma * Phi(s') * (1 - terminated) - Phi(s)`` to the reward.

    Args:
        potential: the potential ``Phi``, one of
            - a ``TensorDictModule``: called on the observation entries it reads, its first out-key is
              ``Phi``;
            - a callable with ``in_keys`` (passed here, or its own ``in_keys`` attribute as on
              drltg's potentials): called as ``potential(*[td[k] for k in in_keys])``;
            - a callable without ``in_keys``: called as ``potential(td)``.
            It returns one value per batch element, shaped like the reward (``[*batch, 1]``).
        gamma: the learner's discount; shaping preserves the optimal policy only for this gamma.
        in_keys: the observation entries passed to a plain callable ``potential`` (default: its
            ``in_keys`` attribute if it has one).
        reward_key: the reward to shape in place.
        task_reward_key: where the unshaped reward is kept (``("next", task_reward_key)``), so that
            logging and evaluation can use the true task reward. Registered as an observation entry
            (zero after a reset), like ``RewardSum``'s ``episode_reward``.
        potential_key: where ``Phi`` of the current state is kept (root after reset, ``("next", ...)``
            after a step). Registered as an observation and a state entry, so the value survives
            ``step_mdp``, partial resets and batched-env workers.

    The shaped reward spec becomes ``Unbounded`` (shaping moves rewards outside any original bounds).
    A ``RewardSum`` placed before this transform sums the task's reward, one placed after it the
    shaped reward. Dynamic potentials that read ``step_count`` need it in the TensorDict at reset
    (drltg's envs keep it; otherwise put ``StepCounter`` before this transform).

    Examples:
        >>> env = TransformedEnv(base_env, PotentialShaping(lambda x: -x.norm(dim=-1, keepdim=True),
        ...                                                 gamma=0.99, in_keys=["observation"]))
        >>> td = env.rollout(10)
        >>> td["next", "reward"], td["next", "task_reward"]  # shaped, unshaped
    """

    def __init__(
        self,
        potential: Potential | TensorDictModuleBase,
        gamma: float,
        *,
        in_keys: Sequence[NestedKey] | None = None,
        reward_key: NestedKey = "reward",
        task_reward_key: NestedKey = "task_reward",
        potential_key: NestedKey = "potential",
    ):
        if not 0.0 <= gamma <= 1.0:
            raise ValueError(f"gamma must lie in [0, 1], got {gamma}.")
        if isinstance(potential, TensorDictModuleBase):
            if in_keys is not None:
                raise ValueError("in_keys are taken from the TensorDictModule potential; do not pass them.")
            in_keys = list(potential.in_keys)
        elif in_keys is None:
            in_keys = getattr(potential, "in_keys", None)
        super().__init__(in_keys=[reward_key], out_keys=[reward_key, task_reward_key, potential_key])
        self.potential = potential
        self.potential_in_keys = None if in_keys is None else list(in_keys)
        self.gamma = float(gamma)
        self.reward_key = reward_key
        self.task_reward_key = task_reward_key
        self.potential_key = potential_key

    def potential_of(self, tensordict: TensorDictBase) -> torch.Tensor:
        """``Phi`` of the states held at the root of ``tensordict``."""
        if isinstance(self.potential, TensorDictModuleBase):
            out = self.potential(tensordict.select(*self.potential_in_keys))
            return out.get(self.potential.out_keys[0])
        if self.potential_in_keys is not None:
            return self.potential(*(tensordict.get(key) for key in self.potential_in_keys))
        return self.potential(tensordict)

    def _shape(self, phi: torch.Tensor, next_tensordict: TensorDictBase) -> TensorDictBase:
        reward = next_tensordict.get(self.reward_key)
        phi_next = self.potential_of(next_tensordict).reshape(reward.shape).to(reward.dtype)
        terminated = next_tensordict.get("terminated", None)
        if terminated is None:
            terminated = next_tensordict.get("done")
        terminated = terminated.reshape(reward.shape)
        shaped = reward + self.gamma * phi_next.masked_fill(terminated, 0.0) - phi.reshape(reward.shape)
        next_tensordict.set(self.task_reward_key, reward)
        next_tensordict.set(self.potential_key, phi_next)
        next_tensordict.set(self.reward_key, shaped)
        return next_tensordict

    def _step(self, tensordict: TensorDictBase, next_tensordict: TensorDictBase) -> TensorDictBase:
        phi = tensordict.get(self.potential_key, None)
        if phi is None:
            phi = self.potential_of(tensordict)
        return self._shape(phi, next_tensordict)

    def _reset(self, tensordict: TensorDictBase, tensordict_reset: TensorDictBase) -> TensorDictBase:
        reward_spec = self.parent.full_reward_spec[self.reward_key]
        tensordict_reset.set(self.task_reward_key, reward_spec.zero())
        phi = self.potential_of(tensordict_reset).reshape(reward_spec.shape).to(reward_spec.dtype)
        tensordict_reset.set(self.potential_key, phi)
        return tensordict_reset

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        """Shapes stored transitions (root ``s``, ``("next", ...)`` ``s'``), e.g. as a replay-buffer
        transform; ``Phi(s)`` is recomputed from the root observation."""
        self._shape(self.potential_of(tensordict), tensordict.get("next"))
        return tensordict

    def _potential_spec(self, reward_spec) -> Unbounded:
        return Unbounded(shape=reward_spec.shape, dtype=reward_spec.dtype, device=reward_spec.device)

    def transform_reward_spec(self, reward_spec: Composite) -> Composite:
        reward_spec[self.reward_key] = self._potential_spec(reward_spec[self.reward_key])
        return reward_spec

    def transform_observation_spec(self, observation_spec: Composite) -> Composite:
        reward_spec = self.parent.full_reward_spec[self.reward_key]
        observation_spec[self.task_reward_key] = reward_spec.clone()
        observation_spec[self.potential_key] = self._potential_spec(reward_spec)
        return observation_spec

    def transform_state_spec(self, state_spec: Composite) -> Composite:
        reward_spec = self.parent.full_reward_spec[self.reward_key]
        state_spec[self.potential_key] = self._potential_spec(reward_spec)
        return state_spec

    def __repr__(self) -> str:
        return f"{type(self).__name__}(gamma={self.gamma}, potential={self.potential!r})"


class TimeDependentPotential(torch.nn.Module):
    """A dynamic potential ``Phi(s, t) = schedule(t) * Phi(s)`` (Devlin & Kudenko 2012).

    ``t`` is the step within the episode (``step_count``, 0 after a reset), so the shaping term is
    ``F = gamma * schedule(t + 1) * Phi(s') - schedule(t) * Phi(s)``. Along any episode the discounted
    sum of ``F`` telescopes to ``-Phi(s_0, 0)`` (plus ``gamma^N Phi(s_N, N)`` at a truncation, which the
    learner's bootstrap absorbs), the same for every policy, so the ranking of policies is unchanged.
    Use it, e.g., to fade a heuristic out as the episode goes on.

    Args:
        potential: the static potential, a callable on the observation tensors.
        schedule: maps ``step_count`` (int64, ``[*batch, 1]``) to a weight of the same shape.
        step_count_key: the entry holding ``t``, read last; ``in_keys`` are the static potential's
            ``in_keys`` (if it has them) followed by this key.

    Examples:
        >>> fade = TimeDependentPotential(FourRoomsPotential(goal), lambda t: (1 - t / 100).clamp_min(0))
        >>> PotentialShaping(fade, gamma=0.99)  # reads "position" and "step_count"
    """

    def __init__(
        self,
        potential: Callable[..., torch.Tensor],
        schedule: Callable[[torch.Tensor], torch.Tensor],
        *,
        step_count_key: str = "step_count",
    ):
        super().__init__()
        self.potential = potential
        self.schedule = schedule
        if hasattr(potential, "in_keys"):
            self.in_keys = [*potential.in_keys, step_count_key]

    def forward(self, *observation_and_step_count: torch.Tensor) -> torch.Tensor:
        *observation, step_count = observation_and_step_count
        return self.schedule(step_count) * self.potential(*observation)
