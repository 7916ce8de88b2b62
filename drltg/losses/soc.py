r"""Soft option-critic: SAC with K options (Bacon, Harb & Precup 2017, maximum-entropy form).

A transition ``(s, o, a, r, s')`` is stored with the option ``o`` that chose ``a``. With ``K``
options the networks are the intra-option policies :math:`\pi_o(a|s)`, twin option critics
:math:`Q_U(s,o,a)` (with target copies :math:`\bar Q_U`) and terminations :math:`\beta_o(s)`.

Option values are derived, not learned:

.. math::

    Q_\Omega(s,o) = \mathbb{E}_{a\sim\pi_o(\cdot|s)}\big[\min_i Q_{U,i}(s,o,a) - \alpha\log\pi_o(a|s)\big]

estimated with one reparameterised action per option (SAC's soft state value, per option). A learned
:math:`Q_\Omega` network would be a second regression target for the same quantity, and with one
option it would break the identity with SAC; the derived value is consistent with :math:`Q_U` and
:math:`\pi_o` by construction, at the price of a one-sample estimate.

Policy over options :math:`\pi_\Omega`, and the value of choosing afresh, an exact expectation over
the K options:

* ``"soft"``: :math:`\pi_\Omega(o|s) = \mathrm{softmax}_o(Q_\Omega(s,o)/\alpha_\Omega)`, the temperature
  tuned to a target entropy;
* ``"egreedy"``: the greedy option with probability :math:`1-\epsilon`, a uniform one otherwise.

.. math::

    V_\Omega(s) = \sum_o \pi_\Omega(o|s)\,Q_\Omega(s,o)
    \quad\big(+\,\alpha_\Omega\,\mathcal H(\pi_\Omega(\cdot|s))\ \text{with}\ \texttt{option\_entropy\_bonus}\big)

By default the option choice is not rewarded for its entropy (maximum entropy acts on actions, as in
SAC; the soft policy over options explores with a tuned temperature). With the bonus,
:math:`V_\Omega \ge \max_o Q_\Omega`, so every switch pays :math:`\alpha_\Omega\mathcal H` and
:math:`A_\Omega \le 0` everywhere: terminations learn to fire at every step and the per-step bonus
inflates the values (measured on ``fourrooms/northeast``, K = 4, 30k frames: the mean termination
probability over training was 0.66 and 0.73 with the bonus, 0.14 to 0.39 without it, over 2 and 3 seeds).

Value upon arrival in :math:`s'` with option :math:`o` still running, and the advantage of keeping it:

.. math::

    A_\Omega(s',o) = Q_\Omega(s',o) - V_\Omega(s'), \qquad
    U(s',o) = (1-\beta_o(s'))\,Q_\Omega(s',o) + \beta_o(s')\,V_\Omega(s') = Q_\Omega(s',o) - \beta_o(s')\,A_\Omega(s',o)

Losses (batch means; :math:`d'` is ``terminated`` at :math:`s'`, never ``truncated``: a horizon
cut still bootstraps; barred values use the target critics, :math:`\beta` its current parameters;
:math:`\ell` is ``loss_function``; the target entropies are :math:`\bar{\mathcal H} = -\dim\mathcal A`
and :math:`\mathcal H_\Omega = \tfrac12\log K` by default):

.. math::

    y &= r + \gamma\,(1-d')\,\big[\bar Q_\Omega(s',o) - \beta_o(s')\,\bar A_\Omega(s',o)\big]

    L_Q &= \textstyle\sum_i \ell\big(Q_{U,i}(s,o,a) - y\big)

    L_\pi &= \alpha\log\pi_o(\tilde a|s) - \min_i Q_{U,i}(s,o,\tilde a), \quad \tilde a\sim\pi_o(\cdot|s)

    L_\beta &= (1-d')\,\beta_o(s')\,\big(\bar A_\Omega(s',o) + \xi\big)

    L_\alpha &= -\log\alpha\,\big(\log\pi_o(\tilde a|s) + \bar{\mathcal H}\big), \qquad
    L_{\alpha_\Omega} = -\log\alpha_\Omega\,\big(\mathcal H_\Omega - \mathcal H(\pi_\Omega(\cdot|s'))\big)

The termination loss lowers :math:`\beta_o` where the running option is at least as good as a fresh
choice (:math:`A_\Omega + \xi > 0`) and raises it elsewhere; the deliberation cost :math:`\xi \ge 0`
(in units of return) keeps an option running unless switching gains more than :math:`\xi`, against
switches on estimation noise (Harb et al. 2018).
Every loss uses the option ``o`` of the transition. With ``K = 1`` the option value is SAC's soft state
value, :math:`V_\Omega = Q_\Omega`, :math:`A_\Omega = 0`, :math:`U = Q_\Omega`: every loss term equals
``SACLoss``'s on the same weights and the termination has no effect.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from tensordict import TensorDict, TensorDictBase, TensorDictParams
from tensordict.nn import ProbabilisticTensorDictSequential, TensorDictModule, dispatch
from tensordict.utils import NestedKey
from torch import Tensor
from torchrl.data import TensorSpec
from torchrl.envs.utils import ExplorationType, set_exploration_type
from torchrl.objectives import LossModule
from torchrl.objectives.sac import compute_rsample_log_prob
from torchrl.objectives.utils import ValueEstimators, default_value_kwargs, dispatch_value_estimator, distance_loss

from drltg.losses.td_keys import TDKeys

OPTION_POLICIES = ("soft", "egreedy")  # drltg.config repeats them to check a run without torch (tests/test_config.py)


class SoftOptionCriticLoss(LossModule):
    """The soft option-critic loss (see the module docstring for the equations).

    Args:
        actor_network: intra-option policies; reads ``option`` and returns the distribution of that option.
        qvalue_network: option critic; reads ``option`` and ``action``, writes ``state_action_value`` ``[*, 1]``.
        termination_network: reads ``option``, writes ``termination_prob`` ``[*, 1]`` in [0, 1].

    Keyword Args:
        num_options (int): K.
        num_qvalue_nets (int): critic ensemble size (min over it). Defaults to 2.
        loss_function (str): critic regression loss. Defaults to ``"smooth_l1"`` (as ``SACLoss``).
        alpha_init, min_alpha, max_alpha, fixed_alpha, target_entropy, action_spec: the action
            temperature, shared by all options, exactly as in ``SACLoss``.
        option_policy (str): ``"soft"`` (softmax of ``Q_Omega / alpha_Omega``) or ``"egreedy"``.
        option_alpha_init (float): initial option temperature ``alpha_Omega`` (``"soft"``). Defaults to 1.
        fixed_option_alpha (bool): keep ``alpha_Omega`` fixed instead of tuning it. Defaults to ``False``.
        option_target_entropy (float or "auto"): entropy the soft policy over options is tuned to;
            ``"auto"`` is half the maximum, ``0.5 * log K``.
        option_epsilon (float): exploration of the ``"egreedy"`` policy over options. Defaults to 0.1.
        deliberation_cost (float): ``xi`` added to the termination advantage. Defaults to 0.
        option_entropy_bonus (bool): add ``alpha_Omega * H(pi_Omega)`` to ``V_Omega`` (``"soft"``).
            Defaults to ``False`` (see the module docstring).
        delay_qvalue (bool): use target critics for the TD target. Defaults to ``True``.
        reduction (str): ``"mean"`` (default), ``"sum"`` or ``"none"``.
        use_prioritized_weights (bool or "auto"): weight the losses by ``priority_weight`` when the batch
            carries it (``"auto"``, default) or always (``True``). The weighted mean is
            ``sum(w * l) / sum(w)``, as in TorchRL's losses.
        deactivate_vmap (bool): evaluate the critic copies one after the other instead of under
            ``torch.vmap`` (same values), as TorchRL's losses' switch of that name. Defaults to ``False``.

    The output keys follow ``SACLoss``: ``loss_actor``, ``loss_qvalue``, ``loss_alpha``,
    ``loss_termination`` (+ ``loss_option_alpha`` for the soft policy), and the diagnostics ``alpha``,
    ``entropy``, ``option_entropy``, ``termination_prob`` (+ ``option_alpha``). Every ``loss_*`` term
    only moves its own parameters, so their sum can be minimised with one optimizer. Use
    ``SoftUpdate(loss, tau=...)`` for the target critics; the termination needs no target copy
    (like SAC's actor, it is evaluated with its current parameters).

    Examples:
        >>> from torchrl.data import Bounded
        >>> from drltg.modules import make_option_actor, make_option_policy, make_option_qvalue, make_termination
        >>> spec, K = Bounded(-1.0, 1.0, (2,)), 4
        >>> loss = SoftOptionCriticLoss(
        ...     make_option_actor(spec, K, [64, 64], in_features=2),
        ...     make_option_qvalue(K, [64, 64], in_features=2 + 2),
        ...     make_termination(K, [64, 64], in_features=2),
        ...     num_options=K, alpha_init=0.01, deliberation_cost=0.01)
        >>> loss.make_value_estimator(gamma=0.99)
        >>> policy = make_option_policy(loss)  # the collector's policy; the env needs option_transforms(K)
    """

    @dataclass
    class _AcceptedKeys(TDKeys):
        """Tensordict keys the loss reads and writes (change them with ``.set_keys(...)``); ``priority``,
        ``done``, ``terminated`` and ``priority_weight`` as in :class:`~drltg.losses.td_keys.TDKeys`.

        Attributes:
            action: the action taken. Defaults to ``"action"``.
            option: the option that chose the action, int64 ``[*, 1]``. Defaults to ``"option"``.
            state_action_value: output of the critic. Defaults to ``"state_action_value"``.
            termination_prob: output of the termination network. Defaults to ``"termination_prob"``.
            value: where ``U(s', o)`` is written for the value estimator. Defaults to ``"state_value"``.
            reward: as in ``SACLoss``.
        """

        action: NestedKey = "action"
        option: NestedKey = "option"
        state_action_value: NestedKey = "state_action_value"
        termination_prob: NestedKey = "termination_prob"
        value: NestedKey = "state_value"
        reward: NestedKey = "reward"

    default_keys = _AcceptedKeys
    tensor_keys: _AcceptedKeys
    default_value_estimator = ValueEstimators.TD0

    actor_network: TensorDictModule
    qvalue_network: TensorDictModule
    termination_network: TensorDictModule
    actor_network_params: TensorDictParams
    qvalue_network_params: TensorDictParams
    termination_network_params: TensorDictParams
    target_actor_network_params: TensorDictParams
    target_qvalue_network_params: TensorDictParams
    target_termination_network_params: TensorDictParams

    def __init__(
        self,
        actor_network: ProbabilisticTensorDictSequential,
        qvalue_network: TensorDictModule,
        termination_network: TensorDictModule,
        *,
        num_options: int,
        num_qvalue_nets: int = 2,
        loss_function: str = "smooth_l1",
        alpha_init: float = 1.0,
        min_alpha: float | None = None,
        max_alpha: float | None = None,
        fixed_alpha: bool = False,
        target_entropy: str | float = "auto",
        action_spec: TensorSpec | None = None,
        option_policy: str = "soft",
        option_alpha_init: float = 1.0,
        fixed_option_alpha: bool = False,
        option_target_entropy: str | float = "auto",
        option_epsilon: float = 0.1,
        deliberation_cost: float = 0.0,
        option_entropy_bonus: bool = False,
        delay_qvalue: bool = True,
        reduction: str | None = None,
        use_prioritized_weights: str | bool = "auto",
        deactivate_vmap: bool = False,
    ) -> None:
        if option_policy not in OPTION_POLICIES:
            raise ValueError(f"option_policy must be one of {OPTION_POLICIES}, got {option_policy!r}.")
        if num_options < 1:
            raise ValueError(f"num_options must be at least 1, got {num_options}.")
        self._in_keys = None
        super().__init__()
        self.use_prioritized_weights = use_prioritized_weights
        self.num_options = num_options
        self.num_qvalue_nets = num_qvalue_nets
        self.loss_function = loss_function
        self.option_policy = option_policy
        self.deliberation_cost = deliberation_cost
        self.option_entropy_bonus = option_entropy_bonus
        self.reduction = reduction or "mean"
        self.deactivate_vmap = deactivate_vmap

        self.convert_to_functional(actor_network, "actor_network", create_target_params=False)
        self.convert_to_functional(termination_network, "termination_network", create_target_params=False)
        self.delay_qvalue = delay_qvalue
        self.convert_to_functional(qvalue_network, "qvalue_network", num_qvalue_nets, create_target_params=delay_qvalue)

        device = next(self.parameters()).device
        for name, bound in (("min_log_alpha", min_alpha), ("max_log_alpha", max_alpha)):
            self.register_buffer(name, None if bound is None else torch.tensor(math.log(bound), device=device))
        self._register_temperature("log_alpha", alpha_init, fixed_alpha, device)
        if target_entropy == "auto":
            spec = action_spec if action_spec is not None else actor_network.spec[self.tensor_keys.action]
            target_entropy = -float(spec.shape.numel())
        self.register_buffer("target_entropy", torch.tensor(float(target_entropy), device=device))

        if option_policy == "soft":
            self._register_temperature("log_option_alpha", option_alpha_init, fixed_option_alpha, device)
            if option_target_entropy == "auto":
                option_target_entropy = 0.5 * math.log(num_options)
            self.register_buffer("option_target_entropy", torch.tensor(float(option_target_entropy), device=device))
        else:
            self.register_buffer("option_epsilon", torch.tensor(float(option_epsilon), device=device))
        self._make_vmap()

    def _make_vmap(self) -> None:
        """The critic under ``torch.vmap`` (TorchRL calls this again when ``set_vmap_randomness`` changes the mode)."""
        self._vmap_critic = torch.vmap(self._critic, (None, 0), randomness=self.vmap_randomness)

    def _critic(self, td: TensorDictBase, params: TensorDictParams) -> TensorDictBase:
        with params.to_module(self.qvalue_network, preserve_module_state=False):
            return self.qvalue_network(td)

    def _critics(self, td: TensorDictBase, params: TensorDictParams) -> Tensor:
        """Every critic copy on the same input, ``[num_qvalue_nets, *B, 1]``: one call per copy with
        ``deactivate_vmap``, else one call under ``torch.vmap``."""
        key = self.tensor_keys.state_action_value
        if self.deactivate_vmap:
            return torch.stack([self._critic(td.copy(), params[i]).get(key) for i in range(self.num_qvalue_nets)])
        return self._vmap_critic(td, params).get(key)

    def _register_temperature(self, name: str, init: float, fixed: bool, device) -> None:
        value = torch.tensor(math.log(init), device=device)
        if fixed:
            self.register_buffer(name, value)
        else:
            self.register_parameter(name, torch.nn.Parameter(value))

    # ------------------------------------------------------------------ keys and estimator
    @property
    def _state_keys(self) -> list[NestedKey]:
        """Observation keys the networks read (everything but the action and the option)."""
        keys = [*self.actor_network.in_keys, *self.qvalue_network.in_keys, *self.termination_network.in_keys]
        return [k for k in dict.fromkeys(keys) if k not in (self.tensor_keys.action, self.tensor_keys.option)]

    def _set_in_keys(self):
        keys = [
            self.tensor_keys.action,
            self.tensor_keys.option,
            ("next", self.tensor_keys.reward),
            ("next", self.tensor_keys.done),
            ("next", self.tensor_keys.terminated),
            *self._state_keys,
            *[("next", key) for key in self._state_keys],
        ]
        self._in_keys = list(dict.fromkeys(keys))

    @property
    def in_keys(self):
        if self._in_keys is None:
            self._set_in_keys()
        return self._in_keys

    @in_keys.setter
    def in_keys(self, values):
        self._in_keys = values

    @property
    def out_keys(self):
        keys = ["loss_actor", "loss_qvalue", "loss_alpha", "loss_termination"]
        if self.option_policy == "soft":
            keys.append("loss_option_alpha")
        keys += ["alpha", "entropy", "option_entropy", "termination_prob"]
        if self.option_policy == "soft":
            keys.append("option_alpha")
        return keys

    def make_value_estimator(self, value_type: ValueEstimators = None, **hyperparams):
        """Only one-step TD targets: a multi-step return would mix the options of later steps."""
        value_type = self.default_value_estimator if value_type is None else value_type
        hp = {**default_value_kwargs(value_type), **hyperparams}
        dispatch_value_estimator(
            self,
            value_type,
            supported=(ValueEstimators.TD0,),
            tensor_keys={
                "value": self.tensor_keys.value,
                "value_target": "value_target",
                "reward": self.tensor_keys.reward,
                "done": self.tensor_keys.done,
                "terminated": self.tensor_keys.terminated,
            },
            value_network=None,
            **hp,
        )

    def _priority_weight(self, tensordict: TensorDictBase) -> Tensor | None:
        key = self.tensor_keys.priority_weight
        if self.use_prioritized_weights in (True, "auto") and key in tensordict.keys():
            return tensordict.get(key)
        return None

    def _reduce(self, loss: Tensor, weights: Tensor | None) -> Tensor:
        """``reduction`` of a per-transition loss; importance-weighted: ``sum(w l) / sum(w)`` (mean), ``sum(w l)``."""
        if weights is not None:
            loss = loss * weights
        if self.reduction == "none":
            return loss
        if self.reduction == "sum":
            return loss.sum()
        return loss.mean() if weights is None else loss.sum() / weights.sum()

    # ------------------------------------------------------------------ temperatures and options
    @property
    def _alpha(self) -> Tensor:
        if self.min_log_alpha is not None or self.max_log_alpha is not None:
            self.log_alpha.data.clamp_(self.min_log_alpha, self.max_log_alpha)
        return self.log_alpha.detach().exp()

    @property
    def _option_alpha(self) -> Tensor:
        return self.log_option_alpha.detach().exp()

    def option_values(self, tensordict: TensorDictBase, *, target: bool = False, deterministic: bool = False) -> Tensor:
        """``Q_Omega(s, o)`` for every option, ``[*, K]``, from the state in ``tensordict``.

        One action per option is drawn from ``pi_o`` (its mean if ``deterministic``, then without the
        entropy term); the critics (``target`` or online) are reduced by their minimum, as in SAC.
        """
        td = tensordict.select(*self._state_keys)
        td = td.unsqueeze(-1).expand(*td.batch_size, self.num_options)
        options = torch.arange(self.num_options, device=td.device or self.log_alpha.device)
        td.set(self.tensor_keys.option, options.unsqueeze(-1).expand(*td.batch_size, 1))
        with (
            set_exploration_type(ExplorationType.RANDOM),
            self.actor_network_params.to_module(self.actor_network, preserve_module_state=False),
        ):
            dist = self.actor_network.get_dist(td)
            if deterministic:
                action, log_prob = dist.deterministic_sample, None
            else:
                action, log_prob = compute_rsample_log_prob(dist)
        td.set(self.tensor_keys.action, action)
        params = self.target_qvalue_network_params if target else self.qvalue_network_params
        value = self._critics(td, params)
        if log_prob is not None:
            value = value - self._alpha * log_prob.unsqueeze(-1)
        return value.min(0)[0].squeeze(-1)

    def option_probs(self, option_values: Tensor) -> Tensor:
        """``pi_Omega(o|s)``, ``[*, K]``: softmax of ``Q_Omega / alpha_Omega``, or epsilon-greedy."""
        if self.option_policy == "soft":
            return torch.softmax(option_values / self._option_alpha, dim=-1)
        greedy = torch.nn.functional.one_hot(option_values.argmax(-1), self.num_options).to(option_values.dtype)
        return (1 - self.option_epsilon) * greedy + self.option_epsilon / self.num_options

    def _option_state_value(self, option_values: Tensor, probs: Tensor) -> Tensor:
        """``V_Omega(s)`` ``[*, 1]``, the exact expectation over the K options."""
        if self.option_policy == "soft" and self.option_entropy_bonus:
            log_probs = torch.log_softmax(option_values / self._option_alpha, dim=-1)
            option_values = option_values - self._option_alpha * log_probs
        return (probs * option_values).sum(-1, keepdim=True)

    # ------------------------------------------------------------------ losses
    @torch.no_grad()
    def _next_option_terms(self, tensordict: TensorDictBase) -> dict[str, Tensor]:
        """Target-critic ``Q_Omega(s', o)``, the advantage ``A_Omega(s', o)`` and ``pi_Omega(.|s')``."""
        option = tensordict.get(self.tensor_keys.option)
        values = self.option_values(tensordict.get("next"), target=True)
        probs = self.option_probs(values)
        value = values.gather(-1, option)
        return {
            "value": value,
            "advantage": value - self._option_state_value(values, probs),
            "option_entropy": -torch.special.xlogy(probs, probs).sum(-1),
        }

    def _termination_prob(self, tensordict: TensorDictBase) -> Tensor:
        """``beta_o(s')`` ``[*, 1]`` of the transition's option, with gradients."""
        td = tensordict.get("next").select(*self.termination_network.in_keys, strict=False)
        td.set(self.tensor_keys.option, tensordict.get(self.tensor_keys.option))
        with self.termination_network_params.to_module(self.termination_network, preserve_module_state=False):
            return self.termination_network(td).get(self.tensor_keys.termination_prob)

    def _qvalue_loss(self, tensordict: TensorDictBase, arrival_value: Tensor) -> tuple[Tensor, Tensor]:
        weights = self._priority_weight(tensordict)
        td = tensordict.clone(False)
        td.set(("next", self.value_estimator.tensor_keys.value), arrival_value)
        target_value = self.value_estimator.value_estimate(td).squeeze(-1)
        pred = self._critics(
            tensordict.select(*self.qvalue_network.in_keys, strict=False), self.qvalue_network_params
        ).squeeze(-1)
        loss = distance_loss(pred, target_value.expand_as(pred), loss_function=self.loss_function).sum(0)
        loss = self._reduce(loss, weights)
        return loss, (pred - target_value).abs().detach().max(0)[0]

    def actor_loss(self, tensordict: TensorDictBase) -> tuple[Tensor, dict[str, Tensor]]:
        """``alpha log pi_o(a~|s) - min_i Q_U,i(s, o, a~)`` with the transition's option ``o``."""
        weights = self._priority_weight(tensordict)
        with (
            set_exploration_type(ExplorationType.RANDOM),
            self.actor_network_params.to_module(self.actor_network, preserve_module_state=False),
        ):
            dist = self.actor_network.get_dist(tensordict)
            action, log_prob = compute_rsample_log_prob(dist)
        td_q = tensordict.select(*self.qvalue_network.in_keys, strict=False)
        td_q.set(self.tensor_keys.action, action)
        min_q = self._critics(td_q, self.qvalue_network_params.detach()).min(0)[0].squeeze(-1)
        loss = self._reduce(self._alpha * log_prob - min_q, weights)
        return loss, {"log_prob": log_prob.detach()}

    @dispatch
    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        weights = self._priority_weight(tensordict)
        beta = self._termination_prob(tensordict)
        next_terms = self._next_option_terms(tensordict)  # samples at s' first, as SACLoss does
        advantage = next_terms["advantage"]
        loss_qvalue, td_error = self._qvalue_loss(tensordict, next_terms["value"] - beta.detach() * advantage)
        loss_actor, actor_meta = self.actor_loss(tensordict)
        log_prob = actor_meta["log_prob"]

        def reduce(loss):
            return self._reduce(loss, weights)

        not_terminal = ~tensordict.get(("next", self.tensor_keys.terminated))
        loss_termination = (beta * (advantage + self.deliberation_cost) * not_terminal).squeeze(-1)
        out = {
            "loss_actor": loss_actor,
            "loss_qvalue": loss_qvalue,
            "loss_alpha": reduce(-self.log_alpha * (log_prob + self.target_entropy)),
            "loss_termination": reduce(loss_termination),
        }
        if self.option_policy == "soft":
            out["loss_option_alpha"] = reduce(
                -self.log_option_alpha * (self.option_target_entropy - next_terms["option_entropy"])
            )
        tensordict.set(self.tensor_keys.priority, td_error)
        if self.reduction == "none":
            return TensorDict(out, batch_size=tensordict.batch_size)
        out.update(
            alpha=self._alpha,
            entropy=-log_prob.mean(),
            option_entropy=next_terms["option_entropy"].mean(),
            termination_prob=beta.detach().mean(),
        )
        if self.option_policy == "soft":
            out["option_alpha"] = self._option_alpha
        return TensorDict(out, batch_size=[])
