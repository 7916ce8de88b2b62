"""TensorDict transforms for transfer: potential-based reward shaping and its potentials."""
from drltg.transforms.potentials import TimeDependentPotential
from drltg.transforms.shaping import PotentialShaping

__all__ = ["PotentialShaping", "TimeDependentPotential"]
