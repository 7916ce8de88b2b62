"""Soft option-critic: K = 1 is SAC exactly; hand-computed targets and termination loss; options are
carried across steps, terminate at the new state for the current option only, and restart at resets."""

import math

import pytest
import torch
import yaml
from tensordict import TensorDict
from tensordict.nn import NormalParamExtractor, TensorDictModule
from torch import nn
from torchrl.collectors import Collector
from torchrl.data import Bounded
from torchrl.envs import ExplorationType, TransformedEnv, set_exploration_type
from torchrl.modules import MLP, ProbabilisticActor, TanhNormal, ValueOperator
from torchrl.objectives import SACLoss, SoftUpdate

from drltg import config as config_lib
from drltg.envs import FourRoomsEnv
from drltg.errors import UsageError
from drltg.learners import make_soc_agent
from drltg.losses import SoftOptionCriticLoss
from drltg.modules import (
    OptionHeads,
    make_option_actor,
    make_option_policy,
    make_option_qvalue,
    make_termination,
    option_statistics,
    option_transforms,
)

OBS, ACT, HIDDEN = 3, 2, (16, 16)
SPEC = Bounded(torch.tensor([-2.0, -1.0]), torch.tensor([1.0, 1.0]), (ACT,))  # not symmetric on purpose


def _batch(n, num_options, *, seed=1, terminated=None, truncated=None):
    g = torch.Generator().manual_seed(seed)
    terminated = torch.rand(n, 1, generator=g) < 0.3 if terminated is None else terminated
    truncated = torch.rand(n, 1, generator=g) < 0.3 if truncated is None else truncated
    truncated = truncated & ~terminated
    return TensorDict(
        {
            "observation": torch.randn(n, OBS, generator=g),
            "action": torch.rand(n, ACT, generator=g) * 2 - 1,
            "option": torch.randint(num_options, (n, 1), generator=g),
            ("next", "observation"): torch.randn(n, OBS, generator=g),
            ("next", "reward"): torch.randn(n, 1, generator=g),
            ("next", "terminated"): terminated,
            ("next", "truncated"): truncated,
            ("next", "done"): terminated | truncated,
        },
        [n],
    )


def _linear_heads(weight, bias, post=None):
    """OptionHeads over one linear layer with the given per-option weight rows and biases."""
    linear = nn.Linear(weight.shape[1], weight.shape[0])
    with torch.no_grad():
        linear.weight.copy_(weight)
        linear.bias.copy_(bias)
    return OptionHeads(linear, weight.shape[0], post)


def _constant_critic(loss, values):
    """Make every critic copy (online and target) output ``values[o]`` whatever the state and action."""
    for params in (loss.qvalue_network_params, loss.target_qvalue_network_params):
        *_, weight, bias = params.values(True, True)
        weight.data.zero_()
        bias.data.copy_(values.expand_as(bias))


def _termination_with_logits(num_options, logits, in_features=OBS):
    heads = _linear_heads(torch.zeros(num_options, in_features), logits, nn.Sigmoid())
    return TensorDictModule(heads, in_keys=["observation", "option"], out_keys=["termination_prob"])


def test_option_heads_return_the_head_of_the_option():
    torch.manual_seed(0)
    net = nn.Linear(4, 3 * 2)
    heads = OptionHeads(net, num_options=3)
    x = torch.randn(5, 4)
    option = torch.tensor([[0], [1], [2], [1], [0]])
    full = net(x).view(5, 3, 2)
    torch.testing.assert_close(heads(x, option), full[torch.arange(5), option.squeeze(-1)])
    # an input copied once per option, as the loss does to evaluate all options at once
    xk = x.unsqueeze(1).expand(5, 3, 4)
    ok = torch.arange(3).view(1, 3, 1).expand(5, 3, 1)
    torch.testing.assert_close(heads(xk, ok), full.gather(1, torch.arange(3).view(1, 3, 1).expand(5, 3, 2)))


