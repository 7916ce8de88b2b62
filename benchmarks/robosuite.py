"""Suite ``robosuite``: the cost of drltg's ``RobosuiteEnv`` over robosuite itself, and ``ParallelEnv``
scaling, on Lift (Panda, OSC_POSE, 20 Hz, object observations, no cameras).

* ``raw``: robosuite's own ``env.step(action)`` loop (reset after 500 steps), on the robosuite
  environment a ``RobosuiteEnv`` builds, so both are constructed with identical arguments;
* ``drltg``: ``RobosuiteEnv`` stepped the way a collector steps it (``step_and_maybe_reset``);
* ``parallel_1`` / ``parallel_2``: ``ParallelEnv`` with one and two worker processes (frames/s over
  all workers).

All loops replay the same pre-drawn uniform actions.
"""
from __future__ import annotations

import numpy as np
import torch

from benchmarks.common import interleaved, ratios

TASK, HORIZON = "lift", 500


def _actions(n: int = 64) -> np.ndarray:
    return np.random.default_rng(0).uniform(-1.0, 1.0, (n, 7))


def raw_case(steps: int):
    from drltg.envs.robosuite import RobosuiteEnv

    env = RobosuiteEnv(TASK, horizon=HORIZON, seed=0).robosuite_env
    env.reset()
    actions = _actions()
    state = {"t": 0}

    def run() -> int:
        for i in range(steps):
            env.step(actions[i % len(actions)])
            state["t"] += 1
            if state["t"] >= HORIZON:
                env.reset()
                state["t"] = 0
        return steps

    return run, env


def drltg_case(steps: int, workers: int | None = None):
    import functools

    from torchrl.envs import ParallelEnv

    from drltg.envs.robosuite import RobosuiteEnv

    if workers is None:
        env = RobosuiteEnv(TASK, horizon=HORIZON, seed=0)
    else:
        env = ParallelEnv(workers, functools.partial(RobosuiteEnv, TASK, horizon=HORIZON))
        env.set_seed(0)
    n = max(env.batch_size.numel(), 1)
    actions = [torch.as_tensor(a, dtype=torch.float32).expand(*env.batch_size, 7).clone() for a in _actions()]
    state = {"td": env.reset()}

    def run() -> int:
        td = state["td"]
        for i in range(steps):
            td["action"] = actions[i % len(actions)]
            _, td = env.step_and_maybe_reset(td)
        state["td"] = td
        return steps * n

    return run, env


def run(device: str = "cpu", quick: bool = False) -> dict:
    try:
        import robosuite  # noqa: F401
    except ImportError as err:
        return {"missing": f"robosuite not importable ({err}); pip install -e '.[robosuite]'"}
    steps, rounds = (50, 2) if quick else (100, 5)
    made = {"raw": raw_case(steps), "drltg": drltg_case(steps)}
    if not quick:
        made["parallel_1"] = drltg_case(steps, workers=1)
        made["parallel_2"] = drltg_case(steps, workers=2)
    try:
        results = interleaved({k: v[0] for k, v in made.items()}, rounds=rounds, warmup=1)
    finally:
        for name, (_, env) in made.items():
            if name != "raw":
                env.close()
    return {
        "unit": "frames/s",
        "task": f"{TASK}, horizon {HORIZON}",
        "rates": results,
        "ratios": ratios(results, [("drltg", "raw"), ("parallel_2", "parallel_1"), ("parallel_1", "drltg")]),
        "target": "drltg >= 0.9x raw; parallel_2 >= 1.6x parallel_1",
        "note": "cpu-clock rates of ParallelEnv count only the main process, not its workers: compare parallel cases on the wall clock",
    }
