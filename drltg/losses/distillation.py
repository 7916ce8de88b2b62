r"""Kickstarting (Schmitt et al. 2018): policy distillation from a teacher as an extra actor loss.

The student keeps its own RL loss and is pulled towards the teacher's (source) policy on the states it
replays itself, with a weight :math:`\lambda_f` that falls to 0 so the student can surpass its teacher:

.. math::

    L = L_{RL} + \lambda_f \, \frac{1}{B}\sum_i D\big(\pi_T(\cdot|s_i), \pi_S(\cdot|s_i)\big)

with :math:`D` chosen by what the two policies are:

- both tanh-Gaussian (SAC): :math:`\mathrm{KL}(\pi_T \| \pi_S)`, computed exactly as the KL of their
  Gaussians before the tanh, which it equals because both share the same invertible squashing onto the
  action box (KL is invariant under a bijection);
- both categorical (discrete SAC):
  :math:`\mathrm{KL}(\pi_T \| \pi_S) = \sum_a \pi_T(a|s)\log\frac{\pi_T(a|s)}{\pi_S(a|s)}`,
  the cross-entropy of the kickstarting paper less the teacher's entropy (a constant for the student);
- a deterministic student (TD3): :math:`\|\mu_S(s) - \mu_T(s)\|^2`, the teacher's mean (greedy) action;
- a stochastic student and a deterministic teacher: :math:`-\log\pi_S(\mu_T(s)|s)`.

Teacher and student may differ in architecture (hidden sizes, a deterministic teacher); they read the
same observation and act in the same action space.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Literal

import torch
from tensordict import TensorDictBase
from tensordict.nn import ProbabilisticTensorDictSequential, TensorDictModuleBase
from torch import distributions as D
from torchrl.envs import ExplorationType, set_exploration_type

from drltg.losses.terms import LossTerm

__all__ = ["KickstartingWeight", "distillation", "Distillation"]

EXPONENTIAL_FLOOR = 0.01
r"""The default share :math:`\rho` of :math:`\lambda_0` an exponential weight reaches at ``frames``, then 0."""


@dataclass(frozen=True)
class KickstartingWeight:
    r"""The distillation weight after ``f`` frames: :math:`\lambda_0 \max(0, 1 - f/F)` (``linear``) or
    :math:`\lambda_0 \rho^{f/F}` for :math:`f < F` and 0 after (``exponential``, :math:`\rho` the ``floor``,
    0.01 by default); ``frames = 0`` keeps :math:`\lambda_0` throughout.

    Schmitt et al. (2018) adapt :math:`\lambda` during training by population-based training; here its
    schedule is fixed by :math:`\lambda_0`, :math:`F`, the decay and :math:`\rho`, the knobs a tuning search
    varies (``transfer.kick_weight``, ``kick_frames``, ``kick_decay``, ``kick_floor``)."""

    initial: float
    frames: int
    decay: Literal["linear", "exponential"] = "linear"
    floor: float = EXPONENTIAL_FLOOR

    def __post_init__(self):
        if self.initial < 0 or self.frames < 0:
            raise ValueError(f"a kickstarting weight needs initial >= 0 and frames >= 0, got {self.initial}, "
                             f"{self.frames}.")
        if self.decay not in ("linear", "exponential"):
            raise ValueError(f"decay must be 'linear' or 'exponential', got {self.decay!r}.")
        if not 0 < self.floor <= 1:
            raise ValueError(f"an exponential weight's floor must lie in (0, 1], got {self.floor}.")

    def __call__(self, frames: int) -> float:
        if self.frames == 0:
            return self.initial
        if frames >= self.frames:
            return 0.0
        share = frames / self.frames
        if self.decay == "linear":
            return self.initial * (1.0 - share)
        return self.initial * math.pow(self.floor, share)


def _is_stochastic(module) -> bool:
    return isinstance(module, ProbabilisticTensorDictSequential)


def _base(dist: D.Distribution) -> D.Distribution:
    """A tanh-Gaussian's Gaussian before the squashing; any other distribution itself."""
    return dist.base_dist if isinstance(dist, D.TransformedDistribution) else dist


