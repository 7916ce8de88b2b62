"""The policy-reuse and jumpstart methods: the learner's policy followed by ``PolicyReuse`` over the source.

jumpstart is JSRL-Curriculum (Uchendu et al. 2023, "Jump-Start Reinforcement Learning"): the source policy (the
guide) acts for the first H steps of every episode and the learner after them; H shrinks from ``guide_steps`` to 0
in ``guide_stages`` equal stages, moving to the next stage when the combined policy's evaluated return holds
within ``guide_tolerance`` of its best (the mean of its last ``guide_window`` evaluations at the stage, compared
with the best such mean so far: :class:`~drltg.collectors.JumpStart`). The combined policy is evaluated at every
evaluation of the learner (``eval.every``), deterministically, on an evaluation env of its own; the learner's own
evaluation, the run's curve, stays the learner's alone. ``guide_curriculum=frames`` shrinks H on a fixed clock
instead, one stage every ``guide_frames / guide_stages`` frames.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Literal, Optional

from pydantic import Field

from drltg.config import Float, Int, Probability, RunConfig
from drltg.errors import ArgumentError, UsageError
from drltg.transfer.registry import Transfer, TransferMethod

if TYPE_CHECKING:
    from drltg.collectors import ReuseSchedule


def _mixed(cfg: RunConfig, agent, env, schedule: ReuseSchedule, **kwargs) -> Transfer:
    """The learner's exploration policy followed by the mixer over the source's past policy."""
    from drltg.collectors import PolicyReuse
    from drltg.transfer.source import source_actor

    mixer = PolicyReuse(source_actor(cfg, env), schedule=schedule, **kwargs)
    return Transfer(train_transforms=[mixer.primer()], mixer=mixer, on_frames=mixer.set_progress)


def _schedule(cfg: RunConfig) -> ReuseSchedule:
    """pi-reuse's schedule from the run's ``transfer.*`` keys; its rules are the schedule's, said here as keys."""
    from drltg.collectors import PiReuse

    t = cfg.transfer
    try:
        return PiReuse(t.psi, t.upsilon, psi_end=t.psi_end, annealing_frames=t.annealing_frames)
    except ArgumentError as err:
        raise UsageError(f"config key 'transfer.{err.argument}' {err.rule}") from None


def _pi_reuse(cfg: RunConfig, agent, env, *, resuming: bool) -> Transfer:
    return _mixed(cfg, agent, env, _schedule(cfg))


POLICY_REUSE = TransferMethod(
    "policy-reuse",
    "pi-reuse: the source policy acts with probability psi * upsilon^h at step h of every episode",
    _pi_reuse,
    source="policy",
    takes=("policy",),
    grouped=True,
    check=_schedule,
    options={
        "psi": (Probability, Field(1.0, description="pi-reuse: probability of reusing at an episode's first step")),
        "upsilon": (Probability, Field(0.95, description="pi-reuse: decay of psi within the episode")),
        "psi_end": (Optional[Probability], Field(None, description="pi-reuse: psi after annealing_frames; null: no "
                                                                   "decay")),
        "annealing_frames": (Int, Field(0, ge=0, description="pi-reuse: frames over which psi decays to psi_end")),
    },
    search={"psi": (1.0, 0.5), "upsilon": (0.95, 0.9)},
    member_options=("psi", "upsilon", "psi_end", "annealing_frames"),  # each seed's schedule in its own mixer
)


def _jumpstart(cfg: RunConfig, agent, env, *, resuming: bool) -> Transfer:
    from drltg.collectors import JumpStart

    t = cfg.transfer
    if t.guide_curriculum == "frames":
        stage = max(t.guide_frames // t.guide_stages, 1)
        return _mixed(cfg, agent, env, JumpStart(t.guide_steps, stages=t.guide_stages, frames_per_stage=stage))
    schedule = JumpStart(t.guide_steps, stages=t.guide_stages, tolerance=t.guide_tolerance, window=t.guide_window)
    transfer = _mixed(cfg, agent, env, schedule, mix_deterministic=True)

    def evaluated(value: float) -> dict:
        schedule.evaluated(value)
        return {"jumpstart/horizon": schedule.horizon}

    transfer.on_eval, transfer.state = evaluated, schedule
    return transfer


JUMPSTART = TransferMethod(
    "jumpstart",
    "JSRL: the source policy acts for the first H steps of every episode, H shrinking to 0 in stages as the "
    "combined policy's evaluated return holds near its best",
    _jumpstart,
    source="policy",
    takes=("policy",),
    grouped=True,
    options={
        "guide_steps": (Int, Field(100, ge=0, description="jumpstart: steps the source policy acts at the start (H "
                                                          "at first)")),
        "guide_stages": (Int, Field(10, ge=1, description="jumpstart: equal steps in which H shrinks to 0")),
        "guide_curriculum": (Literal["return", "frames"],
                             Field("return", description="jumpstart: when H shrinks: return, when the combined "
                                                         "policy's evaluated return holds near its best (JSRL); "
                                                         "frames, on a fixed clock over guide_frames",
                                   json_schema_extra={"absent": "frames"})),  # what runs saved before it did
        "guide_tolerance": (Float, Field(0.05, ge=0, description="jumpstart: the next stage starts once the return "
                                                                 "is at least best - guide_tolerance * abs(best)")),
        "guide_window": (Int, Field(1, ge=1, description="jumpstart: evaluations at a stage whose mean return is "
                                                         "compared with the best")),
        "guide_frames": (Int, Field(20_000, ge=1, description="jumpstart: with guide_curriculum=frames, training "
                                                              "frames until H reaches 0")),
    },
    search={"guide_stages": (10, 5), "guide_tolerance": (0.05, 0.1)},
    member_options=("guide_steps", "guide_stages", "guide_tolerance", "guide_window", "guide_frames"),  # its mixer's
)
