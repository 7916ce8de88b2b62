"""The transfer methods as the training loop composes them, from the config's ``transfer`` section.

    transfer.method = none            plain learning on the task (the baseline)
                    = reward-shaping  PotentialShaping(task potential) on the training env
                    = policy-reuse    PolicyReuse(source actor, PiReuse(psi, upsilon)) after the policy
                    = model-reuse     the learner starts from the source run's weights

Each method is one of drltg's parts (``drltg.transforms``, ``drltg.collectors``, ``drltg.model_reuse``);
this module only reads the config and builds them. ``transfer.source`` is a run directory, or for
policy reuse on the manipulation tasks ``demonstrator:TASK``, the scripted policy of ``TASK``
(``drltg.envs.robosuite.demonstrator_for``) acting as the past policy.
"""
from __future__ import annotations

from pathlib import Path

import torch
import yaml
from tensordict.nn import TensorDictModuleBase, TensorDictSequential

from drltg.agents import Agent, make_agent
from drltg.envs import get_task, make_env
from drltg.envs.robosuite.layout import TASKS as MANIPULATION
from drltg.errors import UsageError

METHODS = ("none", "reward-shaping", "policy-reuse", "model-reuse")
DEMONSTRATOR = "demonstrator:"


def check(cfg: dict) -> None:
    """Fail early, before anything is trained or written, on an unusable transfer section."""
    t = cfg["transfer"]
    if t["method"] not in METHODS:
        raise UsageError(f"unknown transfer method '{t['method']}'; choose one of: {', '.join(METHODS)}.")
    if t["method"] in ("policy-reuse", "model-reuse"):
        if not t["source"]:
            raise UsageError(f"transfer.method={t['method']} needs transfer.source, the source run directory.")
        demonstrated = demonstrator_task(t["source"])
        if demonstrated is not None:
            _check_demonstrator(cfg, demonstrated)
            return
        ckpt = Path(t["source"]).expanduser() / "checkpoints" / "last.pt"
        if not ckpt.is_file():
            raise UsageError(f"transfer.source '{t['source']}' holds no checkpoints/last.pt; train the source first.")
    if t["method"] == "reward-shaping" and get_task(cfg["task"]).potential is None:
        raise UsageError(f"task '{cfg['task']}' has no shaping potential registered.")


def shaping(cfg: dict):
    """The task's potential-based shaping transform (the task's own potential, the learner's gamma)."""
    from drltg.transforms import PotentialShaping

    spec = get_task(cfg["task"])
    potential = spec.potential({**spec.defaults, **cfg["env"]})
    return PotentialShaping(potential, gamma=cfg["optim"]["gamma"])


def demonstrator_task(source) -> str | None:
    """``TASK`` for a source written ``demonstrator:TASK``, else ``None``."""
    if isinstance(source, str) and source.startswith(DEMONSTRATOR):
        return source[len(DEMONSTRATOR):]
    return None


def _check_demonstrator(cfg: dict, task: str) -> None:
    if cfg["transfer"]["method"] != "policy-reuse":
        raise UsageError("a demonstrator has no weights to reuse; use it with transfer.method=policy-reuse.")
    if task not in MANIPULATION or cfg["task"] not in MANIPULATION:
        raise UsageError(
            f"transfer.source=demonstrator:{task} on task '{cfg['task']}': the demonstrator reads the "
            f"manipulation observation and solves {', '.join(MANIPULATION)} only."
        )


def source_actor(cfg: dict) -> TensorDictModuleBase:
    """The past policy: the source run's trained actor, rebuilt from its saved config and checkpoint,
    or the scripted demonstrator of ``demonstrator:TASK``."""
    task = demonstrator_task(cfg["transfer"]["source"])
    if task is not None:
        from drltg.envs.robosuite.demonstrator import demonstrator_for

        return demonstrator_for(task)
    run = Path(cfg["transfer"]["source"]).expanduser()
    src_cfg = yaml.safe_load((run / "config.yaml").read_text())
    env = make_env(src_cfg["task"], device=cfg["device"], **src_cfg["env"])
    agent = make_agent(env, src_cfg)
    state = torch.load(run / "checkpoints" / "last.pt", map_location=cfg["device"], weights_only=False)
    agent.loss.load_state_dict(state["loss"])
    return agent.actor


def reuse_policy(cfg: dict, agent: Agent):
    """The learner's exploration policy followed by the pi-reuse mixer over the source actor."""
    from drltg.collectors import PiReuse, PolicyReuse

    t = cfg["transfer"]
    schedule = PiReuse(t["psi"], t["upsilon"], psi_end=t["psi_end"], annealing_frames=t["annealing_frames"])
    mixer = PolicyReuse(source_actor(cfg), schedule=schedule)
    return TensorDictSequential(agent.policy, mixer), mixer


def reuse_weights(cfg: dict, agent: Agent):
    """Initialise every network of the learner (actor, critics, targets) from the source run."""
    from drltg.model_reuse import load_from_run

    return load_from_run(agent.loss, cfg["transfer"]["source"], freeze=cfg["transfer"]["freeze"])
