"""The training loop's gradient step, made cheap without leaving TorchRL's losses.

A step is ``loss(batch) -> backward(sum of loss_* terms) -> optimizer.step() -> target update``, the
sequence of TorchRL's sota SAC loop (:class:`UpdateStep`). Measured on a 2-core CPU, most of a
``SACLoss`` step at batch 256 is not arithmetic but the machinery around it: the twin critics run
under ``vmap`` (a batched matmul, a separate bias add and copies of the expanded inputs) and every
intermediate passes through TensorDicts. What this module changes, each checked against TorchRL's
own path in ``tests/test_speedups.py``:

* :class:`DirectSACForward`: ``SACLoss.forward`` computed by calling the actor's network and each
  critic (on its slice of the same stacked parameters) directly; same values to float32 rounding,
  same random draws, same parameters for the optimizer and ``SoftUpdate``.
* :func:`soft_update_fn`: ``SoftUpdate.step`` as one ``torch._foreach_lerp_`` (bit for bit).
* :func:`sample_batches`: one index draw and one gather for all the steps of a collector batch,
  split into views; the same draws as one ``buffer.sample()`` per step.
* ``cudagraphs=True`` (CUDA only): the whole step, optimizer included, captured once per
  actor-update flag and replayed (``capturable`` Adam), so no Python or launch cost per step;
  ``compile=True``: the step through ``torch.compile`` (on the 2-core CPU it compiled for over a
  minute and was not faster; see ``benchmarks/README.md``).
"""
from __future__ import annotations

import warnings
from typing import TYPE_CHECKING, Callable

import torch
import torch.nn.functional as F
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import (
    ProbabilisticTensorDictModule,
    ProbabilisticTensorDictSequential,
    TensorDictModule,
    TensorDictModuleBase,
)
from torch import nn
from torch.func import functional_call
from torchrl.data import ReplayBuffer
from torchrl.envs import ExplorationType, set_exploration_type
from torchrl.modules import MLP
from torchrl.objectives import SACLoss, SoftUpdate
from torchrl.objectives.sac import compute_rsample_log_prob
from torchrl.objectives.utils import distance_loss

if TYPE_CHECKING:
    from drltg.agents import Agent


