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
    it did. ``warmup`` chunks of every case run first and are not timed.
    """
    for _ in range(warmup):
        for run in cases.values():
            run()
    sync(device)
    rates: dict[str, list[float]] = {name: [] for name in cases}
    for _ in range(rounds):
        for name, run in cases.items():
            start = time.perf_counter()
            units = run()
            sync(device)
            rates[name].append(units / (time.perf_counter() - start))
    return {name: summarize(r) for name, r in rates.items()}


def summarize(rates: list[float]) -> dict:
    return {
        "median": round(statistics.median(rates), 2),
        "min": round(min(rates), 2),
        "max": round(max(rates), 2),
        "rounds": len(rates),
    }


def ratio(results: dict, a: str, b: str) -> float | None:
    """Median rate of ``a`` over median rate of ``b`` (None when either is missing)."""
    if a not in results or b not in results or not results[b]["median"]:
        return None
    return round(results[a]["median"] / results[b]["median"], 3)


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
