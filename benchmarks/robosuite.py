"""Suite ``robosuite``: ``RobosuiteEnv`` against robosuite's own ``env.step``, where the time of a step
goes, whether the lean step reproduces robosuite over whole episodes, and ``ParallelEnv`` scaling, on
Lift (Panda, OSC_POSE, 20 Hz, 25 physics substeps per step, object observations, no cameras).

Cases, stepped in interleaved rounds on the same pre-drawn uniform actions:

* ``raw``: robosuite's ``env.step(action)`` loop (reset after 500 steps), on the robosuite environment
  a ``RobosuiteEnv(fast=False)`` builds, so both are constructed with identical arguments;
* ``drltg``: ``RobosuiteEnv`` (its default lean step) stepped the way a collector steps it
  (``step_and_maybe_reset``);
* ``drltg_robosuite_step``: the same with ``fast=False`` (robosuite's ``env.step`` inside);
* ``lean``: ``LeanStep.step`` alone, without TorchRL;
* ``parallel_1`` / ``parallel_2``: ``ParallelEnv`` with one and two workers (frames/s over all workers).

``split`` times the parts of the lean step and of robosuite's step with clocks around MuJoCo's calls
and the OSC kernel; ``equivalence`` replays the demonstrator and random actions on all three tasks with
the lean step and with robosuite's, and reports the largest differences.
"""
from __future__ import annotations

import time

import numpy as np
import torch

from benchmarks.common import interleaved, ratios, stepping

TASK, HORIZON = "lift", 500
TASKS = ("lift", "lift-place", "lift-place-barrier")


def _actions(n: int = 64) -> np.ndarray:
    return np.random.default_rng(0).uniform(-1.0, 1.0, (n, 7))


def _episodes(step, reset, steps: int):
    """A timed loop of ``steps`` calls of ``step`` on the fixed actions, ``reset`` every HORIZON steps."""
    actions = _actions()
    state = {"t": 0}

    def run() -> int:
        for i in range(steps):
            step(actions[i % len(actions)])
            state["t"] += 1
            if state["t"] >= HORIZON:
                reset()
                state["t"] = 0
        return steps

    return run


def raw_case(steps: int):
    from drltg.envs.robosuite import RobosuiteEnv

    env = RobosuiteEnv(TASK, horizon=HORIZON, seed=0, fast=False).robosuite_env
    env.reset()
    return _episodes(env.step, env.reset, steps), env


def lean_case(steps: int):
    from drltg.envs.robosuite import RobosuiteEnv

    drltg_env = RobosuiteEnv(TASK, horizon=HORIZON, seed=0)
    env = drltg_env.robosuite_env
    return _episodes(drltg_env._lean.step, env.reset, steps), drltg_env


def drltg_case(steps: int, workers: int | None = None, fast: bool = True):
    import functools

    from torchrl.envs import ParallelEnv

    from drltg.envs.robosuite import RobosuiteEnv

    if workers is None:
        env = RobosuiteEnv(TASK, horizon=HORIZON, seed=0, fast=fast)
    else:
        env = ParallelEnv(workers, functools.partial(RobosuiteEnv, TASK, horizon=HORIZON, fast=fast))
        env.set_seed(0)
    actions = [torch.as_tensor(a, dtype=torch.float32).expand(*env.batch_size, 7).clone() for a in _actions()]
    return stepping(env, actions, steps), env


class _Clock:
    """Wraps a function and adds up the process CPU time spent in it."""

    def __init__(self, fn):
        self.fn, self.seconds = fn, 0.0

    def __call__(self, *args, **kwargs):
        start = time.process_time()
        out = self.fn(*args, **kwargs)
        self.seconds += time.process_time() - start
        return out


