"""Behaviour cloning on demonstrations as an extra actor loss (Nair et al. 2018), Q-filtered on request."""
from __future__ import annotations

from typing import Callable

import torch
from tensordict import TensorDictBase
from torchrl.envs import ExplorationType, set_exploration_type


def _min_q(loss, td: TensorDictBase) -> torch.Tensor:
    """The smaller of ``loss``'s critics at ``td``'s (observation, action), without gradients."""
    values = []
    for params in loss.qvalue_network_params.detach().unbind(0):
        with params.to_module(loss.qvalue_network):
            values.append(loss.qvalue_network(td.clone(False))["state_action_value"])
    return torch.stack(values).amin(0).squeeze(-1)


def behaviour_cloning(loss, count: int, weight: float | Callable[[], float], *, q_filter: bool = False):
    """Nair et al. (2018)'s behaviour-cloning term on the first ``count`` transitions of each batch (the
    demonstrations, as :func:`drltg.collectors.mixed_batches` lays them out), for a SAC or TD3 loss module:

        loss_actor_bc = weight * mean_i ||mu(s_i) - a_i||^2 * 1[Q(s_i, a_i) > Q(s_i, mu(s_i))]

    ``mu`` the actor's deterministic action, ``Q`` the smaller of the current critics. The Q filter
    clones a demonstrated action only while the critic rates it above the actor's own, so the term fades
    where the learner has become better than its demonstrator. ``weight`` may be a function read at every
    step (an annealed weight). Returns ``loss_terms(batch)`` for
    :class:`~drltg.learners.UpdateStep`, with ``bc_accepted``, the share of demonstrations kept."""
    actor, actor_params = loss.actor_network, loss.actor_network_params
    obs_keys = list(actor.in_keys)

    def loss_terms(batch: TensorDictBase) -> dict[str, torch.Tensor]:
        demo = batch[:count]
        with set_exploration_type(ExplorationType.DETERMINISTIC), actor_params.to_module(actor):
            action = actor(demo.select(*obs_keys).clone(False))["action"]
        error = (action - demo["action"]).pow(2).sum(-1)
        accepted = torch.ones_like(error)
        if q_filter:
            pair = demo.select(*obs_keys, "action")
            accepted = (_min_q(loss, pair) > _min_q(loss, pair.clone(False).set("action", action.detach()))).float()
        w = weight() if callable(weight) else weight
        return {"loss_actor_bc": w * (error * accepted).mean(), "bc_accepted": accepted.mean()}

    return loss_terms
