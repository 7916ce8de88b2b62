"""`drltg demo`: a small FourRooms transfer experiment on built-in defaults, ending in one verdict.

SAC learns the source task (goal in the north-east room) once; then the target task (the goal moved one
unit) is learnt from scratch and from that source's weights (model reuse), on paired seeds: baseline and
transfer run i share seed and initial weights. One source run serves every pair, so the experiment's
spread is that of target training, the demo's question being "does reusing *this* source help?"; a
study of sources as well trains one per seed (`drltg experiment`). The baselines train as one seed
group and the transfer runs as another (:mod:`drltg.training.seeds`). The last line is the headline from
:mod:`drltg.analysis.claims`: the mean return gain with its interval and the exact sign-flip test's
verdict. Ten pairs, chosen before the runs: where the sign-flip test decides an effect of 1.5 standard
deviations 98 times in 100 (``results/verdicts``), and 6 would 68 times. Running it again reuses the
finished runs.
"""
from __future__ import annotations

import argparse
from pathlib import Path

from drltg import config as config_lib
from drltg.errors import RunFailed, UsageError
from drltg.store import rundir

DEMO = dict(pair="fourrooms-near", method="model-reuse", algo="sac", seeds=10, seed=0, frames=20_000,
            source_frames=40_000, source_seed=50, eval_every=1000, source_eval_every=5000, threshold=0.5)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", type=Path, default=Path("runs/demo"), help="experiment directory (default runs/demo)")
    p.add_argument("--workers", type=int, default=2, help="runs trained in parallel (default 2)")


def plan(out: Path, d: dict = DEMO) -> list[tuple[str, dict, Path]]:
    """One source run, then ``seeds`` baseline and transfer pairs that all transfer from it."""
    from drltg.envs import PAIRS

    pair = PAIRS[d["pair"]]
    source = out / "source" / f"seed-{d['source_seed']}"
    runs = [("source", config_lib.resolve({}, [f"eval.every={d['source_eval_every']}"], task=pair.source,
                                          algo=d["algo"], frames=d["source_frames"], seed=d["source_seed"]), source)]
    every = f"eval.every={d['eval_every']}"
    for i in range(d["seeds"]):
        seed = config_lib.run_seeds(d["seed"], d["seeds"])[i]
        runs.append(("baseline", config_lib.resolve({}, [every], task=pair.target, algo=d["algo"],
                                                    frames=d["frames"], seed=seed), out / "baseline" / f"seed-{seed}"))
        transfer = config_lib.resolve({}, [every, f"transfer.method={d['method']}"], task=pair.target,
                                      algo=d["algo"], frames=d["frames"], seed=seed)
        runs.append(("transfer", config_lib.updated(transfer, {"transfer.source": str(source)}),
                     out / "transfer" / f"seed-{seed}"))
    return runs


def run(args: argparse.Namespace) -> int:
    from drltg.experiments.experiment import check_runs, check_settings, execute_and_report, print_report

    d = DEMO
    if args.workers < 1:
        raise UsageError("--workers must be at least 1.")
    print(f"demo: {d['method']} on {d['pair']} with {d['algo'].upper()}: one source run of {d['source_frames']:,} "
          f"frames, then {d['seeds']} paired seeds x {d['frames']:,} target frames per side")
    out = rundir.check_directory(args.out, "--out")
    runs = plan(out)
    check_runs(runs)
    saved = out / "demo.yaml"
    check_settings(saved, d)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise UsageError(f"cannot create --out '{out}' ({err.strerror}).") from None
    try:
        result = execute_and_report(runs, out, saved, d, workers=args.workers, name="demo", threshold=d["threshold"],
                                    method=d["method"])
    except RunFailed as err:
        print(err)
        return 1
    print_report(result)
    return 1 if result["diverged"] else 0
