"""Suite ``sac``: SAC gradient updates per second on the same work, side by side.

Batch 256, Lift-sized transitions (observation 50, action 7), actor and twin critics of 2x256 ReLU
layers, Adam lr 3e-4, gamma 0.99, tau 0.005, learned temperature from 1.0, target entropy -7, one
update = critic + actor + temperature step and a soft target update. Every learner samples from a
replay buffer holding the same 20k random transitions. Cases:

* ``drltg``: the training loop's step (``drltg.learners.UpdateStep`` on the SAC agent of
  ``drltg.learners.make_sac_agent``, batches drawn with ``sample_batches``);
* ``torchrl``: TorchRL's stock ``SACLoss`` step as the sota example writes it (``buffer.sample()``,
  ``loss`` with its default ``torch.vmap`` critics, ``backward``, ``Adam.step``, ``SoftUpdate.step``);
* ``plain``: a minimal hand-written PyTorch SAC update (one backward for all three losses), the
  practical bound of eager PyTorch;
* ``sb3``: Stable-Baselines3 ``SAC.train(gradient_steps, batch_size=256)`` on a filled buffer;
* ``soc_k4``: drltg's soft option-critic with 4 options (same networks, per-option heads);
* ``matmul_bound``: only the matrix products of one SAC update (forward and backward, see
  :func:`sac_matmuls`) into preallocated outputs: what this thread's BLAS allows for the update's
  arithmetic, a bound no eager float32 implementation reaches;
* on CPU also ``drltg_bf16`` and ``matmul_bound_bf16``: the drltg step under
  ``torch.autocast("cpu", dtype=torch.bfloat16)`` and the matrix products in bfloat16, what a CPU with
  bfloat16 dot products (AVX512-BF16, AMX) gains from mixed precision;
* on CUDA also ``drltg_cudagraphs``: the drltg step captured in a CUDA graph.

Every learner's update (``drltg`` is SAC; ``discrete_sac``: 7 one-hot actions; ``td3``: its policy
delay of 2; ``soc_k4``: 4 options): ``UpdateStep`` on the agent ``drltg train`` builds (critic copies
in a loop, TorchRL's ``deactivate_vmap=True``), against the same with TorchRL's default ``torch.vmap``
critics (``*_vmap``); ``soc_k4_per_copy``: the SOC update with every option's copy of a state through
the networks' trunk, as before ``OptionHeads`` ran a repeated state once. ``torch.compile`` of the step
is not a case: on the 2-core CPU it compiled for ten minutes and was not faster (``benchmarks/README.md``).
"""
from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from tensordict import TensorDict
from torch import nn
from torchrl.data import Bounded, Composite, LazyTensorStorage, OneHot, ReplayBuffer, Unbounded
from torchrl.envs import EnvBase

from benchmarks.common import interleaved, ratios
from drltg import config as config_lib
from drltg import learners
from drltg.learners import UpdateStep, make_agent, make_sac_agent, sample_batches
from drltg.modules import OptionHeads

OBS, ACT, HIDDEN, BATCH, N_DATA = 50, 7, 256, 256, 20_000
LR, GAMMA, TAU = 3e-4, 0.99, 0.005


class SpecEnv(EnvBase):
    """Specs only (observation 50, action 7, or 7 one-hot actions): what the agent builders read."""

    def __init__(self, device="cpu", discrete: bool = False):
        super().__init__(device=device, batch_size=torch.Size([]))
        self.observation_spec = Composite(observation=Unbounded((OBS,), device=device), device=device)
        self.action_spec = OneHot(ACT, device=device) if discrete else Bounded(-1.0, 1.0, (ACT,), device=device)
        self.reward_spec = Unbounded((1,), device=device)

    def _reset(self, tensordict):
        raise NotImplementedError

    def _step(self, tensordict):
        raise NotImplementedError

    def _set_seed(self, seed):
        pass


def transitions(n: int = N_DATA, seed: int = 0, options: int = 0, discrete: bool = False) -> TensorDict:
    g = torch.Generator().manual_seed(seed)
    terminated = torch.rand(n, 1, generator=g) < 0.01
    if discrete:
        action = F.one_hot(torch.randint(ACT, (n,), generator=g), ACT).bool()
    else:
        action = torch.rand(n, ACT, generator=g) * 2 - 1
    td = TensorDict(
        {
            "observation": torch.randn(n, OBS, generator=g),
            "action": action,
            "next": {
                "observation": torch.randn(n, OBS, generator=g),
                "reward": torch.randn(n, 1, generator=g),
                "terminated": terminated,
                "done": terminated.clone(),
            },
        },
        [n],
    )
    if options:
        td["option"] = torch.randint(0, options, (n, 1), generator=g)
    return td


