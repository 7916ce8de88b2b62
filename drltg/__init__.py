"""drltg — the DRL Transfer Gym: transfer-learning methods for deep RL as composable TorchRL parts."""

__version__ = "0.1.0"
