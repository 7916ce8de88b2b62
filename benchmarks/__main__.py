"""``python -m benchmarks [suite ...] [--device cpu|cuda] [--quick]``: run the comparisons, print one JSON
object (machine, versions, rates, ratios, targets) and append it as one line to
``benchmarks/results.jsonl``.

Suites: ``env`` (FourRooms vs a NumPy reference), ``robosuite`` (wrapper overhead, ParallelEnv),
``sac`` (update throughput vs TorchRL, plain PyTorch, Stable-Baselines3; SOC K=4), ``train`` (whole
``drltg train`` runs), ``memory`` (1e6-transition replay buffer), ``gymnasium`` (FourRooms through
``gymnasium.make_vec`` against copies and the torch env); all six by default. ``lift``
(``drltg train lift`` against Stable-Baselines3 SAC on robosuite's Lift, several minutes) and ``demo``
(``drltg demo``, several minutes), ``seeds`` (N seeds in one process against N runs one after
another, many minutes), ``lift-seeds`` (3 seeds of a Lift run as one seed group against 3 runs one
after another, whole commands, about 20 minutes on one core), ``sweep`` (a FourRooms sweep with seed
groups against every run alone, about 15 minutes on 2 cores) and ``threads`` (SAC steps under torch's
default thread count against one thread, with a core idle and busy; it starts a spinning process) and
``coverage`` (the report's intervals on simulated seeds, results/coverage's tables, a few minutes) and
``checkpoint`` (saving a part-filled 1e6-transition Lift buffer whole and as a checkpoint keeps it) and
``verdict`` (the CPU time of ``fourrooms-near`` model reuse with ``seeds="auto"`` from start to its verdict, seed
groups against every run alone, tens of minutes; ``--quick`` only checks that it runs) run only when named.
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import subprocess
import sys
import tempfile
import time
import traceback
from pathlib import Path

import torch

from benchmarks.common import REPO, machine, versions

DEFAULT = ("env", "robosuite", "sac", "train", "memory", "gymnasium")
NAMED_ONLY = ("lift", "demo", "seeds", "lift-seeds", "sweep", "threads", "coverage", "checkpoint", "verdict")


def _suite(name: str):
    if name == "env":
        from benchmarks.env import run
    elif name == "robosuite":
        from benchmarks.robosuite import run
    elif name == "sac":
        from benchmarks.sac import run
    elif name == "train":
        from benchmarks.e2e import run_train as run
    elif name == "memory":
        from benchmarks.e2e import run_memory as run
    elif name == "checkpoint":
        from benchmarks.e2e import run_checkpoint as run
    elif name == "gymnasium":
        from benchmarks.gymnasium_vec import run
    elif name == "lift":
        from benchmarks.lift_e2e import run
    elif name == "seeds":
        from benchmarks.seeds import run
    elif name == "lift-seeds":
        from benchmarks.seeds import run_lift as run
    elif name == "sweep":
        from benchmarks.sweep import run
    elif name == "threads":
        from benchmarks.threads import run
    elif name == "coverage":
        from benchmarks.coverage import run
    elif name == "verdict":
        from benchmarks.verdict import run
    else:
        run = _demo
    return run


def _demo(device: str = "cpu", quick: bool = False) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        done = subprocess.run([sys.executable, "-m", "drltg.cli", "demo", "--out", tmp], cwd=REPO,
                              capture_output=True, text=True)
        wall = time.perf_counter() - start
    return {"command": "drltg demo", "wall_s": round(wall, 1), "returncode": done.returncode}


def _met(value, target, at_least=True):
    return None if value is None else (value >= target if at_least else value <= target)


def summarize(suites: dict, device: str) -> dict:
    """The figures the targets speak of, each with its target and whether this run met it."""
    clock = "cpu" if device == "cpu" else "wall"
    out = {}
    env = suites.get("env", {})
    for key, r in env.get("ratios", {}).items():
        batch = int(key.split("/")[0].rsplit("_", 1)[1])
        if batch >= 1024:
            out[f"env: drltg batch {batch} / NumPy reference"] = {"value": r, "target": ">= 100", "met": _met(r, 100)}
    rs = suites.get("robosuite", {}).get("ratios", {})
    if "drltg/raw" in rs:
        v = rs["drltg/raw"]["wall"]
        out["robosuite: RobosuiteEnv / raw robosuite"] = {"value": v, "target": ">= 2", "met": _met(v, 2.0)}
    if "parallel_2/parallel_1" in rs:
        v = rs["parallel_2/parallel_1"]["wall"]
        out["robosuite: ParallelEnv 2 workers / 1 worker"] = {"value": v, "target": ">= 1.6", "met": _met(v, 1.6)}
    sac = suites.get("sac", {}).get("ratios", {})
    best = "drltg_cudagraphs" if "drltg_cudagraphs/plain" in sac else "drltg"
    for other, target in (("plain", 1.0), ("torchrl", 2.0), ("sb3", 2.0)):
        key = f"{best}/{other}"
        if key in sac:
            v = sac[key].get(clock, sac[key]["wall"])
            out[f"sac: {key} updates/s ({clock} clock)"] = {
                "value": v, "target": f">= {target}", "met": _met(v, target)
            }
    for key in (f"{best}/matmul_bound", "soc_k4/drltg"):
        if key in sac:
            out[f"sac: {key} updates/s ({clock} clock)"] = {"value": sac[key].get(clock, sac[key]["wall"])}
    train = suites.get("train", {}).get("fourrooms")
    if train:
        out["train: fourrooms speed-up over the reference step"] = {"value": train["speedup_vs_reference_step"]}
    lift = suites.get("lift", {}).get("ratios", {})
    for key in ("drltg/sb3", "drltg/drltg_robosuite_step", "drltg_robosuite_step/sb3"):
        if key in lift:
            out[f"lift: {key} training frames/s (wall clock)"] = {"value": lift[key]["wall"]}
    seeds = suites.get("seeds", {})
    for n, r in seeds.get("fourrooms", {}).get("per_n", {}).items():
        for clock, target in (("command_wall", 4.0 if int(n) == 8 else None), ("loop", None)):
            entry = {"value": r[f"ratio_{clock}"]}
            if target is not None:
                entry |= {"target": f">= {target}", "met": _met(r[f"ratio_{clock}"], target)}
            out[f"seeds: fourrooms {n} seeds, group / one after another ({clock})"] = entry
    for key, r in seeds.get("lift_update", {}).get("ratios", {}).items():
        target = 1.5 if key == "group_8/separate_8" else 0.85 if key.startswith("group_") and "matmul" in key else None
        entry = {"value": r["wall"]}
        if target is not None:
            entry |= {"target": f">= {target}", "met": _met(r["wall"], target)}
        out[f"seeds: lift-sized update {key} (wall clock)"] = entry
    lift_seeds = suites.get("lift-seeds", {}).get("lift")
    if lift_seeds:
        out["lift-seeds: 3 seeds, group / one after another (loop frames per core)"] = {
            "value": lift_seeds["ratio_loop"], "target": ">= 2", "met": _met(lift_seeds["ratio_loop"], 2.0)}
    coverage = suites.get("coverage")
    if coverage:
        out["coverage: cells where the default interval covers below 0.93"] = {
            "value": coverage["default_below_0.93"], "target": "0", "met": coverage["default_below_0.93"] == 0}
    sweep = suites.get("sweep")
    if sweep:
        for clock in ("wall", "cpu"):
            out[f"sweep: every run alone / seed groups ({clock})"] = {"value": sweep[f"ratio_{clock}"]}
    verdict = suites.get("verdict")
    if verdict and "ratio_cpu" in verdict:
        for clock in ("cpu", "wall"):
            out[f"verdict: fourrooms-near model reuse to its verdict, every run alone / seed groups ({clock})"] = {
                "value": verdict[f"ratio_{clock}"]}
    mem = suites.get("memory", {}).get("loss_keys")
    if mem:
        out["memory: replay RSS growth / raw bytes"] = {
            "value": mem["ratio"], "target": "<= 1.3", "met": _met(mem["ratio"], 1.3, False)
        }
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks", description=__doc__.split("\n\n")[0])
    parser.add_argument("suites", nargs="*", metavar="suite",
                        help=f"any of {', '.join(DEFAULT + NAMED_ONLY)} (default: all but {', '.join(NAMED_ONLY)})")
    parser.add_argument("--device", default="cpu", help="cpu or cuda (default cpu)")
    parser.add_argument("--quick", action="store_true", help="a smoke run of about a minute")
    parser.add_argument("--threads", type=int, default=1, help="torch threads (default 1, as drltg train)")
    parser.add_argument("--results", type=Path, default=REPO / "benchmarks" / "results.jsonl",
                        help="JSON-lines file the run is appended to")
    parser.add_argument("--no-save", action="store_true", help="print only; append nothing")
    args = parser.parse_args(argv)
    unknown = sorted(set(args.suites) - {*DEFAULT, *NAMED_ONLY})
    if unknown:
        parser.error(f"unknown suite(s) {', '.join(unknown)}; choose from {', '.join(DEFAULT + NAMED_ONLY)}.")
    if args.device.startswith("cuda") and not torch.cuda.is_available():
        parser.error("--device cuda needs a CUDA build of torch and a visible GPU.")
    torch.set_num_threads(args.threads)
    suites = args.suites or list(DEFAULT)
    record = {
        "time": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "command": "python -m benchmarks " + " ".join(argv if argv is not None else sys.argv[1:]),
        "quick": args.quick,
        "machine": machine(args.device),
        "versions": versions(),
        "note": "indicative figures: other work may share this machine; "
        "see machine.loadavg and each case's cpu-clock rate",
        "suites": {},
    }
    start = time.perf_counter()
    sys.stdout.flush()
    stdout = os.dup(1)
    os.dup2(2, 1)  # libraries and worker processes print to stdout: only the JSON goes there
    try:
        _run_suites(suites, args, record)
    finally:
        sys.stdout.flush()
        os.dup2(stdout, 1)
        os.close(stdout)
    record["seconds"] = round(time.perf_counter() - start, 1)
    record["loadavg_after"] = [round(x, 2) for x in os.getloadavg()]
    record["summary"] = summarize(record["suites"], "cpu" if not args.device.startswith("cuda") else "cuda")
    print(json.dumps(record, indent=1))
    if not args.no_save:
        args.results.parent.mkdir(parents=True, exist_ok=True)
        with open(args.results, "a") as f:
            f.write(json.dumps(record) + "\n")
    return 0


def _run_suites(suites: list[str], args: argparse.Namespace, record: dict) -> None:
    for name in suites:
        print(f"[benchmarks] {name} ...", file=sys.stderr, flush=True)
        t = time.perf_counter()
        try:
            record["suites"][name] = _suite(name)(device=args.device, quick=args.quick)
        except Exception as err:  # one broken suite must not lose the others' figures
            record["suites"][name] = {
                "error": f"{type(err).__name__}: {err}", "traceback": traceback.format_exc(limit=3)
            }
        record["suites"][name]["seconds"] = round(time.perf_counter() - t, 1)


if __name__ == "__main__":
    raise SystemExit(main())