def _buffer(data: TensorDict, device: str) -> ReplayBuffer:
    buffer = ReplayBuffer(storage=LazyTensorStorage(len(data), device=device), batch_size=BATCH)
    buffer.extend(data.to(device))
    return buffer


def _config(**extra) -> config_lib.RunConfig:
    return config_lib.resolve({}, [f"network.hidden=[{HIDDEN},{HIDDEN}]"], **extra)


def drltg_case(device: str, chunk: int, cudagraphs: bool = False, autocast: torch.dtype | None = None):
    torch.manual_seed(0)
    agent = make_sac_agent(SpecEnv(device), _config(device=device))
    step = UpdateStep(agent, cudagraphs=cudagraphs)
    buffer = _buffer(transitions(), device)
    precision = torch.autocast(device.split(":")[0], dtype=autocast, enabled=autocast is not None)

    def run() -> int:
        for batch in sample_batches(buffer, chunk):
            with precision:
                step(batch)
        return chunk

    return run


def _vmap_agent(env: EnvBase, cfg: config_lib.RunConfig) -> learners.Agent:
    """The agent ``make_agent`` builds, its loss with TorchRL's default ``torch.vmap`` critics."""
    shipped, learners.DEACTIVATE_VMAP = learners.DEACTIVATE_VMAP, False
    try:
        return make_agent(env, cfg)
    finally:
        learners.DEACTIVATE_VMAP = shipped


def torchrl_case(device: str, chunk: int):
    torch.manual_seed(0)
    agent = _vmap_agent(SpecEnv(device), _config(device=device))
    loss, updater = agent.loss, agent.target_updater
    optimizer = torch.optim.Adam(loss.parameters(), lr=LR)
    buffer = _buffer(transitions(), device)

    def run() -> int:
        for _ in range(chunk):
            out = loss(buffer.sample())
            (out["loss_actor"] + out["loss_qvalue"] + out["loss_alpha"]).backward()
            optimizer.step()
            optimizer.zero_grad(set_to_none=True)
            updater.step()
        return chunk

    return run


class PlainSAC(nn.Module):
    """SAC in plain PyTorch, written the direct way: tanh-Gaussian actor, two critics, target
    critics, learned temperature, one optimizer and one backward per update."""

    def __init__(self, device: str):
        super().__init__()

        def mlp(i, o):
            layers = [nn.Linear(i, HIDDEN), nn.ReLU(), nn.Linear(HIDDEN, HIDDEN), nn.ReLU(), nn.Linear(HIDDEN, o)]
            return nn.Sequential(*layers)

        self.actor = mlp(OBS, 2 * ACT).to(device)
        self.q = nn.ModuleList([mlp(OBS + ACT, 1) for _ in range(2)]).to(device)
        self.q_target = nn.ModuleList([mlp(OBS + ACT, 1) for _ in range(2)]).to(device)
        self.q_target.load_state_dict(self.q.state_dict())
        self.q_target.requires_grad_(False)
        self.log_alpha = nn.Parameter(torch.zeros((), device=device))
        self.optimizer = torch.optim.Adam([*self.actor.parameters(), *self.q.parameters(), self.log_alpha], lr=LR)

    def policy(self, obs):
        loc, pre_scale = self.actor(obs).chunk(2, -1)
        scale = F.softplus(pre_scale + 0.5413) + 1e-4
        u = loc + scale * torch.randn_like(loc)
        log_prob = (-0.5 * ((u - loc) / scale) ** 2 - scale.log() - 0.5 * math.log(2 * math.pi)).sum(-1)
        log_prob = log_prob - (2 * (math.log(2) - u - F.softplus(-2 * u))).sum(-1)
        return torch.tanh(u), log_prob

    @staticmethod
    def value(nets, obs, action):
        x = torch.cat([obs, action], -1)
        return torch.min(nets[0](x), nets[1](x)).squeeze(-1)

    def update(self, b) -> None:
        obs, action, nxt = b["observation"], b["action"], b["next"]
        alpha = self.log_alpha.exp().detach()
        with torch.no_grad():
            next_action, next_log_prob = self.policy(nxt["observation"])
            next_value = self.value(self.q_target, nxt["observation"], next_action) - alpha * next_log_prob
            y = nxt["reward"].squeeze(-1) + GAMMA * (~nxt["terminated"].squeeze(-1)) * next_value
        x = torch.cat([obs, action], -1)
        q_loss = sum(F.mse_loss(q(x).squeeze(-1), y) for q in self.q)
        new_action, log_prob = self.policy(obs)
        self.q.requires_grad_(False)
        actor_loss = (alpha * log_prob - self.value(self.q, obs, new_action)).mean()
        self.q.requires_grad_(True)
        alpha_loss = -(self.log_alpha * (log_prob.detach() - ACT)).mean()
        self.optimizer.zero_grad(set_to_none=True)
        (q_loss + actor_loss + alpha_loss).backward()
        self.optimizer.step()
        with torch.no_grad():
            for p, t in zip(self.q.parameters(), self.q_target.parameters()):
                t.lerp_(p, TAU)


