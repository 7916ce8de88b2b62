"""A drltg task as a Gymnasium environment: :class:`DrltgEnv` (one episode) and :class:`DrltgVectorEnv`.

The agent sees what drltg's learners see: the ``"observation"`` entry alone (a Box; the state entries
such as ``position`` and ``step_count`` stay inside), a float reward, bool ``terminated`` and
``truncated``, and the episode flags the task reports (``success``; ``lifted`` on the manipulation
tasks) in ``info``. A one-hot action spec is a ``Discrete`` space. Every draw of the task comes from
its own generator, seeded from the Gymnasium ``np_random`` at each ``reset(seed=...)``.

:class:`DrltgVectorEnv` steps the task's own batch (``batch_size=(num_envs,)``: one batched torch
env, not ``num_envs`` copies) and resets a finished element in the same step
(``AutoresetMode.SAME_STEP``: ``info["final_obs"]`` holds its last observation).
"""
from __future__ import annotations

import numbers
from typing import Any

import gymnasium
import numpy as np
import torch
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from torchrl.data import Categorical, OneHot
from torchrl.envs.utils import step_mdp

from drltg.envs.registry import make_env
from drltg.store.rundir import EPISODE_FLAGS

__all__ = ["DrltgEnv", "DrltgVectorEnv", "observation_space", "action_space"]

_SEED_BOUND = 2**31 - 1


def observation_space(spec) -> gymnasium.spaces.Box:
    """The Box of an observation spec: its bounds where it has them, unbounded otherwise."""
    dtype = np.dtype(str(spec.dtype).removeprefix("torch."))
    space = getattr(spec, "space", None)
    low, high = getattr(space, "low", None), getattr(space, "high", None)
    if low is None or high is None:
        return gymnasium.spaces.Box(-np.inf, np.inf, tuple(spec.shape), dtype)
    low = np.broadcast_to(low.cpu().numpy(), spec.shape).astype(dtype)
    high = np.broadcast_to(high.cpu().numpy(), spec.shape).astype(dtype)
    return gymnasium.spaces.Box(low, high, tuple(spec.shape), dtype)


def action_space(spec) -> gymnasium.spaces.Space:
    """``Discrete(n)`` for a one-hot or categorical action spec, else the Box of its bounds."""
    if isinstance(spec, (OneHot, Categorical)):
        return gymnasium.spaces.Discrete(spec.space.n)
    return observation_space(spec)


def _is_number_array(action, space) -> bool:
    """A list or array of numbers for a Box (Box.contains wants its own dtype); a Discrete action is
    checked as given, so that 1.7 is not read as 1."""
    return isinstance(space, gymnasium.spaces.Box) and isinstance(action, (list, tuple, np.ndarray)) and \
        np.asarray(action).dtype.kind in "biuf"


class _Adapter:
    """What both adapters share: the specs, action encoding and the flags read into ``info``."""

    def _bind(self, env) -> None:
        self._env = env
        unbatched = env.full_observation_spec_unbatched
        self._obs_space = observation_space(unbatched["observation"])
        self._action_spec = env.full_action_spec_unbatched["action"]
        self._act_space = action_space(self._action_spec)
        self._flags = [key for key in EPISODE_FLAGS if key in unbatched.keys()]
        self._td = None

    def _action(self, action, space: gymnasium.spaces.Space) -> torch.Tensor:
        if not space.contains(np.asarray(action, dtype=space.dtype) if _is_number_array(action, space) else action):
            raise ValueError(f"action {action!r} is not in the action space {space} of task {self.task!r}.")
        action = torch.as_tensor(np.asarray(action), device=self._env.device)
        if isinstance(self._action_spec, OneHot):
            return torch.nn.functional.one_hot(action.long(), self._act_space.n).to(self._action_spec.dtype)
        if isinstance(self._action_spec, Categorical):
            return action.to(self._action_spec.dtype).reshape(self._env.action_spec.shape)
        return action.to(self._action_spec.dtype)

    def _obs(self, td) -> np.ndarray:
        return td["observation"].detach().cpu().numpy().astype(self._obs_space.dtype, copy=True)

    def _reseed(self, seed: int | None) -> None:
        """Seeds the task's generator from ``np_random`` (itself seeded by ``seed``, or at random once)."""
        if seed is not None or not self._seeded:
            self._env.set_seed(int(self.np_random.integers(_SEED_BOUND)))
            self._seeded = True


