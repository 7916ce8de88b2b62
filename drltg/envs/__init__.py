"""Task environments (TorchRL ``EnvBase``) and the registry of tasks and task pairs."""
from drltg.envs.fourrooms import FourRoomsEnv
from drltg.envs.gridrooms import GridFourRoomsEnv
from drltg.envs.gym import register_gym_task
from drltg.envs.registry import (
    PAIRS,
    TASKS,
    PairSpec,
    TaskSpec,
    get_pair,
    get_task,
    make_env,
    register_pair,
    register_task,
)
from drltg.envs.robosuite import RobosuiteEnv  # robosuite itself is imported when one is built

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
