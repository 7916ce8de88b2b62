"""Add your own environment and task pair to drltg, then train and transfer on it.

    python examples/custom_env.py [--frames 6000]

`OpenRoom` is a minimal batched TorchRL env — a point in the unit square that must reach a goal disc —
written like TorchRL's `PendulumEnv`: stateless, specs built in one place, pure torch. Registering two
goals as tasks and naming them a pair is all drltg needs: `drltg.training.loop.train`, `drltg experiment`
(from code, see the end) and the report then work on them like on the built-in tasks.
"""
import argparse
import shutil

import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Bounded, Categorical, Composite, Unbounded
from torchrl.envs import EnvBase

from drltg import config
from drltg.envs import make_env, register_pair, register_task
from drltg.training.loop import read_eval_csv, train


class OpenRoom(EnvBase):
    """A point in [0, 1]^2 moves by 0.1 * action; +1 and `terminated` inside the goal disc (r 0.1),
    -0.01 per other step, `truncated` after `horizon` steps. Observation: the position."""

    def __init__(self, goal=(0.8, 0.8), horizon=50, batch_size=(), device=None):
        super().__init__(batch_size=batch_size, device=device)
        self.goal, self.horizon = torch.tensor(goal, device=self.device), horizon
        self.observation_spec = Composite(
            observation=Bounded(0.0, 1.0, (*self.batch_size, 2), device=self.device),
            step_count=Unbounded((*self.batch_size, 1), dtype=torch.int64, device=self.device),
            success=Categorical(2, (*self.batch_size, 1), dtype=torch.bool, device=self.device),
            shape=self.batch_size,
        )
        self.action_spec = Bounded(-1.0, 1.0, (*self.batch_size, 2), device=self.device)
        self.reward_spec = Unbounded((*self.batch_size, 1), device=self.device)
        flag = Categorical(2, (*self.batch_size, 1), dtype=torch.bool, device=self.device)
        self.done_spec = Composite(done=flag, terminated=flag.clone(), truncated=flag.clone(), shape=self.batch_size)
        self.rng = torch.Generator(device=self.device)

    def _reset(self, td: TensorDictBase | None) -> TensorDictBase:
        position = torch.rand(*self.batch_size, 2, generator=self.rng, device=self.device)
        zeros = torch.zeros(*self.batch_size, 1, device=self.device)
        return TensorDict(
            observation=position, step_count=zeros.long(), success=zeros.bool(), batch_size=self.batch_size
        )

    def _step(self, td: TensorDictBase) -> TensorDictBase:
        position = (td["observation"] + 0.1 * td["action"].clamp(-1, 1)).clamp(0, 1)
        step_count = td["step_count"] + 1
        success = (position - self.goal).norm(dim=-1, keepdim=True) <= 0.1
        truncated = (step_count >= self.horizon) & ~success
        return TensorDict(
            observation=position, step_count=step_count, success=success,
            reward=torch.where(success, 1.0, -0.01), terminated=success, truncated=truncated,
            done=success | truncated, batch_size=self.batch_size,
        )

    def _set_seed(self, seed: int | None) -> None:
        self.rng.manual_seed(seed if seed is not None else torch.seed())


# 1. Register two tasks (same env, two goals) and a pair. `train=` holds per-task config defaults: small nets,
# and an entropy temperature of 0.01, since at SAC's default 1.0 the entropy bonus outweighs the goal's sparse
# reward of 1 and nothing is learned (docs/extending.md, "Which defaults matter").
small = {"network": {"hidden": [64, 64]}, "sac": {"alpha_init": 0.01}}
register_task("openroom/ne", OpenRoom, "open room, goal (0.8, 0.8)", goal=(0.8, 0.8), train=small)
register_task("openroom/nw", OpenRoom, "open room, goal (0.2, 0.8)", goal=(0.2, 0.8), train=small)
register_pair("openroom-flip", "openroom/ne", "openroom/nw", "the goal moves to the other corner")

# 2. The env passes TorchRL's own checks, batched and unbatched.
from torchrl.envs.utils import check_env_specs  # noqa: E402

check_env_specs(make_env("openroom/ne", seed=0))
check_env_specs(make_env("openroom/ne", batch_size=(4,), seed=0))

# 3. Train on the source task with drltg's loop, then fine-tune on the target from its weights.
parser = argparse.ArgumentParser()
parser.add_argument("--frames", type=int, default=6000)
parser.add_argument("--out", default="runs/example-custom-env")
args = parser.parse_args()
shutil.rmtree(args.out, ignore_errors=True)  # the example always trains anew
source_cfg = config.resolve({}, ["eval.every=1000"], task="openroom/ne", frames=args.frames, seed=0)
source = train(source_cfg, f"{args.out}/source")
target_cfg = config.resolve(
    {}, ["eval.every=1000", "transfer.method=model-reuse", f"transfer.source={source}"],
    task="openroom/nw", frames=args.frames, seed=1,
)
target = train(target_cfg, f"{args.out}/target")
for name, run in (("source", source), ("target (model reuse)", target)):
    last = read_eval_csv(run / "eval.csv")[-1]
    print(f"{name}: return {last['return_mean']:+.3f}, success {last['success_rate']:.2f} at {last['frames']} frames")