def test_option_heads_run_a_repeated_state_once_with_the_same_values_and_gradients():
    """A state expanded over the options (stride 0) goes through the trunk once, not once per option; the
    values and the weights' gradients equal those of the same states materialised, copy by copy."""
    torch.manual_seed(0)
    net = nn.Sequential(nn.Linear(4, 8), nn.ReLU(), nn.Linear(8, 3 * 2))
    heads = OptionHeads(net, num_options=3)
    rows = []
    net.register_forward_hook(lambda module, args, out: rows.append(args[0].shape[:-1]))
    xk = torch.randn(5, 1, 4).expand(5, 3, 4)
    ok = torch.tensor([[0, 2, 1]] * 5).unsqueeze(-1)
    grads = []
    for x in (xk, xk.contiguous()):
        net.zero_grad()
        out = heads(x, ok)
        (out * torch.arange(out.numel()).view_as(out)).sum().backward()
        grads.append([p.grad.clone() for p in net.parameters()])
        if x is xk:
            shortcut = out
    assert rows == [(5,), (5, 3)]
    torch.testing.assert_close(shortcut, out)
    for a, b in zip(*grads):
        torch.testing.assert_close(a, b)


# ------------------------------------------------------------------------------------------ K = 1 is SAC
def _sac_twin(soc: SoftOptionCriticLoss, alpha_init: float, deactivate_vmap: bool = False) -> SACLoss:
    """TorchRL's SACLoss on plain MLPs holding exactly the K = 1 option networks' weights."""
    actor_mlp = MLP(in_features=OBS, out_features=2 * ACT, num_cells=list(HIDDEN), activation_class=nn.ReLU)
    actor_mlp.load_state_dict(soc.actor_network.module[0].module.net.state_dict())
    actor = ProbabilisticActor(
        TensorDictModule(
            nn.Sequential(actor_mlp, NormalParamExtractor()), in_keys=["observation"], out_keys=["loc", "scale"]
        ),
        in_keys=["loc", "scale"],
        spec=SPEC,
        distribution_class=TanhNormal,
        distribution_kwargs={"low": SPEC.space.low, "high": SPEC.space.high},
    )
    qvalue = ValueOperator(
        MLP(in_features=OBS + ACT, out_features=1, num_cells=list(HIDDEN), activation_class=nn.ReLU),
        in_keys=["observation", "action"],
    )
    sac = SACLoss(actor, qvalue, alpha_init=alpha_init, deactivate_vmap=deactivate_vmap)
    sac.make_value_estimator(gamma=0.9)
    for src, dst in [
        (soc.qvalue_network_params, sac.qvalue_network_params),
        (soc.target_qvalue_network_params, sac.target_qvalue_network_params),
    ]:
        for a, b in zip(src.values(True, True), dst.values(True, True), strict=True):
            b.data.copy_(a.data)
    return sac


def _flat(params):
    return torch.cat([p.detach().flatten() for p in params.values(True, True)])


