"""Value shaping by hand: a source run's value of a state is the potential that shapes the target's reward.

    python examples/value_shaping.py [--frames 3000] [--out runs/example-value-shaping]   # about 1 min on 2 cores

Phi(s) = min_k Q_k^source(s, mu^source(s)) (Brys et al. 2015): what the source learned, as a potential,
so it guides exploration without changing the target's optimal policy. The source trains first.
"""
import argparse
import json
from pathlib import Path

import torch
from torchrl.collectors import Collector
from torchrl.data import LazyTensorStorage, ReplayBuffer
from torchrl.envs import TransformedEnv

from drltg import (
    PotentialShaping,
    UpdateStep,
    evaluate,
    get_pair,
    is_complete,
    load_critic,
    make_agent,
    make_env,
    resolve,
    sample_batches,
    train,
)

parser = argparse.ArgumentParser()
parser.add_argument("--frames", type=int, default=3000)
parser.add_argument("--out", default="runs/example-value-shaping")
args = parser.parse_args()
torch.manual_seed(0)
torch.set_num_threads(1)
pair = get_pair("fourrooms-near")  # the goal moves 1 unit within the north-east room

# 1. The source: SAC on the source task through drltg's loop, then its value as a frozen module.
source_dir = Path(args.out) / "source"
if not is_complete(source_dir):
    train(resolve(task=pair.source, frames=args.frames), source_dir, progress=False)
value = load_critic(source_dir)

# 2. make_env: the target task, shaped by the source's value (training env only).
cfg = resolve(task=pair.target, frames=args.frames, seed=1)
shaping = PotentialShaping(value, gamma=cfg.optim.gamma)
env = TransformedEnv(make_env(pair.target, batch_size=(8,), seed=1), shaping)
eval_env = make_env(pair.target, batch_size=(16,), seed=10_001)
steps = env.rollout(3, lambda td: td.set("action", torch.ones(8, 2)))
gap = (steps["potential"] - value(steps["observation"])).abs().max().item()  # Phi(s) is the source's value of s
print("potential", json.dumps({"phi_minus_source_value": gap, "phi": steps["potential"][0].flatten().tolist(),
                                "phi_next": steps["next", "potential"][0].flatten().tolist(),
                                "task_reward": steps["next", "task_reward"][0].flatten().tolist(),
                                "terminated": steps["next", "terminated"][0].flatten().tolist(),
                                "reward": steps["next", "reward"][0].flatten().tolist()}))

# 3. make_agent, collector, buffer, loss.
agent = make_agent(env, cfg)
fpb = cfg.collector.frames_per_batch
warmup = min(cfg.collector.init_random_frames, cfg.frames // 4 // fpb * fpb)
collector = Collector(env, agent.policy, frames_per_batch=fpb, total_frames=cfg.frames, init_random_frames=warmup,
                      auto_register_policy_transforms=False)
buffer = ReplayBuffer(storage=LazyTensorStorage(cfg.frames), batch_size=cfg.buffer.batch_size)
update = UpdateStep(agent)

# 4. The loop.
frames = 0
for batch in collector:
    buffer.extend(batch.reshape(-1))
    frames += batch.numel()
    if frames > warmup:
        for sample in sample_batches(buffer, cfg.optim.updates_per_batch):
            update(sample)
collector.shutdown()
print("result", json.dumps({"frames": frames, **evaluate(eval_env, agent.actor)}))
