"""robosuite manipulation tasks (Lift, Lift+Place, Lift+Place with barrier) as TorchRL envs.

Importing this package imports neither robosuite nor torch (its names are imported on first use);
building a :class:`RobosuiteEnv` imports robosuite.
"""
import importlib

_LAZY = {
    "PickPlaceDemonstrator": "demonstrator",
    "demonstrator_for": "demonstrator",
    "TASK_CLASSES": "env",
    "RobosuiteEnv": "env",
    "make_robosuite_env": "env",
    "LAYOUT": "layout",
    "OBSERVABLES": "layout",
    "OBSERVATION_SIZE": "layout",
    "Carry": "potentials",
    "Grasp": "potentials",
    "LiftHeight": "potentials",
    "LiftPotential": "potentials",
    "PlacePotential": "potentials",
    "Reach": "potentials",
    "potential_for": "potentials",
}


def __getattr__(name: str):
    if name in _LAZY:
        return getattr(importlib.import_module(f"drltg.envs.robosuite.{_LAZY[name]}"), name)
    raise AttributeError(f"module 'drltg.envs.robosuite' has no attribute {name!r}")


__all__ = sorted(_LAZY)