def _same_box(teacher: D.Distribution, student: D.Distribution) -> bool:
    """Whether two tanh-Gaussians squash onto the same action box (else their KLs before the tanh differ)."""
    bounds = [(getattr(d, "low", None), getattr(d, "high", None)) for d in (teacher, student)]
    if any(b is None for pair in bounds for b in pair):
        return True
    (lt, ht), (ls, hs) = bounds
    return bool(torch.equal(torch.as_tensor(lt), torch.as_tensor(ls)) and torch.equal(torch.as_tensor(ht),
                                                                                       torch.as_tensor(hs)))


def _divergence(teacher_dist: D.Distribution, student_dist: D.Distribution) -> torch.Tensor:
    """``KL(teacher || student)``, per action dimension where the Gaussians are not ``Independent``."""
    if hasattr(teacher_dist, "logits") and hasattr(student_dist, "logits"):
        p_log = torch.log_softmax(teacher_dist.logits, -1)
        return (p_log.exp() * (p_log - torch.log_softmax(student_dist.logits, -1))).sum(-1)
    if not _same_box(teacher_dist, student_dist):
        raise ValueError("teacher and student squash their actions onto different action boxes; kickstarting "
                         "needs the same action space.")
    return D.kl_divergence(_base(teacher_dist), _base(student_dist))


def distillation(loss, teacher: TensorDictModuleBase, weight: float | Callable[[], float]):
    r"""The kickstarting term for the actor of ``loss`` (a TorchRL SAC, discrete SAC or TD3 loss, or a
    :class:`~drltg.losses.SoftOptionCriticLoss`, whose actor reads each replayed transition's option), towards
    the frozen ``teacher`` on every replayed state (see the module docstring for :math:`D`)::

        loss_actor_distill = w * mean_i D(pi_T(.|s_i), pi_S(.|s_i))

    ``weight`` may be a function read at every step (:class:`KickstartingWeight` behind a frame counter).
    The term is named ``loss_actor_*``, so TD3's policy delay skips it with the actor's own loss. Returns
    ``loss_terms(batch)`` for :class:`~drltg.learners.UpdateStep` (a :class:`~drltg.losses.terms.LossTerm`,
    which a seed group evaluates for every seed at once, each with its own teacher); with weight 0 the
    update is the learner's own, exactly."""
    return Distillation(loss, teacher, weight)


class Distillation(LossTerm):
    """:func:`distillation`'s term: the teacher is its submodule (frozen), the student the actor of the loss
    it is evaluated with (:class:`~drltg.losses.terms.LossTerm`), so a seed group stacks the seeds' teachers
    and evaluates seed k's term with seed k's teacher and actor."""

    def __init__(self, loss, teacher: TensorDictModuleBase, weight: float | Callable[[], float]):
        super().__init__(loss, weight)
        self.teacher = teacher

    def evaluate(self, loss, batch: TensorDictBase, weights: torch.Tensor) -> dict[str, torch.Tensor]:
        actor, teacher = loss.actor_network, self.teacher
        student_stochastic, teacher_stochastic = _is_stochastic(actor), _is_stochastic(teacher)
        states = batch.select(*actor.in_keys, *teacher.in_keys, strict=False)
        with torch.no_grad():
            if teacher_stochastic and student_stochastic:
                teacher_dist = teacher.get_dist(states.clone(False))
            else:
                with set_exploration_type(ExplorationType.DETERMINISTIC):
                    teacher_action = teacher(states.clone(False))["action"]
        with loss.actor_network_params.to_module(actor):
            if student_stochastic:
                student_dist = actor.get_dist(states.clone(False))
                if teacher_stochastic:
                    gap = _divergence(teacher_dist, student_dist)
                else:
                    gap = -student_dist.log_prob(teacher_action)
            else:
                with set_exploration_type(ExplorationType.DETERMINISTIC):
                    action = actor(states.clone(False))["action"]
                gap = (action - teacher_action).pow(2)
        gap = gap.reshape(*states.batch_size, -1).sum(-1)
        return {"loss_actor_distill": weights[0] * gap.mean(), "distill_gap": gap.detach().mean(),
                "distill_weight": weights[0].detach()}
