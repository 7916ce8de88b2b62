"""TensorDict transforms: potential-based reward shaping and its potentials.

    PotentialShaping        r' = r + gamma * Phi(s') * (1 - terminated) - Phi(s)     (shaping)
    TimeDependentPotential  Phi(s, t) = schedule(t) * Phi(s)                        (shaping)
    SourceValue             Phi(s) = scale * min_k Q_k^source(s, mu^source(s))       (source_value)

The tasks' own potentials live beside their tasks (``drltg.envs``).
"""
from drltg.transforms.shaping import PotentialShaping, TimeDependentPotential
from drltg.transforms.source_value import SourceValue

__all__ = ["PotentialShaping", "TimeDependentPotential", "SourceValue"]
