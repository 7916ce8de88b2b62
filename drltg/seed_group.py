"""Seed groups: N agents of one config trained in step, as one vmapped update.

The agents' loss parameters and buffers (target networks included) are stacked along a leading seed
dimension with ``TensorDict.from_modules``, as TorchRL stacks its critic ensembles. One update is

    losses_k = loss(batch_k; theta_k)   for every seed k, under ``torch.vmap`` (``p.to_module(loss)``)
    backward(sum_k total_k)             seeds share no parameter, so d/d theta_k of the sum is seed k's gradient
    Adam over the stacked tensors       elementwise, so it is each seed's own Adam
    theta_target <- lerp(theta_target, theta, tau)   for every seed at once

so each seed gets the losses, gradients and parameters of its own :class:`~drltg.learners.UpdateStep`
given the same parameters, batch and random draws (``tests/test_seed_groups.py``). The acting policy
is vmapped the same way over blocks of a batched env (:mod:`drltg.envs.seeding`).

With :class:`SeedStreams` every seed draws from its own random stream: the state torch's global CPU
generator would hold in the seed's run alone, swapped in for the seed's own draws. The vmapped calls
then take no random draw of their own (``randomness="error"``): each seed's standard normal draws are
made beforehand from its stream, in the order and shapes its run alone draws them, and handed to
``Normal.rsample`` inside the vmapped call: a seed in a group draws the random numbers of its run alone.
"""
from __future__ import annotations

import contextlib
import copy
from typing import Sequence

import torch
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import TensorDictModuleBase
from torchrl.envs.utils import exploration_type

from drltg.learners import Agent, loss_total

__all__ = ["SeedGroup", "GroupPolicy", "SeedLoopPolicy", "SeedBlocks", "SeedStreams"]


@contextlib.contextmanager
def _normal_draws(draw=None):
    """Route ``torch.distributions.Normal.rsample``'s standard normal draws through ``draw(shape, dtype,
    device)``. By default ``torch.randn(shape)``: ``rsample`` draws with ``torch.empty(shape).normal_()``,
    an in-place draw on an unbatched tensor that ``torch.vmap(randomness="different")`` refuses, and
    ``randn`` is the same draw (it fills an empty tensor with ``normal_``) as a factory vmap can batch."""
    normal = torch.distributions.normal
    previous = normal._standard_normal
    normal._standard_normal = draw or (lambda shape, dtype, device: torch.randn(shape, dtype=dtype, device=device))
    try:
        yield
    finally:
        normal._standard_normal = previous


class SeedStreams:
    """One random stream per seed of a group: ``states[k]`` is the state torch's global CPU generator
    holds in seed k's run alone; :meth:`use` swaps it in for seed k's draws and keeps where they left it."""

    def __init__(self, states: Sequence[torch.Tensor]):
        self.states = [state.clone() for state in states]

    @contextlib.contextmanager
    def use(self, k: int):
        outer = torch.get_rng_state()
        torch.set_rng_state(self.states[k])
        try:
            yield
        finally:
            self.states[k] = torch.get_rng_state()
            torch.set_rng_state(outer)

    def normal(self, shapes: Sequence[torch.Size]) -> list[torch.Tensor]:
        """Each seed's standard normal draws of ``shapes``, in order, as ``rsample`` alone draws them;
        one tensor ``[seeds, *shape]`` per shape."""
        per_seed = []
        for k in range(len(self.states)):
            with self.use(k):
                per_seed.append([torch.empty(shape).normal_() for shape in shapes])
        return [torch.stack(draws) for draws in zip(*per_seed)]


class _Replay:
    """Inside a vmapped call: the pre-drawn standard normals, handed out in order (``record``: only note
    the shapes asked for, for the first call)."""

    def __init__(self, draws: Sequence[torch.Tensor] | None = None):
        self.draws, self.shapes = list(draws or []), []

    def __call__(self, shape, dtype, device):
        shape = torch.Size(shape)
        self.shapes.append(shape)
        if not self.draws:
            return torch.zeros(shape, dtype=dtype, device=device)
        draw = self.draws.pop(0)
        if draw.shape != shape:
            raise RuntimeError(f"a seed drew a standard normal of shape {tuple(shape)} where {tuple(draw.shape)} was "
                               "drawn for it: its draws changed between calls.")
        return draw.to(dtype)