def plain_case(device: str, chunk: int):
    torch.manual_seed(0)
    sac = PlainSAC(device)
    buffer = _buffer(transitions(), device)

    def run() -> int:
        for _ in range(chunk):
            sac.update(buffer.sample())
        return chunk

    return run


def sb3_case(device: str, chunk: int):
    import gymnasium as gym
    import numpy as np
    from stable_baselines3 import SAC
    from stable_baselines3.common.logger import Logger

    class Box(gym.Env):
        observation_space = gym.spaces.Box(-np.inf, np.inf, (OBS,), np.float32)
        action_space = gym.spaces.Box(-1.0, 1.0, (ACT,), np.float32)

    model = SAC(
        "MlpPolicy", Box(), learning_rate=LR, buffer_size=N_DATA, learning_starts=0, batch_size=BATCH, tau=TAU,
        gamma=GAMMA, policy_kwargs={"net_arch": [HIDDEN, HIDDEN]}, device=device, seed=0,
    )
    model.set_logger(Logger(None, []))
    data, rb = transitions(), model.replay_buffer
    rb.observations[:, 0] = data["observation"].numpy()
    rb.next_observations[:, 0] = data["next", "observation"].numpy()
    rb.actions[:, 0] = data["action"].numpy()
    rb.rewards[:, 0] = data["next", "reward"].squeeze(-1).numpy()
    rb.dones[:, 0] = data["next", "terminated"].squeeze(-1).numpy()
    rb.full = True

    def run() -> int:
        model.train(gradient_steps=chunk, batch_size=BATCH)
        return chunk

    return run


class _PerCopyHeads(OptionHeads):
    """``OptionHeads`` with its inputs materialised: a state repeated for each option goes through the trunk
    once per copy (the peer of ``OptionHeads``' repeated-state shortcut)."""

    def forward(self, *inputs: torch.Tensor):
        *inputs, option = inputs
        return super().forward(*[x.contiguous() for x in inputs], option)


LEARNERS = {"sac": ("sac", False), "discrete_sac": ("sac", True), "td3": ("td3", False), "soc_k4": ("soc", False)}


def learner_case(learner: str, device: str, chunk: int, *, vmap: bool = False, per_copy: bool = False):
    """The training loop's ``UpdateStep`` on the agent of ``learner`` (TD3 with its policy delay); with
    ``per_copy``, its option heads run every copy of a repeated state (:class:`_PerCopyHeads`)."""
    algo, discrete = LEARNERS[learner]
    torch.manual_seed(0)
    cfg = _config(algo=algo, device=device, **({"soc.num_options": 4} if algo == "soc" else {}))
    agent = (_vmap_agent if vmap else make_agent)(SpecEnv(device, discrete), cfg)
    if per_copy:
        networks = (agent.loss.actor_network, agent.loss.qvalue_network, agent.loss.termination_network)
        for module in (m for net in networks for m in net.modules() if isinstance(m, OptionHeads)):
            module.__class__ = _PerCopyHeads
    step = UpdateStep(agent)
    buffer = _buffer(transitions(options=4 if algo == "soc" else 0, discrete=discrete), device)
    updates = 0

    def run() -> int:
        nonlocal updates
        for batch in sample_batches(buffer, chunk):
            step(batch, update_actor=updates % agent.actor_delay == 0)
            updates += 1
        return chunk

    return run


