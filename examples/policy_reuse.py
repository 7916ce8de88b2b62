"""Probabilistic policy reuse in user code: a source policy guides SAC on a moved goal.

    python examples/policy_reuse.py [--frames 10240] [--out runs/example-policy-reuse]

The source agent is trained with drltg's loop; the target agent with a short loop of its own whose
collector runs the learner's policy followed by ``PolicyReuse``: at step h of every episode the
source actor acts with probability psi * upsilon^h, the learner explores otherwise.
"""
import argparse
from pathlib import Path

import torch
from tensordict.nn import TensorDictSequential
from torchrl.collectors import Collector
from torchrl.data import LazyTensorStorage, ReplayBuffer

from drltg.collectors import PiReuse, PolicyReuse
from drltg.config import resolve
from drltg.envs import get_pair, make_env
from drltg.learners import make_agent
from drltg.training.loop import evaluate, is_complete, train
from drltg.transfer import load_from_run

parser = argparse.ArgumentParser()
parser.add_argument("--frames", type=int, default=10_240)
parser.add_argument("--out", default="runs/example-policy-reuse")
args = parser.parse_args()
torch.set_num_threads(1)
pair = get_pair("fourrooms-near")

# 1. The past policy: train on the source task, then rebuild its actor from the run's checkpoint.
source_cfg = resolve(task=pair.source, frames=args.frames, seed=0)
source_dir = Path(args.out) / "source"
if not is_complete(source_dir):
    train(source_cfg, source_dir)
source = make_agent(make_env(pair.source), source_cfg)
load_from_run(source.loss, source_dir)

# 2. The target learner; its behaviour policy is its own exploration followed by pi-reuse.
torch.manual_seed(1)
cfg = resolve(task=pair.target, seed=1)
agent = make_agent(make_env(pair.target), cfg)
reuse = PolicyReuse(source.actor, schedule=PiReuse(psi=1.0, upsilon=0.95))
env = make_env(pair.target, batch_size=(8,), seed=1)
env = env.append_transform(reuse.primer())  # declares the episode's choice, "reuse_index", redrawn at every reset
collector = Collector(
    env, TensorDictSequential(agent.policy, reuse), frames_per_batch=32, total_frames=args.frames,
    auto_register_policy_transforms=False,
)
buffer = ReplayBuffer(storage=LazyTensorStorage(100_000), batch_size=256)
eval_env = make_env(pair.target, batch_size=(16,), seed=2)

# 3. An off-policy loop. Evaluation measures the learner alone: under DETERMINISTIC the mixer
#    passes the learner's action through.
print(f"frames 0: {evaluate(eval_env, agent.actor)}")
frames = 0
for batch in collector:
    frames += batch.numel()
    reuse.set_progress(frames)  # only decaying schedules use it; harmless otherwise
    reused = batch["reused"].float().mean().item()
    buffer.extend(batch.reshape(-1))
    for _ in range(8):
        losses = agent.loss(buffer.sample())
        agent.optimizer.zero_grad()
        sum(v for k, v in losses.items() if k.startswith("loss_")).backward()
        agent.optimizer.step()
        agent.target_updater.step()
    if frames % 2048 == 0:
        print(f"frames {frames}: reused {reused:.2f}, {evaluate(eval_env, agent.actor)}")
collector.shutdown()
