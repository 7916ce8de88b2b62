"""A seed group's update: N learners of one config stacked along a leading seed dimension and stepped as one.

The seeds' loss parameters and buffers (target networks included) are stacked with ``TensorDict.from_modules``,
as TorchRL stacks its critic ensembles; one update is drltg's :class:`~drltg.learners.UpdateStep` over
:class:`StackedLoss`, the loss vmapped over seeds::

    losses_k = loss(batch_k; theta_k)        for every seed k, under torch.vmap
    backward(sum_k total_k)                  seeds share no parameter: d/d theta_k of the sum is seed k's gradient
    Adam over the stacked tensors            elementwise, so it is each seed's own Adam
    SoftUpdate over the stacked targets      theta_target <- lerp(theta_target, theta, tau), each seed's own

A transfer's loss terms (behaviour cloning, distillation) run inside the vmapped loss: seed k's
:class:`~drltg.losses.terms.LossTerm` with seed k's parameters, its stacked state (seed k's teacher) and its
weight. :mod:`drltg.training.seeds` trains such a group; :func:`drltg.training.pretraining.pretrain_together`
steps the members' pretraining with it.
"""
from __future__ import annotations

import contextlib
import copy
from typing import Sequence

import torch
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import TensorDictParams
from torchrl.objectives import LossModule, SoftUpdate

from drltg.errors import UsageError
from drltg.learners import Agent, UpdateStep
from drltg.losses.terms import LossTerm

__all__ = ["SeedGroup", "StackedLoss", "stacked_soft_update"]


class StackedLoss(torch.nn.Module):
    """The seeds' losses as one loss: ``params`` holds every seed's loss parameters and buffers stacked
    along a leading seed dimension, and ``forward(batch)`` runs ``loss`` under each seed's slice on that
    seed's slice of ``batch`` (one ``torch.vmap``), returning the losses with a leading seed dimension.

    ``terms`` (one :class:`~drltg.losses.terms.LossTerm` per seed, a transfer method's extra terms) are
    evaluated in the same vmapped call: seed k's with seed k's slice of the loss, of the terms' stacked
    state (each seed's teacher) and of their weights, read for every seed at every step."""

    def __init__(self, loss: LossModule, params: TensorDictBase, randomness: str = "different",
                 terms: Sequence[LossTerm] = ()):
        super().__init__()
        self.params = params
        self.__dict__["seed_loss"] = loss  # run under each seed's parameters; not a submodule of its own
        self.__dict__["terms"] = list(terms)
        self.__dict__["seed_term"] = None
        self.term_state = None
        if len({tuple(sorted(TensorDict.from_module(t).keys(True, True))) for t in self.terms}) > 1:
            raise UsageError("the seeds of a group have loss terms of different forms (one with transfer.bc_alpha "
                             "null, another with a number, say); train them in groups of their own.")
        if self.terms:  # one seed's term, reading the group's loss; each seed's state is swapped into it
            self.__dict__["seed_term"] = copy.deepcopy(self.terms[0], memo={id(self.terms[0].loss): loss})
            state = TensorDict.from_modules(*self.terms)
            self.term_state = state.detach().clone() if not state.is_empty() else None
        dims = (0, None if self.term_state is None else 0, None if not self.terms else 0, 0)
        self._losses = torch.vmap(self._seed_losses, dims, randomness=randomness)

    def _seed_losses(self, params: TensorDictBase, state: TensorDictBase | None, weights: torch.Tensor | None,
                     batch: TensorDictBase) -> TensorDictBase:
        # an unlocked copy: the loss swaps its own sub-parameters in and out while it runs
        with params.copy().unlock_().to_module(self.seed_loss):
            losses = self.seed_loss(batch)
            if self.seed_term is not None:
                with contextlib.nullcontext() if state is None else state.copy().unlock_().to_module(self.seed_term):
                    losses.update(self.seed_term.evaluate(self.seed_loss, batch, weights))
            return losses

    def forward(self, batch: TensorDictBase) -> TensorDictBase:
        weights = torch.stack([t.weights() for t in self.terms]).to(batch.device) if self.terms else None
        return self._losses(self.params, self.term_state, weights, batch)


