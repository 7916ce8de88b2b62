r"""The kickstarting method (Schmitt et al. 2018, "Kickstarting deep reinforcement learning"): the learner's own
loss plus a decaying distillation term towards the source's actor.

:math:`L = L_{RL} + \lambda_f \cdot \mathrm{mean}_i\, D(\pi_T(\cdot|s_i), \pi_S(\cdot|s_i))` on replayed states
(:func:`drltg.losses.distillation`), :math:`\lambda_f` the :class:`~drltg.losses.KickstartingWeight` of the
frames collected so far. The paper tunes :math:`\lambda` (by population-based training); here every knob of its
schedule is an option, with these defaults: :math:`\lambda_0` = ``kick_weight`` = 1, :math:`F` = ``kick_frames``
= 10,000, ``kick_decay`` = linear and, for an exponential decay, the share left at :math:`F`, ``kick_floor`` = 0.01.
"""
from __future__ import annotations

from typing import Literal

from pydantic import Field

from drltg.config import Float, Int, RunConfig
from drltg.transfer.registry import Transfer, TransferMethod


def _build(cfg: RunConfig, agent, env, *, resuming: bool) -> Transfer:
    """The teacher is the source run's actor; it is rebuilt under a forked random state, so the learner
    draws what it would draw without transfer, and ``kick_weight=0`` trains exactly as the baseline. The term
    goes to the learner as it is (a :class:`~drltg.losses.terms.LossTerm`), so a seed group evaluates each
    seed's term with that seed's own teacher."""
    import torch

    from drltg.errors import UsageError
    from drltg.losses import KickstartingWeight, SoftOptionCriticLoss, distillation
    from drltg.transfer.source import source_agent

    t = cfg.transfer
    with torch.random.fork_rng(devices=[]):
        source = source_agent(cfg, env)
    if isinstance(source.loss, SoftOptionCriticLoss):
        raise UsageError(f"kickstarting distils a SAC or TD3 source's actor; transfer.source '{t.source}' is a soft "
                         "option-critic run, whose policy acts through its options.")
    teacher = source.actor.requires_grad_(False)
    schedule = KickstartingWeight(t.kick_weight, t.kick_frames, t.kick_decay, t.kick_floor)
    frames = [0]

    def weight() -> float:
        return schedule(frames[0])

    def tell(f: int) -> None:
        frames[0] = f

    return Transfer(loss_terms=distillation(agent.loss, teacher, weight), on_frames=tell,
                    summary={"kickstarting": {"weight": t.kick_weight, "frames": t.kick_frames, "decay": t.kick_decay,
                                             "floor": t.kick_floor}})


KICKSTARTING = TransferMethod(
    "kickstarting",
    "policy distillation: the learner's loss plus w_f * D(pi_source, pi_learner) on replayed states, w_f falling to 0",
    _build,
    source="run",
    algos=("sac", "td3", "soc"),
    grouped=True,
    options={
        "kick_weight": (Float, Field(1.0, ge=0,
                                     description="kickstarting: weight of the distillation term at frame 0")),
        "kick_frames": (Int, Field(10_000, ge=0, description="kickstarting: frames over which the weight falls to 0 "
                                                             "(0: constant)")),
        "kick_decay": (Literal["linear", "exponential"],
                       Field("linear", description="kickstarting: how the weight falls (exponential: to "
                                                   "kick_floor of it at kick_frames, then 0)")),
        "kick_floor": (Float, Field(0.01, gt=0, le=1, description="kickstarting: the share of kick_weight an "
                                                                   "exponential decay reaches at kick_frames")),
    },
    search={"kick_weight": (1.0, 0.3), "kick_decay": ("linear", "exponential")},  # as Schmitt et al. tune it
    member_options=("kick_weight", "kick_frames", "kick_decay", "kick_floor"),  # each seed's own weight schedule
)