def split(steps: int = 200) -> dict:
    """Milliseconds of CPU time per step, by part, for the lean step alone (``lean``), for
    ``RobosuiteEnv`` around it (``drltg``) and for robosuite's own ``env.step`` (``raw``): MuJoCo
    (``mj_step1`` + ``mj_step2``); the arm controller (lean: the numba OSC kernel, mostly robosuite's
    ``opspace_matrices``, a 7x7 inverse and three pseudo-inverses per substep; raw: ``robot.control``
    at every substep); observables (lean: sampling the listed ones; raw: ``_update_observables`` at every
    substep and ``_get_observations``); the goal (lean, once per step); reward and task latches
    (``_post_action``); the rest (the substep loop, TorchRL's step for ``drltg``)."""
    import mujoco

    from drltg.envs.robosuite import RobosuiteEnv, fast_osc

    actions = _actions()
    out = {}
    step1, step2, kernel = mujoco.mj_step1, mujoco.mj_step2, fast_osc.osc_torques
    for case in ("lean", "drltg", "raw"):
        env = RobosuiteEnv(TASK, horizon=HORIZON, seed=0, fast=case != "raw")
        td = env.reset()
        rs = env.robosuite_env
        clocks = {"mujoco": [_Clock(step1), _Clock(step2)], "controller": [_Clock(kernel)]}
        mujoco.mj_step1, mujoco.mj_step2 = clocks["mujoco"]
        fast_osc.osc_torques = clocks["controller"][0]
        if case == "raw":
            robot = rs.robots[0]
            robot.control = _Clock(robot.control)
            rs._update_observables, rs._get_observations = _Clock(rs._update_observables), _Clock(rs._get_observations)
            clocks["controller"] = [robot.control]
            clocks["observables"] = [rs._update_observables, rs._get_observations]
        else:
            env._lean._sample, env._lean._goal = _Clock(env._lean._sample), _Clock(env._lean._goal)
            clocks["observables"], clocks["goal"] = [env._lean._sample], [env._lean._goal]
        rs._post_action = _Clock(rs._post_action)
        clocks["reward"] = [rs._post_action]
        try:
            start = time.process_time()
            for i in range(steps):
                if case == "lean":
                    env._lean.step(actions[i % len(actions)])
                elif case == "raw":
                    rs.step(actions[i % len(actions)])
                else:
                    td["action"] = torch.as_tensor(actions[i % len(actions)], dtype=torch.float32)
                    _, td = env.step_and_maybe_reset(td)
            total = time.process_time() - start
        finally:
            mujoco.mj_step1, mujoco.mj_step2, fast_osc.osc_torques = step1, step2, kernel
            env.close()
        ms = {part: 1e3 * sum(c.seconds for c in cs) / steps for part, cs in clocks.items()}
        ms["rest"] = 1e3 * total / steps - sum(ms.values())
        out[case] = {"ms_per_step": round(1e3 * total / steps, 3), **{k: round(v, 3) for k, v in ms.items()},
                     "shares": {k: round(v / (1e3 * total / steps), 3) for k, v in ms.items()}}
    return out


def equivalence(steps: int = HORIZON, seed: int = 0) -> dict:
    """Largest absolute differences between ``RobosuiteEnv`` with the lean step and with robosuite's
    ``env.step`` (positions, velocities, observations, rewards) and the number of steps whose success
    flags differ, over one ``steps``-step episode per task and policy (demonstrator, uniform random)."""
    from drltg.envs.robosuite import RobosuiteEnv, demonstrator_for

    out = {}
    for task in TASKS:
        fast = RobosuiteEnv(task, seed=seed, horizon=steps)
        slow = RobosuiteEnv(task, seed=seed, horizon=steps, fast=False)
        rng = np.random.default_rng(seed)
        policies = {"demonstrator": demonstrator_for(task).act,
                    "random": lambda obs: torch.as_tensor(rng.uniform(-1, 1, 7), dtype=torch.float32)}
        for name, policy in policies.items():
            a, b = fast.reset(), slow.reset()
            worst = {"qpos": 0.0, "qvel": 0.0, "observation": 0.0, "reward": 0.0}
            success_mismatch, successes = 0, 0
            for _ in range(steps):
                action = policy(a["observation"])
                a = fast.step(a.set("action", action))["next"]
                b = slow.step(b.set("action", action.clone()))["next"]
                da, db = fast.robosuite_env.sim.data, slow.robosuite_env.sim.data
                worst["qpos"] = max(worst["qpos"], float(np.abs(da.qpos - db.qpos).max()))
                worst["qvel"] = max(worst["qvel"], float(np.abs(da.qvel - db.qvel).max()))
                difference = (a["observation"] - b["observation"]).abs().max().item()
                worst["observation"] = max(worst["observation"], difference)
                worst["reward"] = max(worst["reward"], (a["reward"] - b["reward"]).abs().item())
                success_mismatch += int(a["success"].item() != b["success"].item())
                successes += int(a["success"].item())
            out[f"{task}/{name}"] = {**worst, "success_mismatches": success_mismatch, "success_steps": successes}
        fast.close()
        slow.close()
    out["identical"] = all(
        v["qpos"] == v["qvel"] == v["observation"] == v["reward"] == 0 and not v["success_mismatches"]
        for v in out.values()
    )
    return out


def run(device: str = "cpu", quick: bool = False) -> dict:
    try:
        import robosuite  # noqa: F401
    except ImportError as err:
        return {"missing": f"robosuite not importable ({err}); pip install -e '.[robosuite]'"}
    steps, rounds = (50, 2) if quick else (100, 7)
    made = {"raw": raw_case(steps), "drltg": drltg_case(steps), "lean": lean_case(steps),
            "drltg_robosuite_step": drltg_case(steps, fast=False)}
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
        "ratios": ratios(results, [("drltg", "raw"), ("lean", "raw"), ("drltg_robosuite_step", "raw"),
                                   ("parallel_2", "parallel_1"), ("parallel_1", "drltg")]),
        "split_ms_per_step": split(50 if quick else 200),
        "equivalence": equivalence(100 if quick else HORIZON),
        "target": "drltg >= 2x raw with identical trajectories; parallel_2 >= 1.6x parallel_1",
        "note": "cpu-clock rates of ParallelEnv count only the main process, not its workers: "
                "compare parallel cases on the wall clock",
    }


if __name__ == "__main__":
    import json
    import sys

    print(json.dumps(run(quick="--quick" in sys.argv), indent=1))
