"""drltg — the DRL Transfer Gym: transfer-learning methods for deep RL as composable TorchRL parts."""

__version__ = "0.1.0"

from drltg import gymnasium_ids  # noqa: E402  (registers drltg/<task>-v0 ids with Gymnasium, lazily)

gymnasium_ids.install()
