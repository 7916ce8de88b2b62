r"""Generalised policy improvement (GPI) over source policies' successor features (Barreto et al. 2017).

Source policy :math:`\pi_i`'s successor features :math:`\psi_i` value it on any task of the family:
:math:`Q_i(s, a) = \psi_i(s, a)^\top w` for the target's weights ``w``. GPI acts by the best of them:

.. math::

    \pi_{GPI}(s) \in \arg\max_a \max_i Q_i(s, a)

and then :math:`Q^{\pi_{GPI}}_w \ge \max_i Q^{\pi_i}_w` everywhere (Barreto et al. 2017, theorem 1; with
approximate :math:`\psi_i` the loss is bounded by their error). With discrete actions the max runs over
every action. With continuous actions it runs over candidate actions, each source policy's own
:math:`a_j = \pi_j(s)` (and, optionally, the action already in the tensordict, e.g. the learner's):

.. math::

    \pi_{GPI}(s) = a_{j^*}, \qquad j^* = \arg\max_j \max_i \psi_i(s, a_j)^\top w

(Barreto et al. 2018); the guarantee holds, since the candidates include every :math:`\pi_i(s)`. The
learner's own values may join the library as one more :math:`Q_i` (discrete: ``own_value_key``; continuous:
``own_values`` of the candidates), so GPI acts over every policy it holds, the learner included.

The module is stateless and draws nothing: it writes the greedy GPI action, chosen per batch element
with ``argmax``/``gather`` (as TorchRL's ``EGreedyModule`` chooses with ``torch.where``). Exploration is
composed around it (the sf-gpi method follows it with TorchRL's ``EGreedyModule``: epsilon-greedy GPI, as
Barreto et al. 2017's agents explore).
"""
from __future__ import annotations

import copy
from collections.abc import Sequence

import torch
from tensordict import NestedKey, TensorDictBase
from tensordict.nn import TensorDictModuleBase
from torch import nn
from torchrl.envs.utils import ExplorationType, set_exploration_type

from drltg.errors import UsageError

__all__ = ["GPIPolicy"]


