"""robosuite manipulation tasks (Lift, Lift+Place, Lift+Place with barrier) as TorchRL envs.

Importing this package does not import robosuite; building a :class:`RobosuiteEnv` does.
"""
from drltg.envs.robosuite.demonstrator import PickPlaceDemonstrator, demonstrator_for
from drltg.envs.robosuite.env import TASK_CLASSES, RobosuiteEnv, make_robosuite_env
from drltg.envs.robosuite.layout import LAYOUT, OBSERVABLES, OBSERVATION_SIZE
from drltg.envs.robosuite.potentials import (
    Carry,
    Grasp,
    LiftHeight,
    LiftPotential,
    PlacePotential,
    Reach,
    potential_for,
)

__all__ = [
    "Carry",
    "Grasp",
    "LAYOUT",
    "LiftHeight",
    "LiftPotential",
    "OBSERVABLES",
    "OBSERVATION_SIZE",
    "PickPlaceDemonstrator",
    "PlacePotential",
    "Reach",
    "RobosuiteEnv",
    "TASK_CLASSES",
    "demonstrator_for",
    "make_robosuite_env",
    "potential_for",
]
