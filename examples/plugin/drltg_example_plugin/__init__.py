"""An example drltg plugin: importing it registers a task pair on a one-dimensional corridor and a
transfer method.

    drltg tasks --import drltg_example_plugin            (with examples/plugin on PYTHONPATH)
    drltg experiment line-shift --method critic-reuse --seeds 3 --frames 4000 --import drltg_example_plugin

``LineWorld`` is a point on [0, 1] that moves by 0.1 * action; inside the goal interval
(|x - goal| <= 0.05) it gets +1 and the episode ends (``terminated``), every other step costs 0.01,
and after ``horizon`` steps the episode is ``truncated``. The potential is minus the number of steps
to the goal, Phi(x) = -|x - goal| / 0.1, so shaping with it is policy-invariant.

``critic-reuse`` transfers the source run's critics (and temperature) and lets the actor start fresh:
the target's first updates follow the source's values rather than a random critic.
"""
import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Bounded, Categorical, Composite, Unbounded
from torchrl.envs import EnvBase

from drltg.envs import register_pair, register_task
from drltg.transfer import Transfer, TransferMethod, load_from_run, register_method


class LineWorld(EnvBase):
    def __init__(self, goal: float = 0.9, horizon: int = 30, batch_size=(), device=None):
        super().__init__(batch_size=batch_size, device=device)
        self.goal, self.horizon = float(goal), int(horizon)
        shape = self.batch_size
        flag = Categorical(2, (*shape, 1), dtype=torch.bool, device=self.device)
        self.observation_spec = Composite(
            observation=Bounded(0.0, 1.0, (*shape, 1), device=self.device),
            step_count=Unbounded((*shape, 1), dtype=torch.int64, device=self.device),
            success=flag.clone(),
            shape=shape,
        )
        self.action_spec = Bounded(-1.0, 1.0, (*shape, 1), device=self.device)
        self.reward_spec = Unbounded((*shape, 1), device=self.device)
        self.done_spec = Composite(done=flag.clone(), terminated=flag.clone(), truncated=flag.clone(), shape=shape)
        self.rng = torch.Generator(device=self.device)

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs) -> TensorDictBase:
        start = torch.rand((*self.batch_size, 1), generator=self.rng, device=self.device)
        zeros = torch.zeros((*self.batch_size, 1), dtype=torch.bool, device=self.device)
        return TensorDict(
            {"observation": start, "step_count": torch.zeros_like(zeros, dtype=torch.int64), "success": zeros,
             "done": zeros, "terminated": zeros.clone(), "truncated": zeros.clone()},
            batch_size=self.batch_size, device=self.device,
        )

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        x = (tensordict["observation"] + 0.1 * tensordict["action"].clamp(-1, 1)).clamp(0, 1)
        steps = tensordict["step_count"] + 1
        success = (x - self.goal).abs() <= 0.05
        truncated = ~success & (steps >= self.horizon)
        reward = torch.where(success, 1.0, -0.01)
        return TensorDict(
            {"observation": x, "step_count": steps, "success": success, "reward": reward,
             "done": success | truncated, "terminated": success, "truncated": truncated},
            batch_size=self.batch_size, device=self.device,
        )

    def _set_seed(self, seed: int | None) -> None:
        self.rng.manual_seed(int(seed) if seed is not None else torch.seed())


class StepsToGoal(torch.nn.Module):
    """Phi(x) = -|x - goal| / 0.1: minus the steps the point needs to reach the goal."""

    in_keys = ["observation"]

    def __init__(self, goal: float):
        super().__init__()
        self.goal = goal

    def forward(self, observation: torch.Tensor) -> torch.Tensor:
        return -(observation - self.goal).abs().sum(-1, keepdim=True) / 0.1


TRAIN = {"sac": {"alpha_init": 0.01}, "network": {"hidden": [32, 32]}}
"""The tasks' own training settings (a run's defaults, below any -o). SAC's default entropy temperature 1.0
pays more for acting at random than the goal's reward of 1 pays for reaching it, so with it SAC never
learns these sparse tasks (the report then says no run reached the threshold); 0.01 lets the reward lead."""


def returns(options):
    """-0.01 a step until the goal pays 1: from never reaching it in ``horizon`` steps to reaching it at once."""
    return -0.01 * options["horizon"], 1.0


register_task("line/right", LineWorld, "a point on [0, 1] reaches the goal at 0.9", goal=0.9, train=TRAIN,
              potential=lambda options: StepsToGoal(options["goal"]), returns=returns, replace=True)
register_task("line/middle", LineWorld, "a point on [0, 1] reaches the goal at 0.6", goal=0.6, train=TRAIN,
              potential=lambda options: StepsToGoal(options["goal"]), returns=returns, replace=True)
register_pair("line-shift", "line/right", "line/middle", "the goal moves from 0.9 to 0.6", replace=True)


def critic_reuse(cfg, agent, env, *, resuming):
    if resuming:  # the checkpoint holds the weights
        return Transfer()
    report = load_from_run(agent.loss, cfg.transfer.source, checkpoint=cfg.transfer.source_checkpoint,
                           exclude=["actor_network_params"])
    return Transfer(files={"model_reuse.txt": f"{report}\n"})


register_method(TransferMethod("critic-reuse", "the critics start from the source run's, the actor from scratch",
                               critic_reuse, source="run"), replace=True)
