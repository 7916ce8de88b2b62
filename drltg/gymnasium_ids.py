"""drltg's tasks as Gymnasium environments: the id of every task and pair, registered on ``import drltg``.

Task ``fourrooms/northeast`` is ``drltg/fourrooms-northeast-v0`` (``/`` becomes ``-``, namespace
``drltg``, version 0); its entry points are strings (:mod:`drltg.envs.gymnasium_env`), so registering
imports neither torch nor the env. Gymnasium 1.x loads no plugins itself (its entry-point plugins were
removed in 1.0): a package registers its ids when it is imported, as ``ale_py`` does, and so does drltg,
whose ``__init__`` calls :func:`register_ids` (``gymnasium.make("drltg:drltg/...")`` imports ``drltg``;
``gymnasium.register_envs(drltg)`` states the import). Nothing waits for a later import: no import hook
is installed. A task registered afterwards (a plugin) gets its id when it is registered.

Examples:
    >>> import gymnasium, drltg
    >>> env = gymnasium.make("drltg/fourrooms-northeast-v0")
    >>> source, target = drltg.gymnasium_ids.pair_ids("fourrooms-near")
    >>> vec = gymnasium.make_vec(target, num_envs=64)  # one batched torch env, not 64 copies
"""
from __future__ import annotations

import re
import warnings
from typing import Iterable

NAMESPACE = "drltg"
ENTRY_POINT = "drltg.envs.gymnasium_env:DrltgEnv"
VECTOR_ENTRY_POINT = "drltg.envs.gymnasium_env:DrltgVectorEnv"
_VALID = re.compile(r"^[\w:.-]+$")


def task_id(task: str) -> str:
    """The Gymnasium id of the drltg task ``task``: ``drltg/<task with / as ->-v0``."""
    name = task.replace("/", "-")
    if not _VALID.match(name):
        raise ValueError(f"task {task!r} has no Gymnasium id: Gymnasium ids allow letters, digits, '_', '-', '.', ':'.")
    return f"{NAMESPACE}/{name}-v0"


def pair_ids(pair: str) -> tuple[str, str]:
    """The Gymnasium ids ``(source, target)`` of the registered drltg pair ``pair``."""
    from drltg.envs.registry import get_pair

    spec = get_pair(pair)
    return task_id(spec.source), task_id(spec.target)


def register_ids(tasks: Iterable[str] | None = None) -> list[str]:
    """Registers the Gymnasium id of each task (default: every registered task, and from then on every
    task registered) that has none yet; returns the ids registered. A task whose name cannot be an id is
    left out."""
    import gymnasium

    if tasks is None:
        from drltg.envs.registry import ON_REGISTER, TASKS

        if _on_register not in ON_REGISTER:
            ON_REGISTER.append(_on_register)
            _load_plugins()
        tasks = list(TASKS)
    added = []
    for task in tasks:
        try:
            env_id = task_id(task)
        except ValueError:
            continue
        if env_id in gymnasium.registry:
            continue
        gymnasium.register(env_id, entry_point=ENTRY_POINT, vector_entry_point=VECTOR_ENTRY_POINT,
                           kwargs={"task": task}, disable_env_checker=False)
        added.append(env_id)
    return added


def _load_plugins() -> None:
    """The user's plugins (``DRLTG_IMPORT``, entry points), as every drltg command loads them: their tasks
    get ids too. A plugin that fails is a warning here, not an error inside ``import drltg`` (a command
    that loads it says its error)."""
    from drltg import plugins
    from drltg.errors import UsageError

    try:
        plugins.load()
    except UsageError as err:
        warnings.warn(f"drltg: {err}", stacklevel=2)


def _on_register(spec) -> None:
    register_ids([spec.name])
