"""Successor features and GPI by hand: two source goals' successor features act on a new goal, untrained.

    python examples/successor_features.py [--frames 12800]   # about 10 s on one core

Grid FourRooms, three candidate goals: A in the northeast room, B in the southeast room, C in the east
hallway between them. phi(s') = [at A, at B, at C, 1], so every task's reward is phi . w exactly. For each
source goal, psi is learnt by TD on random-walk transitions, greedy on its own w (successor-feature
Q-learning). On the target C, w is regressed from random transitions, and GPI acts by
argmax_a max_i psi_i(s, a) . w: a source's path that crosses the hallway is worth 1 on C, so GPI follows
the source whose path crosses it from where it stands. Printed: each source on its own goal and on C,
GPI on C (64 deterministic episodes each), and how far the regressed w is from the true one.
"""
import argparse
import json

import torch
from torchrl.data import LazyTensorStorage, ReplayBuffer
from torchrl.objectives import SoftUpdate

from drltg.collectors import GPIPolicy
from drltg.envs.gridrooms import N_CELLS, GridFourRoomsEnv
from drltg.losses import SuccessorFeatureLoss
from drltg.modules import GoalFeatures, make_sf_critic, regress_weights
from drltg.training.loop import evaluate

parser = argparse.ArgumentParser()
parser.add_argument("--frames", type=int, default=12800, help="random-walk frames per source (and for w)")
args = parser.parse_args()
torch.manual_seed(0)
torch.set_num_threads(1)
SOURCES, TARGET = [(3, 9), (10, 9)], (7, 9)
features = GoalFeatures(SOURCES + [TARGET])
steps = max(args.frames // 64, 1)


def random_transitions(goal, seed):
    """``steps`` random-walk steps in 64 envs of the task ``goal``, with their features."""
    env = GridFourRoomsEnv(goal=goal, batch_size=(64,), seed=seed)
    return features(env.rollout(steps, break_when_any_done=False).reshape(-1)), env.step_cost


def train_sf(goal, seed):
    """psi of the greedy policy of the task ``goal``, by TD on random transitions (Adam, soft target)."""
    data, step_cost = random_transitions(goal, seed)
    buffer = ReplayBuffer(storage=LazyTensorStorage(data.numel()), batch_size=256)
    buffer.extend(data)
    critic = make_sf_critic(N_CELLS, features.num_features, num_actions=4, num_cells=(), bias=False)
    loss = SuccessorFeatureLoss(critic, weights=features.task_weights(goal, step_cost), reduction="sum")
    loss.make_value_estimator(gamma=0.95)
    target = SoftUpdate(loss, tau=0.1)
    optim = torch.optim.SGD(loss.parameters(), lr=0.25)
    for _ in range(args.frames // 16):
        optim.zero_grad()
        loss(buffer.sample())["loss_sf"].backward()
        optim.step()
        target.step()
    return critic


critics = [train_sf(goal, seed) for seed, goal in enumerate(SOURCES)]
target_data, step_cost = random_transitions(TARGET, 10)
w = regress_weights(target_data["next", "features"], target_data["next", "reward"])
w_true = features.task_weights(TARGET, step_cost)

result = {"frames": args.frames, "target_goal_transitions": int(target_data["next", "success"].sum()),
          "w_error": (w - w_true).abs().max().item()}
target_env = GridFourRoomsEnv(goal=TARGET, batch_size=(64,), seed=1000)
for name, goal, critic in zip("AB", SOURCES, critics):
    own = evaluate(GridFourRoomsEnv(goal=goal, batch_size=(64,), seed=1000), GPIPolicy([critic], features.task_weights(
        goal, step_cost)))  # GPI over one critic is that critic's greedy policy
    result[f"source_{name}_on_own_goal"] = own["success_rate"]
    result[f"source_{name}_on_target"] = evaluate(target_env, GPIPolicy([critic], w))["success_rate"]
gpi = GPIPolicy(critics, w)
result["gpi_on_target"] = evaluate(target_env, gpi)["success_rate"]
result["gpi_index_range"] = sorted(set(gpi(target_env.reset())["gpi_index"].flatten().tolist()))
print("result", json.dumps(result))
