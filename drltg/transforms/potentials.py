"""Potentials for :class:`~drltg.transforms.PotentialShaping`.

A potential is an ``nn.Module`` from observation tensors to ``Phi`` of shape ``[*batch, 1]``; pass the
entries it reads as the shaping transform's ``in_keys``.
"""
from __future__ import annotations

from typing import Callable

import torch
from torch import nn


class TimeDependentPotential(nn.Module):
    """A dynamic potential ``Phi(s, t) = schedule(t) * Phi(s)`` (Devlin & Kudenko 2012).

    ``t`` is the step within the episode (``step_count``, 0 after a reset), so the shaping term is
    ``F = gamma * schedule(t + 1) * Phi(s') - schedule(t) * Phi(s)`` and the optimal policy of the
    (time-augmented) task is unchanged. Use it, e.g., to fade a heuristic out as the episode goes on.

    Args:
        potential: the static potential, called on the observation tensors.
        schedule: maps ``step_count`` (int64, ``[*batch, 1]``) to a weight of the same shape.

    Examples:
        >>> fade = TimeDependentPotential(potential, lambda t: (1 - t / 100).clamp_min(0))
        >>> PotentialShaping(fade, gamma=0.99, in_keys=["position", "step_count"])
    """

    def __init__(self, potential: Callable[..., torch.Tensor], schedule: Callable[[torch.Tensor], torch.Tensor]):
        super().__init__()
        self.potential = potential
        self.schedule = schedule

    def forward(self, *observation_and_step_count: torch.Tensor) -> torch.Tensor:
        *observation, step_count = observation_and_step_count
        return self.schedule(step_count) * self.potential(*observation)
