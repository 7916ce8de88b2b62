"""``python -m benchmarks.faults [--trials N] [--seed S]``: kill -9 a tiny experiment and a tiny sweep at
seeded random points, run the same command again, and compare with an undisturbed run.

A kill point is a seeded (run, evaluation count) pair: the command is killed with SIGKILL as soon as
that run's ``eval.csv`` holds that many rows (or when the command ends first). After the kill the
script waits for every worker to exit (they get SIGTERM from the kernel when their parent dies), runs
the same command to its end and checks:

* the command then exits 0 and every run is complete, its ``manifest.json`` matching every file;
* each run's ``eval.csv`` has the undisturbed run's frames; a run the kill did not touch (complete
  before it, or not started) is byte for byte the undisturbed one, and a resumed run equals it up to
  the checkpoint it resumed from (after it, the training envs start fresh episodes: docs/training.md, resume);
* no worker outlived the kill.

Prints one JSON object and writes it to ``benchmarks/faults_result.json`` (slow: minutes; not a test).
"""
from __future__ import annotations

import argparse
import json
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
TINY = ["network.hidden=[16,16]", "collector.num_envs=4", "collector.frames_per_batch=16",
        "collector.init_random_frames=32", "optim.updates_per_batch=1", "buffer.batch_size=16",
        "eval.every=64", "eval.episodes=2", "checkpoint.every=128", "log.every=64"]
EXPERIMENT = ["experiment", "gridrooms/northeast", "--method", "reward-shaping", "--seeds", "2", "--frames", "384",
              "--workers", "2", *[a for o in TINY for a in ("-o", o)]]
SWEEP_SPEC = {"pairs": ["gridrooms-near"], "methods": ["reward-shaping", "model-reuse"], "seeds": 1, "frames": 384,
              "overrides": {k: v for k, v in (o.split("=", 1) for o in TINY)}}


def _command(kind: str, out: Path) -> list[str]:
    import yaml

    if kind == "experiment":
        return [*EXPERIMENT, "--out", str(out)]
    spec = out.parent / f"{out.name}.yaml"
    spec.write_text(yaml.safe_dump({**SWEEP_SPEC, "overrides": {k: yaml.safe_load(v)
                                                                for k, v in SWEEP_SPEC["overrides"].items()}}))
    return ["sweep", str(spec), "--workers", "2", "--out", str(out)]


def _drltg(args: list[str], **kwargs) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": str(REPO), "OMP_NUM_THREADS": "1"}
    return subprocess.Popen([sys.executable, "-m", "drltg.cli", *args], env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, **kwargs)


def _runs(out: Path) -> dict[str, Path]:
    return {str(p.parent.relative_to(out)): p.parent for p in sorted(out.rglob("config.yaml"))
            if "logs" not in p.parts}


def _rows(path: Path) -> list[str]:
    return path.read_text().splitlines() if path.is_file() else []


def _workers_of(pid: int) -> list[int]:
    found = []
    for proc in Path("/proc").iterdir():
        if proc.name.isdigit():
            try:
                if int((proc / "stat").read_text().rsplit(")", 1)[1].split()[1]) == pid:
                    found.append(int(proc.name))
            except (OSError, IndexError, ValueError):
                pass
    return found


def _running(pid: int) -> bool:
    """Whether ``pid`` runs (a zombie, exited but not reaped by this container's init, does not)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except (OSError, IndexError):
        return False


def trial(kind: str, reference: Path, work: Path, rng: random.Random) -> dict:
    from drltg.store import manifest, rundir

    ref_runs = _runs(reference)
    target, rows = rng.choice(sorted(ref_runs)), rng.randint(1, 6)
    out = work / f"{kind}-{target.replace('/', '_')}-{rows}"
    proc = _drltg(_command(kind, out))
    eval_csv = out / target / "eval.csv"
    while proc.poll() is None and len(_rows(eval_csv)) < rows + 1:
        time.sleep(0.02)
    children = _workers_of(proc.pid)
    killed = proc.poll() is None
    if killed:
        proc.kill()
    proc.wait()
    deadline = time.monotonic() + 60
    while any(_running(c) for c in children) and time.monotonic() < deadline:
        time.sleep(0.1)
    orphans = [c for c in children if _running(c)]
    checkpoints = {}
    for name, run in _runs(out).items():
        ckpt = run / rundir.CHECKPOINT
        if ckpt.is_file() and not rundir.is_complete(run):
            import torch

            checkpoints[name] = torch.load(ckpt, weights_only=True, map_location="cpu")["frames"]
    before = {name: (run / "eval.csv").read_bytes() if (run / "eval.csv").is_file() else None
              for name, run in _runs(out).items() if rundir.is_complete(run)}
    rerun = _drltg(_command(kind, out)).wait()
    problems = []
    if rerun != 0:
        problems.append(f"the second command exited {rerun}")
    runs = _runs(out)
    if sorted(runs) != sorted(ref_runs):
        problems.append(f"runs {sorted(runs)} != {sorted(ref_runs)}")
    for name, run in runs.items():
        if not rundir.is_complete(run):
            problems.append(f"{name} incomplete")
            continue
        for rel in manifest.read(run):
            try:
                manifest.verify(run, rel)
            except Exception as err:  # noqa: BLE001 - report every mismatch
                problems.append(str(err))
        got, ref = _rows(run / "eval.csv"), _rows(ref_runs[name] / "eval.csv")
        if [r.split(",")[0] for r in got] != [r.split(",")[0] for r in ref]:
            problems.append(f"{name}: frames differ")
        elif name in checkpoints:
            upto = [r for r in ref[1:] if int(r.split(",")[0]) <= checkpoints[name]]
            if got[1:len(upto) + 1] != upto:
                problems.append(f"{name}: differs before its checkpoint at frame {checkpoints[name]}")
        elif name in before and before[name] != (run / "eval.csv").read_bytes():
            problems.append(f"{name}: a run complete before the kill changed")
        elif name not in before and got != ref:
            problems.append(f"{name}: a run the kill did not reach differs from the undisturbed one")
    return {"kind": kind, "kill_at": f"{target}: {rows} evaluation(s)", "killed": killed,
            "resumed_from": checkpoints, "orphans": orphans, "problems": problems}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--trials", type=int, default=3, help="kill points per command (default 3)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--result", type=Path, default=REPO / "benchmarks" / "faults_result.json")
    args = parser.parse_args(argv)
    rng = random.Random(args.seed)
    work = Path(tempfile.mkdtemp(prefix="drltg-faults-"))
    start = time.time()
    trials = []
    try:
        for kind in ("experiment", "sweep"):
            reference = work / f"{kind}-reference"
            assert _drltg(_command(kind, reference)).wait() == 0, f"the undisturbed {kind} failed"
            for _ in range(args.trials):
                trials.append(trial(kind, reference, work, rng))
                print(json.dumps(trials[-1]), file=sys.stderr)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    result = {"time": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()), "seed": args.seed,
              "commit": subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=REPO, capture_output=True,
                                       text=True).stdout.strip(),
              "wall_s": round(time.time() - start, 1), "trials": trials,
              "passed": sum(not t["problems"] and not t["orphans"] for t in trials), "of": len(trials)}
    args.result.write_text(json.dumps(result, indent=1) + "\n")
    print(json.dumps(result))
    return 0 if result["passed"] == result["of"] else 1


if __name__ == "__main__":
    signal.signal(signal.SIGINT, signal.default_int_handler)
    sys.exit(main())
