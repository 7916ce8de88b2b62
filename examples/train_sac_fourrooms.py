"""SAC on continuous FourRooms, composed from TorchRL parts in user code (no drltg training loop).

    python examples/train_sac_fourrooms.py [--frames 30000] [--seed 0]

env -> Collector -> ReplayBuffer -> SACLoss -> Adam -> SoftUpdate, with a deterministic evaluation on
a separate env every 5000 frames. `drltg train` runs the same loop with logging and checkpoints.
"""
import argparse

import torch
from tensordict.nn import NormalParamExtractor, TensorDictModule
from torch import nn
from torchrl.collectors import Collector
from torchrl.data import LazyTensorStorage, ReplayBuffer
from torchrl.envs import ExplorationType, set_exploration_type
from torchrl.modules import MLP, ProbabilisticActor, TanhNormal, ValueOperator
from torchrl.objectives import SACLoss, SoftUpdate

from drltg.envs import make_env

parser = argparse.ArgumentParser()
parser.add_argument("--frames", type=int, default=30_000)
parser.add_argument("--seed", type=int, default=0)
args = parser.parse_args()
torch.manual_seed(args.seed)
torch.set_num_threads(1)  # small nets: one thread is fastest

# 1. Environments: 8 batched training envs, 16 evaluation envs seeded apart.
env = make_env("fourrooms/northeast", batch_size=(8,), seed=args.seed)
eval_env = make_env("fourrooms/northeast", batch_size=(16,), seed=args.seed + 10_000)
spec = env.action_spec_unbatched  # one policy for any batch size

# 2. Networks: a tanh-Gaussian actor and a Q(s, a) critic (SACLoss makes the twin and the targets).
actor = ProbabilisticActor(
    TensorDictModule(nn.Sequential(MLP(out_features=4, num_cells=[64, 64]), NormalParamExtractor()),
                     in_keys=["observation"], out_keys=["loc", "scale"]),
    in_keys=["loc", "scale"], spec=spec, distribution_class=TanhNormal,
    distribution_kwargs={"low": spec.space.low, "high": spec.space.high},
)
qvalue = ValueOperator(MLP(out_features=1, num_cells=[64, 64]), in_keys=["observation", "action"])
with torch.no_grad():  # materialise the lazy layers
    td = env.fake_tensordict()
    qvalue(actor(td))

# 3. Loss: a small initial temperature, or the entropy bonus drowns the sparse goal reward.
loss = SACLoss(actor, qvalue, num_qvalue_nets=2, loss_function="l2", alpha_init=0.01, action_spec=spec)
loss.make_value_estimator(gamma=0.99)
target_update = SoftUpdate(loss, tau=0.005)
optim = torch.optim.Adam(loss.parameters(), lr=3e-4)

# 4. Data: the collector runs the stochastic actor; the buffer keeps every transition.
collector = Collector(env, actor, frames_per_batch=32, total_frames=args.frames, init_random_frames=1024,
                      auto_register_policy_transforms=False)
buffer = ReplayBuffer(storage=LazyTensorStorage(100_000), batch_size=256)


@torch.no_grad()
def evaluate():
    """Success rate and mean return of one deterministic episode per eval env."""
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        rollout = eval_env.rollout(eval_env.horizon, actor, break_when_any_done=False)
    first_done = rollout["next", "done"].cumsum(1).cumsum(1) <= 1  # steps up to each env's first done
    ret = (rollout["next", "reward"] * first_done).sum(1).mean().item()
    success = (rollout["next", "success"] & first_done).any(1).float().mean().item()
    return ret, success


# 5. The loop: 8 gradient steps per batch of 32 frames once the warm-up is collected.
frames = 0
print(f"frames {frames:>6}: return {evaluate()[0]:+.3f}")
for batch in collector:
    buffer.extend(batch.reshape(-1))
    frames += batch.numel()
    if frames >= 1024:
        for _ in range(8):
            losses = loss(buffer.sample())
            optim.zero_grad()
            (losses["loss_actor"] + losses["loss_qvalue"] + losses["loss_alpha"]).backward()
            optim.step()
            target_update.step()
    if frames % 5024 < 32:
        ret, success = evaluate()
        print(f"frames {frames:>6}: return {ret:+.3f}, success {success:.2f}")
collector.shutdown()
