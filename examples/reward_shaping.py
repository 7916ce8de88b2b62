"""Potential-based reward shaping in user code: a dense signal that keeps the optimal policy.

    python examples/reward_shaping.py [--frames 10000] [--seeds 2] [--out runs/example-reward-shaping]

1. The part: ``PotentialShaping`` with the FourRooms potential (minus the path length to the goal
   through the doorways) adds ``gamma * Phi(s') - Phi(s)`` to every reward, and keeps the task's own
   reward under ``("next", "task_reward")``.
2. SAC on the task without and with shaping, through drltg's loop (``transfer.method``); the
   evaluation always measures the task's own reward and success.
"""
import argparse
from pathlib import Path

import torch
from torchrl.envs import TransformedEnv

from drltg.config import resolve
from drltg.envs import get_task, make_env
from drltg.envs.fourrooms import FourRoomsPotential
from drltg.training.loop import is_complete, read_eval_csv, train
from drltg.transforms import PotentialShaping

parser = argparse.ArgumentParser()
parser.add_argument("--frames", type=int, default=10_000)
parser.add_argument("--seeds", type=int, default=2)
parser.add_argument("--out", default="runs/example-reward-shaping")
args = parser.parse_args()
torch.set_num_threads(1)
task = "fourrooms/northeast"  # +1 at the goal disc, -0.01 per step
goal = get_task(task).defaults["goal"]

# 1. One shaped episode step by step: shaped reward, task reward and the potential of s'.
env = TransformedEnv(make_env(task, seed=0), PotentialShaping(FourRoomsPotential(goal), gamma=0.99))
steps = env.rollout(5, lambda td: td.set("action", torch.tensor([1.0, 1.0])))  # head north-east
for key in ("reward", "task_reward", "potential"):
    print(f"{key:>12}: {[round(v, 4) for v in steps['next', key].flatten().tolist()]}")

# 2. Learning curves (evaluation success rate) of the baseline and the shaped learner.
curves = {}
for method in ("none", "reward-shaping"):
    for seed in range(args.seeds):
        cfg = resolve(
            task=task, seed=seed, frames=args.frames, overrides=[f"transfer.method={method}", "eval.every=2000"]
        )
        run = Path(args.out) / method / f"seed{seed}"
        if not is_complete(run):
            train(cfg, run, progress=False)
        for row in read_eval_csv(run / "eval.csv"):
            curves.setdefault(method, {}).setdefault(row["frames"], []).append(row["success_rate"])
print(f"{'frames':>8} {'baseline':>9} {'shaped':>9}   (eval success rate, mean over {args.seeds} seeds)")
for frames in sorted(curves["none"]):
    base, shaped = (sum(curves[m][frames]) / len(curves[m][frames]) for m in ("none", "reward-shaping"))
    print(f"{frames:>8} {base:>9.2f} {shaped:>9.2f}")
