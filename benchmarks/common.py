"""Shared measurement helpers: interleaved A/B timing with warm-ups, medians, machine and versions.

Every comparison runs its cases in rounds, one chunk of each case per round in turn (A, B, C, A, B,
C, ...), after warm-up chunks, and reports the median rate over rounds. Interleaving spreads a
change in the machine's load over all cases instead of biasing whichever ran during it.
"""
from __future__ import annotations

import importlib.metadata
import os
import platform
import statistics
import subprocess
import time
from pathlib import Path
from typing import Callable

import torch

REPO = Path(__file__).resolve().parent.parent


def sync(device: str | torch.device | None) -> None:
    if device is not None and torch.device(device).type == "cuda":
        torch.cuda.synchronize()


def interleaved(
    cases: dict[str, Callable[[], int]],
    *,
    rounds: int,
    warmup: int = 1,
    device: str | None = None,
) -> dict[str, dict]:
    """Rate of each case in units per second: median over ``rounds`` interleaved chunks.

    A case is a callable that does one chunk of work and returns how many units (frames, updates)
    it did. ``warmup`` chunks of every case run first and are not timed. Besides the wall-clock rate,
    on the CPU the rate per second of this process's CPU time (``cpu``) is reported: on a machine
    shared with other work it moves far less with the load than the wall-clock rate does.
    """
    for _ in range(warmup):
        for run in cases.values():
            run()
    sync(device)
    wall: dict[str, list[float]] = {name: [] for name in cases}
    cpu: dict[str, list[float]] = {name: [] for name in cases}
    for _ in range(rounds):
        for name, run in cases.items():
            start, start_cpu = time.perf_counter(), time.process_time()
            units = run()
            sync(device)
            wall[name].append(units / (time.perf_counter() - start))
            cpu[name].append(units / max(time.process_time() - start_cpu, 1e-9))
    on_cpu = device is None or torch.device(device).type == "cpu"
    return {name: summarize(wall[name]) | ({"cpu": summarize(cpu[name])} if on_cpu else {}) for name in cases}


def stepping(env, actions: list[torch.Tensor], steps: int) -> Callable[[], int]:
    """A case that steps ``env`` ``steps`` times through ``actions`` in turn (resetting finished envs)
    from where its last call stopped; returns the frames stepped."""
    state = {"td": env.reset()}
    batch = max(env.batch_size.numel(), 1)

    def run() -> int:
        td = state["td"]
        for i in range(steps):
            td["action"] = actions[i % len(actions)]
            _, td = env.step_and_maybe_reset(td)
        state["td"] = td
        return steps * batch

    return run


def summarize(rates: list[float]) -> dict:
    return {
        "median": round(statistics.median(rates), 2),
        "min": round(min(rates), 2),
        "max": round(max(rates), 2),
        "rounds": len(rates),
    }


def ratio(results: dict, a: str, b: str, clock: str = "wall") -> float | None:
    """Median rate of ``a`` over median rate of ``b`` on the ``"wall"`` or ``"cpu"`` clock (None when
    either is missing)."""
    if a not in results or b not in results:
        return None
    ra, rb = (results[a], results[b]) if clock == "wall" else (results[a].get("cpu"), results[b].get("cpu"))
    if not ra or not rb or not rb["median"]:
        return None
    return round(ra["median"] / rb["median"], 3)


def ratios(results: dict, pairs: list[tuple[str, str]]) -> dict:
    """``{"a/b": {"wall": ..., "cpu": ...}}`` for each pair present in ``results``."""
    out = {}
    for a, b in pairs:
        r = {clock: ratio(results, a, b, clock) for clock in ("wall", "cpu")}
        if r["wall"] is not None:
            out[f"{a}/{b}"] = {k: v for k, v in r.items() if v is not None}
    return out


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def machine(device: str) -> dict:
    info = {
        "platform": platform.platform(),
        "cpu": _cpu_model(),
        "cpu_count": os.cpu_count(),
        "affinity": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None,
        "torch_threads": torch.get_num_threads(),
        "loadavg": [round(x, 2) for x in os.getloadavg()],
        "device": device,
    }
    try:
        pages, size = os.sysconf("SC_PHYS_PAGES"), os.sysconf("SC_PAGE_SIZE")
        info["memory_gib"] = round(pages * size / 2**30, 1)
    except (ValueError, OSError):
        pass
    if torch.device(device).type == "cuda":
        info["gpu"] = torch.cuda.get_device_name()
    return info


def versions() -> dict:
    out = {"python": platform.python_version()}
    for dist in ("torch", "torchrl", "tensordict", "numpy", "stable-baselines3", "gymnasium", "robosuite", "mujoco"):
        try:
            out[dist] = importlib.metadata.version(dist)
        except importlib.metadata.PackageNotFoundError:
            out[dist] = None
    try:
        out["drltg_commit"] = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], cwd=REPO, capture_output=True, text=True, timeout=10
        ).stdout.strip() or None
    except (OSError, subprocess.SubprocessError):
        out["drltg_commit"] = None
    return out
