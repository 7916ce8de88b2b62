"""Option-indexed networks and the option-carrying policy of soft option-critic.

Every network has one output head per option on a shared trunk and reads the option index
(``"option"``, int64 ``[*, 1]``) from the tensordict:

* intra-option policies ``pi_o(a|s)``: tanh-Gaussian, ``loc``/``scale`` of option ``o``;
* critics ``Q_U(s, o, a)``: ``"state_action_value"`` of option ``o`` (the loss makes twin copies);
* terminations ``beta_o(s)``: ``"termination_prob"``, a sigmoid per option.

With one option each network is exactly the plain MLP it wraps, so the same weights serve TorchRL's
``SACLoss``.

Acting: the option is part of the environment state. :func:`option_transforms` adds ``InitTracker``
(``"is_init"``, true at every reset) and a ``TensorDictPrimer`` for ``"option"`` so that collectors
carry it from step to step. :class:`OptionSelector` then, at each step and before the intra-option
policy acts,

1. samples the termination of the *current* option only, at the *new* state:
   ``option_terminated ~ Bernoulli(beta_{o_{t-1}}(s_t))`` (never at an episode's first step);
2. picks a new option from the policy over options when it fired or when the episode starts;
3. writes ``"option"`` (the option that acts now) and ``"option_terminated"``.

Under ``ExplorationType.DETERMINISTIC`` terminations are thresholded at 1/2, options are chosen
greedily and each option plays its mean action.
"""

from __future__ import annotations

from typing import Sequence

import torch
from tensordict import TensorDictBase
from tensordict.nn import (
    NormalParamExtractor,
    TensorDictModule,
    TensorDictModuleBase,
    TensorDictSequential,
)
from torch import nn
from torchrl.data import Categorical, TensorSpec
from torchrl.envs import InitTracker, TensorDictPrimer, Transform
from torchrl.envs.utils import ExplorationType, exploration_type
from torchrl.modules import MLP, ProbabilisticActor

from drltg.modules.distributions import TanhNormal

OPTION_KEY = "option"


class OptionHeads(nn.Module):
    """``net`` with one output head per option; ``forward(*inputs, option)`` returns that option's head.

    ``net(*inputs)`` has ``num_options * F`` features, read as ``[*, num_options, F]``; the row of
    ``option`` (int64 ``[*, 1]``) is kept and ``post`` (e.g. ``NormalParamExtractor``) applied to it.
    All options share one forward pass; with ``num_options=1`` this is ``post(net(*inputs))``.

    Inputs expanded along their next-to-last dimension (stride 0: one state repeated for each option, as
    the option values read it) go through ``net`` once, not once per copy.
    """

    def __init__(self, net: nn.Module, num_options: int, post: nn.Module | None = None):
        super().__init__()
        self.net = net
        self.num_options = num_options
        self.post = post

    def forward(self, *inputs: torch.Tensor):
        *inputs, option = inputs
        if all(x.dim() > 1 and x.stride(-2) == 0 for x in inputs):
            copies = inputs[0].shape[-2]
            out = self.net(*[x.select(-2, 0) for x in inputs])
            heads = out.unsqueeze(-2).expand(*out.shape[:-1], copies, out.shape[-1])
        else:
            heads = self.net(*inputs)
        heads = heads.unflatten(-1, (self.num_options, -1))
        index = option.unsqueeze(-1).expand(*option.shape[:-1], 1, heads.shape[-1])
        out = heads.gather(-2, index).squeeze(-2)
        return out if self.post is None else self.post(out)


def _mlp(out_features: int, num_cells: Sequence[int], in_features: int | None) -> MLP:
    return MLP(in_features=in_features, out_features=out_features, num_cells=list(num_cells), activation_class=nn.ReLU)


def make_option_actor(
    action_spec: TensorSpec,
    num_options: int,
    num_cells: Sequence[int] = (256, 256),
    *,
    in_features: int | None = None,
    observation_key: str = "observation",
    option_key: str = OPTION_KEY,
) -> ProbabilisticActor:
    """Intra-option policies ``pi_o(a|s)``: tanh-Gaussian in the action box, the head of ``option``.

    ``action_spec`` is the unbatched (``Bounded``) action spec; ``in_features=None`` builds lazy layers.
    """
    n_act = action_spec.shape[-1]
    heads = OptionHeads(_mlp(num_options * 2 * n_act, num_cells, in_features), num_options, NormalParamExtractor())
    return ProbabilisticActor(
        TensorDictModule(heads, in_keys=[observation_key, option_key], out_keys=["loc", "scale"]),
        in_keys=["loc", "scale"],
        spec=action_spec,
        distribution_class=TanhNormal,
        distribution_kwargs={"low": action_spec.space.low, "high": action_spec.space.high},
        return_log_prob=False,
    )


