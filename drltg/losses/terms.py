r"""Extra terms of a learner's loss (behaviour cloning, distillation) as modules a seed group can vmap.

A term is a function of the loss module it reads, the batch, its weights and its own parameters and
buffers (a teacher's network)::

    term(batch) = term.evaluate(term.loss, batch, term.weights())  ->  {"loss_<name>": scalar, <diagnostic>: scalar}

It reads the loss's parameters when it is called (``loss.actor_network_params``), never a copy taken when it
was built. So a seed group (:mod:`drltg.training.seeds`) evaluates seed k's term inside its vmapped loss,
with seed k's slice of the loss's stacked parameters, of the seeds' terms' stacked state and of their
weights (read outside the vmap, one row per seed)::

    losses_k = loss(batch_k; theta_k) + evaluate(loss(theta_k), batch_k, w_k; state_k)     under torch.vmap

which is seed k's run alone, given the same parameters and batch. The state is a constant of the update
(a frozen teacher): it takes no gradient step.
"""
from __future__ import annotations

from typing import Callable, Sequence

import torch
from tensordict import TensorDictBase

__all__ = ["LossTerm", "LossTerms"]


class LossTerm(torch.nn.Module):
    """One weighted extra term of ``loss``, its weight a number or a function read at every step (an
    annealed weight). Subclasses define :meth:`evaluate`, reading the loss only through its argument."""

    def __init__(self, loss, weight: float | Callable[[], float]):
        super().__init__()
        self.__dict__["loss"] = loss  # read, not owned: its parameters are the learner's
        self.weight = weight

    def weights(self) -> torch.Tensor:
        """The current weight, as a 1-d tensor (a seed group stacks the seeds' rows)."""
        return torch.tensor([self.weight() if callable(self.weight) else self.weight])

    def evaluate(self, loss, batch: TensorDictBase, weights: torch.Tensor) -> dict[str, torch.Tensor]:
        raise NotImplementedError

    def forward(self, batch: TensorDictBase) -> dict[str, torch.Tensor]:
        return self.evaluate(self.loss, batch, self.weights())


class LossTerms(LossTerm):
    """Several terms as one (a combination of transfer methods): their entries joined, ``weights`` the
    parts' weights in order."""

    def __init__(self, parts: Sequence[LossTerm]):
        torch.nn.Module.__init__(self)
        self.parts = torch.nn.ModuleList(parts)
        self.__dict__["loss"] = parts[0].loss

    def weights(self) -> torch.Tensor:
        return torch.cat([p.weights() for p in self.parts])

    def evaluate(self, loss, batch: TensorDictBase, weights: torch.Tensor) -> dict[str, torch.Tensor]:
        sizes = [len(p.weights()) for p in self.parts]
        return {k: v for p, w in zip(self.parts, weights.split(sizes)) for k, v in p.evaluate(loss, batch, w).items()}
