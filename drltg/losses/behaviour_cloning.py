r"""Behaviour cloning on demonstrations as an extra actor loss (Nair et al. 2018), Q-filtered on request and
scaled to the critic's size as TD3+BC scales it (Fujimoto & Gu 2021), and the option a demonstration is
credited to when the learner has options.

A demonstrator acts without options, but every loss of the soft option-critic reads the option ``o`` of
a transition: the critic regresses :math:`Q_U(s,o,a)` on
:math:`y(o) = r + \gamma(1-d')\,[\bar Q_\Omega(s',o) - \beta_o(s')\,\bar A_\Omega(s',o)]`, and the actor and
termination losses use ``o`` as well. The critic is off-policy in ``a`` and :math:`y(o)` is defined for every
option, so a demonstrated :math:`(s, a, r, s')` is a valid sample for each of them; it is credited to the
option the learner would choose afresh at ``s`` (:func:`option_labels`),

.. math::

    o \sim \pi_\Omega(\cdot|s), \qquad
    \mathbb{E}_{o\sim\pi_\Omega(\cdot|s)}\big[L_Q(s,o,a)\big],

drawn anew each time the transition is sampled, with the current networks. The options the learner
would act with at ``s`` learn what the demonstrated action returns there, and the behaviour-cloning term
pulls the same options, in the same proportions, towards it (:func:`behaviour_cloning`). A label drawn
once per episode (or uniformly) would credit options the learner does not choose at ``s`` and that the
cloning term does not train there. With one option the label is 0 and both are SAC's.
"""
from __future__ import annotations

from typing import Callable

import torch
from tensordict import TensorDictBase
from torchrl.envs import ExplorationType, set_exploration_type

from drltg.losses.terms import LossTerm
from drltg.modules.critics import min_over_critics

__all__ = ["behaviour_cloning", "BehaviourCloning", "option_labels", "OPTION_PROBS"]

OPTION_PROBS = "option_probs"
"""Where :func:`option_labels` leaves ``pi_Omega(.|s)`` of the demonstrations it labelled (``[B, K]``, zero
past them), for :func:`behaviour_cloning` in the same update to reuse instead of computing again."""


def _min_q(loss, td: TensorDictBase) -> torch.Tensor:
    """The smaller of ``loss``'s critics at ``td``'s (observation[, option], action), without gradients."""
    return min_over_critics(loss.qvalue_network, loss.qvalue_network_params.detach(), td).squeeze(-1)


def _num_options(loss) -> int:
    return getattr(loss, "num_options", 1)


@torch.no_grad()
def _option_probs(loss, demo: TensorDictBase) -> torch.Tensor:
    """``pi_Omega(o|s)`` ``[k, K]`` of the policy over options (ones for a learner without options)."""
    if _num_options(loss) == 1:
        return torch.ones(*demo.batch_size, 1, device=demo.device)
    return loss.option_probs(loss.option_values(demo))


def option_labels(loss, count: int) -> Callable[[TensorDictBase], TensorDictBase]:
    """``label(batch)`` writes into the first ``count`` rows of ``batch`` (the demonstrations, as
    :func:`drltg.collectors.mixed_batches` lays them out) an option drawn from the policy over options of
    the :class:`~drltg.losses.SoftOptionCriticLoss` ``loss`` at their state, ``o ~ pi_Omega(.|s)`` (see the
    module docstring), and ``pi_Omega(.|s)`` itself into ``OPTION_PROBS``, and returns the batch; with one
    option, 0 (no random draw). Call it just before the batch's update, so that the draw uses the networks
    that update trains."""
    key = loss.tensor_keys.option

    def label(batch: TensorDictBase) -> TensorDictBase:
        probs = _option_probs(loss, batch[:count])
        option = torch.zeros(count, 1, dtype=torch.int64, device=probs.device)
        if probs.shape[-1] > 1:
            option = torch.multinomial(probs, 1)
        batch.get(key)[:count] = option
        full = probs.new_zeros(*batch.batch_size, probs.shape[-1])
        full[:count] = probs
        batch.set(OPTION_PROBS, full)
        return batch

    return label


