"""Task environments (TorchRL ``EnvBase``) and the registry of tasks and task pairs.

The registry imports no torch: the environment classes are imported when first used
(``from drltg.envs import FourRoomsEnv`` or building a task), so listing tasks stays fast.
"""
import importlib

import drltg.envs.tasks  # noqa: F401  (registers the built-in tasks and pairs)
from drltg.envs.gym import register_gym_task, resolve
from drltg.envs.registry import (
    PAIRS,
    RESOLVERS,
    TASKS,
    PairSpec,
    TaskSpec,
    get_pair,
    get_task,
    make_env,
    register_pair,
    register_task,
)

RESOLVERS.append(resolve)  # gym/<ID> names every installed Gymnasium id

_LAZY = {
    "FourRoomsEnv": "drltg.envs.fourrooms",
    "GridFourRoomsEnv": "drltg.envs.gridrooms",
    "RobosuiteEnv": "drltg.envs.robosuite.env",  # robosuite itself is imported when one is built
}


def __getattr__(name: str):
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'drltg.envs' has no attribute {name!r}")


__all__ = [
    "FourRoomsEnv",
    "GridFourRoomsEnv",
    "RobosuiteEnv",
    "PAIRS",
    "TASKS",
    "PairSpec",
    "TaskSpec",
    "get_pair",
    "get_task",
    "make_env",
    "register_pair",
    "register_task",
    "register_gym_task",
]