class GPIPolicy(TensorDictModuleBase):
    """Acts by GPI over successor-feature critics (see the module docstring for the equations).

    Args:
        critics: the source policies' successor-feature critics (:func:`~drltg.modules.make_sf_critic`),
            all discrete (``psi(s)`` ``[*, A, d]``) or all continuous (``psi(s, a)`` ``[*, d]``).
        weights: the target task's ``w``, ``[d]`` (:meth:`~drltg.modules.GoalFeatures.task_weights` or
            :func:`~drltg.modules.regress_weights`); change it with :meth:`set_weights`.

    Keyword Args:
        policies: for continuous critics, the source policies ``pi_j`` (TensorDict modules writing
            ``action``, run under ``ExplorationType.DETERMINISTIC``) whose actions are the candidates.
        include_action: continuous: also weigh the action already in the tensordict (chain this module
            after the learner's policy); its index is ``len(policies)``.
        own_value_key: discrete: an entry ``[*, A]`` of the learner's own action values, taken as one more
            ``Q_i`` (index ``len(critics)``) when it is present.
        own_values: continuous: ``own_values(tensordict, candidates) -> [*, J]``, the learner's own values of
            the candidate actions ``[*, J, action_dim]``, taken as one more ``Q_i`` (index ``len(critics)``).
        action_key: where the action is written (one-hot for discrete critics).
        index_key: where the chosen policy's index is written, int64 ``[*, 1]``: discrete, the ``i`` of
            the best ``Q_i`` at the chosen action; continuous, the ``j`` whose action was chosen.
        value_key: where ``max_i Q_i`` at the chosen action is written, ``[*, 1]``.
        features_key: the entry the critics write psi to. Defaults to ``"successor_features"``.

    The critics and policies are copied and frozen; they are not trained through this module.
    """

    def __init__(
        self,
        critics: Sequence[TensorDictModuleBase],
        weights: torch.Tensor,
        *,
        policies: Sequence[TensorDictModuleBase] | None = None,
        include_action: bool = False,
        own_value_key: NestedKey | None = None,
        own_values=None,
        action_key: NestedKey = "action",
        index_key: NestedKey = "gpi_index",
        value_key: NestedKey = "gpi_value",
        features_key: NestedKey = "successor_features",
    ) -> None:
        super().__init__()
        critics = list(critics)
        if not critics:
            raise UsageError("GPI needs at least one source critic.")
        kinds = {action_key in c.in_keys for c in critics}
        if len(kinds) != 1:
            raise UsageError("GPI's critics must be all discrete (psi(s)) or all continuous (psi(s, a)).")
        self.discrete = not kinds.pop()
        if self.discrete and (policies is not None or include_action):
            raise UsageError("discrete GPI maximises over every action: it takes no policies or include_action.")
        if self.discrete and own_values is not None:
            raise UsageError("discrete GPI reads the learner's own values from own_value_key, not own_values.")
        if not self.discrete and not policies and not include_action:
            raise UsageError("continuous GPI needs candidate actions: the source policies (policies=) "
                             "or include_action=True.")
        self.critics = nn.ModuleList(copy.deepcopy(c).requires_grad_(False).eval() for c in critics)
        self.policies = nn.ModuleList(copy.deepcopy(p).requires_grad_(False).eval() for p in policies or ())
        self.include_action = include_action
        self.own_value_key = own_value_key
        self.own_values = own_values
        self.action_key, self.index_key, self.value_key, self.features_key = (
            action_key, index_key, value_key, features_key)
        self.register_buffer("weights", torch.as_tensor(weights, dtype=torch.float32).clone())
        reads = [k for m in (*self.critics, *self.policies) for k in m.in_keys if k != action_key]
        if include_action:
            reads.append(action_key)
        if own_value_key is not None:
            reads.append(own_value_key)
        self.in_keys = list(dict.fromkeys(reads))
        self.out_keys = [action_key, index_key, value_key]

    def set_weights(self, weights: torch.Tensor) -> None:
        """Set the target task's ``w`` (e.g. after a new reward regression)."""
        self.weights.copy_(torch.as_tensor(weights, dtype=self.weights.dtype))

    def candidates(self, tensordict: TensorDictBase) -> torch.Tensor:
        """Continuous: the candidate actions ``[*, J, action_dim]``, the policies' then the tensordict's."""
        acts = []
        with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
            for policy in self.policies:
                acts.append(policy(tensordict.select(*policy.in_keys).copy()).get(self.action_key))
        if self.include_action:
            acts.append(tensordict.get(self.action_key))
        return torch.stack(acts, -2)

    def action_values(self, tensordict: TensorDictBase, candidates: torch.Tensor | None = None) -> torch.Tensor:
        """``Q_i(s, a) = psi_i(s, a) . w``: discrete ``[*, I, A]`` (every action), continuous ``[*, I, J]`` (the
        candidate actions); the learner's own values last, where it has them."""
        w = self.weights
        values = []
        with torch.no_grad():
            for critic in self.critics:
                keys = [k for k in critic.in_keys if k != self.action_key]
                td = tensordict.select(*keys)
                if not self.discrete:
                    n = candidates.shape[-2]
                    td = td.unsqueeze(-1).expand(*td.batch_size, n).clone(False)
                    td.set(self.action_key, candidates)
                values.append(critic(td).get(self.features_key) @ w.to(tensordict.device or w.device))
            if self.discrete and self.own_value_key is not None and self.own_value_key in tensordict.keys(True):
                values.append(tensordict.get(self.own_value_key).to(values[0].dtype))
            if not self.discrete and self.own_values is not None:
                values.append(self.own_values(tensordict, candidates).to(values[0].dtype))
        return torch.stack(values, -2)

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        candidates = None if self.discrete else self.candidates(tensordict)
        q = self.action_values(tensordict, candidates)
        best, source = q.max(-2)  # max over policies i, per action (candidate)
        value, choice = best.max(-1, keepdim=True)  # the best action (candidate)
        if self.discrete:
            index = source.gather(-1, choice)
            action = nn.functional.one_hot(choice.squeeze(-1), q.shape[-1])
            old = tensordict.get(self.action_key, None)
            if old is not None:
                action = action.to(old.dtype)
        else:
            index = choice
            gather = choice.unsqueeze(-1).expand(*choice.shape, candidates.shape[-1])
            action = candidates.gather(-2, gather).squeeze(-2)
        return tensordict.update({self.action_key: action, self.index_key: index, self.value_key: value})
