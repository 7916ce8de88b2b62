"""Jump-start RL by hand: a source policy acts for the first H steps of every episode, H shrinking to 0.

    python examples/jumpstart.py [--frames 3000] [--out runs/example-jumpstart]   # about 1 min on 2 cores

JSRL (Uchendu et al. 2022): the guide (the source's actor) brings each episode part of the way, the
learner takes over after H steps; H goes from 20 to 0 in 4 stages over the first half of training.
It is the PolicyReuse mixer with the JumpStart schedule. The source trains first.
"""
import argparse
import json
from pathlib import Path

import torch
from tensordict.nn import TensorDictSequential
from torchrl.collectors import Collector
from torchrl.data import LazyTensorStorage, ReplayBuffer

from drltg import (
    JumpStart,
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
parser.add_argument("--out", default="runs/example-jumpstart")
args = parser.parse_args()
torch.manual_seed(0)
torch.set_num_threads(1)
pair = get_pair("fourrooms-near")

# 1. The source: SAC on the source task through drltg's loop, then its actor as the guide.
source_dir = Path(args.out) / "source"
if not is_complete(source_dir):
    train(resolve(task=pair.source, frames=args.frames), source_dir, progress=False)
guide = PolicyReuse(load_actor(source_dir), schedule=JumpStart(20, stages=4, frames_per_stage=max(args.frames // 8, 1)))

# 2. make_env (with the mixer's primer), make_agent, collector, buffer, loss.
cfg = resolve(task=pair.target, frames=args.frames, seed=1)
env = make_env(pair.target, batch_size=(8,), seed=1).append_transform(guide.primer())
eval_env = make_env(pair.target, batch_size=(16,), seed=10_001)
agent = make_agent(env, cfg)
fpb = cfg.collector.frames_per_batch
warmup = min(cfg.collector.init_random_frames, cfg.frames // 4 // fpb * fpb)
collector = Collector(env, TensorDictSequential(agent.policy, guide), frames_per_batch=fpb, total_frames=cfg.frames,
                      init_random_frames=warmup, auto_register_policy_transforms=False)
buffer = ReplayBuffer(storage=LazyTensorStorage(cfg.frames), batch_size=cfg.buffer.batch_size)
update = UpdateStep(agent)

# 3. The loop: after each batch the schedule learns the frames collected (H shrinks on its curriculum).
frames, horizons, as_scheduled = 0, [], True
for batch in collector:
    buffer.extend(batch.reshape(-1))
    if frames >= warmup:  # the guide acted exactly on the first H steps of every episode
        horizons.append(guide.schedule.horizon)
        as_scheduled &= torch.equal(batch["reused"], batch["step_count"] < guide.schedule.horizon)
    frames += batch.numel()
    guide.set_progress(frames)
    if frames > warmup:
        for sample in sample_batches(buffer, cfg.optim.updates_per_batch):
            update(sample)
collector.shutdown()
print("result", json.dumps({"frames": frames, "horizons": sorted(set(horizons), reverse=True),
                            "guided_as_scheduled": as_scheduled, **evaluate(eval_env, agent.actor)}))
