"""Reward shaping by hand: SAC on FourRooms with the task's potential added to every reward.

    python examples/reward_shaping.py [--frames 3000]     # about 30 s on 2 cores

PotentialShaping adds F = gamma * Phi(s') * (1 - terminated) - Phi(s) to the reward (Ng et al. 1999),
Phi = minus the path length to the goal through the doorways; the optimal policy stays the task's.
The evaluation env has no shaping: it measures the task's own return and success.
"""
import argparse
import json

import torch
from torchrl.collectors import Collector
from torchrl.data import LazyTensorStorage, ReplayBuffer
from torchrl.envs import TransformedEnv

from drltg import PotentialShaping, UpdateStep, evaluate, get_task, make_agent, make_env, resolve, sample_batches

parser = argparse.ArgumentParser()
parser.add_argument("--frames", type=int, default=3000)
args = parser.parse_args()
torch.manual_seed(0)
torch.set_num_threads(1)

# 1. make_env: the task (+1 at the goal, -0.01 a step) with shaping on the training env only.
task = "fourrooms/northeast"
cfg = resolve(task=task, frames=args.frames)
potential = get_task(task).potential(cfg.env)
env = TransformedEnv(make_env(task, batch_size=(8,), seed=0), PotentialShaping(potential, gamma=cfg.optim.gamma))
eval_env = make_env(task, batch_size=(16,), seed=10_000)

# 2. What the transform writes: Phi(s) in "potential", Phi(s') and the task's reward in "next".
steps = env.rollout(3, lambda td: td.set("action", torch.ones(8, 2)))[0]  # env 0, heading north-east
for t in range(3):
    row = {k: steps[k][t].item() for k in ("potential", ("next", "potential"), ("next", "task_reward"),
                                            ("next", "terminated"), ("next", "reward"))}
    print("step", json.dumps({"/".join(k) if isinstance(k, tuple) else k: v for k, v in row.items()}))

# 3. make_agent, collector, buffer and loss: SAC as `drltg train` builds it.
agent = make_agent(env, cfg)
fpb = cfg.collector.frames_per_batch
warmup = min(cfg.collector.init_random_frames, cfg.frames // 4 // fpb * fpb)
collector = Collector(env, agent.policy, frames_per_batch=fpb, total_frames=cfg.frames, init_random_frames=warmup,
                      auto_register_policy_transforms=False)
buffer = ReplayBuffer(storage=LazyTensorStorage(cfg.frames), batch_size=cfg.buffer.batch_size)
update = UpdateStep(agent)

# 4. The loop: the learner sees the shaped reward, the evaluation the task's.
frames = 0
for batch in collector:
    buffer.extend(batch.reshape(-1))
    frames += batch.numel()
    if frames > warmup:
        for sample in sample_batches(buffer, cfg.optim.updates_per_batch):
            update(sample)
collector.shutdown()
print("result", json.dumps({"frames": frames, **evaluate(eval_env, agent.actor)}))
