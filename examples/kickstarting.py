"""Kickstarting by hand: a trained source teaches a larger student on a moved goal, then lets go.

    python examples/kickstarting.py [--frames 3000] [--out runs/example-kickstarting]   # about 1 min on 2 cores

The student keeps SAC's own loss and adds w_f * KL(pi_teacher(.|s) || pi_student(.|s)) on the states it
replays (Schmitt et al. 2018); w_f falls linearly to 0 over the first half of training, so the student
can end better than its teacher. No weights are copied: the student's networks are twice as wide.
The source trains first.
"""
import argparse
import json
from pathlib import Path

import torch
from torchrl.collectors import Collector
from torchrl.data import LazyTensorStorage, ReplayBuffer

from drltg import (
    UpdateStep,
    evaluate,
    get_pair,
    is_complete,
    load_agent,
    make_agent,
    make_env,
    resolve,
    sample_batches,
    train,
)
from drltg.losses import KickstartingWeight, distillation

parser = argparse.ArgumentParser()
parser.add_argument("--frames", type=int, default=3000)
parser.add_argument("--out", default="runs/example-kickstarting")
args = parser.parse_args()
torch.manual_seed(0)
torch.set_num_threads(1)
pair = get_pair("fourrooms-near")

# 1. The teacher: SAC on the source task through drltg's loop, then its (stochastic) actor.
source_dir = Path(args.out) / "source"
if not is_complete(source_dir):
    train(resolve(task=pair.source, frames=args.frames), source_dir, progress=False)
teacher = load_agent(source_dir).actor

# 2. A wider student and its distillation term, weighted by the frames collected so far.
cfg = resolve(task=pair.target, frames=args.frames, seed=1, **{"network.hidden": [128, 128]})
env = make_env(pair.target, batch_size=(8,), seed=1)
eval_env = make_env(pair.target, batch_size=(16,), seed=10_001)
agent = make_agent(env, cfg)
weight, frames = KickstartingWeight(initial=1.0, frames=cfg.frames // 2), 0
update = UpdateStep(agent, loss_terms=distillation(agent.loss, teacher, lambda: weight(frames)))

# 3. The loop, as plain SAC's; record the teacher-student KL as the weight falls.
fpb = cfg.collector.frames_per_batch
warmup = min(cfg.collector.init_random_frames, cfg.frames // 4 // fpb * fpb)
collector = Collector(env, agent.policy, frames_per_batch=fpb, total_frames=cfg.frames, init_random_frames=warmup,
                      auto_register_policy_transforms=False)
buffer = ReplayBuffer(storage=LazyTensorStorage(cfg.frames), batch_size=cfg.buffer.batch_size)
gaps = []
for batch in collector:
    buffer.extend(batch.reshape(-1))
    frames += batch.numel()
    if frames > warmup:
        for sample in sample_batches(buffer, cfg.optim.updates_per_batch):
            gaps.append(update(sample)["distill_gap"].item())
collector.shutdown()
print("result", json.dumps({"frames": frames, "first_kl": gaps[0], "last_kl": gaps[-1], "final_weight": weight(frames),
                            **evaluate(eval_env, agent.actor)}))
