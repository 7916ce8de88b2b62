"""Learning from demonstrations by hand: a source policy's episodes in a buffer of their own.

    python examples/demonstrations.py [--frames 3000] [--out runs/example-demonstrations]   # about 1 min on 2 cores

The demonstrator is a source run's actor, acting deterministically on the target task. Its episodes are
never overwritten by the learner's experience; every update draws a fixed share of its batch from them
(DQfD, DDPGfD) and adds a behaviour-cloning term on them (Nair et al. 2018). The source trains first.
"""
import argparse
import json
from pathlib import Path

import torch
from torchrl.collectors import Collector
from torchrl.data import LazyTensorStorage, ReplayBuffer

from drltg import (
    UpdateStep,
    behaviour_cloning,
    collect_demonstrations,
    demonstration_buffer,
    evaluate,
    get_pair,
    is_complete,
    load_actor,
    make_agent,
    make_env,
    mixed_batches,
    resolve,
    train,
)

parser = argparse.ArgumentParser()
parser.add_argument("--frames", type=int, default=3000)
parser.add_argument("--out", default="runs/example-demonstrations")
args = parser.parse_args()
torch.manual_seed(0)
torch.set_num_threads(1)
pair, ratio = get_pair("fourrooms-near"), 0.25

# 1. The source: SAC on the source task through drltg's loop; its actor demonstrates on the target task.
source_dir = Path(args.out) / "source"
if not is_complete(source_dir):
    train(resolve(task=pair.source, frames=args.frames), source_dir, progress=False)
demos = collect_demonstrations(make_env(pair.target, batch_size=(8,), seed=20_001), load_actor(source_dir), episodes=8)

# 2. make_env, make_agent, the two buffers, and the loss with its behaviour-cloning term.
cfg = resolve(task=pair.target, frames=args.frames, seed=1)
env = make_env(pair.target, batch_size=(8,), seed=1)
eval_env = make_env(pair.target, batch_size=(16,), seed=10_001)
agent = make_agent(env, cfg)
demo_buffer = demonstration_buffer(demos, agent.loss.in_keys)
buffer = ReplayBuffer(storage=LazyTensorStorage(cfg.frames), batch_size=cfg.buffer.batch_size)
k = round(ratio * buffer.batch_size)
update = UpdateStep(agent, loss_terms=behaviour_cloning(agent.loss, k, weight=1.0, q_filter=True, alpha=2.5))
fpb = cfg.collector.frames_per_batch
warmup = min(cfg.collector.init_random_frames, cfg.frames // 4 // fpb * fpb)
collector = Collector(env, agent.policy, frames_per_batch=fpb, total_frames=cfg.frames, init_random_frames=warmup,
                      auto_register_policy_transforms=False)

# 3. The loop: every batch is k demonstrated transitions, then the learner's own (the keys the loss reads).
frames, demo_rows = 0, None
for batch in collector:
    buffer.extend(batch.reshape(-1).select(*agent.loss.in_keys))
    frames += batch.numel()
    if frames > warmup:
        for sample in mixed_batches(buffer, demo_buffer, cfg.optim.updates_per_batch, ratio):
            update(sample)
        if demo_rows is None:  # how many rows of a mixed batch are demonstrated transitions
            found = (sample["observation"][:, None] == demos["observation"][None]).all(-1).any(-1)
            demo_rows = int(found[:k].sum())
collector.shutdown()
print("result", json.dumps({"frames": frames, "demonstration_frames": demos.numel(), "demo_rows": demo_rows,
                            "k": k, **evaluate(eval_env, agent.actor)}))
