r"""Successor features learnt by temporal differences (Barreto et al. 2017, 2018).

The successor features of a policy satisfy a Bellman equation with the features as the reward:

.. math::

    \psi^\pi(s, a) = \phi(s, a, s') + \gamma\,(1 - d')\,\psi^\pi(s', \pi(s'))

so they are learnt as a critic is, one ``d``-vector target per transition, with target parameters
:math:`\bar\psi` (``SoftUpdate``-compatible):

.. math::

    L = \textstyle\sum_{k=1}^{d} \ell\big(\psi_k(s, a) - [\phi_k + \gamma\,(1 - d')\,\bar\psi_k(s', a')]\big)

:math:`d'` is ``terminated`` at :math:`s'`, never ``done``: a horizon cut (``truncated``) still
bootstraps. The next action :math:`a'` is the evaluated policy's: a given policy module's deterministic
action (a trained source actor, continuous or discrete), or, for discrete actions without one,
:math:`a' = \arg\max_a \bar\psi(s', a)^\top w` for the source task's weights ``w`` (successor-feature
Q-learning: the policy greedy on its own task, learnt with its features).

What :math:`\psi` values follows the data's episodes: a source's transitions end at the source's
terminal states, so :math:`\psi_i^\top w` is the source policy's value for the reward ``w`` in episodes
that end where the source's do.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass

import torch
from tensordict import TensorDict, TensorDictBase, TensorDictParams
from tensordict.nn import TensorDictModule, TensorDictModuleBase, dispatch
from tensordict.utils import NestedKey
from torchrl.envs.utils import ExplorationType, set_exploration_type
from torchrl.objectives import LossModule
from torchrl.objectives.utils import ValueEstimators, default_value_kwargs, distance_loss

from drltg.losses.td_keys import TDKeys

__all__ = ["SuccessorFeatureLoss"]


class SuccessorFeatureLoss(LossModule):
    """TD learning of a successor-feature critic (see the module docstring for the equation).

    Args:
        sf_network: a successor-feature critic (:func:`~drltg.modules.make_sf_critic`). If it reads the
            action it is a continuous critic, ``psi(s, a)`` ``[*, d]``; otherwise a discrete one, ``psi(s)``
            ``[*, num_actions, d]``, indexed with the one-hot ``action``.

    Keyword Args:
        policy: the policy whose features are learnt, a TensorDict module writing ``action`` (run without
            gradient, under ``ExplorationType.DETERMINISTIC``, on ``("next", ...)``). Copied and frozen.
        weights: ``w`` of the source task, ``[d]``: for a discrete critic without ``policy``, the next action
            is greedy on ``psi_target(s', .) . w``.
        loss_function: ``"l2"`` (default), ``"l1"`` or ``"smooth_l1"``, per feature, summed over features.
        delay_value: use target parameters for ``psi(s', a')``. Defaults to ``True``.
        reduction: ``"mean"`` (default), ``"sum"`` or ``"none"`` over the batch.
        use_prioritized_weights: as in TorchRL's losses (``"auto"``: when ``priority_weight`` is in the batch).

    The discount is set with ``make_value_estimator(gamma=...)`` (TD(0); default 0.99). Reads ``action``,
    the critic's inputs at the root and under ``"next"``, ``("next", "features")`` (see
    :class:`~drltg.modules.GoalFeatures`) and ``("next", "terminated")``; writes ``td_error`` (the squared
    error summed over features) and returns ``loss_sf`` and ``sf_target_sq``, the batch's mean squared norm of
    the TD target (``loss_sf / sf_target_sq`` is the relative TD error, which does not grow as psi does). Use
    ``SoftUpdate(loss, tau=...)`` for the target.
    """

    @dataclass
    class _AcceptedKeys(TDKeys):
        """Tensordict keys the loss reads and writes (change them with ``.set_keys(...)``); ``priority``,
        ``done``, ``terminated`` and ``priority_weight`` as in :class:`~drltg.losses.td_keys.TDKeys`
        (``done`` is never used to stop bootstrapping).

        Attributes:
            action: the action taken (one-hot for a discrete critic). Defaults to ``"action"``.
            features: phi of the transition, read under ``"next"``. Defaults to ``"features"``.
            successor_features: the critic's output. Defaults to ``"successor_features"``.
        """

        action: NestedKey = "action"
        features: NestedKey = "features"
        successor_features: NestedKey = "successor_features"

    default_keys = _AcceptedKeys
    tensor_keys: _AcceptedKeys
    default_value_estimator = ValueEstimators.TD0
    out_keys = ["loss_sf"]

    sf_network: TensorDictModule
    sf_network_params: TensorDictParams
    target_sf_network_params: TensorDictParams

    def __init__(
        self,
        sf_network: TensorDictModule,
        *,
        policy: TensorDictModuleBase | None = None,
        weights: torch.Tensor | None = None,
        loss_function: str = "l2",
        delay_value: bool = True,
        reduction: str = "mean",
        use_prioritized_weights: str | bool = "auto",
    ) -> None:
        super().__init__()
        self.discrete = self.tensor_keys.action not in sf_network.in_keys
        if policy is None and not (self.discrete and weights is not None):
            raise ValueError("SuccessorFeatureLoss needs the evaluated policy (policy=) or, for a discrete critic, "
                             "the source task's weights (weights=) to act greedily on.")
        self.delay_value = delay_value
        self.convert_to_functional(sf_network, "sf_network", create_target_params=delay_value)
        self.policy = None if policy is None else copy.deepcopy(policy).requires_grad_(False).eval()
        self.register_buffer("weights", None if weights is None else torch.as_tensor(weights, dtype=torch.float32))
        self.loss_function = loss_function
        self.reduction = reduction
        self.use_prioritized_weights = use_prioritized_weights
        self.gamma = default_value_kwargs(ValueEstimators.TD0)["gamma"]

    def make_value_estimator(self, value_type: ValueEstimators | None = None, **hyperparams) -> SuccessorFeatureLoss:
        """Set the discount (``gamma=``) of the TD(0) target; TD(0) is the only estimator."""
        if value_type not in (None, ValueEstimators.TD0):
            raise NotImplementedError(f"SuccessorFeatureLoss uses a TD(0) target, not {value_type}.")
        self.value_type = ValueEstimators.TD0
        self.gamma = float(hyperparams.get("gamma", self.gamma))
        return self

    def _forward_value_estimator_keys(self, **kwargs) -> None:
        pass

    @property
    def in_keys(self) -> list[NestedKey]:
        keys = self.tensor_keys
        net = [k for k in self.sf_network.in_keys if k != keys.action]
        policy = [] if self.policy is None else list(self.policy.in_keys)
        return list(dict.fromkeys([keys.action, *net, *[("next", k) for k in (*net, *policy)],
                                   ("next", keys.features), ("next", keys.terminated)]))

    def _psi(self, tensordict: TensorDictBase, action: torch.Tensor, params: TensorDictParams) -> torch.Tensor:
        """``psi(s, a)`` ``[*, d]`` under ``params``."""
        keys = self.tensor_keys
        td = tensordict.select(*[k for k in self.sf_network.in_keys if k != keys.action])
        if not self.discrete:
            td.set(keys.action, action)
        with params.to_module(self.sf_network):
            psi = self.sf_network(td).get(keys.successor_features)
        if self.discrete:
            psi = (psi * action.unsqueeze(-1).to(psi.dtype)).sum(-2)
        return psi

    def _next_action(self, next_td: TensorDictBase, params: TensorDictParams) -> torch.Tensor:
        keys = self.tensor_keys
        if self.policy is not None:
            with set_exploration_type(ExplorationType.DETERMINISTIC):
                return self.policy(next_td.select(*self.policy.in_keys).copy()).get(keys.action)
        with params.to_module(self.sf_network):
            psi = self.sf_network(next_td.select(*self.sf_network.in_keys).copy()).get(keys.successor_features)
        q = psi @ self.weights.to(psi.dtype)
        return torch.nn.functional.one_hot(q.argmax(-1), q.shape[-1])

    @dispatch
    def forward(self, tensordict: TensorDictBase) -> TensorDict:
        keys = self.tensor_keys
        psi = self._psi(tensordict, tensordict.get(keys.action), self.sf_network_params)
        target_params = self.target_sf_network_params if self.delay_value else self.sf_network_params.detach()
        next_td = tensordict.get("next")
        with torch.no_grad():
            next_action = self._next_action(next_td, target_params)
            psi_next = self._psi(next_td, next_action, target_params)
            phi = next_td.get(keys.features).to(psi.dtype)
            alive = 1.0 - next_td.get(keys.terminated).to(psi.dtype)
            target = phi + self.gamma * alive * psi_next
        loss = distance_loss(psi, target, self.loss_function).sum(-1)
        with torch.no_grad():
            tensordict.set(keys.priority, (psi - target).pow(2).sum(-1, keepdim=True), inplace=True)
        weights = None
        if self.use_prioritized_weights in (True, "auto") and keys.priority_weight in tensordict.keys(True):
            weights = tensordict.get(keys.priority_weight).reshape(loss.shape)
        loss = self._reduce_loss(loss, tensordict=tensordict, weights=weights)
        out = TensorDict(loss_sf=loss, sf_target_sq=target.pow(2).sum(-1).mean())
        self._clear_weakrefs(tensordict, out, "sf_network_params", "target_sf_network_params")
        return out