@pytest.mark.parametrize("deactivate_vmap", [False, True])
def test_one_option_equals_sac_loss_gradients_and_training_steps(deactivate_vmap):
    """With the critic copies under ``torch.vmap`` (TorchRL's default) and in a loop (drltg's agents)."""
    torch.manual_seed(0)
    soc = SoftOptionCriticLoss(
        make_option_actor(SPEC, 1, HIDDEN, in_features=OBS),
        make_option_qvalue(1, HIDDEN, in_features=OBS + ACT),
        make_termination(1, HIDDEN, in_features=OBS),
        num_options=1,
        alpha_init=0.3,
        deactivate_vmap=deactivate_vmap,
    )
    soc.make_value_estimator(gamma=0.9)
    sac = _sac_twin(soc, alpha_init=0.3, deactivate_vmap=deactivate_vmap)
    terms = ["loss_actor", "loss_qvalue", "loss_alpha", "alpha", "entropy"]
    updaters = [SoftUpdate(sac, tau=0.1), SoftUpdate(soc, tau=0.1)]
    optims = [torch.optim.Adam(sac.parameters(), lr=1e-2), torch.optim.Adam(soc.parameters(), lr=1e-2)]
    termination_before = _flat(soc.termination_network_params)
    for step in range(3):
        batch = _batch(64, 1, seed=step)
        outs = []
        for loss, opt, upd in zip((sac, soc), optims, updaters):
            torch.manual_seed(100 + step)  # the same noise for the sampled actions at s' and at s
            out = loss(batch.clone())
            opt.zero_grad()
            sum(v for k, v in out.items() if k.startswith("loss_")).backward()
            opt.step()
            upd.step()
            outs.append(out)
        for k in terms:
            torch.testing.assert_close(outs[1][k], outs[0][k], rtol=1e-6, atol=1e-6, msg=k)
        assert outs[1]["loss_alpha"].abs() > 0 and outs[1]["loss_termination"] == 0
        assert outs[1]["loss_option_alpha"] == 0 and outs[1]["option_entropy"] == 0
    # the parameters stayed identical through three optimiser steps and target updates
    torch.testing.assert_close(_flat(soc.actor_network_params), _flat(sac.actor_network_params), rtol=1e-5, atol=1e-6)
    torch.testing.assert_close(_flat(soc.qvalue_network_params), _flat(sac.qvalue_network_params), rtol=1e-5, atol=1e-6)
    torch.testing.assert_close(
        _flat(soc.target_qvalue_network_params), _flat(sac.target_qvalue_network_params), rtol=1e-5, atol=1e-6
    )
    torch.testing.assert_close(soc.log_alpha, sac.log_alpha)
    torch.testing.assert_close(_flat(soc.termination_network_params), termination_before, rtol=0, atol=0)


# ------------------------------------------------------------------------------------------ hand-computed
@pytest.mark.parametrize("option_policy,bonus", [("soft", False), ("soft", True), ("egreedy", False)])
def test_targets_and_termination_loss_by_hand(option_policy, bonus):
    """K = 3, critics constant per option (Q_U = b_o), terminations beta_o(s) = sigmoid(w_o . s + c_o)."""
    torch.manual_seed(0)
    K, gamma, xi, alpha_omega, eps = 3, 0.9, 0.05, 0.5, 0.2
    b = torch.tensor([0.2, -0.4, 0.7])
    w, c = torch.randn(K, OBS), torch.tensor([-1.0, 0.0, 1.0])
    termination = TensorDictModule(
        _linear_heads(w, c, nn.Sigmoid()), in_keys=["observation", "option"], out_keys=["termination_prob"]
    )
    loss = SoftOptionCriticLoss(
        make_option_actor(SPEC, K, HIDDEN, in_features=OBS),
        make_option_qvalue(K, HIDDEN, in_features=OBS + ACT),
        termination,
        num_options=K,
        loss_function="l2",
        alpha_init=1e-9,  # no entropy bonus: Q_Omega(s, o) = b_o
        fixed_alpha=True,
        option_policy=option_policy,
        option_alpha_init=alpha_omega,
        fixed_option_alpha=True,
        option_epsilon=eps,
        deliberation_cost=xi,
        option_entropy_bonus=bonus,
    )
    loss.make_value_estimator(gamma=gamma)
    _constant_critic(loss, b)
    terminated = torch.tensor([[False], [False], [True], [False], [False], [True]])
    truncated = torch.tensor([[False], [True], [False], [True], [False], [False]])
    batch = _batch(6, K, terminated=terminated, truncated=truncated)
    batch["option"] = torch.tensor([[0], [1], [2], [0], [1], [2]])

    out = loss(batch)

    o = batch["option"].squeeze(-1)
    s_next, r = batch["next", "observation"], batch["next", "reward"].squeeze(-1)
    beta = torch.sigmoid((s_next * w[o]).sum(-1) + c[o])  # at s', for the transition's option only
    if option_policy == "soft":
        p = torch.softmax(b / alpha_omega, 0)
        v = (p * (b - bonus * alpha_omega * p.log())).sum()
    else:
        p = torch.full((K,), eps / K)
        p[b.argmax()] += 1 - eps
        v = (p * b).sum()
    advantage = b[o] - v
    u = (1 - beta) * b[o] + beta * v
    y = r + gamma * (~terminated.squeeze(-1)) * u
    torch.testing.assert_close(batch["td_error"], (b[o] - y).abs(), atol=1e-5, rtol=0)
    torch.testing.assert_close(out["loss_qvalue"], (2 * (b[o] - y) ** 2).mean(), atol=1e-5, rtol=1e-5)
    expected_term = (beta * (advantage + xi) * (~terminated.squeeze(-1))).mean()
    torch.testing.assert_close(out["loss_termination"], expected_term, atol=1e-6, rtol=1e-6)
    torch.testing.assert_close(out["termination_prob"], beta.mean())
    torch.testing.assert_close(out["option_entropy"], -(p * p.log()).sum())
    # a horizon cut (truncated, not terminated) bootstraps; only `terminated` stops it
    assert torch.allclose(y[[1, 3]], r[[1, 3]] + gamma * u[[1, 3]]) and torch.equal(y[[2, 5]], r[[2, 5]])