class DrltgEnv(_Adapter, gymnasium.Env):
    """The drltg task ``task`` (``make_env(task, **options)``, one episode at a time) as a Gymnasium env.

    ``render_mode="rgb_array"`` renders the task's image (the tasks that draw one)."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(self, task: str, render_mode: str | None = None, **options: Any):
        self.task = task
        self._bind(make_env(task, **options))
        if not callable(getattr(self._env, "render", None)):
            self.metadata = {**self.metadata, "render_modes": []}
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            modes = self.metadata["render_modes"] or "nothing"
            raise ValueError(f"task {task!r} renders {modes}, not {render_mode!r}.")
        self.render_mode = render_mode
        self.observation_space = self._obs_space
        self.action_space = self._act_space
        self._seeded = False

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        self._reseed(seed)
        self._td = self._env.reset()
        return self._obs(self._td), {key: bool(self._td[key].item()) for key in self._flags}

    def step(self, action):
        if self._td is None:
            raise gymnasium.error.ResetNeeded("call reset() before step().")
        td = self._env.step(self._td.set("action", self._action(action, self.action_space)))
        nxt = td["next"]
        info = {key: bool(nxt[key].item()) for key in self._flags}
        self._td = step_mdp(td, keep_other=True)
        return (self._obs(nxt), float(nxt["reward"].item()), bool(nxt["terminated"].item()),
                bool(nxt["truncated"].item()), info)

    def render(self):
        if self.render_mode != "rgb_array":
            return None
        return self._env.render(self._td)

    def close(self):
        if not self._env.is_closed:
            self._env.close()


class DrltgVectorEnv(_Adapter, VectorEnv):
    """``num_envs`` elements of the drltg task ``task`` as one batched torch env (``make_env(task,
    batch_size=(num_envs,), **options)``), a Gymnasium vector env that resets a finished element in
    the same step."""

    metadata = {"autoreset_mode": AutoresetMode.SAME_STEP, "render_modes": []}

    def __init__(self, task: str, num_envs: int = 1, **options: Any):
        self.task = task
        if not isinstance(num_envs, numbers.Integral) or num_envs < 1:
            raise ValueError(f"num_envs must be a positive integer, got {num_envs!r}.")
        self.num_envs = int(num_envs)
        self._bind(make_env(task, batch_size=(self.num_envs,), **options))
        self.single_observation_space = self._obs_space
        self.single_action_space = self._act_space
        self.observation_space = batch_space(self._obs_space, self.num_envs)
        self.action_space = batch_space(self._act_space, self.num_envs)
        self._seeded = False

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        if seed is not None and not isinstance(seed, int):
            raise ValueError(f"DrltgVectorEnv takes one int seed for its batch, got {seed!r}.")
        super().reset(seed=seed)
        self._reseed(seed)
        self._td = self._env.reset()
        return self._obs(self._td), self._info(self._td)

    def step(self, actions):
        if self._td is None:
            raise gymnasium.error.ResetNeeded("call reset() before step().")
        td, self._td = self._env.step_and_maybe_reset(self._td.set("action", self._action(actions, self.action_space)))
        nxt = td["next"]
        done = nxt["done"].reshape(self.num_envs).cpu().numpy()
        info = self._info(nxt)
        if done.any():
            final = np.empty(self.num_envs, dtype=object)
            last = self._obs(nxt)
            for i in np.flatnonzero(done):
                final[i] = last[i]
            info |= {"final_obs": final, "_final_obs": done,
                     "final_info": self._info(nxt, mask=done), "_final_info": done}
        return (self._obs(self._td), nxt["reward"].reshape(self.num_envs).cpu().numpy().astype(np.float64),
                nxt["terminated"].reshape(self.num_envs).cpu().numpy(),
                nxt["truncated"].reshape(self.num_envs).cpu().numpy(), info)

    def _info(self, td, mask: np.ndarray | None = None) -> dict:
        info = {}
        for key in self._flags:
            info[key] = td[key].reshape(self.num_envs).cpu().numpy()
            info[f"_{key}"] = np.ones(self.num_envs, dtype=bool) if mask is None else mask
        return info

    def close_extras(self, **kwargs):
        if not self._env.is_closed:
            self._env.close()