def make_option_qvalue(
    num_options: int,
    num_cells: Sequence[int] = (256, 256),
    *,
    in_features: int | None = None,
    observation_key: str = "observation",
    action_key: str = "action",
    option_key: str = OPTION_KEY,
) -> TensorDictModule:
    """Option critic ``Q_U(s, o, a)``: ``"state_action_value"`` ``[*, 1]`` of the option in ``option``."""
    heads = OptionHeads(_mlp(num_options, num_cells, in_features), num_options)
    return TensorDictModule(heads, in_keys=[observation_key, action_key, option_key], out_keys=["state_action_value"])


def make_termination(
    num_options: int,
    num_cells: Sequence[int] = (256, 256),
    *,
    in_features: int | None = None,
    observation_key: str = "observation",
    option_key: str = OPTION_KEY,
) -> TensorDictModule:
    """Termination ``beta_o(s)``: ``"termination_prob"`` ``[*, 1]``, a sigmoid head per option."""
    heads = OptionHeads(_mlp(num_options, num_cells, in_features), num_options, nn.Sigmoid())
    return TensorDictModule(heads, in_keys=[observation_key, option_key], out_keys=["termination_prob"])


def option_transforms(num_options: int, option_key: str = OPTION_KEY) -> list[Transform]:
    """The transforms an environment needs to carry options: ``InitTracker`` (``"is_init"``) and a
    primer that declares ``option`` (int64 ``[*, 1]``) so collectors keep it across steps.

    The primer draws a uniform option at every reset: :class:`OptionSelector` replaces it at once, but
    a policy that ignores options (e.g. random warm-up actions) then spreads its data over all options.
    """
    primer = TensorDictPrimer(
        {option_key: Categorical(num_options, shape=(1,), dtype=torch.int64)}, random=True, expand_specs=True
    )
    return [InitTracker(), primer]


class OptionSelector(TensorDictModuleBase):
    """Keeps the option carried in the tensordict, or picks a new one where it terminates or an episode starts.

    It reads the networks, temperatures and policy over options of a ``SoftOptionCriticLoss`` (the
    option values need the loss's twin critics), so acting and learning always agree. Chain it before
    the intra-option actor: ``TensorDictSequential(OptionSelector(loss), actor)`` (see
    :func:`make_option_policy`).
    """

    def __init__(self, loss, *, is_init_key: str = "is_init", terminated_key: str = "option_terminated"):
        super().__init__()
        self.__dict__["loss"] = loss  # not a submodule: the loss owns the parameters
        self.option_key = loss.tensor_keys.option
        self.is_init_key = is_init_key
        self.terminated_key = terminated_key
        keys = [*loss.termination_network.in_keys, *loss.actor_network.in_keys, is_init_key]
        self.in_keys = list(dict.fromkeys(keys))
        self.out_keys = [self.option_key, terminated_key]

    @torch.no_grad()
    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        loss = self.loss
        if self.is_init_key not in tensordict.keys():
            raise KeyError(
                f"OptionSelector needs '{self.is_init_key}' in the tensordict: add the transforms of "
                "drltg.modules.option_transforms() to the environment."
            )
        is_init = tensordict.get(self.is_init_key)
        option = tensordict.get(self.option_key)
        terminated = torch.zeros_like(is_init)
        if loss.num_options > 1:
            deterministic = exploration_type() is ExplorationType.DETERMINISTIC
            beta = loss.termination_network(tensordict.select(*loss.termination_network.in_keys).copy()).get(
                loss.tensor_keys.termination_prob
            )
            fired = beta > 0.5 if deterministic else torch.bernoulli(beta).bool()
            terminated = fired & ~is_init
            switch = terminated | is_init
            if switch.any():
                values = loss.option_values(tensordict, deterministic=deterministic)
                if deterministic:
                    choice = values.argmax(-1, keepdim=True)
                else:
                    probs = loss.option_probs(values)
                    choice = torch.multinomial(probs.reshape(-1, loss.num_options), 1).reshape(option.shape)
                option = torch.where(switch, choice, option)
        else:
            option = torch.zeros_like(option)
        tensordict.set(self.option_key, option)
        tensordict.set(self.terminated_key, terminated)
        return tensordict


def make_option_policy(loss) -> TensorDictSequential:
    """The option-carrying policy of a ``SoftOptionCriticLoss``: option selection, then ``pi_o`` acts."""
    return TensorDictSequential(OptionSelector(loss), loss.actor_network)


def option_statistics(data: TensorDictBase, num_options: int, option_key: str = OPTION_KEY) -> dict[str, float]:
    """Usage and mean length of options in collected data (needs ``is_init`` and ``option_terminated``).

    ``option_length`` is steps per option start (a start is an episode start or a termination), the
    mean number of steps an option runs; ``option_usage/<o>`` is the fraction of steps option ``o`` acted.
    """
    option = data.get(option_key).reshape(-1)
    starts = (data.get("is_init") | data.get("option_terminated")).sum().item()
    stats = {
        "option_length": option.numel() / max(starts, 1),
        "option_termination_rate": data.get("option_terminated").float().mean().item(),
    }
    counts = torch.bincount(option, minlength=num_options).float() / option.numel()
    stats.update({f"option_usage/{o}": counts[o].item() for o in range(num_options)})
    return stats
