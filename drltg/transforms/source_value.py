"""Shaping with what the source learned: the potential is the source learner's value of the state.

Policy transfer through potential-based shaping (Brys et al. 2015): a source policy's knowledge
enters the target as a potential, so it guides exploration without changing the target's optimal
policy (Ng, Harada & Russell 1999). Here the potential is the source run's own value estimate,

    Phi(s) = scale * min_k Q_k^source(s, mu^source(s))

the smaller of its twin critics at its deterministic action (for discrete SAC, the Q of the greedy
action). Unlike a task's hand-written potential (FourRooms' exact distance to the goal), it uses only
what the source run learned; where the source's goal differs, Phi points to the source's goal and
the transfer can be negative, which the report shows.
"""
from __future__ import annotations

import torch
from tensordict import TensorDict
from torch import nn
from torchrl.envs import ExplorationType, set_exploration_type
from torchrl.objectives import DiscreteSACLoss, SACLoss, TD3Loss

from drltg.errors import UsageError
from drltg.modules.critics import min_over_critics

__all__ = ["SourceValue"]


class SourceValue(nn.Module):
    """``Phi(observation) = scale * min_k Q_k(s, mu(s))`` of a trained SAC, discrete-SAC or TD3 loss
    module, frozen. Reads ``"observation"``; returns ``[*batch, 1]``."""

    in_keys = ["observation"]

    def __init__(self, loss: nn.Module, *, discrete: bool, scale: float = 1.0) -> None:
        super().__init__()
        if not isinstance(loss, (SACLoss, DiscreteSACLoss, TD3Loss)):
            raise UsageError(f"value shaping reads a SAC, discrete-SAC or TD3 source, not a {type(loss).__name__}.")
        self.actor = loss.actor_network
        self.critic = loss.qvalue_network
        self.critic_params = loss.qvalue_network_params.detach().clone()
        self.discrete, self.scale = discrete, scale
        self.requires_grad_(False)

    @torch.no_grad()
    def forward(self, observation: torch.Tensor) -> torch.Tensor:
        td = TensorDict({"observation": observation}, batch_size=observation.shape[:-1])
        with set_exploration_type(ExplorationType.DETERMINISTIC):
            action = self.actor(td.clone())["action"]
        if self.discrete:  # the one-hot action picks min_k Q_k(s, a) from each action's minimum
            values = min_over_critics(self.critic, self.critic_params, td, "action_value")
            value = (values * action).sum(-1, keepdim=True)
        else:
            value = min_over_critics(self.critic, self.critic_params, td.set("action", action))
        return self.scale * value