def behaviour_cloning(loss, count: int, weight: float | Callable[[], float], *, q_filter: bool = False,
                      alpha: float | None = None):
    r"""Nair et al. (2018)'s behaviour-cloning term on the first ``count`` transitions of each batch (the
    demonstrations, as :func:`drltg.collectors.mixed_batches` lays them out), for a SAC, TD3 or soft
    option-critic loss module:

        loss_actor_bc = (w / lambda) * mean_i sum_o pi_Omega(o|s_i) ||mu_o(s_i) - a_i||^2
                                         * 1[Q(s_i,o,a_i) > Q(s_i,o,mu_o(s_i))]

    ``w`` the ``weight``, ``mu_o`` the deterministic action of the actor (of option ``o``), ``Q`` the
    smaller of the current critics, ``pi_Omega`` the soft option-critic's policy over options at ``s_i``
    (without gradients): the expected cloning error of the option the learner would choose there, from
    the distribution the demonstrations' labels are drawn from (:func:`option_labels`). Without options
    (SAC, TD3) the sum has the one term ``pi = 1``: ``(w / lambda) * mean_i ||mu(s_i) - a_i||^2 * 1[...]``, so
    one option is exactly SAC's term.

    The indicator is the Q filter (``q_filter``; Nair et al. 2018, section 4): a demonstrated action is cloned only
    while the critic rates it above the actor's own, so the term fades where the learner has become better
    than its demonstrator, and a demonstration of another task's behaviour stops being copied once the critic
    knows better. Without it the indicator is 1.

    ``lambda`` scales the cloning term to the critic's size as TD3+BC does (Fujimoto & Gu 2021): TD3+BC
    maximises ``lambda Q(s, pi(s)) - (pi(s) - a)^2`` with ``lambda = alpha / mean_i |Q(s_i, .)|`` (``alpha`` =
    2.5 in the paper); divided by ``lambda`` that is the learner's own ``-Q`` plus the cloning error weighted
    ``1 / lambda = mean|Q| / alpha``, so the two keep their balance whatever the scale of the task's returns.
    Here the mean runs over the demonstrations' states at the actor's action (as the authors' code takes it),
    ``mean_i sum_o pi_Omega(o|s_i) |Q(s_i,o,mu_o(s_i))|``, without gradients; ``alpha=None`` is ``lambda = 1``
    (the weight alone).

    ``weight`` may be a function read at every step (an annealed weight); ``pi_Omega`` is read from the
    batch's ``OPTION_PROBS`` where :func:`option_labels` left it. Returns ``loss_terms(batch)`` for
    :class:`~drltg.learners.UpdateStep` (a :class:`~drltg.losses.terms.LossTerm`), with ``bc_accepted``, the
    (``pi_Omega``-weighted) share of demonstrations kept, and, with ``alpha``, ``bc_scale = 1 / lambda``."""
    return BehaviourCloning(loss, count, weight, q_filter=q_filter, alpha=alpha)


class BehaviourCloning(LossTerm):
    """:func:`behaviour_cloning`'s term; it reads the actor's and critics' parameters of the loss it is
    evaluated with (:class:`~drltg.losses.terms.LossTerm`), so a seed group evaluates each seed's term with
    that seed's parameters. ``alpha`` is a buffer, so the seeds of a group may each have their own (a tuning
    grid's settings in one group)."""

    def __init__(self, loss, count: int, weight: float | Callable[[], float], *, q_filter: bool = False,
                 alpha: float | None = None):
        super().__init__(loss, weight)
        if alpha is not None and not alpha > 0:
            raise ValueError(f"TD3+BC's alpha must be > 0 (or None), got {alpha}.")
        self.count, self.q_filter, self.scaled = count, q_filter, alpha is not None
        self.register_buffer("alpha", None if alpha is None else torch.tensor(float(alpha)))

    def evaluate(self, loss, batch: TensorDictBase, weights: torch.Tensor) -> dict[str, torch.Tensor]:
        actor, num_options = loss.actor_network, _num_options(loss)
        option_key = loss.tensor_keys.option if num_options > 1 else None
        demo = batch[:self.count]
        probs = demo.get(OPTION_PROBS) if OPTION_PROBS in demo.keys() else _option_probs(loss, demo)
        # the demonstrations' inputs [k, K], one copy per option ([k, 1] without options)
        obs_keys = [k for k in actor.in_keys if k != option_key]
        pair = demo.select(*obs_keys, "action").unsqueeze(-1).expand(*demo.batch_size, num_options).clone(False)
        if option_key is not None:
            options = torch.arange(num_options, device=pair.device).unsqueeze(-1)
            pair.set(option_key, options.expand(*pair.batch_size, 1))
        with set_exploration_type(ExplorationType.DETERMINISTIC), loss.actor_network_params.to_module(actor):
            action = actor(pair.exclude("action"))["action"]
        error = (action - pair["action"]).pow(2).sum(-1)
        accepted = torch.ones_like(error)
        out = {}
        if self.q_filter or self.scaled:
            own = _min_q(loss, pair.clone(False).set("action", action.detach()))  # Q(s, o, mu_o(s)) [k, K]
        if self.q_filter:
            accepted = (_min_q(loss, pair) > own).float()
        scale = 1.0
        if self.scaled:
            scale = (probs * own.abs()).sum(-1).mean() / self.alpha  # 1 / lambda = mean|Q| / alpha
            out["bc_scale"] = scale
        return {"loss_actor_bc": weights[0] * scale * (probs * error * accepted).sum(-1).mean(),
                "bc_accepted": (probs * accepted).sum(-1).mean(), **out}
