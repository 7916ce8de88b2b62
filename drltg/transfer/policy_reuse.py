"""The policy-reuse and jumpstart methods: the learner's policy followed by ``PolicyReuse`` over the source."""
from __future__ import annotations

from typing import TYPE_CHECKING, Optional

from pydantic import Field

from drltg.config import Int, Probability, RunConfig
from drltg.errors import UsageError
from drltg.transfer.registry import Transfer, TransferMethod

if TYPE_CHECKING:
    from drltg.collectors import ReuseSchedule


def _mixed(cfg: RunConfig, agent, env, schedule: ReuseSchedule) -> Transfer:
    """The learner's exploration policy followed by the mixer over the source's past policy."""
    from drltg.collectors import PolicyReuse
    from drltg.transfer.source import source_actor

    mixer = PolicyReuse(source_actor(cfg, env), schedule=schedule)
    return Transfer(train_transforms=[mixer.primer()], mixer=mixer, on_frames=mixer.set_progress)


def _pi_reuse(cfg: RunConfig, agent, env, *, resuming: bool) -> Transfer:
    from drltg.collectors import PiReuse

    t = cfg.transfer
    return _mixed(cfg, agent, env, PiReuse(t.psi, t.upsilon, psi_end=t.psi_end, annealing_frames=t.annealing_frames))


def _check_pi_reuse(cfg: RunConfig) -> None:
    t = cfg.transfer
    if t.psi_end is not None and t.psi_end != t.psi and t.annealing_frames <= 0:
        raise UsageError("config key 'transfer.psi_end' needs transfer.annealing_frames > 0, the frames over "
                         "which psi decays.")


POLICY_REUSE = TransferMethod(
    "policy-reuse",
    "pi-reuse: the source policy acts with probability psi * upsilon^h at step h of every episode",
    _pi_reuse,
    source="policy",
    takes=("policy",),
    grouped=True,
    check=_check_pi_reuse,
    options={
        "psi": (Probability, Field(1.0, description="pi-reuse: probability of reusing at an episode's first step")),
        "upsilon": (Probability, Field(0.95, description="pi-reuse: decay of psi within the episode")),
        "psi_end": (Optional[Probability], Field(None, description="pi-reuse: psi after annealing_frames; null: no "
                                                                   "decay")),
        "annealing_frames": (Int, Field(0, ge=0, description="pi-reuse: frames over which psi decays to psi_end")),
    },
)


def _jumpstart(cfg: RunConfig, agent, env, *, resuming: bool) -> Transfer:
    from drltg.collectors import JumpStart

    t = cfg.transfer
    stage = max(t.guide_frames // t.guide_stages, 1)
    return _mixed(cfg, agent, env, JumpStart(t.guide_steps, stages=t.guide_stages, frames_per_stage=stage))


JUMPSTART = TransferMethod(
    "jumpstart",
    "JSRL: the source policy acts for the first H steps of every episode, H shrinking to 0 in stages",
    _jumpstart,
    source="policy",
    takes=("policy",),
    grouped=True,
    options={
        "guide_steps": (Int, Field(100, ge=0, description="jumpstart: steps the source policy acts at the start (H "
                                                          "at first)")),
        "guide_stages": (Int, Field(10, ge=1, description="jumpstart: equal steps in which H shrinks to 0")),
        "guide_frames": (Int, Field(20_000, ge=1, description="jumpstart: training frames until H reaches 0")),
    },
)
