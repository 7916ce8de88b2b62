"""Soft option-critic (SAC with K options) on continuous FourRooms, composed from parts in user code.

    python examples/soft_option_critic.py [--options 4] [--frames 60000] [--seed 0]

The option is part of the environment state (InitTracker + a primer), so the collector carries it;
the option-carrying policy ends the current option at the new state with probability beta_o(s), picks
a new one from softmax(Q_Omega / alpha_Omega) when it ends or an episode starts, then pi_o acts.
With --options 1 this is exactly SAC. `drltg train TASK --algo soc` runs the same loop with logging.
"""
import argparse

import torch
from torchrl.collectors import Collector
from torchrl.data import LazyTensorStorage, ReplayBuffer
from torchrl.envs import ExplorationType, TransformedEnv, set_exploration_type
from torchrl.objectives import SoftUpdate

from drltg.envs import make_env
from drltg.losses import SoftOptionCriticLoss
from drltg.modules import (
    make_option_actor,
    make_option_policy,
    make_option_qvalue,
    make_termination,
    option_statistics,
    option_transforms,
)

parser = argparse.ArgumentParser()
parser.add_argument("--options", type=int, default=4)
parser.add_argument("--frames", type=int, default=60_000)
parser.add_argument("--seed", type=int, default=0)
args = parser.parse_args()
K = args.options
torch.manual_seed(args.seed)
torch.set_num_threads(1)

# 1. Environments that carry the option: "is_init" marks every reset, the primer declares "option".
env = TransformedEnv(make_env("fourrooms/northeast", batch_size=(8,), seed=args.seed))
eval_env = TransformedEnv(make_env("fourrooms/northeast", batch_size=(16,), seed=args.seed + 10_000))
for transform in option_transforms(K):
    env.append_transform(transform.clone())
    eval_env.append_transform(transform.clone())
spec = env.action_spec_unbatched

# 2. Networks with one head per option: pi_o(a|s), Q_U(s, o, a) and beta_o(s) (in_features: 2-D position).
actor = make_option_actor(spec, K, [64, 64], in_features=2)
qvalue = make_option_qvalue(K, [64, 64], in_features=2 + 2)
termination = make_termination(K, [64, 64], in_features=2)

# 3. Loss: twin option critics with targets, learned temperatures for actions and for options.
loss = SoftOptionCriticLoss(actor, qvalue, termination, num_options=K, loss_function="l2",
                            alpha_init=0.01, option_alpha_init=0.01, deliberation_cost=0.01, action_spec=spec)
loss.make_value_estimator(gamma=0.99)
target_update = SoftUpdate(loss, tau=0.005)
optim = torch.optim.Adam(loss.parameters(), lr=3e-4)
policy = make_option_policy(loss)  # explores; under ExplorationType.DETERMINISTIC it is greedy

# 4. Data.
collector = Collector(env, policy, frames_per_batch=32, total_frames=args.frames, init_random_frames=1024,
                      auto_register_policy_transforms=False)
buffer = ReplayBuffer(storage=LazyTensorStorage(100_000), batch_size=256)


@torch.no_grad()
def evaluate():
    """Success rate and mean return of one deterministic episode per eval env."""
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        rollout = eval_env.rollout(eval_env.base_env.horizon, policy, break_when_any_done=False)
    first_done = rollout["next", "done"].cumsum(1).cumsum(1) <= 1
    ret = (rollout["next", "reward"] * first_done).sum(1).mean().item()
    success = (rollout["next", "success"] & first_done).any(1).float().mean().item()
    return ret, success


# 5. The loop: all loss terms move disjoint parameters, so one optimizer minimises their sum.
frames = 0
print(f"frames {frames:>6}: return {evaluate()[0]:+.3f}")
for batch in collector:
    buffer.extend(batch.reshape(-1))
    frames += batch.numel()
    if frames >= 1024:
        for _ in range(8):
            losses = loss(buffer.sample())
            optim.zero_grad()
            sum(v for k, v in losses.items() if k.startswith("loss_")).backward()
            optim.step()
            target_update.step()
    if frames % 5024 < 32:
        ret, success = evaluate()
        stats = option_statistics(batch, K)
        usage = " ".join(f"{stats[f'option_usage/{o}']:.2f}" for o in range(K))
        print(f"frames {frames:>6}: return {ret:+.3f}, success {success:.2f}, "
              f"option length {stats['option_length']:.1f}, usage {usage}")
collector.shutdown()
