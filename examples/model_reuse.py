"""Model reuse in user code: start a target learner from a source run's weights.

    python examples/model_reuse.py [--frames 10240] [--out runs/example-model-reuse]

The target observes its goal (4 inputs) while the source did not (2 inputs): the layers reading the
observation are widened with zero weights for the new inputs, so the loaded learner starts out
acting exactly like the source policy and is then fine-tuned.
"""
import argparse
from pathlib import Path

import torch

from drltg.config import resolve
from drltg.envs import get_pair, make_env
from drltg.learners import make_agent
from drltg.training.loop import evaluate, is_complete, read_eval_csv, train
from drltg.transfer import load_from_run

parser = argparse.ArgumentParser()
parser.add_argument("--frames", type=int, default=10_240)
parser.add_argument("--out", default="runs/example-model-reuse")
args = parser.parse_args()
torch.set_num_threads(1)
pair = get_pair("fourrooms-near")
out = Path(args.out)

# 1. The source run.
source_dir = out / "source"
if not is_complete(source_dir):
    train(resolve(task=pair.source, frames=args.frames, seed=0), source_dir)

# 2. A fresh target learner, and the same learner started from the source's weights.
torch.manual_seed(1)
cfg = resolve(task=pair.target, seed=1, overrides=["env.observe_goal=true"])
fresh = make_agent(make_env(pair.target, observe_goal=True), cfg)
reused = make_agent(make_env(pair.target, observe_goal=True), cfg)
print(load_from_run(reused.loss, source_dir))  # loaded / widened / skipped, entry by entry

# 3. The jumpstart: both learners on the target task before any training.
eval_env = make_env(pair.target, batch_size=(32,), seed=2, observe_goal=True)
print(f"fresh learner:  {evaluate(eval_env, fresh.actor)}")
print(f"reused weights: {evaluate(eval_env, reused.actor)}")

# 4. Fine-tune: drltg's loop composes the same loader (transfer.method=model-reuse).
overrides = ["env.observe_goal=true", "transfer.method=model-reuse", f"transfer.source={source_dir}"]
target_dir = out / "target"
if not is_complete(target_dir):
    train(resolve(task=pair.target, frames=args.frames, seed=1, overrides=overrides), target_dir)
for row in read_eval_csv(target_dir / "eval.csv"):
    print(row)