class DirectSACForward:
    """``SACLoss.forward`` (SAC v2, no value network) computed with direct module calls.

    TorchRL's forward evaluates the twin critics under ``vmap`` on stacked parameters and moves
    every intermediate through TensorDicts; for 2x256 networks at batch 256 that costs as much CPU
    time as the matrix products. This evaluates the same quantities in the same order (same random
    draws), calling each critic on its slice of the same stacked parameters, so gradients, the
    optimizer and ``SoftUpdate`` are those of the ``SACLoss``:

    .. math::

        y = r + \\gamma (1 - d') \\big[\\min_i \\bar Q_i(s', a') - \\alpha \\log\\pi(a'|s')\\big],\\quad
        L_Q = \\tfrac1B\\sum_b \\sum_i (Q_i(s,a) - y)^2,

        L_\\pi = \\alpha\\log\\pi(\\tilde a|s) - \\min_i Q_i(s,\\tilde a),\\quad
        L_\\alpha = -\\log\\alpha\\,(\\log\\pi(\\tilde a|s) + \\bar{\\mathcal H}).

    Built by :meth:`for_loss`, which returns None for any loss it does not reproduce exactly (another
    loss class, a value network, prioritised weights, ``reduction`` other than ``"mean"``); a batch
    carrying priority weights falls back to ``SACLoss.forward``. ``tests/test_speedups.py`` checks
    the values against ``SACLoss.forward``.
    """

    def __init__(self, loss: SACLoss):
        self.loss = loss
        critic = loss.qvalue_network
        self._critic = critic.module
        self._critic_in = list(critic.in_keys)
        self._critic_out = critic.out_keys[0]
        self._keys = list(loss.qvalue_network_params.keys(include_nested=True, leaves_only=True))
        self._names = [".".join(k[1:]) for k in self._keys]
        self._plan = _mlp_plan(self._critic, self._names)
        self._dist = _direct_dist(loss.actor_network) or loss.actor_network.get_dist

    def _params(self, params: TensorDictBase) -> list[torch.Tensor]:
        return [params.get(k) for k in self._keys]

    @classmethod
    def for_loss(cls, loss) -> DirectSACForward | None:
        if type(loss) is not SACLoss or loss._version != 2 or loss.reduction != "mean" or loss.skip_done_states:
            return None
        critic = loss.qvalue_network
        if not isinstance(critic, TensorDictModule) or isinstance(critic.module, TensorDictModuleBase):
            return None
        keys = loss.qvalue_network_params.keys(include_nested=True, leaves_only=True)
        if len(critic.out_keys) != 1 or not all(isinstance(k, tuple) and k[0] == "module" for k in keys):
            return None
        own = dict(loss.actor_network.named_parameters())
        if any(own.get(k) is not v for k, v in loss.actor_network_params.flatten_keys(".").items()):
            return None  # the actor's weights live outside its module: only to_module finds them
        return cls(loss)

    def _critics(self, params: list[torch.Tensor], inputs: list[torch.Tensor]) -> list[torch.Tensor]:
        n = self.loss.num_qvalue_nets
        if self._plan is None:
            return [functional_call(self._critic, {k: p[i] for k, p in zip(self._names, params)}, tuple(inputs)) for i in range(n)]
        x = torch.cat(inputs, -1) if len(inputs) > 1 else inputs[0]
        out = []
        for i in range(n):
            h = x
            for layer, w, b in self._plan:
                h = layer(h) if layer is not None else F.linear(h, params[w][i], params[b][i])
            out.append(h)
        return out

    def _inputs(self, td: TensorDictBase, action: torch.Tensor) -> list[torch.Tensor]:
        action_key = self.loss.tensor_keys.action
        return [action if k == action_key else td.get(k) for k in self._critic_in]

    def __call__(self, tensordict: TensorDictBase) -> TensorDictBase:
        loss = self.loss
        keys = loss.tensor_keys
        if loss._maybe_get_priority_weight(tensordict) is not None:
            return loss(tensordict)
        alpha = loss._alpha
        with set_exploration_type(ExplorationType.RANDOM):
            with torch.no_grad():
                nxt = tensordict.get("next")
                next_action, next_log_prob = compute_rsample_log_prob(self._dist(nxt))
                target_q = self._critics(self._params(loss.target_qvalue_network_params), self._inputs(nxt, next_action))
                next_log_prob = next_log_prob.unsqueeze(-1) if next_log_prob.shape != target_q[0].shape else next_log_prob
                next_value = torch.stack(target_q).sub(alpha * next_log_prob).min(0)[0]
                td = tensordict.clone(False)
                td.set(("next", loss.value_estimator.tensor_keys.value), next_value)
                target = loss.value_estimator.value_estimate(td).squeeze(-1)
            pred = torch.stack(self._critics(self._params(loss.qvalue_network_params), self._inputs(tensordict, tensordict.get(keys.action)))).squeeze(-1)
            loss_qvalue = distance_loss(pred, target.expand_as(pred), loss_function=loss.loss_function).sum(0).mean()
            action, log_prob = compute_rsample_log_prob(self._dist(tensordict))
        q = self._critics(self._params(loss._cached_detached_qvalue_params), self._inputs(tensordict, action))
        min_q = torch.stack(q).min(0)[0].squeeze(-1)
        loss_actor = (alpha * log_prob - min_q).mean()
        log_prob = log_prob.detach()
        loss_alpha = loss._alpha_loss(log_prob).mean()
        tensordict.set(keys.priority, (pred - target).detach().abs().max(0)[0])
        return TensorDict(
            {
                "loss_actor": loss_actor,
                "loss_qvalue": loss_qvalue,
                "loss_alpha": loss_alpha,
                "alpha": alpha,
                "entropy": -log_prob.mean(),
            },
            batch_size=[],
        )


def _mlp_plan(module: nn.Module, names: list[str]):
    """For a TorchRL ``MLP`` of ``Linear`` layers and parameter-free layers, the layer sequence as
    ``(layer, None, None)`` or ``(None, weight_index, bias_index)`` into ``names``; else None."""
    if type(module) is not MLP or module._reshape_out:
        return None
    plan = []
    for idx, layer in enumerate(module):
        if type(layer) is nn.Linear and layer.bias is not None:
            plan.append((None, names.index(f"{idx}.weight"), names.index(f"{idx}.bias")))
        elif next(layer.parameters(), None) is None and next(layer.buffers(), None) is None:
            plan.append((layer, None, None))
        else:
            return None
    return plan


