"""Suite ``lift``: ``drltg train lift`` against Stable-Baselines3 SAC on robosuite's Lift, end to end.

Three training runs of ``FRAMES`` frames take turns, one of each per round:

* ``drltg``: ``drltg.training.loop.train`` (what ``drltg train --task lift`` runs) with the task's settings
  (2 ``ParallelEnv`` workers with the lean robosuite step, replay 1e6, batch 256, 2x256 networks,
  Adam 3e-4, one update per frame after ``WARMUP`` random frames), except one evaluation episode
  and no TensorBoard;
* ``drltg_robosuite_step``: the same with ``env.fast=false`` (robosuite's own ``env.step`` inside),
  which splits the comparison into what the lean step gives and what the rest of the loop gives;
* ``sb3``: Stable-Baselines3 ``SAC`` on robosuite's ``GymWrapper`` around ``robosuite.make("Lift",
  ...)`` with robosuite's defaults (one env, OSC_POSE, hard reset), the same networks, batch, buffer,
  learning rate, warm-up and one gradient step per frame.

Only training is timed. ``drltg train`` always evaluates at frame 0 and at the last frame, and saves a
checkpoint at the end; its clocks are read at the end of the first evaluation, at the first update
batch and at the start of the last evaluation (``evaluate`` and ``sample_batches`` are wrapped to read
them). For ``sb3`` they are read around ``learn()`` and, by a callback, at the last warm-up frame. Two
windows are reported: ``updating`` (after the warm-up: one env step and one update per frame, the
steady state) and ``loop`` (the whole training loop, random warm-up and worker start included). CPU
time is that of the whole process tree (``ParallelEnv`` workers included), read from ``/proc``.
"""
from __future__ import annotations

import json
import os
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.common import ratios, summarize

FRAMES, WARMUP, ROUNDS = 1500, 500, 2
HORIZON = 500


