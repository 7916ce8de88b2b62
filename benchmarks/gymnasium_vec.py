"""Suite ``gymnasium``: frames per second of FourRooms through Gymnasium's vector API.

Three ways to step ``n`` FourRooms agents from NumPy actions, as a Gymnasium agent does:

* ``make_vec_native_n``: ``gymnasium.make_vec("drltg/fourrooms-northeast-v0", num_envs=n)``, drltg's
  vector entry point (one torch env of batch ``n``, finished elements reset in the same step);
* ``sync_copies_n``: Gymnasium's ``SyncVectorEnv`` of ``n`` single-episode ``drltg/...`` envs, what a
  vector env made of copies costs;
* ``torch_n``: the torch env itself in a collector's loop (``step_and_maybe_reset``), the ceiling.

Ratios ``make_vec_native_n/sync_copies_n`` (what the native vector env buys) and
``make_vec_native_n/torch_n`` (what the Gymnasium interface costs) are reported side by side.
"""
from __future__ import annotations

import gymnasium
import numpy as np
import torch

import drltg  # noqa: F401  (registers the drltg/ ids)
from benchmarks.common import interleaved, ratios, stepping
from drltg.envs import make_env

ENV_ID, TASK = "drltg/fourrooms-northeast-v0", "fourrooms/northeast"


def _vector_case(env, steps: int):
    n = env.num_envs
    actions = np.random.default_rng(0).uniform(-1, 1, (16, n, 2)).astype(np.float32)
    env.reset(seed=0)

    def run() -> int:
        for i in range(steps):
            env.step(actions[i % 16])
        return steps * n

    return run


def _torch_case(n: int, steps: int):
    env = make_env(TASK, batch_size=(n,), seed=0)
    actions = [torch.rand(n, 2, generator=torch.Generator().manual_seed(i)) * 2 - 1 for i in range(16)]
    return stepping(env, actions, steps)


def run(device: str = "cpu", quick: bool = False) -> dict:
    sizes = (16,) if quick else (16, 256)
    cases = {}
    for n in sizes:
        steps = 50 if n > 16 else 200
        cases[f"make_vec_native_{n}"] = _vector_case(gymnasium.make_vec(ENV_ID, num_envs=n), steps)
        copies = gymnasium.vector.SyncVectorEnv([lambda: gymnasium.make(ENV_ID)] * n,
                                                autoreset_mode=gymnasium.vector.AutoresetMode.SAME_STEP)
        cases[f"sync_copies_{n}"] = _vector_case(copies, max(steps // n, 2) if n > 16 else 20)
        cases[f"torch_{n}"] = _torch_case(n, steps)
    results = interleaved(cases, rounds=3 if quick else 5)
    pairs = [(f"make_vec_native_{n}", other) for n in sizes for other in (f"sync_copies_{n}", f"torch_{n}")]
    return {"device": "cpu", "rates_frames_per_s": results, "ratios": ratios(results, pairs)}