def test_each_loss_term_moves_only_its_own_parameters():
    torch.manual_seed(0)
    K = 3
    loss = SoftOptionCriticLoss(
        make_option_actor(SPEC, K, HIDDEN, in_features=OBS),
        make_option_qvalue(K, HIDDEN, in_features=OBS + ACT),
        make_termination(K, HIDDEN, in_features=OBS),
        num_options=K,
        deliberation_cost=0.1,
    )
    loss.make_value_estimator(gamma=0.9)
    owners = {
        "loss_actor": "actor_network_params",
        "loss_qvalue": "qvalue_network_params",
        "loss_termination": "termination_network_params",
        "loss_alpha": "log_alpha",
        "loss_option_alpha": "log_option_alpha",
    }
    out = loss(_batch(32, K))
    for key, owner in owners.items():
        loss.zero_grad(set_to_none=True)
        out[key].backward(retain_graph=True)
        touched = {n.split(".")[0] for n, p in loss.named_parameters() if p.grad is not None and p.grad.abs().sum() > 0}
        assert touched == {owner}, (key, touched)


def test_soft_update_moves_the_target_critics_only():
    torch.manual_seed(0)
    loss = SoftOptionCriticLoss(
        make_option_actor(SPEC, 2, HIDDEN, in_features=OBS),
        make_option_qvalue(2, HIDDEN, in_features=OBS + ACT),
        make_termination(2, HIDDEN, in_features=OBS),
        num_options=2,
    )
    updater = SoftUpdate(loss, tau=0.25)
    old_target = _flat(loss.target_qvalue_network_params).clone()
    for p in loss.qvalue_network_params.values(True, True):
        p.data.add_(1.0)
    online = _flat(loss.qvalue_network_params)
    updater.step()
    torch.testing.assert_close(_flat(loss.target_qvalue_network_params), 0.75 * old_target + 0.25 * online)
    assert not any(k.startswith(("target_actor", "target_termination")) for k in loss.state_dict())


# ------------------------------------------------------------------------------------------ acting
def _acting_loss(K, *, termination, critic_values, option_alpha=1.0, in_features=OBS):
    torch.manual_seed(0)
    loss = SoftOptionCriticLoss(
        make_option_actor(Bounded(-1.0, 1.0, (2,)), K, HIDDEN, in_features=in_features),
        make_option_qvalue(K, HIDDEN, in_features=in_features + 2),
        termination,
        num_options=K,
        alpha_init=1e-9,
        fixed_alpha=True,
        option_alpha_init=option_alpha,
        fixed_option_alpha=True,
    )
    _constant_critic(loss, critic_values)
    return loss


