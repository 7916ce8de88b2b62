"""`drltg demo`: a short SAC run on FourRooms with the built-in defaults, then where the results are.

Running it again reuses a completed demo run instead of training anew (pass --fresh to retrain).
"""
from __future__ import annotations

import argparse
import shutil
from pathlib import Path

from drltg import config as config_lib

DEMO = {"task": "fourrooms/northeast", "algo": "sac", "frames": 50_000, "seed": 0}


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", type=Path, default=Path("runs/demo"), help="run directory (default: runs/demo)")
    p.add_argument("--frames", type=int, default=DEMO["frames"], help=f"frame budget (default {DEMO['frames']})")
    p.add_argument("--fresh", action="store_true", help="delete a previous demo run and train again")


def run(args: argparse.Namespace) -> int:
    from drltg.train import is_complete, read_eval_csv, train

    cfg = config_lib.resolve({**DEMO, "frames": args.frames})
    run_dir = args.out.expanduser().resolve()
    if args.fresh:
        shutil.rmtree(run_dir, ignore_errors=True)
    if is_complete(run_dir):
        print(f"reusing the completed demo run in {run_dir} (--fresh to train again)")
    else:
        print(f"training {cfg['algo'].upper()} on {cfg['task']} for {cfg['frames']} frames (seed {cfg['seed']})")
        train(cfg, run_dir, resume=(run_dir / "config.yaml").is_file())
    rows = read_eval_csv(run_dir / "eval.csv")
    print(f"\n{'frames':>8} {'return':>8} {'success':>8}")
    for r in rows:
        print(f"{r['frames']:>8} {r['return_mean']:>8.3f} {r.get('success_rate', float('nan')):>8.2f}")
    print(f"\nresults: {run_dir}  (eval.csv, config.yaml, logs/tensorboard, checkpoints/)")
    return 0