def _streamed(fn, streams: SeedStreams, shapes: dict, key, params: TensorDictBase, data: TensorDictBase):
    """``fn(params, data, draws)`` vmapped over seeds, each seed's normal draws taken from its stream."""
    if key not in shapes:  # the first call only notes the shapes; its result is not used
        record = _Replay()
        with _normal_draws(record):
            torch.vmap(fn, (0, 0, None), randomness="error")(params, data, record)
        shapes[key] = record.shapes
    draws = streams.normal(shapes[key]) if shapes[key] else []

    def run(p, d, seed_draws):
        return fn(p, d, _Replay(seed_draws))

    return torch.vmap(run, (0, 0, 0), randomness="error")(params, data, draws)


def _touch_lazy_buffers(agent: Agent) -> None:
    """Create the buffers a TorchRL loss registers on its first call (SAC's target entropy), so that
    every seed's loss has the same entries before they are stacked."""
    getattr(agent.loss, "target_entropy", None)


class SeedGroup:
    """N agents (same config, one per seed) updated by one vmapped step; ``agents[k]`` keeps seed k's
    own modules, refreshed from the stacked parameters by :meth:`sync` (evaluation of one seed,
    checkpoints).

    Args:
        agents: the seeds' agents, built from the same config (their optimisers' states, if any, are
            stacked too: a resumed group continues each seed's Adam).
        randomness: ``torch.vmap``'s randomness for the losses' random draws: ``"different"`` draws
            independent noise per seed; ``"same"`` shares one draw, which is what a single update
            draws from the same generator state (the equality test).
        streams: the seeds' own random streams (:class:`SeedStreams`): each seed's losses draw from its
            stream as its update alone draws from the global generator (``randomness`` is then unused;
            a loss with any random draw other than ``Normal.rsample``'s is refused by ``torch.vmap``).
    """

    def __init__(self, agents: Sequence[Agent], randomness: str = "different", streams: SeedStreams | None = None):
        self.agents = list(agents)
        for agent in self.agents:
            _touch_lazy_buffers(agent)
        self.seeds = len(self.agents)
        first = self.agents[0]
        self.loss = copy.deepcopy(first.loss)  # run under each seed's parameters; the agents' own stay apart
        self.actor_delay = first.actor_delay
        self.randomness = randomness
        self.params = TensorDict.from_modules(*(a.loss for a in self.agents), as_module=True)
        names = [name for name, _ in first.loss.named_parameters()]
        self._param_list = [self.params.get(tuple(name.split("."))) for name in names]
        self.optimizer = torch.optim.Adam(self._param_list, **{k: v for k, v in first.optimizer.defaults.items()})
        if first.optimizer.state:
            self.optimizer.load_state_dict(self._stacked_optimizer_state())
        targets = [k for k in self.params.keys(True, True) if k[0].startswith("target_")]
        self._targets = [self.params.get(k) for k in targets]
        self._sources = [self.params.get((k[0][len("target_"):], *k[1:])) for k in targets]
        self.tau = 1.0 - first.target_updater.eps
        self._views = [TensorDict.from_module(a.loss) for a in self.agents]
        self.streams, self._draw_shapes = streams, {}
        self._losses = torch.vmap(self._seed_losses, (0, 0), randomness=randomness)

    def _seed_losses(self, params: TensorDictBase, batch: TensorDictBase, draw=None) -> TensorDictBase:
        # an unlocked copy: the loss swaps its own sub-parameters in and out while it runs
        with _normal_draws(draw), params.copy().unlock_().to_module(self.loss):
            return self.loss(batch)

    def update(self, batch: TensorDictBase, update_actor: bool = True) -> TensorDictBase:
        """One step for every seed; ``batch`` has a leading seed dimension. Returns the detached losses
        (each entry with a leading seed dimension)."""
        if self.streams is None:
            losses = self._losses(self.params, batch)
        else:
            losses = _streamed(self._seed_losses, self.streams, self._draw_shapes, update_actor, self.params, batch)
        self.optimizer.zero_grad(set_to_none=True)
        loss_total(losses, update_actor).sum().backward()
        self.optimizer.step()
        if update_actor:
            with torch.no_grad():
                for target, source in zip(self._targets, self._sources):  # SoftUpdate: target += tau (source - target)
                    target.lerp_(source, self.tau)
        return losses.detach()

    def sync(self) -> None:
        """Copy the stacked parameters into each seed's own modules."""
        with torch.no_grad():
            for k, view in enumerate(self._views):
                view.update_(self.params[k].data)

    def optimizer_state(self, k: int) -> dict:
        """Seed k's part of the stacked Adam state, as its own ``Adam.state_dict()`` would be."""
        stacked = self.optimizer.state_dict()
        state = {
            i: {name: (value if name == "step" else value[k]).clone() for name, value in entry.items()}
            for i, entry in stacked["state"].items()
        }
        return {"state": state, "param_groups": stacked["param_groups"]}

    def _stacked_optimizer_state(self) -> dict:
        states = [a.optimizer.state_dict() for a in self.agents]
        stacked = {
            i: {
                name: (value if name == "step" else torch.stack([s["state"][i][name] for s in states]))
                for name, value in entry.items()
            }
            for i, entry in states[0]["state"].items()
        }
        return {"state": stacked, "param_groups": states[0]["param_groups"]}


