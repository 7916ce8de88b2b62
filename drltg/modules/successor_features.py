r"""Successor-feature critics: a policy's discounted sum of features, one critic for every task of a family.

.. math::

    \psi^\pi(s, a) = \mathbb E_\pi\big[\textstyle\sum_t \gamma^t \phi_{t+1} \mid s_0 = s, a_0 = a\big]

Its value is a ``d``-vector instead of a number: for any reward :math:`r = \phi^\top w`,
:math:`Q^\pi_w(s, a) = \psi^\pi(s, a)^\top w` (Barreto et al. 2017), so one critic values its policy on
every task of the family. Two shapes, as TorchRL's Q critics:

* discrete actions: ``psi(s)`` ``[*, num_actions, d]``, every action's features at once (as a Q-value actor);
* continuous actions: ``psi(s, a)`` ``[*, d]``, the action an input.
"""
from __future__ import annotations

from collections.abc import Sequence

import torch
from tensordict import NestedKey
from tensordict.nn import TensorDictModule
from torchrl.modules import MLP

__all__ = ["SF_KEY", "make_sf_critic"]

SF_KEY = "successor_features"
"""Where a successor-feature critic writes psi."""


def make_sf_critic(
    observation_dim: int,
    num_features: int,
    *,
    num_actions: int | None = None,
    action_dim: int | None = None,
    num_cells: Sequence[int] = (64, 64),
    bias: bool = True,
    observation_key: NestedKey = "observation",
    action_key: NestedKey = "action",
    out_key: NestedKey = SF_KEY,
) -> TensorDictModule:
    """An MLP successor-feature critic (see the module docstring for its two shapes).

    Args:
        observation_dim: size of the observation.
        num_features: ``d``, the size of ``phi``.
        num_actions: for discrete actions: psi of every action, ``[*, num_actions, d]``.
        action_dim: for continuous actions: the action is concatenated to the observation, psi ``[*, d]``.
        num_cells: hidden layer sizes; ``()`` is one linear layer (on one-hot states, a table).
        bias: whether the last layer has a bias (with ``num_cells=()`` and one-hot states, ``False`` is an exact table).
        observation_key, action_key, out_key: the entries read and written.

    Exactly one of ``num_actions`` and ``action_dim`` is given.
    """
    if (num_actions is None) == (action_dim is None):
        raise ValueError("give num_actions (discrete actions) or action_dim (continuous actions), not both or neither.")
    depth = len(num_cells)
    if num_actions is not None:
        net = MLP(in_features=observation_dim, out_features=torch.Size((num_actions, num_features)),
                  num_cells=list(num_cells), depth=depth, bias_last_layer=bias)
        return TensorDictModule(net, in_keys=[observation_key], out_keys=[out_key])
    net = MLP(in_features=observation_dim + action_dim, out_features=num_features, num_cells=list(num_cells),
              depth=depth, bias_last_layer=bias)
    return TensorDictModule(net, in_keys=[observation_key, action_key], out_keys=[out_key])
