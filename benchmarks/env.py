"""Suite ``env``: frames per second of drltg's batched ``FourRoomsEnv`` against a single-environment
NumPy implementation of the same dynamics, the reference a user would write.

drltg is timed in the loop a collector runs (``step_and_maybe_reset``: a step plus the partial
reset of finished episodes) with pre-drawn random actions. The reference steps one environment in a
Python loop (reset when the episode ends) in two styles: NumPy arrays (the reference of the
target) and plain Python floats (for a system this small several times faster than NumPy; reported
too). Before timing, both references are checked to reproduce ``FourRoomsEnv``'s positions, rewards
and episode ends on the same starts and actions.

Where the collector loop's time goes is shown by two more cases at the large batch sizes:
``drltg_step_batch_*`` (``env.step`` with no resets: TorchRL's step bookkeeping plus the dynamics)
and ``drltg_dynamics_batch_*`` (``FourRoomsEnv._step`` alone: the batched dynamics' own tensor
arithmetic, with no TorchRL code around it).
"""
from __future__ import annotations

import math

import numpy as np
import torch

from benchmarks.common import interleaved, ratio, stepping
from drltg.envs import FourRoomsEnv
from drltg.envs.fourrooms import ARENA_SIZE, WALLS

GOAL, GOAL_RADIUS, MAX_STEP, STEP_COST, HORIZON = (8.0, 8.0), 0.5, 0.5, 0.01, 100


class NumpyFourRooms:
    """Continuous FourRooms for one agent, gymnasium-style ``reset``/``step``, NumPy arrays."""

    walls = np.array(WALLS)

    def __init__(self, seed: int = 0):
        self.rng = np.random.default_rng(seed)
        self.goal = np.array(GOAL)

    def reset(self, position=None):
        while position is None:
            p = self.rng.uniform(0.0, ARENA_SIZE, 2)
            inside = (
                (self.walls[:, 0] < p[0]) & (p[0] < self.walls[:, 2])
                & (self.walls[:, 1] < p[1]) & (p[1] < self.walls[:, 3])
            )
            if not inside.any() and np.linalg.norm(p - self.goal) > GOAL_RADIUS:
                position = p
        self.pos, self.t = np.asarray(position, dtype=np.float64), 0
        return self.pos * (2.0 / ARENA_SIZE) - 1.0, {}

    def _slide(self, coord, across, delta, axis):
        w = self.walls
        lo, hi, olo, ohi = w[:, axis], w[:, axis + 2], w[:, 1 - axis], w[:, 3 - axis]
        in_the_way = (olo < across) & (across < ohi)
        upper = np.where(in_the_way & (lo >= coord), lo, ARENA_SIZE).min()
        lower = np.where(in_the_way & (hi <= coord), hi, 0.0).max()
        return min(max(coord + delta, lower), upper)

    def step(self, action):
        d = np.clip(action, -1.0, 1.0) * MAX_STEP
        x = self._slide(self.pos[0], self.pos[1], d[0], 0)
        y = self._slide(self.pos[1], x, d[1], 1)
        self.pos, self.t = np.array([x, y]), self.t + 1
        success = np.linalg.norm(self.pos - self.goal) <= GOAL_RADIUS
        truncated = self.t >= HORIZON and not success
        reward = 1.0 if success else -STEP_COST
        return self.pos * (2.0 / ARENA_SIZE) - 1.0, reward, bool(success), truncated, {}


class FloatFourRooms(NumpyFourRooms):
    """The same environment on Python floats (no array per step)."""

    def _slide(self, coord, across, delta, axis):
        upper, lower = ARENA_SIZE, 0.0
        for w in WALLS:
            lo, hi, olo, ohi = w[axis], w[axis + 2], w[1 - axis], w[3 - axis]
            if olo < across < ohi:
                if lo >= coord:
                    upper = min(upper, lo)
                if hi <= coord:
                    lower = max(lower, hi)
        return min(max(coord + delta, lower), upper)

    def step(self, action):
        ax = min(max(float(action[0]), -1.0), 1.0) * MAX_STEP
        ay = min(max(float(action[1]), -1.0), 1.0) * MAX_STEP
        x = self._slide(self.pos[0], self.pos[1], ax, 0)
        y = self._slide(self.pos[1], x, ay, 1)
        self.pos, self.t = (x, y), self.t + 1
        success = math.hypot(x - GOAL[0], y - GOAL[1]) <= GOAL_RADIUS
        truncated = self.t >= HORIZON and not success
        reward = 1.0 if success else -STEP_COST
        return (x * 0.2 - 1.0, y * 0.2 - 1.0), reward, success, truncated, {}

    def reset(self, position=None):
        obs, info = super().reset(position)
        self.pos = (float(self.pos[0]), float(self.pos[1]))
        return obs, info


