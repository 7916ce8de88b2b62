"""`drltg evaluate RUN_DIR [--checkpoint last|best] [--episodes N] [--seed S] [--out FILE]`"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from drltg.config.values import EVAL_SEED_OFFSET, FRESH_SEED_OFFSET
from drltg.errors import UsageError


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("run_dir", type=Path, help="a run directory (drltg train's --run-dir)")
    p.add_argument("--checkpoint", choices=("last", "best"), default="last",
                   help="last (default): the networks of checkpoints/last.pt; best: those of the run's best "
                        "evaluation, checkpoints/best.safetensors")
    p.add_argument("--episodes", type=int, default=100, metavar="N", help="fresh episodes to evaluate (default 100)")
    p.add_argument("--seed", type=int, metavar="S",
                   help=f"seed of the evaluation env (default: the run's seed + {FRESH_SEED_OFFSET}; its training "
                        f"evaluations used seed + {EVAL_SEED_OFFSET})")
    p.add_argument("--device", default="cpu", help="torch device (default cpu)")
    p.add_argument("--out", type=Path, metavar="FILE",
                   help="JSON result (default: RUN_DIR/evaluate-<checkpoint>-seed<S>-<N>ep.json)")


def run(args: argparse.Namespace) -> int:
    from drltg.store.rundir import atomic_write, check_directory, refuse_special
    from drltg.training.reevaluate import evaluate_run

    check_directory(args.run_dir, "RUN_DIR")
    if not args.run_dir.expanduser().is_dir():
        raise UsageError(f"run directory '{args.run_dir}' does not exist.")
    if args.out is not None:
        refuse_special(args.out, "--out")
        if args.out.is_dir():
            raise UsageError(f"--out '{args.out}' is a directory; name a JSON file.")
    result = evaluate_run(args.run_dir, checkpoint=args.checkpoint, episodes=args.episodes, seed=args.seed,
                          device=args.device)
    out = args.out or args.run_dir / f"evaluate-{args.checkpoint}-seed{result['seed']}-{args.episodes}ep.json"
    atomic_write(out, json.dumps(result, indent=2) + "\n")
    rates = "".join(f", {key.removesuffix('_rate')} {result[key]:.2f} "
                    f"[{result[key + '_ci95'][0]:.2f}, {result[key + '_ci95'][1]:.2f}]"
                    for key in result if key.endswith("_rate"))
    print(f"{args.run_dir} {args.checkpoint}.pt (frame {result['frames']}): return {result['return_mean']:.3f}{rates} "
          f"over {result['episodes']} episodes, seed {result['seed']} (95% intervals) -> {out}")
    return 0
