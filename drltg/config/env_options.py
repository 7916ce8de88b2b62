"""The ``env`` section: the task factory's declared keywords, checked by the task registry."""
from __future__ import annotations

from typing import Any

from drltg.config.run import task_spec
from drltg.errors import UsageError

_ENV_RESERVED = {"batch_size": "collector.num_envs and eval.episodes", "device": "device", "seed": "seed"}


def env_defaults(task: str) -> dict[str, Any]:
    """The options of task ``task``: its factory's declared keywords (its registered defaults win), less
    its registration fields; read without importing the env where the registry can
    (:meth:`drltg.envs.TaskSpec.keywords`)."""
    return task_spec(task).keywords()


def task_env(task: str) -> dict[str, Any]:
    """Every env setting of ``task`` at its default (the factory's declared keywords, the task's
    registered values over them), as plain YAML values: ``resolve`` writes them all into the config,
    so a run's ``config.yaml`` says exactly which env it trained on and a changed default is a
    changed config."""
    declared = env_defaults(task)
    return {k: _plain(v) for k, v in declared.items() if k not in _ENV_RESERVED}


def _plain(value: Any) -> Any:
    return [_plain(v) for v in value] if isinstance(value, (list, tuple)) else value


def check_env(task: str, env: dict) -> dict:
    """``env`` checked by the task (:meth:`drltg.envs.TaskSpec.check`), its sentences naming config keys;
    a key the run sets itself is refused first."""
    for name in env:
        if name in _ENV_RESERVED:
            raise UsageError(f"config key 'env.{name}' cannot be set: the run sets it from {_ENV_RESERVED[name]}.")
    return task_spec(task).check(env, key="config key 'env.{}'".format)