def make_drltg(batch: int, device: str) -> FourRoomsEnv:
    return FourRoomsEnv(GOAL, goal_radius=GOAL_RADIUS, max_step=MAX_STEP, step_cost=STEP_COST, horizon=HORIZON,
                        batch_size=(batch,), device=device, seed=0)


def check_same_dynamics(steps: int = 300, batch: int = 64) -> float:
    """Largest position difference between FourRoomsEnv and both references over ``steps`` random
    steps from FourRoomsEnv's starts; raises if rewards or episode ends differ."""
    env = make_drltg(batch, "cpu")
    td = env.reset()
    gen = torch.Generator().manual_seed(1)
    refs = []
    for cls in (NumpyFourRooms, FloatFourRooms):
        for p in td["position"].double().tolist():
            r = cls()
            r.reset(p)
            refs.append(r)
    worst = 0.0
    for _ in range(steps):
        action = torch.rand(batch, 2, generator=gen) * 2.4 - 1.2
        stepped, td = env.step_and_maybe_reset(td.set("action", action))
        out = stepped["next"]
        pos = out["position"].double()
        for i, r in enumerate(refs):
            j = i % batch
            _, reward, terminated, truncated, _ = r.step(action[j].double().numpy())
            worst = max(worst, float(np.abs(np.asarray(r.pos) - pos[j].numpy()).max()))
            same_end = (terminated, truncated) == (bool(out["terminated"][j]), bool(out["truncated"][j]))
            if not same_end or abs(reward - float(out["reward"][j])) > 1e-6:
                raise AssertionError(f"reference {type(r).__name__} diverged from FourRoomsEnv at element {j}")
            if terminated or truncated:
                r.reset(td["position"][j].double().tolist())
    return worst


def _reference_case(cls, steps: int):
    env = cls(seed=0)
    env.reset()
    actions = np.random.default_rng(0).uniform(-1.0, 1.0, (1024, 2))

    def run() -> int:
        for i in range(steps):
            _, _, terminated, truncated, _ = env.step(actions[i % 1024])
            if terminated or truncated:
                env.reset()
        return steps

    return run


def _drltg_case(batch: int, device: str, steps: int):
    env = make_drltg(batch, device)
    gen = torch.Generator().manual_seed(0)
    actions = [(torch.rand(batch, 2, generator=gen) * 2 - 1).to(device) for _ in range(16)]
    return stepping(env, actions, steps)


def _drltg_part_case(batch: int, device: str, steps: int, dynamics_only: bool):
    env = make_drltg(batch, device)
    td = env.reset()
    td["action"] = (torch.rand(batch, 2, generator=torch.Generator().manual_seed(0)) * 2 - 1).to(device)

    def run() -> int:
        for _ in range(steps):
            env._step(td) if dynamics_only else env.step(td.clone(False))
        return steps * batch

    return run


def run(device: str = "cpu", quick: bool = False) -> dict:
    batches = (1, 1024) if quick else (1, 16, 256, 1024, 4096)
    rounds = 3 if quick else 5
    worst = check_same_dynamics(steps=100 if quick else 300)
    cases = {
        "numpy_reference": _reference_case(NumpyFourRooms, 2000),
        "float_reference": _reference_case(FloatFourRooms, 2000),
    }
    for b in batches:
        cases[f"drltg_batch_{b}"] = _drltg_case(b, device, 100 if b > 1 else 300)
    for b in [b for b in batches if b >= 1024]:
        cases[f"drltg_step_batch_{b}"] = _drltg_part_case(b, device, 100, dynamics_only=False)
        cases[f"drltg_dynamics_batch_{b}"] = _drltg_part_case(b, device, 100, dynamics_only=True)
    results = interleaved(cases, rounds=rounds, warmup=1, device=device)
    return {
        "unit": "frames/s",
        "same_dynamics_max_position_error": worst,
        "rates": results,
        "ratios": {
            f"drltg_batch_{b}/numpy_reference": ratio(results, f"drltg_batch_{b}", "numpy_reference") for b in batches
        },
        "ratios_vs_float_reference": {
            f"drltg_batch_{b}/float_reference": ratio(results, f"drltg_batch_{b}", "float_reference") for b in batches
        },
        "target": "drltg >= 100x the NumPy reference at batch >= 1024",
    }
