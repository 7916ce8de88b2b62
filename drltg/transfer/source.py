"""Where transferred knowledge comes from: ``transfer.source``, a source run or a scripted demonstrator.

``transfer.source`` is a drltg run directory (its ``config.yaml`` and ``checkpoints/last.pt``), or for
methods that reuse a policy on the manipulation tasks ``demonstrator:TASK``, the scripted policy of
``TASK`` (:func:`drltg.envs.robosuite.demonstrator_for`) acting as the past policy. :func:`check` runs
before anything is trained or written; :func:`source_actor` rebuilds the past policy.
"""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import yaml

from drltg.envs import make_env
from drltg.envs.robosuite.layout import TASKS as MANIPULATION
from drltg.errors import UsageError
from drltg.training.rundir import CHECKPOINT, CONFIG, SUMMARY, is_complete, load_checkpoint
from drltg.transfer.registry import get_method

if TYPE_CHECKING:
    from tensordict.nn import TensorDictModuleBase
    from torchrl.envs import EnvBase

DEMONSTRATOR = "demonstrator:"


def check(cfg: dict) -> None:
    """Fail early, before anything is trained or written, on a source the method cannot use."""
    method, t = get_method(cfg["transfer"]["method"]), cfg["transfer"]
    if method.source is None:
        return
    if not t["source"]:
        raise UsageError(f"transfer.method={method.name} needs transfer.source, the source run directory.")
    demonstrated = demonstrator_task(t["source"])
    if demonstrated is None:
        _check_source_run(Path(t["source"]).expanduser(), t)
    elif method.source != "policy":
        raise UsageError(f"a demonstrator has no weights to reuse; {method.name} needs a source run directory.")
    elif demonstrated not in MANIPULATION or cfg["task"] not in MANIPULATION:
        raise UsageError(
            f"transfer.source=demonstrator:{demonstrated} on task '{cfg['task']}': the demonstrator reads the "
            f"manipulation observation and solves {', '.join(MANIPULATION)} only."
        )


def _check_source_run(run: Path, t: dict) -> None:
    if not (run / CHECKPOINT).is_file():
        raise UsageError(f"transfer.source '{t['source']}' holds no {CHECKPOINT.as_posix()}; train the source first.")
    if not (run / CONFIG).is_file():
        raise UsageError(f"transfer.source '{t['source']}' holds no {CONFIG}; is it a drltg run directory?")
    if not is_complete(run) and not t.get("allow_incomplete"):
        frames = load_checkpoint(run, mmap=True).get("frames", "?")
        raise UsageError(
            f"transfer.source '{t['source']}' did not finish (no {SUMMARY}; its checkpoint is at frame {frames}); "
            f"finish it with `drltg train --resume --run-dir {t['source']}`, or reuse it as it is with "
            "transfer.allow_incomplete=true."
        )


def demonstrator_task(source) -> str | None:
    """``TASK`` for a source written ``demonstrator:TASK``, else ``None``."""
    if isinstance(source, str) and source.startswith(DEMONSTRATOR):
        return source[len(DEMONSTRATOR):]
    return None


def _spaces(env: EnvBase) -> tuple[str, str]:
    """What a policy of ``env`` reads and writes: the observation size, the action spec's kind and size."""
    action = env.full_action_spec_unbatched["action"]
    return (f"{env.full_observation_spec_unbatched['observation'].shape[-1]} observation entries",
            f"{type(action).__name__} actions of shape {tuple(action.shape)}")


def check_same_spaces(source: EnvBase, target: EnvBase, source_name: str, target_name: str) -> None:
    """Refuse to run a policy of ``source`` on ``target`` when they differ in observation or action space."""
    mine, theirs = _spaces(source), _spaces(target)
    if mine != theirs:
        raise UsageError(
            f"the policy of {source_name} reads {mine[0]} and writes {mine[1]}, but {target_name} has "
            f"{theirs[0]} and {theirs[1]}."
        )


def source_agent(cfg: dict, target_env: EnvBase | None = None):
    """The source run's learner (:class:`drltg.learners.Agent`: actor, critics, temperature), rebuilt from
    its saved config and checkpoint. With ``target_env``, a source that observes or acts differently is
    refused here rather than failing inside the first rollout."""
    from drltg.learners import make_agent

    run = Path(cfg["transfer"]["source"]).expanduser()
    src_cfg = yaml.safe_load((run / CONFIG).read_text())
    env = make_env(src_cfg["task"], device=cfg["device"], **src_cfg["env"])
    if target_env is not None:
        check_same_spaces(env, target_env, f"transfer.source '{cfg['transfer']['source']}' ({src_cfg['task']})",
                          f"task '{cfg['task']}'")
    agent = make_agent(env, src_cfg)
    agent.loss.load_state_dict(load_checkpoint(run, map_location=cfg["device"])["loss"])
    return agent


def source_actor(cfg: dict, target_env: EnvBase | None = None) -> TensorDictModuleBase:
    """The past policy: the source run's trained actor (:func:`source_agent`), or the scripted
    demonstrator of ``demonstrator:TASK``."""
    task = demonstrator_task(cfg["transfer"]["source"])
    if task is not None:
        from drltg.envs.robosuite.demonstrator import demonstrator_for

        return demonstrator_for(task)
    return source_agent(cfg, target_env).actor
