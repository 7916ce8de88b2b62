"""The value-shaping method: ``PotentialShaping`` with Phi = the source run's value (``SourceValue``)."""
from __future__ import annotations

from pydantic import Field

from drltg.config import Float, RunConfig
from drltg.transfer.registry import Transfer, TransferMethod


def _build(cfg: RunConfig, agent, env, *, resuming: bool) -> Transfer:
    from torchrl.data import OneHot

    from drltg.transfer.source import source_agent
    from drltg.transforms import PotentialShaping, SourceValue

    source = source_agent(cfg, env)
    discrete = isinstance(env.full_action_spec_unbatched["action"], OneHot)
    potential = SourceValue(source.loss, discrete=discrete, scale=cfg.transfer.value_scale)
    return Transfer(train_transforms=[PotentialShaping(potential, gamma=cfg.optim.gamma)])


VALUE_SHAPING = TransferMethod(
    "value-shaping",
    "adds gamma Phi(s') - Phi(s) to the training reward, Phi the source run's value V_source(s)",
    _build,
    grouped=True,
    source="run",
    algos=("sac", "td3"),
    options={"value_scale": (Float, Field(1.0, ge=0, description="value shaping: Phi = value_scale * V_source(s)"))},
    search={"value_scale": (1.0, 0.5, 2.0, 4.0)},
    member_options=("value_scale",),  # each seed's potential on its own block
)
