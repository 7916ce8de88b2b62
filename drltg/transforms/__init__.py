"""TensorDict transforms for transfer: potential-based reward shaping and its potentials."""
from drltg.transforms.potentials import FourRoomsPotential, GridFourRoomsPotential, TimeDependentPotential
from drltg.transforms.shaping import PotentialShaping

__all__ = ["FourRoomsPotential", "GridFourRoomsPotential", "PotentialShaping", "TimeDependentPotential"]
