"""Probabilistic policy reuse by hand: a source policy guides SAC on a moved goal.

    python examples/policy_reuse.py [--frames 3000] [--out runs/example-policy-reuse]   # about 1 min on 2 cores

At step h of every episode the source actor acts with probability psi * upsilon^h, the learner's own
exploration otherwise (Fernandez & Veloso 2006). The mixer follows the learner's policy in the
collector; the episode's choice travels in the tensordict ("reuse_index", declared by its primer).
The evaluation measures the learner alone. The source trains first.
"""
import argparse
import json
from pathlib import Path

import torch
from tensordict.nn import TensorDictSequential
from torchrl.collectors import Collector
from torchrl.data import LazyTensorStorage, ReplayBuffer
from torchrl.envs import ExplorationType, set_exploration_type

from drltg import (
    PiReuse,
    PolicyReuse,
    UpdateStep,
    evaluate,
    get_pair,
    is_complete,
    load_actor,
    make_agent,
    make_env,
    resolve,
    sample_batches,
    train,
)

parser = argparse.ArgumentParser()
parser.add_argument("--frames", type=int, default=3000)
parser.add_argument("--out", default="runs/example-policy-reuse")
args = parser.parse_args()
torch.manual_seed(0)
torch.set_num_threads(1)
pair = get_pair("fourrooms-near")

# 1. The source: SAC on the source task through drltg's loop, then its actor.
source_dir = Path(args.out) / "source"
if not is_complete(source_dir):
    train(resolve(task=pair.source, frames=args.frames), source_dir, progress=False)
reuse = PolicyReuse(load_actor(source_dir), schedule=PiReuse(psi=1.0, upsilon=0.95))

# 2. make_env (with the mixer's primer) and make_agent; the collector runs learner then mixer.
cfg = resolve(task=pair.target, frames=args.frames, seed=1)
env = make_env(pair.target, batch_size=(8,), seed=1).append_transform(reuse.primer())
eval_env = make_env(pair.target, batch_size=(16,), seed=10_001)
agent = make_agent(env, cfg)
fpb = cfg.collector.frames_per_batch
warmup = min(cfg.collector.init_random_frames, cfg.frames // 4 // fpb * fpb)
collector = Collector(env, TensorDictSequential(agent.policy, reuse), frames_per_batch=fpb, total_frames=cfg.frames,
                      init_random_frames=warmup, auto_register_policy_transforms=False)
buffer = ReplayBuffer(storage=LazyTensorStorage(cfg.frames), batch_size=cfg.buffer.batch_size)
update = UpdateStep(agent)

# 3. The loop. After the random warm-up, check the mixer: where "reused", the action is the source's.
frames, reused, gap = 0, [], 0.0
for batch in collector:
    buffer.extend(batch.reshape(-1))
    if frames >= warmup:
        with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
            source_action = reuse.past_policies[0](batch.select("observation").clone())["action"]
        mask = batch["reused"].squeeze(-1)
        gap = max(gap, (batch["action"][mask] - source_action[mask]).abs().max().item() if mask.any() else 0.0)
        reused.append(batch["reused"].float().mean().item())
    frames += batch.numel()
    if frames > warmup:
        for sample in sample_batches(buffer, cfg.optim.updates_per_batch):
            update(sample)
collector.shutdown()
print("result", json.dumps({"frames": frames, "reused_fraction": sum(reused) / len(reused), "source_action_gap": gap,
                            **evaluate(eval_env, agent.actor)}))