class GroupPolicy(TensorDictModuleBase):
    """A seed group's policy on its batched env: the flat batch of ``seeds * E`` envs is split into
    ``seeds`` blocks and ``module`` acts on block k with seed k's parameters (one vmapped call).

    Args:
        module: one seed's actor (its own parameters are not used).
        params: the stacked parameters of ``module``, with a leading seed dimension.
        then: a module applied to the whole batch afterwards (TD3's exploration noise).
        streams: the seeds' own random streams (see :class:`SeedGroup`): block k's draws in ``module``
            come from seed k's stream (``then``'s do not: groups with a ``then`` have no streams).
    """

    def __init__(self, module: TensorDictModuleBase, params: TensorDictBase, then: TensorDictModuleBase | None = None,
                 streams: SeedStreams | None = None):
        super().__init__()
        self.module, self.then = copy.deepcopy(module), then
        self.params = params
        self.in_keys = list(module.in_keys)
        self.out_keys = list(module.out_keys)
        self.streams, self._draw_shapes = streams, {}
        self._act = torch.vmap(self._seed_act, (0, 0), randomness="different")

    def _seed_act(self, params: TensorDictBase, td: TensorDictBase, draw=None) -> TensorDictBase:
        with _normal_draws(draw), params.copy().unlock_().to_module(self.module):
            return self.module(td)

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        seeds = self.params.batch_size[0]
        shape = tensordict.batch_size
        td = tensordict.select(*self.in_keys, strict=False).reshape(seeds, -1)
        if self.streams is None:
            out = self._act(self.params, td)
        else:
            key = (str(exploration_type()), tuple(td.batch_size))
            out = _streamed(self._seed_act, self.streams, self._draw_shapes, key, self.params, td)
        tensordict.update(out.reshape(shape).select(*self.out_keys, strict=False))
        if self.then is not None:
            tensordict = self.then(tensordict)
        return tensordict


class SeedLoopPolicy(TensorDictModuleBase):
    """A seed group's policy called once per seed block, for a policy ``torch.vmap`` cannot batch
    (soft option-critic's option choice branches on the data): ``make_policy(loss)`` is built on the
    group's loss, and block k runs with seed k's parameters swapped into it."""

    def __init__(self, group: SeedGroup, make_policy):
        super().__init__()
        self.__dict__["group"] = group  # not a submodule: the group owns the parameters
        self.policy = make_policy(group.loss)
        self.in_keys, self.out_keys = list(self.policy.in_keys), list(self.policy.out_keys)

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        group, loss = self.group, self.group.loss
        blocks = tensordict.reshape(group.seeds, -1)
        outs = []
        for k in range(group.seeds):
            params = group.params[k].copy().unlock_()
            with params.to_module(loss), params["actor_network_params"].to_module(loss.actor_network):
                outs.append(self.policy(blocks[k].copy()))
        out = torch.stack(outs).reshape(tensordict.batch_size)
        tensordict.update(out.select(*self.out_keys, strict=False))
        return tensordict


class SeedBlocks(TensorDictModuleBase):
    """Per-seed modules on a seed group's batched env: block k of the flat batch (seed k's envs) goes
    through ``modules[k]`` (e.g. seed k's policy-reuse mixer over its own source policy), drawing from
    seed k's stream where the group has :class:`SeedStreams`, as the module draws in seed k's run alone."""

    def __init__(self, modules: Sequence[TensorDictModuleBase], streams: SeedStreams | None = None):
        super().__init__()
        self.blocks = torch.nn.ModuleList(modules)
        self.streams = streams
        self.in_keys = list(dict.fromkeys(k for m in modules for k in m.in_keys))
        self.out_keys = list(dict.fromkeys(k for m in modules for k in m.out_keys))

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        blocks = tensordict.reshape(len(self.blocks), -1)
        outs = []
        for k, module in enumerate(self.blocks):
            with contextlib.nullcontext() if self.streams is None else self.streams.use(k):
                outs.append(module(blocks[k].copy()))
        out = torch.stack(outs).reshape(tensordict.batch_size)
        return tensordict.update(out.select(*self.out_keys, strict=False))