def test_termination_is_drawn_for_the_current_option_only():
    K, n = 4, 400
    loss = _acting_loss(
        K,
        termination=_termination_with_logits(K, torch.tensor([-40.0, -40.0, 40.0, -40.0])),
        critic_values=torch.zeros(K),
    )
    policy = make_option_policy(loss)
    g = torch.Generator().manual_seed(0)
    previous = torch.randint(K, (n, 1), generator=g)
    is_init = torch.rand(n, 1, generator=g) < 0.2
    td = TensorDict(
        {"observation": torch.randn(n, OBS, generator=g), "option": previous.clone(), "is_init": is_init}, [n]
    )
    policy(td)
    assert torch.equal(td["option_terminated"], (previous == 2) & ~is_init)
    kept = (previous != 2) & ~is_init
    assert torch.equal(td["option"][kept], previous[kept])  # beta_o = 0: no other option ever ends
    assert td["option"][is_init | (previous == 2)].unique().numel() == K  # fresh choices from pi_Omega


def _rooms_env(batch, horizon, K, seed=0):
    env = TransformedEnv(FourRoomsEnv(horizon=horizon, batch_size=(batch,), seed=seed))
    for t in option_transforms(K):
        env.append_transform(t)
    return env


def test_termination_is_evaluated_at_the_new_state():
    """beta_2(s) = 1 east of the middle (x > 0 in observation units), 0 west; other options never end."""
    K = 3
    heads = _linear_heads(
        torch.tensor([[0.0, 0.0], [0.0, 0.0], [1e4, 0.0]]), torch.tensor([-40.0, -40.0, 0.0]), nn.Sigmoid()
    )
    termination = TensorDictModule(heads, in_keys=["observation", "option"], out_keys=["termination_prob"])
    loss = _acting_loss(K, termination=termination, critic_values=torch.zeros(K), in_features=2)
    torch.manual_seed(1)
    data = _rooms_env(8, 6, K).rollout(40, make_option_policy(loss), break_when_any_done=False)
    x = data["observation"][..., 1:, 0]
    previous, fired = data["option"][..., :-1, 0], data["option_terminated"][..., 1:, 0]
    fresh = data["is_init"][..., 1:, 0]
    clear = x.abs() > 1e-3
    assert clear.float().mean() > 0.9
    assert ((previous == 2) & ~fresh & clear).sum() > 20
    assert torch.equal(fired[clear], ((previous == 2) & (x > 0) & ~fresh)[clear])


def test_collector_carries_options_and_restarts_them_at_every_reset():
    K, horizon = 4, 4
    never = _termination_with_logits(K, torch.full((K,), -40.0), in_features=2)
    # a greedy choice: option 1 has the best value; the primer draws a random option at each reset
    greedy = _acting_loss(
        K, termination=never, critic_values=torch.tensor([0.0, 1.0, 0.5, 0.0]), option_alpha=1e-6, in_features=2
    )
    torch.manual_seed(0)
    collector = Collector(_rooms_env(6, horizon, K), make_option_policy(greedy), frames_per_batch=48, total_frames=48)
    data = next(iter(collector))
    collector.shutdown()
    assert data["is_init"].sum() >= 12 and (data["option"] == 1).all()
    assert torch.equal(data["next", "option"], data["option"])  # the primer carries o_t into s_{t+1}

    # a uniform soft choice: options differ between episodes but hold within one
    uniform = _acting_loss(K, termination=never, critic_values=torch.zeros(K), option_alpha=1.0, in_features=2)
    torch.manual_seed(0)
    collector = Collector(_rooms_env(6, horizon, K), make_option_policy(uniform), frames_per_batch=96, total_frames=96)
    data = next(iter(collector))
    collector.shutdown()
    option, is_init = data["option"][..., 0], data["is_init"][..., 0]
    assert not data["option_terminated"].any()
    assert torch.equal(option[:, 1:][~is_init[:, 1:]], option[:, :-1][~is_init[:, 1:]])
    assert option[is_init].unique().numel() == K