def _direct_dist(actor) -> Callable[[TensorDictBase], torch.distributions.Distribution] | None:
    """``actor.get_dist`` for a ``ProbabilisticActor`` made of one parameter network and its
    distribution module: the network's module called on the input tensors; else None."""
    if not isinstance(actor, ProbabilisticTensorDictSequential) or len(actor.module) != 2:
        return None
    net, prob = actor.module
    if type(net) is not TensorDictModule or isinstance(net.module, TensorDictModuleBase):
        return None
    if not isinstance(prob, ProbabilisticTensorDictModule) or not set(prob.in_keys) <= set(net.out_keys):
        return None
    names = [k[-1] if isinstance(k, tuple) else k for k in prob.dist_keys]
    wanted = [net.out_keys.index(k) for k in prob.in_keys]
    kwargs = dict(prob.distribution_kwargs)

    def dist(td: TensorDictBase) -> torch.distributions.Distribution:
        out = net.module(*(td.get(k) for k in net.in_keys))
        out = out if isinstance(out, tuple) else (out,)
        return prob.distribution_class(**{n: out[i] for n, i in zip(names, wanted)}, **kwargs)

    return dist


def soft_update_fn(updater) -> Callable[[], None]:
    """``updater.step`` for a TorchRL ``SoftUpdate``: ``target.lerp_(source, tau)`` over all pairs in one
    ``torch._foreach_lerp_`` (the same per-tensor lerp, without the per-step TensorDict walk)."""
    if type(updater) is not SoftUpdate:
        return updater.step
    sources = updater._sources
    pairs = [(updater._targets.get(("target_" + k[0], *k[1:])), sources.get(k)) for k in sources.keys(True, True)]
    weight = 1 - updater.eps

    def step() -> None:
        torch._foreach_lerp_([t.data for t, _ in pairs], [p.data for _, p in pairs], weight)

    return step


def loss_total(losses: TensorDictBase, update_actor: bool = True) -> torch.Tensor:
    """Sum of the ``loss_*`` entries; the actor's term is left out when ``update_actor`` is False."""
    return sum(v for k, v in losses.items() if k.startswith("loss_") and (update_actor or k != "loss_actor"))


class UpdateStep:
    """One gradient step of ``agent``: ``step(batch, update_actor) -> detached losses``.

    Args:
        agent: the :class:`~drltg.agents.Agent` whose ``loss``, ``optimizer`` and ``target_updater``
            are stepped; ``update_actor=False`` leaves out the actor's loss term and the target
            update (TD3's policy delay).
        direct: evaluate ``SACLoss`` with :class:`DirectSACForward` and step ``SoftUpdate`` with
            :func:`soft_update_fn` where they apply (same values to float rounding); ``False`` runs
            TorchRL's own ``forward`` and ``step``.
        compile: run the step through ``torch.compile``.
        cudagraphs: capture the step in a CUDA graph (every tensor on one CUDA device, a fixed batch
            shape; Adam is switched to ``capturable``).
    """

    def __init__(self, agent: Agent, *, direct: bool = True, compile: bool = False, cudagraphs: bool = False):
        self.agent = agent
        self.forward = (DirectSACForward.for_loss(agent.loss) if direct else None) or agent.loss
        self.update_targets = soft_update_fn(agent.target_updater) if direct else agent.target_updater.step
        self.compile = compile
        self.cudagraphs = cudagraphs
        if cudagraphs:
            for group in agent.optimizer.param_groups:
                group["capturable"] = True
        self._steps = {}

    def _build(self, update_actor: bool):
        optimizer, forward, update_targets = self.agent.optimizer, self.forward, self.update_targets

        def step(batch: TensorDictBase) -> TensorDictBase:
            losses = forward(batch)
            optimizer.zero_grad(set_to_none=True)
            loss_total(losses, update_actor).backward()
            optimizer.step()
            if update_actor:
                update_targets()
            return losses.detach()

        if self.compile:
            step = torch.compile(step)
        if self.cudagraphs:
            from tensordict.nn import CudaGraphModule

            step = CudaGraphModule(step, warmup=3, in_keys=[], out_keys=[])
        return step

    def __call__(self, batch: TensorDictBase, update_actor: bool = True) -> TensorDictBase:
        if update_actor not in self._steps:
            self._steps[update_actor] = self._build(update_actor)
        losses = self._steps[update_actor](batch)
        return losses.clone() if self.cudagraphs else losses


def sample_batches(buffer: ReplayBuffer, count: int) -> list[TensorDictBase]:
    """``count`` batches of ``buffer.batch_size`` transitions drawn with one ``sample`` call.

    Equal, draw for draw, to ``count`` calls of ``buffer.sample()`` for a buffer whose sampler
    draws indices independently and uniformly (TorchRL's default ``RandomSampler``).
    """
    size = buffer.batch_size
    if count == 1:
        return [buffer.sample()]
    with warnings.catch_warnings():  # a batch size given to sample() differs from the buffer's: intended
        warnings.filterwarnings("ignore", message="Got conflicting batch_sizes")
        return list(buffer.sample(size * count).split(size))
