r"""The pessimistic value of a loss's critic ensemble, :math:`\min_k Q_k`, as SAC and TD3 take it for their
targets: read by behaviour cloning's Q filter, value shaping's potential and SF-GPI's own values."""
from __future__ import annotations

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModuleBase

__all__ = ["min_over_critics"]


@torch.no_grad()
def min_over_critics(critic: TensorDictModuleBase, params: TensorDictBase, td: TensorDictBase,
                     key: str = "state_action_value") -> torch.Tensor:
    r""":math:`\min_k Q_k` at ``td``: ``critic`` (a loss's ``qvalue_network``) run under each copy ``k`` of its
    stacked ``params`` (the loss's ``qvalue_network_params``), ``key`` read from its output; no gradients."""
    values = []
    for copy in params.unbind(0):
        with copy.to_module(critic):
            values.append(critic(td.clone(False))[key])
    return torch.stack(values).amin(0)