def test_deterministic_mode_picks_the_best_option_and_its_mean_action():
    K, n = 3, 16
    half = _termination_with_logits(K, torch.full((K,), math.log(0.6 / 0.4)))  # beta = 0.6 > 1/2
    loss = _acting_loss(K, termination=half, critic_values=torch.tensor([0.0, 0.3, 0.9]))
    policy = make_option_policy(loss)
    g = torch.Generator().manual_seed(0)
    td = TensorDict(
        {
            "observation": torch.randn(n, OBS, generator=g),
            "option": torch.zeros(n, 1, dtype=torch.long),
            "is_init": torch.zeros(n, 1, dtype=torch.bool),
        },
        [n],
    )
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        first, second = policy(td.clone()), policy(td.clone())
        mean = loss.actor_network(td.clone().set("option", torch.full((n, 1), 2)))["action"]
    assert first["option_terminated"].all() and (first["option"] == 2).all()
    torch.testing.assert_close(first["action"], mean)
    torch.testing.assert_close(second["action"], first["action"])


def test_option_statistics_by_hand():
    data = TensorDict(
        {
            "option": torch.tensor([[0], [0], [1], [1], [1], [2]]),
            "is_init": torch.tensor([[True], [False], [False], [False], [True], [False]]),
            "option_terminated": torch.tensor([[False], [False], [True], [False], [False], [False]]),
        },
        [6],
    )
    stats = option_statistics(data, num_options=4)
    assert stats["option_length"] == 2.0  # 6 steps, 3 option starts
    assert stats["option_termination_rate"] == pytest.approx(1 / 6)
    assert [stats[f"option_usage/{o}"] for o in range(4)] == pytest.approx([2 / 6, 3 / 6, 1 / 6, 0.0])


# ------------------------------------------------------------------------------------------ agent builder
def test_soc_agent_trains_in_the_training_loop(tmp_path):
    from drltg.training.loop import read_eval_csv, train

    tiny = [
        "network.hidden=[16,16]",
        "collector.num_envs=4",
        "collector.frames_per_batch=16",
        "collector.init_random_frames=128",
        "optim.updates_per_batch=1",
        "buffer.batch_size=32",
        "eval.every=256",
        "eval.episodes=4",
        "checkpoint.every=256",
        "log.every=128",
        "log.tensorboard=false",
    ]
    cfg = config_lib.resolve({}, [*tiny, "soc.num_options=2"], task="fourrooms/northeast", algo="soc", frames=256)
    run = train(cfg, tmp_path / "run", progress=False)
    assert [r["frames"] for r in read_eval_csv(run / "eval.csv")] == [0, 256]
    state = torch.load(run / "checkpoints" / "last.pt", weights_only=True)["loss"]
    assert "log_option_alpha" in state and any(k.startswith("termination_network_params") for k in state)
    assert state["termination_network_params.module.net.4.weight"].shape == (2, 16)  # one beta_o per option
    assert yaml.safe_load((run / "config.yaml").read_text())["soc"]["num_options"] == 2


def test_cli_options_sets_the_number_of_options(tmp_path, capsys):
    from drltg.cli import main

    assert main(["train", "fourrooms/northeast", "--algo", "td3", "--options", "2"]) == 2
    assert "--algo soc" in capsys.readouterr().err
    with pytest.raises(UsageError, match="unknown config key 'soc.num_option'"):
        config_lib.resolve({}, ["soc.num_option=2"], task="fourrooms/northeast", algo="soc")


def test_soc_agent_rejects_discrete_actions_and_unknown_options():
    from drltg.envs import make_env

    cfg = config_lib.resolve({}, [], task="gridrooms/northeast", algo="soc")
    with pytest.raises(UsageError, match="continuous actions"):
        make_soc_agent(make_env("gridrooms/northeast"), cfg)
    with pytest.raises(UsageError, match=r"unknown config key .soc.num_option.; did you mean .soc.num_options.\?"):
        config_lib.resolve({"soc": {"num_option": 2}}, [], task="fourrooms/northeast", algo="soc")
