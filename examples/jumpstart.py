"""Jump-start RL by hand: a source policy acts for the first H steps of every episode, H shrinking to 0.

    python examples/jumpstart.py [--frames 3000] [--out runs/example-jumpstart]   # about 1 min on 2 cores

JSRL (Uchendu et al. 2023): the guide (the source's actor) brings each episode part of the way, the
learner takes over after H steps; H goes from 20 to 0 in 4 stages, one stage further each time the
combined policy (the guide for H steps, then the learner, both deterministic) evaluates within 5% of its
best return. It is the PolicyReuse mixer with the JumpStart schedule. The source trains first.
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
# mix_deterministic: evaluated (deterministically), the learner's actor followed by the mixer is the combined policy
guide = PolicyReuse(load_actor(source_dir), schedule=JumpStart(20, stages=4, tolerance=0.05), mix_deterministic=True)

# 2. make_env (with the mixer's primer), make_agent, collector, buffer, loss; an env to evaluate the combined policy.
cfg = resolve(task=pair.target, frames=args.frames, seed=1)
env = make_env(pair.target, batch_size=(8,), seed=1).append_transform(guide.primer())
eval_env = make_env(pair.target, batch_size=(16,), seed=10_001)
guided_env = make_env(pair.target, batch_size=(16,), seed=40_001).append_transform(guide.primer())
agent = make_agent(env, cfg)
combined = TensorDictSequential(agent.actor, guide)
fpb = cfg.collector.frames_per_batch
every = max(cfg.frames // 8 // fpb, 1) * fpb
warmup = min(cfg.collector.init_random_frames, cfg.frames // 4 // fpb * fpb)
collector = Collector(env, TensorDictSequential(agent.policy, guide), frames_per_batch=fpb, total_frames=cfg.frames,
                      init_random_frames=warmup, auto_register_policy_transforms=False)
buffer = ReplayBuffer(storage=LazyTensorStorage(cfg.frames), batch_size=cfg.buffer.batch_size)
update = UpdateStep(agent)

# 3. The loop: every `every` frames the combined policy is evaluated and the curriculum told its return.
frames, returns, horizons, as_scheduled = 0, [], [], True
for batch in collector:
    buffer.extend(batch.reshape(-1))
    if frames >= warmup:  # the guide acted exactly on the first H steps of every episode
        as_scheduled &= torch.equal(batch["reused"], batch["step_count"] < guide.schedule.horizon)
    frames += batch.numel()
    if frames > warmup:
        for sample in sample_batches(buffer, cfg.optim.updates_per_batch):
            update(sample)
    if frames % every == 0:
        returns.append(evaluate(guided_env, combined)["return_mean"])
        guide.schedule.evaluated(returns[-1])  # the next stage once it holds within 5% of its best
        horizons.append(guide.schedule.horizon)
collector.shutdown()
print("result", json.dumps({"frames": frames, "combined_returns": returns, "horizons": horizons,
                            "guided_as_scheduled": as_scheduled, **evaluate(eval_env, agent.actor)}))
