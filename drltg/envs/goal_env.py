"""The skeleton both FourRooms envs share: reach a goal in a batch of independent episodes.

A step pays ``+1`` and terminates on reaching the goal (``success``), costs ``step_cost`` otherwise, and
is truncated (never terminated) after ``horizon`` steps. The state is one entry (``state_key``: the
continuous ``position`` or the grid ``cell``) plus ``step_count``; starts and noise come from a CPU
generator, the env's own (``set_seed``).
Subclasses pass the common settings to ``GoalEnv.__init__`` (which checks the horizon), build their specs with
:meth:`_state_specs`, seed with :meth:`_seed_or_draw`, and write :meth:`_observe`, the start draw and the
move; :meth:`_first` and :meth:`_next` assemble what ``_reset`` and ``_step`` return.
"""
from __future__ import annotations

from typing import Sequence

import torch
from tensordict import TensorDict
from torchrl.data import Bounded, Categorical, Composite, TensorSpec, Unbounded
from torchrl.envs import EnvBase

from drltg.envs.limits import MAX_HORIZON
from drltg.errors import UsageError


class GoalEnv(EnvBase):
    state_key: str
    _supports_set_state = True

    def __init__(
        self,
        *,
        step_cost: float,
        horizon: int,
        observe_goal: bool,
        batch_size: Sequence[int] | torch.Size,
        device: torch.device | str | None,
    ):
        super().__init__(device=device, batch_size=torch.Size(batch_size))
        if horizon < 1:
            raise UsageError(f"horizon {horizon} must be at least 1 step.")
        if horizon > MAX_HORIZON:
            raise UsageError(f"horizon {horizon} is more than the {MAX_HORIZON:,} steps an evaluation runs an episode.")
        self.step_cost = float(step_cost)
        self.horizon = int(horizon)
        self.observe_goal = bool(observe_goal)

    def _seed_or_draw(self, seed: int | None) -> None:
        """Seed the env's generator; ``None`` draws the seed from torch's global RNG."""
        if seed is None:
            seed = torch.empty((), dtype=torch.int64).random_().item()
        self.set_seed(seed)

    def _state_specs(self, state: TensorSpec, obs_dim: int) -> None:
        """Set every spec from the state entry's spec and the observation's size."""
        flag = Categorical(2, (1,), dtype=torch.bool, device=self.device)
        full_state = Composite(
            {self.state_key: state,
             "step_count": Bounded(0, self.horizon, (1,), dtype=torch.int64, device=self.device)},
            device=self.device,
        )
        observation = full_state.clone()
        observation["observation"] = Bounded(-1.0, 1.0, (obs_dim,), dtype=torch.float32, device=self.device)
        observation["success"] = flag.clone()
        self.observation_spec = observation.expand(self.batch_size)
        self.state_spec = full_state.expand(self.batch_size)
        self.reward_spec = Unbounded((*self.batch_size, 1), dtype=torch.float32, device=self.device)
        self.done_spec = Composite(
            done=flag.clone(), terminated=flag.clone(), truncated=flag.clone(), device=self.device
        ).expand(self.batch_size)

    def _observe(self, state: torch.Tensor) -> torch.Tensor:
        raise NotImplementedError

    def _set_seed(self, seed: int | None) -> None:
        self.rng = torch.Generator()
        if seed is not None:
            self.rng.manual_seed(seed)

    def _first(self, state: torch.Tensor) -> TensorDict:
        """What ``_reset`` returns for the start states ``state``."""
        shape = self.batch_size
        return TensorDict(
            {
                "observation": self._observe(state),
                self.state_key: state,
                "step_count": torch.zeros((*shape, 1), dtype=torch.int64, device=self.device),
                "success": torch.zeros((*shape, 1), dtype=torch.bool, device=self.device),
            },
            batch_size=shape,
            device=self.device,
        )

    def _next(self, state: torch.Tensor, step_count: torch.Tensor, success: torch.Tensor) -> TensorDict:
        """What ``_step`` returns for the next states: +1 and terminated at the goal, else the step cost;
        truncated at the horizon."""
        truncated = (step_count >= self.horizon) & ~success
        return TensorDict(
            {
                "observation": self._observe(state),
                self.state_key: state,
                "step_count": step_count,
                "success": success,
                "reward": torch.where(success, 1.0, -self.step_cost),
                "done": success | truncated,
                "terminated": success,
                "truncated": truncated,
            },
            batch_size=self.batch_size,
            device=self.device,
        )
