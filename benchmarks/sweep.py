"""Suite ``sweep``: a whole sweep with seed groups against the same sweep with every run alone.

``drltg sweep examples/sweeps/fourrooms.yaml --out DIR --workers 2`` (45 runs: 5 sources, and 5 paired
seeds of baseline and transfer on 2 targets with reward shaping, policy reuse and model reuse; 9 seed
groups of 5) against the same command with ``--no-seed-groups`` (45 units), as a user runs them: whole
commands, wall time and the CPU time of the command and its workers (``RUSAGE_CHILDREN``). The two sides
alternate, round after round. ``--quick`` runs the same spec at a tenth of its frames.
"""
from __future__ import annotations

import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

from benchmarks.common import REPO

SPEC = REPO / "examples" / "sweeps" / "fourrooms.yaml"
WORKERS = 2


def _sweep(spec: Path, out: Path, *extra: str) -> tuple[float, float]:
    env = {**os.environ, "OMP_NUM_THREADS": "1", "PYTHONPATH": str(REPO)}
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "drltg.cli", "sweep", str(spec), "--out", str(out),
                           "--workers", str(WORKERS), *extra], cwd=REPO, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode:
        raise RuntimeError((done.stderr or done.stdout).strip().splitlines()[-1])
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def run(device: str = "cpu", quick: bool = False, rounds: int = 1) -> dict:
    spec = yaml.safe_load(SPEC.read_text())
    if quick:
        spec |= {"frames": spec["frames"] // 10, "source_frames": spec["source_frames"] // 10}
        spec["overrides"] = {**spec.get("overrides", {}), "eval.every": 500}
    sides = {"groups": [], "alone": []}
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "spec.yaml"
        path.write_text(yaml.safe_dump(spec))
        for r in range(rounds):
            for side in (("groups", "alone") if r % 2 == 0 else ("alone", "groups")):
                extra = () if side == "groups" else ("--no-seed-groups",)
                sides[side].append(_sweep(path, Path(tmp) / f"{side}-{r}", *extra))
    median = {side: sorted(v)[len(v) // 2] for side, v in sides.items()}
    return {
        "spec": str(SPEC.relative_to(REPO)) + (" at a tenth of its frames" if quick else ""),
        "commands": {"groups": f"drltg sweep {SPEC.relative_to(REPO)} --out DIR --workers {WORKERS}",
                     "alone": f"drltg sweep {SPEC.relative_to(REPO)} --out DIR --workers {WORKERS} --no-seed-groups"},
        "rounds": rounds,
        "wall_s": {side: round(m[0], 1) for side, m in median.items()},
        "cpu_s": {side: round(m[1], 1) for side, m in median.items()},
        "ratio_wall": round(median["alone"][0] / median["groups"][0], 3),
        "ratio_cpu": round(median["alone"][1] / median["groups"][1], 3),
    }
