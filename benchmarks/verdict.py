"""Suite ``verdict``: the CPU time from start to a decided verdict, seed groups against every run alone.

``drltg.experiment("fourrooms-near", "model-reuse", seeds="auto", frames=20_000, threshold=0.5)``: the demo's
pair, method, target frames and threshold, and ``drltg experiment``'s defaults otherwise (source runs of
``frames``, ``max_seeds=20``, ``workers=1``, the tasks' own settings), so paired seeds train in rounds (8, 12,
16, 20 pairs) until the exact sign-flip test decides the mean return gain at its share of 0.05. It runs twice
into temporary folders, each side in a fresh process: with seed groups (runs that differ only in their seed
train as one vmapped group) and with ``group_seeds=False`` (every run alone, one after another). For each side:

* ``cpu_s``: CPU seconds (user + system) of the side's whole process tree, ``resource.getrusage`` of the
  process itself plus its waited-for children (the worker processes that train the runs), read when the
  verdict is in; interpreter start and imports included. ``cpu_s_seen_by_parent`` is the same tree's time
  as the benchmark's own ``RUSAGE_CHILDREN`` sees it, the side's exit included (a little more).
* ``wall_s``, the looks taken (pairs and p), where it stopped (``pairs``, ``stopped``: ``decided`` or
  ``cap``), ``verdict`` and its ``p``.

``ratio_cpu`` (and ``ratio_wall``) = every run alone / seed groups. ``--quick`` (256 frames, tiny networks and
batches, at most 2 pairs: one look that cannot decide) only checks that the suite runs; its figures mean nothing.
"""
from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.common import REPO

PAIR, METHOD = "fourrooms-near", "model-reuse"
SETTINGS = {"frames": 20_000, "threshold": 0.5}
QUICK = {"frames": 256, "threshold": 0.5, "max_seeds": 2,
         "overrides": ["network.hidden=[16,16]", "collector.num_envs=4", "collector.frames_per_batch=16",
                       "collector.init_random_frames=128", "optim.updates_per_batch=1", "buffer.batch_size=32",
                       "eval.every=256", "eval.episodes=4", "log.tensorboard=false"]}


def _cpu_seconds(*who: int) -> float:
    return sum(u.ru_utime + u.ru_stime for u in map(resource.getrusage, who))


def side(group: bool, quick: bool, out: Path) -> dict:
    """One side, in this process: the experiment until its verdict, and what it cost this process tree."""
    import drltg

    report = drltg.experiment(PAIR, METHOD, seeds="auto", out=out, group_seeds=group, progress=False,
                              **(QUICK if quick else SETTINGS))
    cpu = _cpu_seconds(resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN)
    seq, m = report["settings"]["sequential"], report["metrics"]
    return {"cpu_s": round(cpu, 1), "looks": [{"pairs": t["pairs"], "p": t["p"]} for t in seq["taken"]],
            "pairs": seq["pairs"], "stopped": seq["stopped"], "verdict": m["mean_return_gain_verdict"],
            "p": m["mean_return_gain_verdict_p"], "mean_return_gain": m.get("mean_return_gain")}


def _measure(group: bool, quick: bool, tmp: Path) -> dict:
    name = "grouped" if group else "alone"
    result = tmp / f"{name}.json"
    env = {**os.environ, "OMP_NUM_THREADS": "1", "PYTHONPATH": str(REPO)}
    before = _cpu_seconds(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "benchmarks.verdict", name, str(tmp / name), str(result),
                           *(["--quick"] if quick else [])], cwd=REPO, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - start
    if done.returncode:
        raise RuntimeError(f"the {name} side failed: {(done.stderr.strip().splitlines() or ['no output'])[-1]}")
    return {**json.loads(result.read_text()), "wall_s": round(wall, 1),
            "cpu_s_seen_by_parent": round(_cpu_seconds(resource.RUSAGE_CHILDREN) - before, 1)}


def run(device: str = "cpu", quick: bool = False) -> dict:
    if device != "cpu":
        return {"missing": "the verdict suite measures CPU time"}
    with tempfile.TemporaryDirectory() as tmp:
        sides = {"grouped": _measure(True, quick, Path(tmp)), "alone": _measure(False, quick, Path(tmp))}
    g, a = sides["grouped"], sides["alone"]
    settings = QUICK if quick else SETTINGS
    return {
        "call": f"drltg.experiment({PAIR!r}, {METHOD!r}, seeds='auto', "
                + ", ".join(f"{k}={v!r}" for k, v in settings.items()) + ", group_seeds=True | False)",
        **sides,
        "ratio_cpu": round(a["cpu_s"] / g["cpu_s"], 3),
        "ratio_wall": round(a["wall_s"] / g["wall_s"], 3),
        "same_stop": (g["pairs"], g["verdict"]) == (a["pairs"], a["verdict"]),
    }


if __name__ == "__main__":  # one side: python -m benchmarks.verdict grouped|alone OUT RESULT_JSON [--quick]
    kind, out, result = sys.argv[1:4]
    Path(result).write_text(json.dumps(side(kind == "grouped", "--quick" in sys.argv[4:], Path(out))))
