"""Soft option-critic by hand: SAC with K options on continuous FourRooms.

    python examples/soft_option_critic.py [--frames 3000] [--options 4]   # about 40 s on 2 cores

The option is environment state (InitTracker + a primer), so the collector carries it. The policy ends
the current option at the new state with probability beta_o(s), picks a new one from
softmax(Q_Omega / alpha_Omega) when it ends or an episode starts, then pi_o acts. With --options 1
this is exactly SAC. `drltg train TASK --algo soc` runs the same loss in drltg's loop.
"""
import argparse
import json

import torch
from torchrl.collectors import Collector
from torchrl.data import LazyTensorStorage, ReplayBuffer
from torchrl.objectives import SoftUpdate

from drltg import SoftOptionCriticLoss, evaluate, make_env, make_option_policy, option_transforms
from drltg.modules import make_option_actor, make_option_qvalue, make_termination, option_statistics

parser = argparse.ArgumentParser()
parser.add_argument("--frames", type=int, default=3000)
parser.add_argument("--options", type=int, default=4)
args = parser.parse_args()
K = args.options
torch.manual_seed(0)
torch.set_num_threads(1)

# 1. make_env: environments that carry the option ("is_init" at every reset, the primer declares "option").
env = make_env("fourrooms/northeast", batch_size=(8,), seed=0)
eval_env = make_env("fourrooms/northeast", batch_size=(16,), seed=10_000)
for transform in option_transforms(K):
    env, eval_env = env.append_transform(transform.clone()), eval_env.append_transform(transform.clone())
spec = env.action_spec_unbatched

# 2. The agent: one head per option for pi_o(a|s), Q_U(s, o, a) and beta_o(s) (2-D position in).
actor = make_option_actor(spec, K, [64, 64], in_features=2)
qvalue = make_option_qvalue(K, [64, 64], in_features=2 + 2)
termination = make_termination(K, [64, 64], in_features=2)

# 3. Loss: twin option critics with targets, learned temperatures for actions and for options.
loss = SoftOptionCriticLoss(actor, qvalue, termination, num_options=K, loss_function="l2", alpha_init=0.01,
                            option_alpha_init=0.01, deliberation_cost=0.01, action_spec=spec)
loss.make_value_estimator(gamma=0.99)
target_update = SoftUpdate(loss, tau=0.005)
optim = torch.optim.Adam(loss.parameters(), lr=3e-4)
policy = make_option_policy(loss)  # explores; under ExplorationType.DETERMINISTIC it is greedy

# 4. Collector and buffer.
warmup = min(1024, args.frames // 4 // 32 * 32)
collector = Collector(env, policy, frames_per_batch=32, total_frames=args.frames, init_random_frames=warmup,
                      auto_register_policy_transforms=False)
buffer = ReplayBuffer(storage=LazyTensorStorage(args.frames), batch_size=256)

# 5. The loop: all loss terms move disjoint parameters, so one optimiser minimises their sum.
frames = 0
for batch in collector:
    buffer.extend(batch.reshape(-1))
    frames += batch.numel()
    if frames > warmup:
        for _ in range(8):
            losses = loss(buffer.sample())
            optim.zero_grad()
            sum(v for k, v in losses.items() if k.startswith("loss_")).backward()
            optim.step()
            target_update.step()
collector.shutdown()
stats = option_statistics(batch, K)  # of the last batch: which options acted, for how long
print("result", json.dumps({"frames": frames, "options": K, **stats, **evaluate(eval_env, policy)}))
