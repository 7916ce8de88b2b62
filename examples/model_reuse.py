"""Model reuse by hand: a target learner starts from a source run's weights, then trains.

    python examples/model_reuse.py [--frames 3000] [--out runs/example-model-reuse]   # about 1 min on 2 cores

The target also observes its goal (4 inputs, the source 2): load_from_run widens the layers that read
the observation with zero weights for the new inputs, so the loaded learner starts out acting exactly
like the source policy, and is then fine-tuned on the target task. The source trains first.
"""
import argparse
import json
from pathlib import Path

import torch
from torchrl.collectors import Collector
from torchrl.data import LazyTensorStorage, ReplayBuffer
from torchrl.envs import ExplorationType, set_exploration_type

from drltg import (
    UpdateStep,
    evaluate,
    get_pair,
    is_complete,
    load_actor,
    load_from_run,
    make_agent,
    make_env,
    resolve,
    sample_batches,
    train,
)

parser = argparse.ArgumentParser()
parser.add_argument("--frames", type=int, default=3000)
parser.add_argument("--out", default="runs/example-model-reuse")
args = parser.parse_args()
torch.manual_seed(0)
torch.set_num_threads(1)
pair = get_pair("fourrooms-near")

# 1. The source: SAC on the source task through drltg's loop.
source_dir = Path(args.out) / "source"
if not is_complete(source_dir):
    train(resolve(task=pair.source, frames=args.frames), source_dir, progress=False)

# 2. make_env and make_agent on the target (goal observed), then the source's weights loaded into it.
cfg = resolve(task=pair.target, frames=args.frames, seed=1, overrides=["env.observe_goal=true"])
env = make_env(pair.target, batch_size=(8,), seed=1, observe_goal=True)
eval_env = make_env(pair.target, batch_size=(16,), seed=10_001, observe_goal=True)
agent = make_agent(env, cfg)
report = load_from_run(agent.loss, source_dir)  # loaded / widened / skipped, entry by entry
print(report.summary())
obs = env.reset()
with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
    mine = agent.actor(obs.clone())["action"]
    theirs = load_actor(source_dir)(obs.clone().set("observation", obs["observation"][..., :2]))["action"]
print("start", json.dumps({"action_gap_to_source": (mine - theirs).abs().max().item(),
                           **evaluate(eval_env, agent.actor)}))

# 3. Collector, buffer, loss and the loop: fine-tuning from the loaded weights.
fpb = cfg.collector.frames_per_batch
warmup = min(cfg.collector.init_random_frames, cfg.frames // 4 // fpb * fpb)
collector = Collector(env, agent.policy, frames_per_batch=fpb, total_frames=cfg.frames, init_random_frames=warmup,
                      auto_register_policy_transforms=False)
buffer = ReplayBuffer(storage=LazyTensorStorage(cfg.frames), batch_size=cfg.buffer.batch_size)
update = UpdateStep(agent)
frames = 0
for batch in collector:
    buffer.extend(batch.reshape(-1))
    frames += batch.numel()
    if frames > warmup:
        for sample in sample_batches(buffer, cfg.optim.updates_per_batch):
            update(sample)
collector.shutdown()
print("result", json.dumps({"frames": frames, **evaluate(eval_env, agent.actor)}))