def learner_cases(device: str, chunk: int) -> dict:
    """Every learner's update as built and with ``torch.vmap`` critics (``drltg`` is SAC's, made apart)."""
    cases = {}
    for learner in LEARNERS:
        n = max(chunk // 4, 2) if learner == "soc_k4" else chunk
        if learner != "sac":
            cases[learner] = learner_case(learner, device, n)
        cases[f"{learner}_vmap"] = learner_case(learner, device, n, vmap=True)
    cases["soc_k4_per_copy"] = learner_case("soc_k4", device, max(chunk // 4, 2), per_copy=True)
    return cases


LEARNER_PAIRS = [("drltg", "sac_vmap"), ("discrete_sac", "discrete_sac_vmap"), ("td3", "td3_vmap"),
                 ("soc_k4", "soc_k4_vmap"), ("soc_k4", "soc_k4_per_copy")]


def _mlp_matmuls(dims: list[int], batch: int, forward: bool, weight_grads: bool, input_grads: str) -> list[tuple]:
    """``(m, k, n)`` of the products of an MLP with layer widths ``dims`` on ``batch`` rows: the
    forward ``x W^T``, the weight gradients ``g^T x`` and the input gradients ``g W`` (``input_grads``
    ``"none"``, ``"hidden"``: all layers but the first, ``"all"``)."""
    layers = list(zip(dims[:-1], dims[1:]))
    out = [(batch, i, o) for i, o in layers] if forward else []
    if weight_grads:
        out += [(o, batch, i) for i, o in layers]
    if input_grads != "none":
        out += [(batch, o, i) for n, (i, o) in enumerate(layers) if n or input_grads == "all"]
    return out


def sac_matmuls(
    obs: int = OBS, act: int = ACT, hidden: int = HIDDEN, batch: int = BATCH, critics: int = 2
) -> list[tuple]:
    """The matrix products of one SAC update: the target ``y`` (actor and target critics on s', no
    gradient), the critic loss (critics on (s, a), weight and hidden-layer input gradients), the
    actor loss (actor on s with weight gradients; critics on (s, a~) with input gradients only, down
    to a~)."""
    actor, critic = [obs, hidden, hidden, 2 * act], [obs + act, hidden, hidden, 1]
    out = _mlp_matmuls(actor, batch, True, False, "none") + critics * _mlp_matmuls(critic, batch, True, False, "none")
    out += critics * _mlp_matmuls(critic, batch, True, True, "hidden")
    out += _mlp_matmuls(actor, batch, True, True, "hidden") + critics * _mlp_matmuls(critic, batch, True, False, "all")
    return out


def matmul_case(device: str, chunk: int, dtype: torch.dtype = torch.float32):
    shapes = sac_matmuls()
    g = torch.Generator().manual_seed(0)
    operands = [(torch.randn(m, k, generator=g).to(device, dtype), torch.randn(k, n, generator=g).to(device, dtype),
                 torch.empty(m, n, device=device, dtype=dtype)) for m, k, n in shapes]

    def run() -> int:
        for _ in range(chunk):
            for a, b, out in operands:
                torch.mm(a, b, out=out)
        return chunk

    return run


def run(device: str = "cpu", quick: bool = False) -> dict:
    chunk, rounds = (8, 3) if quick else (16, 15)
    cases = {
        "drltg": drltg_case(device, chunk),
        "torchrl": torchrl_case(device, chunk),
        "plain": plain_case(device, chunk),
        "matmul_bound": matmul_case(device, chunk),
    }
    missing = {}
    if device == "cpu":
        cases["drltg_bf16"] = drltg_case(device, chunk, autocast=torch.bfloat16)
        cases["matmul_bound_bf16"] = matmul_case(device, chunk, torch.bfloat16)
    if device.startswith("cuda"):
        try:
            case = drltg_case(device, chunk, cudagraphs=True)
            case()  # capture now: a failure is reported, the other cases still run
            cases["drltg_cudagraphs"] = case
        except Exception as err:  # noqa: BLE001
            missing["drltg_cudagraphs"] = f"{type(err).__name__}: {err}"
    try:
        cases["sb3"] = sb3_case(device, chunk)
    except ImportError as err:
        missing["sb3"] = f"not installed ({err.name}); pip install -e '.[bench]'"
    cases |= learner_cases(device, chunk)
    results = interleaved(cases, rounds=rounds, warmup=1, device=device)
    pairs = [("drltg", "plain"), ("drltg", "torchrl"), ("drltg", "sb3"), ("torchrl", "plain"), ("sb3", "plain"),
             ("drltg_cudagraphs", "plain"), ("drltg_cudagraphs", "torchrl"), ("soc_k4", "drltg"),
             ("drltg", "matmul_bound"), ("plain", "matmul_bound"), ("sb3", "matmul_bound"), ("torchrl", "matmul_bound"),
             ("drltg_bf16", "drltg"), ("matmul_bound_bf16", "matmul_bound")]
    flops = sum(2 * m * k * n for m, k, n in sac_matmuls())
    return {
        "unit": "updates/s",
        "work": f"batch {BATCH}, obs {OBS}, act {ACT}, 2x{HIDDEN} actor and twin critics, Adam {LR}",
        "matmul_gflop_per_update": round(flops / 1e9, 3),
        "matmul_bound_gflops": round(results["matmul_bound"]["median"] * flops / 1e9, 1),
        "rates": results,
        "ratios": ratios(results, pairs + LEARNER_PAIRS),
        "missing": missing,
        "target": "drltg >= 1.0x plain and >= 2x torchrl and sb3",
    }
