"""The policy-reuse and jumpstart methods: the learner's policy followed by ``PolicyReuse`` over the source."""
from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Optional

from pydantic import Field

from drltg.config import Int, Probability, RunConfig, builtin_options
from drltg.errors import UsageError
from drltg.transfer.registry import Transfer, TransferMethod, register_method

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


POLICY_REUSE = register_method(TransferMethod(
    "policy-reuse",
    "pi-reuse: the source policy acts with probability psi * upsilon^h at step h of every episode",
    _pi_reuse,
    source="policy",
    takes=("policy",),
    grouped=True,
    check=_check_pi_reuse,
    options=builtin_options("policy-reuse", {
        "psi": Annotated[Probability, Field(description="pi-reuse: probability of reusing at an episode's first step")],
        "upsilon": Annotated[Probability, Field(description="pi-reuse: decay of psi within the episode")],
        "psi_end": Annotated[Optional[Probability],
                             Field(description="pi-reuse: psi after annealing_frames; null: no decay")],
        "annealing_frames": Annotated[Int, Field(ge=0, description="pi-reuse: frames over which psi decays to "
                                                                  "psi_end")],
    }),
))


def _jumpstart(cfg: RunConfig, agent, env, *, resuming: bool) -> Transfer:
    from drltg.collectors import JumpStart

    t = cfg.transfer
    stage = max(t.guide_frames // t.guide_stages, 1)
    return _mixed(cfg, agent, env, JumpStart(t.guide_steps, stages=t.guide_stages, frames_per_stage=stage))


JUMPSTART = register_method(TransferMethod(
    "jumpstart",
    "JSRL: the source policy acts for the first H steps of every episode, H shrinking to 0 in stages",
    _jumpstart,
    source="policy",
    takes=("policy",),
    grouped=True,
    options=builtin_options("jumpstart", {
        "guide_steps": Annotated[Int, Field(ge=0, description="jumpstart: steps the source policy acts at the "
                                                             "start (H at first)")],
        "guide_stages": Annotated[Int, Field(ge=1, description="jumpstart: equal steps in which H shrinks to 0")],
        "guide_frames": Annotated[Int, Field(ge=1, description="jumpstart: training frames until H reaches 0")],
    }),
))