def _tree_cpu_s() -> float:
    """CPU seconds (user + system) of this process and all its descendants: the living ones' own
    times, and the ended ones' through their parents' ``cutime``/``cstime``."""
    parent, cpu = {}, {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
        except OSError:  # ended while listed
            continue
        pid = int(entry)
        parent[pid] = int(fields[1])
        cpu[pid] = sum(int(t) for t in fields[11:15]) / os.sysconf("SC_CLK_TCK")
    me, total = os.getpid(), 0.0
    for pid, seconds in cpu.items():
        p = pid
        while p > 1 and p != me:
            p = parent.get(p, 0)
        if p == me:
            total += seconds
    return total


def drltg_run(fast: bool, frames: int = FRAMES, warmup: int = WARMUP) -> dict:
    """One ``drltg train --task lift`` run, read at three marks: the end of the first evaluation, the
    first update batch (the warm-up's frames are in the buffer) and the start of the last evaluation."""
    import drltg.training.loop as train_mod
    from drltg import config as config_lib

    overrides = [f"collector.init_random_frames={warmup}", "eval.episodes=1", f"eval.every={10 * frames}",
                 "log.tensorboard=false", f"env.fast={str(fast).lower()}"]
    cfg = config_lib.resolve({}, overrides, task="lift", frames=frames, seed=0)
    evals: list[tuple[float, float]] = []
    updating: list[tuple[float, float]] = []
    evaluate, sample_batches = train_mod.evaluate, train_mod.sample_batches

    def timed_evaluate(*args, **kwargs):
        evals.append((time.perf_counter(), _tree_cpu_s()))
        row = evaluate(*args, **kwargs)
        evals.append((time.perf_counter(), _tree_cpu_s()))
        return row

    def timed_sample_batches(*args, **kwargs):
        if not updating:
            updating.append((time.perf_counter(), _tree_cpu_s()))
        return sample_batches(*args, **kwargs)

    train_mod.evaluate, train_mod.sample_batches = timed_evaluate, timed_sample_batches
    try:
        with tempfile.TemporaryDirectory() as tmp:
            start = time.perf_counter()
            train_mod.train(cfg, Path(tmp) / "run", progress=False)
            whole = time.perf_counter() - start
            updates = json.loads((Path(tmp) / "run" / "summary.json").read_text())["updates"]
    finally:
        train_mod.evaluate, train_mod.sample_batches = evaluate, sample_batches
    begin, first_update, end = evals[1], updating[0], evals[-2]
    return {
        "loop": {"frames": frames, "wall_s": end[0] - begin[0], "cpu_s": end[1] - begin[1]},
        "updating": {"frames": frames - warmup, "wall_s": end[0] - first_update[0], "cpu_s": end[1] - first_update[1]},
        "updates": updates, "whole_call_s": round(whole, 1),
        "command": "drltg train --task lift --frames {} --seed 0 {}".format(frames, " ".join(overrides)),
    }


def sb3_env():
    """robosuite's Lift as a user of robosuite and Stable-Baselines3 builds it: robosuite's defaults
    (OSC_POSE arm, hard reset, object and proprioceptive state) behind its ``GymWrapper``."""
    import robosuite
    from robosuite.wrappers import GymWrapper

    env = robosuite.make("Lift", robots="Panda", use_camera_obs=False, has_offscreen_renderer=False,
                         has_renderer=False, reward_shaping=False, control_freq=20, horizon=HORIZON)
    return GymWrapper(env)


def sb3_run(frames: int = FRAMES, warmup: int = WARMUP) -> dict:
    """One Stable-Baselines3 SAC run with drltg's Lift settings, read at the start of ``learn()``, at
    the last warm-up frame (a callback) and at its end."""
    from stable_baselines3 import SAC
    from stable_baselines3.common.callbacks import BaseCallback

    class Mark(BaseCallback):
        def _on_step(self) -> bool:
            if self.num_timesteps == warmup:
                updating.append((time.perf_counter(), _tree_cpu_s()))
            return True

    updating: list[tuple[float, float]] = []
    model = SAC("MlpPolicy", sb3_env(), policy_kwargs={"net_arch": [256, 256]}, batch_size=256,
                buffer_size=1_000_000, learning_starts=warmup, train_freq=1, gradient_steps=1,
                learning_rate=3e-4, gamma=0.99, tau=0.005, device="cpu", seed=0, verbose=0)
    begin = time.perf_counter(), _tree_cpu_s()
    model.learn(total_timesteps=frames, callback=Mark())
    end = time.perf_counter(), _tree_cpu_s()
    first_update = updating[0]
    return {
        "loop": {"frames": frames, "wall_s": end[0] - begin[0], "cpu_s": end[1] - begin[1]},
        "updating": {"frames": frames - warmup, "wall_s": end[0] - first_update[0], "cpu_s": end[1] - first_update[1]},
        "updates": model._n_updates,
    }


def run(device: str = "cpu", quick: bool = False) -> dict:
    if device != "cpu":
        return {"skipped": "CPU only: robosuite steps on the CPU, and SB3 is compared on the CPU"}
    missing = {}
    for module, extra in (("robosuite", "robosuite"), ("stable_baselines3", "bench")):
        try:
            __import__(module)
        except ImportError:
            missing[module] = f"not installed; pip install -e '.[{extra}]'"
    if missing:
        return {"missing": missing}
    frames, warmup, rounds = (600, 300, 1) if quick else (FRAMES, WARMUP, ROUNDS)
    cases = {
        "drltg": lambda: drltg_run(True, frames, warmup),
        "drltg_robosuite_step": lambda: drltg_run(False, frames, warmup),
        "sb3": lambda: sb3_run(frames, warmup),
    }
    runs: dict[str, list[dict]] = {name: [] for name in cases}
    for _ in range(rounds):
        for name, case in cases.items():
            runs[name].append(case())
            print(f"[benchmarks] lift {name}: {runs[name][-1]}", file=sys.stderr, flush=True)
    pairs = [("drltg", "sb3"), ("drltg", "drltg_robosuite_step"), ("drltg_robosuite_step", "sb3")]
    out: dict = {"frames": frames, "warmup": warmup, "rounds": rounds}
    for window in ("updating", "loop"):
        rates = {
            name: summarize([r[window]["frames"] / r[window]["wall_s"] for r in rs])
            | {"cpu": summarize([r[window]["frames"] / r[window]["cpu_s"] for r in rs])}
            for name, rs in runs.items()
        }
        out[window] = {"results": rates, "ratios": ratios(rates, pairs)}
    for rs in runs.values():
        for r in rs:
            for window in ("updating", "loop"):
                r[window] = {k: round(v, 2) for k, v in r[window].items()}
    out["ratios"] = out["updating"]["ratios"]
    return out | {
        "runs": runs,
        "unit": "training frames/s, wall clock and per CPU second of the process tree; evaluation excluded. "
                "updating: after the warm-up (one env step and one update per frame); loop: the whole "
                "training loop (random warm-up and env start included)",
        "note": "drltg: 2 ParallelEnv workers, lean step, soft reset, 50 observations (task observables); "
                "sb3: one env in-process, robosuite's step, hard reset every 500 steps, robosuite's default "
                "object + proprio observations",
    }
