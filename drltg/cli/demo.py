"""`drltg demo`: a small FourRooms transfer experiment on built-in defaults, with its report.

SAC learns the source task (goal in the north-east room), then the target task (the goal moved one
unit) is learnt from scratch and from the source weights (model reuse), three seeds each; the report
compares the two. Running it again reuses the finished runs (`drltg experiment` semantics).
"""
from __future__ import annotations

import argparse
from pathlib import Path

from drltg.experiments import experiment

DEMO = dict(pair="fourrooms-near", method="model-reuse", algo="sac", seeds=3, seed=0,
            frames=15_000, source_frames=30_000, overrides=["eval.every=1500"], threshold="0.5")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", type=Path, default=Path("runs/demo"), help="experiment directory (default runs/demo)")
    p.add_argument("--workers", type=int, default=2, help="runs trained in parallel (default 2)")


def run(args: argparse.Namespace) -> int:
    print(
        f"demo: {DEMO['method']} on {DEMO['pair']} with {DEMO['algo'].upper()}, {DEMO['seeds']} seeds; "
        f"source runs {DEMO['source_frames']} frames, target runs {DEMO['frames']} frames"
    )
    return experiment.run(argparse.Namespace(**DEMO, out=args.out, workers=args.workers))
