"""The model-reuse method: the learner starts from a source run's weights (``load_weights``), those of its
``transfer.source_checkpoint``."""
from __future__ import annotations

import logging
from pathlib import Path
from typing import TYPE_CHECKING

from pydantic import Field

from drltg.config import Bool, RunConfig, Str
from drltg.store.rundir import MODEL_REUSE, load_networks
from drltg.transfer.registry import Transfer, TransferMethod

if TYPE_CHECKING:
    from torch import nn

    from drltg.modules.weights import LoadReport


def load_from_run(loss_module: nn.Module, run_dir: str | Path, *, checkpoint: str = "last", **kwargs) -> LoadReport:
    """Initialise ``loss_module`` from the networks of ``<run_dir>/checkpoints/last.pt`` (``checkpoint="best"``:
    of the best evaluation), read from their networks file ``last.safetensors`` (``best.safetensors``) without
    opening the training checkpoint.

    Keyword arguments go to :func:`load_weights`. The file is data only and checked against the run's
    manifest (:func:`drltg.store.rundir.load_networks`): a run from anyone can be loaded.
    """
    from drltg.modules.weights import load_weights

    saved, _ = load_networks(Path(run_dir).expanduser(), checkpoint)
    return load_weights(loss_module, saved, **kwargs)


def _build(cfg: RunConfig, agent, env, *, resuming: bool) -> Transfer:
    """Every network of the learner (actor, critics, targets) starts from the source run; a resumed
    run has its weights already, and only its frozen parameters are frozen again."""
    from drltg.modules.weights import freeze_parameters

    t = cfg.transfer
    if resuming:
        freeze_parameters(agent.loss, t.freeze)
        return Transfer()
    report = load_from_run(agent.loss, t.source, checkpoint=t.source_checkpoint, freeze=t.freeze, partial=t.partial)
    logging.getLogger(__name__).info(report.summary())
    return Transfer(files={MODEL_REUSE: f"{report}\n"})


MODEL_REUSE_METHOD = TransferMethod(
    "model-reuse",
    "the learner starts from the source run's weights (observation-size changes mapped)",
    _build,
    grouped=True,
    source="run",
    takes=("weights",),
    options={
        "freeze": (list[Str], Field([], description="model reuse: parameter-name patterns to keep fixed",
                                    json_schema_extra={"what": "a list of parameter-name patterns (e.g. "
                                                               "[actor_network_params])"})),
        "partial": (Bool, Field(False, description="model reuse: accept a source whose core networks cannot all be "
                                                   "loaded")),
    },
)
