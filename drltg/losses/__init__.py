"""Loss modules drltg adds to TorchRL's (SAC and TD3 come from ``torchrl.objectives``)."""
from drltg.losses.soc import SoftOptionCriticLoss

__all__ = ["SoftOptionCriticLoss"]