def stacked_soft_update(loss: LossModule, params: TensorDictBase, eps: float) -> SoftUpdate:
    """TorchRL's ``SoftUpdate`` of every seed's targets at once, ``theta_target <- lerp(theta_target, theta,
    1 - eps)`` on the stacked tensors: built on a copy of one seed's loss whose ``*_params`` (targets and their
    sources) are the stacked ones (the same tensors as ``params``)."""
    holder = copy.deepcopy(loss)
    names = [name for name, _ in loss.named_children() if name.endswith("_params")]
    for name in names:
        setattr(holder, name, TensorDictParams(params.get(name).copy(), no_convert=True))
    targets = {name: params.get(name).clone() for name in names if name.startswith("target_")}
    updater = SoftUpdate(holder, eps=eps)  # which sets the targets to their sources, as for a new loss
    with torch.no_grad():
        for name, saved in targets.items():  # the seeds' own targets (a source's, a checkpoint's) stay
            params.get(name).update_(saved)
    return updater


class SeedGroup:
    """N agents (same config, one per seed) updated by one vmapped step; ``agents[k]`` keeps seed k's
    own modules, refreshed from the stacked parameters by :meth:`sync` (evaluation of one seed,
    checkpoints).

    Args:
        agents: the seeds' agents, built from the same config (their optimisers' states, if any, are
            stacked too: a resumed group continues each seed's Adam).
        randomness: ``torch.vmap``'s randomness for the losses' random draws: ``"different"`` draws
            independent noise per seed; ``"same"`` shares one draw, which is what a single update
            draws from the same generator state (the equality test).
        terms: each seed's extra loss terms (:class:`StackedLoss`), built on its own agent's loss.
    """

    def __init__(self, agents: Sequence[Agent], randomness: str = "different", terms: Sequence[LossTerm] = ()):
        self.agents = list(agents)
        for agent in self.agents:  # the buffers a TorchRL loss registers on its first call (SAC's target entropy)
            getattr(agent.loss, "target_entropy", None)
        self.seeds = len(self.agents)
        first = self.agents[0]
        self.loss = copy.deepcopy(first.loss)
        self.actor_delay = first.actor_delay
        self.params = TensorDict.from_modules(*(a.loss for a in self.agents), as_module=True)
        names = [name for name, _ in first.loss.named_parameters()]
        params = [self.params.get(tuple(name.split("."))) for name in names]
        self.optimizer = torch.optim.Adam(params, **first.optimizer.defaults)
        if first.optimizer.state:
            self.optimizer.load_state_dict(self._stacked_optimizer_state())
        self.stacked = StackedLoss(self.loss, self.params, randomness, terms)
        target_updater = stacked_soft_update(first.loss, self.params, first.target_updater.eps)
        self.step = UpdateStep(Agent(first.actor, first.policy, self.stacked, target_updater, self.optimizer),
                               threads=None)
        self._views = [TensorDict.from_module(a.loss) for a in self.agents]

    def update(self, batch: TensorDictBase, update_actor: bool = True) -> TensorDictBase:
        """One step for every seed; ``batch`` has a leading seed dimension. Returns the detached losses
        (each entry with a leading seed dimension)."""
        return self.step(batch, update_actor)

    def seed_params(self, k: int):
        """A context in which seed k's own modules hold its current (stacked) parameters, without a copy."""
        return self.params[k].copy().unlock_().to_module(self.agents[k].loss)

    def sync(self) -> None:
        """Copy the stacked parameters into each seed's own modules."""
        with torch.no_grad():
            for k, view in enumerate(self._views):
                view.update_(self.params[k].data)

    def optimizer_state(self, k: int) -> dict:
        """Seed k's part of the stacked Adam state, as its own ``Adam.state_dict()`` would be."""
        stacked = self.optimizer.state_dict()
        state = {
            i: {name: (value if name == "step" else value[k]).clone() for name, value in entry.items()}
            for i, entry in stacked["state"].items()
        }
        return {"state": state, "param_groups": stacked["param_groups"]}

    def _stacked_optimizer_state(self) -> dict:
        states = [a.optimizer.state_dict() for a in self.agents]
        stacked = {
            i: {
                name: (value if name == "step" else torch.stack([s["state"][i][name] for s in states]))
                for name, value in entry.items()
            }
            for i, entry in states[0]["state"].items()
        }
        return {"state": stacked, "param_groups": states[0]["param_groups"]}
