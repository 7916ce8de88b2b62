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
from torchrl.data import OneHot
from torchrl.envs import ExplorationType, set_exploration_type
from torchrl.objectives import DiscreteSACLoss, SACLoss, TD3Loss

from drltg.config import Field, builtin_options
from drltg.errors import UsageError
from drltg.methods.registry import Transfer, TransferMethod, register_method
from drltg.methods.reward_shaping import PotentialShaping

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
        values = []
        for params in self.critic_params.unbind(0):
            with params.to_module(self.critic):
                if self.discrete:
                    q = (self.critic(td.clone())["action_value"] * action).sum(-1, keepdim=True)
                else:
                    q = self.critic(td.clone().set("action", action))["state_action_value"]
            values.append(q)
        return self.scale * torch.stack(values).amin(0)


def _build(cfg: dict, agent, env, *, resuming: bool) -> Transfer:
    from drltg.methods.source import source_agent

    source = source_agent(cfg, env)
    discrete = isinstance(env.full_action_spec_unbatched["action"], OneHot)
    potential = SourceValue(source.loss, discrete=discrete, scale=cfg["transfer"]["value_scale"])
    return Transfer(train_transforms=[PotentialShaping(potential, gamma=cfg["optim"]["gamma"])])


VALUE_SHAPING = register_method(TransferMethod(
    "value-shaping",
    "adds gamma Phi(s') - Phi(s) to the training reward, Phi the source run's value V_source(s)",
    _build,
    source="run",
    algos=("sac", "td3"),
    options=builtin_options("value-shaping", {
        "value_scale": Field(float, "value shaping: Phi = value_scale * V_source(s)", low=0.0),
    }),
))
