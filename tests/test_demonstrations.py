"""Learning from demonstrations: collecting demonstrator episodes and the mixed batches."""
import json
import math

import pytest
import torch
from tensordict import TensorDict
from tensordict.nn import TensorDictModule
from torchrl.data import LazyTensorStorage, ReplayBuffer

from drltg.collectors import collect_demonstrations, demonstration_buffer, mixed_batches
from drltg.envs import make_env


def test_collects_at_least_the_asked_episodes_of_the_demonstrator():
    env = make_env("fourrooms/northeast", batch_size=(3,), seed=0, horizon=20)
    east = TensorDictModule(lambda obs: torch.tensor([1.0, 0.0]).expand(*obs.shape[:-1], 2),
                            in_keys=["observation"], out_keys=["action"])
    data = collect_demonstrations(env, east, episodes=4, steps_per_batch=10)
    # 3 envs truncate together every 20 steps: 2 batches of 10 steps end 3 episodes, 4 batches end 6.
    assert data.batch_size == (3 * 40,)
    assert int(data["next", "done"].sum()) == 6
    assert torch.equal(data["action"], torch.tensor([1.0, 0.0]).expand(120, 2))
    moved = data["next", "position"][:, 0] >= data["position"][:, 0]
    assert moved.all()


def test_noisy_demonstrations_execute_and_store_the_clipped_perturbed_action():
    """noise=0.3 on the always-east policy [1, 0]: every stored action lies in the box, the east component is
    clipped at 1 where the draw was positive, the north one is 0.3 z with z of unit spread (240 draws: a
    standard deviation within 0.75-1.25 is 3.8 standard errors wide), the env moved by it, and the same
    seed collects the same episodes."""
    east = TensorDictModule(lambda obs: torch.tensor([1.0, 0.0]).expand(*obs.shape[:-1], 2),
                            in_keys=["observation"], out_keys=["action"])

    def collect(noise):
        torch.manual_seed(0)
        return collect_demonstrations(make_env("fourrooms/northeast", batch_size=(3,), seed=0, horizon=20), east,
                                      episodes=4, steps_per_batch=10, noise=noise)

    data, plain = collect(0.3), collect(0.0)
    action = data["action"]
    assert (action >= -1).all() and (action <= 1).all()
    assert (action[:, 0] == 1).any() and (action[:, 0] < 1).any()
    assert 0.75 < (action[:, 1] / 0.3).std() < 1.25
    assert torch.equal(plain["action"], torch.tensor([1.0, 0.0]).expand(120, 2))
    assert not torch.equal(data["next", "position"], plain["next", "position"])  # the perturbed actions were run
    assert torch.equal(collect(0.3)["next", "position"], data["next", "position"])
    with pytest.raises(ValueError, match="standard deviation"):
        collect_demonstrations(make_env("fourrooms/northeast"), east, episodes=1, noise=-0.1)


def test_collecting_leaves_the_callers_env_open():
    from torchrl.envs import SerialEnv

    env = SerialEnv(2, lambda: make_env("fourrooms/northeast", horizon=5))  # closing it twice raises
    east = TensorDictModule(lambda obs: torch.tensor([1.0, 0.0]).expand(*obs.shape[:-1], 2),
                            in_keys=["observation"], out_keys=["action"])
    collect_demonstrations(env, east, episodes=2, steps_per_batch=5)
    assert not env.is_closed
    env.close()


def test_collect_refuses_zero_episodes():
    env = make_env("fourrooms/northeast", batch_size=(2,), seed=0)
    with pytest.raises(ValueError, match="at least one episode"):
        collect_demonstrations(env, None, episodes=0)


def _buffers(batch_size=8):
    demos = TensorDict({"obs": torch.arange(10.0), "demo": torch.ones(10, dtype=torch.bool)}, [10])
    own = ReplayBuffer(storage=LazyTensorStorage(100), batch_size=batch_size)
    own.extend(TensorDict({"obs": -torch.arange(1.0, 51.0), "demo": torch.zeros(50, dtype=torch.bool)}, [50]))
    return own, demonstration_buffer(demos, ["obs", "demo"])


@pytest.mark.parametrize("ratio, k", [(0.25, 2), (0.3, 2), (0.5, 4), (0.0, 0), (1.0, 8)])
def test_each_batch_holds_the_demonstration_share_first(ratio, k):
    torch.manual_seed(0)
    own, demos = _buffers()
    batches = mixed_batches(own, demos, count=5, ratio=ratio)
    assert len(batches) == 5
    for batch in batches:
        assert batch.batch_size == (8,)
        assert batch["demo"].tolist() == [True] * k + [False] * (8 - k)
        assert ((batch["obs"] >= 0) == batch["demo"]).all()


def test_demonstration_buffer_keeps_only_the_given_keys():
    data = TensorDict({"observation": torch.zeros(4, 2), "extra": torch.zeros(4)}, [4])
    buffer = demonstration_buffer(data, ["observation"])
    assert len(buffer) == 4 and set(buffer.sample(2).keys()) == {"observation"}


# ------------------------------------------------------------------ the method in drltg train
from drltg import config as config_lib  # noqa: E402
from drltg.errors import UsageError  # noqa: E402
from drltg.training.loop import read_eval_csv, train  # noqa: E402

TINY = ["network.hidden=[16,16]", "collector.num_envs=4", "collector.frames_per_batch=16",
        "collector.init_random_frames=64", "optim.updates_per_batch=2", "buffer.batch_size=32",
        "eval.every=128", "eval.episodes=4", "checkpoint.every=256", "log.tensorboard=false",
        "env.horizon=20"]


@pytest.fixture(scope="module")
def source_run(tmp_path_factory):
    cfg = config_lib.resolve({}, TINY, task="fourrooms/northeast", frames=256, seed=1)
    return train(cfg, tmp_path_factory.mktemp("src") / "source", progress=False)


def test_demonstrations_of_a_source_run_train_the_target_reproducibly(source_run, tmp_path):
    cfg = config_lib.resolve({}, TINY + [f"transfer.source={source_run}", "transfer.method=demonstrations",
                                         "transfer.demo_episodes=5", "transfer.demo_ratio=0.5"],
                             task="fourrooms/northeast-shifted", frames=256, seed=2)
    a, b = (train(cfg, tmp_path / name, progress=False) for name in ("a", "b"))
    summary = json.loads((a / "summary.json").read_text())
    # 4 envs in batches of 50 steps, every episode truncated at 20 steps: one batch ends 8 episodes.
    assert summary["demonstration_frames"] == 4 * 50
    assert read_eval_csv(a / "eval.csv") == read_eval_csv(b / "eval.csv")
    plain = config_lib.resolve({}, TINY, task="fourrooms/northeast-shifted", frames=256, seed=2)
    c = train(plain, tmp_path / "c", progress=False)
    weights = [torch.load(run / "checkpoints" / "last.pt", weights_only=True)["loss"] for run in (a, b, c)]
    same = [all(torch.equal(w[k], weights[0][k]) for k in w) for w in weights]
    assert same == [True, True, False]  # the same demonstrations each time; the updates saw them


def test_soft_option_critic_learns_from_demonstrations_from_the_command_line(source_run, tmp_path):
    from drltg.cli import main

    args = ["train", "fourrooms/northeast-shifted", "--algo", "soc", "--options", "2", "--frames", "128",
            "--seed", "3", "--no-progress",
            *[x for o in [*TINY, f"transfer.source={source_run}",
                          "transfer.method=reward-shaping+demonstrations", "transfer.demo_episodes=5", "log.every=32",
                          "transfer.demo_ratio=0.5"] for x in ("-o", o)]]
    assert main([*args, "--run-dir", str(tmp_path / "a")]) == 0
    assert main([*args, "--run-dir", str(tmp_path / "b")]) == 0
    summary = json.loads((tmp_path / "a" / "summary.json").read_text())
    assert summary["demonstration_frames"] == 4 * 50
    assert read_eval_csv(tmp_path / "a" / "eval.csv") == read_eval_csv(tmp_path / "b" / "eval.csv")
    logged = {p.stem: p for p in (tmp_path / "a" / "logs" / "csv").rglob("*.csv")}
    cloned = [float(line.split(",")[-1]) for line in logged["loss_actor_bc"].read_text().split()]
    assert cloned and all(x > 0 for x in cloned)  # the options' actors were pulled towards the demonstrations


@pytest.mark.parametrize("override, message", [
    (["transfer.source=demonstrator:lift"], "solves lift"),
    ([], "needs transfer.source"),
])
def test_demonstrations_refuse_what_they_cannot_use(override, message, tmp_path):
    cfg = config_lib.resolve({}, TINY + ["transfer.method=demonstrations", *override],
                             task="fourrooms/northeast", frames=256, seed=0)
    with pytest.raises(UsageError, match=message):
        train(cfg, tmp_path / "run", progress=False)
    assert not (tmp_path / "run").exists()


def test_the_lift_demonstrator_serves_lift_under_its_dense_reward():
    """lift-dense is Lift's scene and observation with robosuite's dense reward: its demonstrator is Lift's."""
    from drltg.transfer.source import check

    cfg = config_lib.resolve({}, ["transfer.method=demonstrations", "transfer.source=demonstrator:lift"],
                             task="lift-dense", frames=256, seed=0)
    check(cfg)  # accepted: no env is built
    wrong = config_lib.resolve({}, ["transfer.method=demonstrations", "transfer.source=demonstrator:lift"],
                               task="pendulum/g10", frames=256, seed=0)
    with pytest.raises(UsageError, match="solves lift"):
        check(wrong)


# ------------------------------------------------------------------ behaviour cloning (Nair et al. 2018)
from torchrl.envs import ExplorationType, set_exploration_type  # noqa: E402

from drltg.learners import UpdateStep, loss_total, make_agent  # noqa: E402
from drltg.losses import behaviour_cloning  # noqa: E402


def _agent_and_batch(algo="sac", n=32, seed=0):
    cfg = config_lib.resolve({}, ["network.hidden=[16,16]"], task="fourrooms/northeast", algo=algo)
    torch.manual_seed(seed)
    agent = make_agent(make_env("fourrooms/northeast", seed=0), cfg)
    env = make_env("fourrooms/northeast", batch_size=(n,), seed=seed)
    batch = env.rand_step(env.reset())
    return agent, batch


def _critic_min(loss, obs, action):
    values = []
    for params in loss.qvalue_network_params.detach().unbind(0):
        with params.to_module(loss.qvalue_network):
            td = TensorDict({"observation": obs, "action": action}, [obs.shape[0]])
            values.append(loss.qvalue_network(td)["state_action_value"].squeeze(-1))
    return torch.minimum(*values)


@pytest.mark.parametrize("algo", ["sac", "td3"])
def test_behaviour_cloning_is_the_q_filtered_squared_error_on_the_demonstrations(algo):
    agent, batch = _agent_and_batch(algo)
    count, weight = 12, 0.5
    with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
        mu = agent.actor(batch[:count].select("observation").clone())["action"]
    obs, demo_action = batch["observation"][:count], batch["action"][:count]
    keep = _critic_min(agent.loss, obs, demo_action) > _critic_min(agent.loss, obs, mu)
    error = (mu - demo_action).pow(2).sum(-1)

    plain = behaviour_cloning(agent.loss, count, weight)(batch)
    filtered = behaviour_cloning(agent.loss, count, weight, q_filter=True)(batch)
    assert torch.allclose(plain["loss_actor_bc"], weight * error.mean())
    assert torch.allclose(filtered["loss_actor_bc"], weight * (error * keep).mean())
    assert filtered["bc_accepted"] == keep.float().mean() and 0 < keep.sum() < count  # both kinds occur
    later = batch.clone()
    later["action"][count:] = -later["action"][count:]  # rows past the demonstrations do not count
    assert torch.equal(behaviour_cloning(agent.loss, count, weight, q_filter=True)(later)["loss_actor_bc"],
                       filtered["loss_actor_bc"])


def test_behaviour_cloning_moves_the_actor_only_and_waits_for_the_policy_delay():
    agent, batch = _agent_and_batch("td3")
    twin, _ = _agent_and_batch("td3")
    bc = behaviour_cloning(agent.loss, 16, 1.0, q_filter=False)
    losses = agent.loss(batch.clone()).update(bc(batch))
    assert torch.equal(loss_total(losses, update_actor=False), losses["loss_qvalue"])

    step, plain = UpdateStep(agent, loss_terms=bc), UpdateStep(twin)
    torch.manual_seed(0)
    step(batch.clone(), update_actor=True)
    torch.manual_seed(0)
    plain(batch.clone(), update_actor=True)

    def same(params, other):
        pairs = zip(params.values(True, True), other.values(True, True))
        return [torch.equal(p, q) for p, q in pairs if p.requires_grad]

    assert not any(same(agent.loss.actor_network_params, twin.loss.actor_network_params))
    assert all(same(agent.loss.qvalue_network_params, twin.loss.qvalue_network_params))


def test_behaviour_cloning_alone_fits_the_demonstrated_actions():
    agent, batch = _agent_and_batch("sac", n=8)
    target = torch.tensor([0.5, -0.25]).expand(8, 2)
    batch["action"] = target.clone()
    bc = behaviour_cloning(agent.loss, 8, 1.0, q_filter=False)
    optimizer = torch.optim.Adam(agent.loss.actor_network_params.values(True, True), lr=1e-2)
    for _ in range(300):
        optimizer.zero_grad()
        bc(batch)["loss_actor_bc"].backward()
        optimizer.step()
    with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
        assert torch.allclose(agent.actor(batch.select("observation").clone())["action"], target, atol=1e-2)


@pytest.mark.parametrize("override, key", [([], "bc_weight"), (["transfer.bc_weight=0", "transfer.demo_noise=0.1"],
                                                                   "demo_noise")])
def test_cloning_and_noise_refuse_discrete_actions(override, key):
    from drltg.transfer import get_method

    cfg = config_lib.resolve({}, TINY + ["transfer.method=demonstrations", *override], task="gridrooms/northeast")
    env = make_env("gridrooms/northeast")
    with pytest.raises(UsageError, match=f"transfer.{key} works on continuous actions; task 'gridrooms/northeast'"):
        get_method("demonstrations").build(cfg, make_agent(env, cfg), env, resuming=False)


def test_annealed_behaviour_cloning_falls_linearly_to_zero(source_run):
    from drltg.learners import make_agent
    from drltg.transfer import get_method

    cfg = config_lib.resolve({}, TINY + [f"transfer.source={source_run}", "transfer.method=demonstrations",
                                         "transfer.demo_episodes=1", "transfer.bc_anneal_frames=200"],
                             task="fourrooms/northeast-shifted", seed=2)
    env = make_env("fourrooms/northeast-shifted", batch_size=(4,), horizon=20)
    agent = make_agent(env, cfg)
    transfer = get_method("demonstrations").build(cfg, agent, env, resuming=False)
    buffer = ReplayBuffer(storage=LazyTensorStorage(64), batch_size=32)
    buffer.extend(env.rollout(8, break_when_any_done=False).reshape(-1).select(*agent.loss.in_keys))
    batch = next(iter(transfer.batches(buffer, 1)))
    bc = []
    for frames in (0, 50, 200, 400):
        transfer.on_frames(frames)
        bc.append(transfer.loss_terms(batch)["loss_actor_bc"].item())
    assert bc[0] > 0
    assert bc[1] == pytest.approx(0.75 * bc[0], rel=1e-6) and bc[2] == 0.0 and bc[3] == 0.0


# ------------------------------------------------------------------ with options
from torchrl.data import Bounded  # noqa: E402

from drltg.losses import SoftOptionCriticLoss, option_labels  # noqa: E402
from drltg.modules import make_option_actor, make_option_qvalue, make_termination  # noqa: E402


def _copy(src, dst):
    for a, b in zip(src.values(True, True), dst.values(True, True), strict=True):
        assert a.shape == b.shape
        b.data.copy_(a.data)


@pytest.mark.parametrize("q_filter", [False, True])
def test_one_option_clones_exactly_as_sac(q_filter):
    """SOC with K = 1 holding SAC's weights: the same term, the same gradients, and no option drawn."""
    sac, batch = _agent_and_batch("sac", n=48, seed=3)
    cfg = config_lib.resolve({}, ["network.hidden=[16,16]", "soc.num_options=1"], task="fourrooms/northeast",
                             algo="soc")
    soc = make_agent(make_env("fourrooms/northeast", seed=0), cfg)
    for name in ("actor_network_params", "qvalue_network_params"):
        _copy(getattr(sac.loss, name), getattr(soc.loss, name))
    count, weight = 20, 0.7
    with_option = batch.clone().set("option", torch.full((48, 1), 5, dtype=torch.int64))  # not an option
    rng = torch.get_rng_state()
    option_labels(soc.loss, count)(with_option)
    assert torch.equal(torch.get_rng_state(), rng)
    assert with_option["option"][:count].eq(0).all() and with_option["option"][count:].eq(5).all()
    with_option["option"][count:] = 0

    out = []
    for agent, b in ((sac, batch), (soc, with_option)):
        terms = behaviour_cloning(agent.loss, count, weight, q_filter=q_filter)(b)
        params = [p for p in agent.loss.actor_network_params.values(True, True) if p.requires_grad]
        out.append((terms, torch.autograd.grad(terms["loss_actor_bc"], params)))
    (sac_terms, sac_grads), (soc_terms, soc_grads) = out
    torch.testing.assert_close(soc_terms["loss_actor_bc"], sac_terms["loss_actor_bc"], rtol=0, atol=1e-6)
    torch.testing.assert_close(soc_terms["bc_accepted"], sac_terms["bc_accepted"], rtol=0, atol=1e-6)
    assert len(soc_grads) == len(sac_grads) > 0
    for g, h in zip(soc_grads, sac_grads):
        torch.testing.assert_close(g, h, rtol=0, atol=1e-6)
    assert sac_terms["loss_actor_bc"] > 0
    if q_filter:
        assert 0 < sac_terms["bc_accepted"] < 1  # both kinds of demonstration occur


SPEC2 = Bounded(-1.0, 1.0, (2,))


def _two_option_loss(epsilon):
    """K = 2, one linear layer per network: mu_o = tanh(c_o) everywhere; Q_U(s, o, a) = v_o . a + b_o with
    b = (0, 5), so option 1 is the greedy option at every state (|v_o . a| <= 0.8 < 5)."""
    K, obs = 2, 3
    actor = make_option_actor(SPEC2, K, (), in_features=obs)
    loc = torch.tensor([[0.5, -0.2], [-0.4, 0.3]])
    with torch.no_grad():
        linear = actor.module[0].module.net[0]
        linear.weight.zero_()
        linear.bias.copy_(torch.cat([loc, torch.zeros(K, 2)], -1).flatten())
    loss = SoftOptionCriticLoss(actor, make_option_qvalue(K, (), in_features=obs + 2),
                                make_termination(K, (), in_features=obs), num_options=K, alpha_init=1e-9,
                                fixed_alpha=True, option_policy="egreedy", option_epsilon=epsilon)
    v, b = torch.tensor([[0.5, -0.3], [-0.2, 0.4]]), torch.tensor([0.0, 5.0])
    for params in (loss.qvalue_network_params, loss.target_qvalue_network_params):
        weight, bias = params.values(True, True)
        weight.data.copy_(torch.cat([torch.zeros(K, obs), v], -1).expand_as(weight))
        bias.data.copy_(b.expand_as(bias))
    return loss, loc, v


def _demo_batch(actions, extra=2):
    n = len(actions) + extra
    g = torch.Generator().manual_seed(0)
    return TensorDict({"observation": torch.randn(n, 3, generator=g),
                       "action": torch.cat([torch.tensor(actions), torch.zeros(extra, 2)]),
                       "option": torch.zeros(n, 1, dtype=torch.int64)}, [n])


def test_two_options_clone_by_hand():
    """pi_Omega = (eps/2, 1 - eps/2) = (0.1, 0.9); each demonstration's squared error to each option's
    mean action, weighted by it, kept where v_o . a > v_o . mu_o (the Q filter)."""
    loss, loc, v = _two_option_loss(epsilon=0.2)
    actions = [[0.4, -0.2], [-0.5, 0.5], [0.9, 0.9]]
    batch = _demo_batch(actions)
    probs = [0.1, 0.9]
    mu = [[math.tanh(x) for x in row] for row in loc.tolist()]
    plain = kept = accepted = 0.0
    for a in actions:
        for o in range(2):
            error = sum((m - x) ** 2 for m, x in zip(mu[o], a))
            keep = sum(w * x for w, x in zip(v[o].tolist(), a)) > sum(w * m for w, m in zip(v[o].tolist(), mu[o]))
            plain += probs[o] * error / len(actions)
            kept += probs[o] * error * keep / len(actions)
            accepted += probs[o] * keep / len(actions)
    assert 0 < accepted < 1
    out = behaviour_cloning(loss, len(actions), 2.0)(batch)
    assert out["loss_actor_bc"].item() == pytest.approx(2.0 * plain, rel=1e-5)
    filtered = behaviour_cloning(loss, len(actions), 2.0, q_filter=True)(batch)
    assert filtered["loss_actor_bc"].item() == pytest.approx(2.0 * kept, rel=1e-5)
    assert filtered["bc_accepted"].item() == pytest.approx(accepted, rel=1e-5)
    assert out["bc_accepted"].item() == pytest.approx(1.0)
    labelled = option_labels(loss, len(actions))(batch.clone())  # pi_Omega left in the batch is the same
    torch.testing.assert_close(labelled["option_probs"], torch.tensor([probs] * len(actions) + [[0.0, 0.0]] * 2))
    assert behaviour_cloning(loss, len(actions), 2.0, q_filter=True)(labelled)["loss_actor_bc"].item() == \
        pytest.approx(2.0 * kept, rel=1e-5)


def test_demonstrations_are_credited_to_the_option_the_learner_would_choose():
    loss, *_ = _two_option_loss(epsilon=0.0)  # pi_Omega = (0, 1): every label is option 1
    batch = _demo_batch([[0.1, 0.2]] * 5, extra=3)
    assert option_labels(loss, 5)(batch)["option"].squeeze(-1).tolist() == [1] * 5 + [0] * 3
    loss, *_ = _two_option_loss(epsilon=0.5)  # pi_Omega = (0.25, 0.75)
    torch.manual_seed(0)
    batch = _demo_batch([[0.1, 0.2]] * 4000, extra=0)
    share = option_labels(loss, 4000)(batch)["option"].float().mean().item()
    assert abs(share - 0.75) < 0.03  # binomial sd 0.007


def test_each_batch_credits_its_demonstrations_with_the_networks_of_its_own_update(source_run):
    """The method's batches are drawn one at a time: a change of the critics between two updates
    changes the second batch's options (egreedy with epsilon 0: the greedy option only)."""
    from torchrl.envs import TransformedEnv

    from drltg.modules import option_transforms
    from drltg.transfer import get_method

    cfg = config_lib.resolve({}, TINY + [f"transfer.source={source_run}", "transfer.method=demonstrations",
                                         "transfer.demo_episodes=1", "soc.num_options=2",
                                         "soc.option_policy=egreedy", "soc.option_epsilon=0"],
                             task="fourrooms/northeast-shifted", algo="soc", seed=2)
    env = TransformedEnv(make_env("fourrooms/northeast-shifted", batch_size=(4,), horizon=20))
    for transform in option_transforms(2):  # the option the buffer's transitions carry, as in training
        env.append_transform(transform)
    agent = make_agent(env, cfg)
    transfer = get_method("demonstrations").build(cfg, agent, env, resuming=False)
    buffer = ReplayBuffer(storage=LazyTensorStorage(64), batch_size=32)
    buffer.extend(env.rollout(8, break_when_any_done=False).reshape(-1).select(*agent.loss.in_keys))
    *_, bias = agent.loss.qvalue_network_params.values(True, True)  # the critics' last bias, [2 copies, K]

    def prefer(option):
        bias.data.fill_(-100.0)
        bias.data[:, option] = 100.0

    k = round(cfg.transfer.demo_ratio * 32)
    batches = transfer.batches(buffer, 2)
    prefer(1)
    first = next(batches)
    prefer(0)
    second = next(batches)
    assert first["option"][:k].eq(1).all() and second["option"][:k].eq(0).all()


def _one_option_loss(u, v, b):
    """K = 1 (SAC's terms exactly), one linear layer per network: mu = tanh(0) = (0, 0) at every state, and
    Q(s, a) = u . s + v . a + b."""
    obs = len(u)
    actor = make_option_actor(SPEC2, 1, (), in_features=obs)
    with torch.no_grad():
        linear = actor.module[0].module.net[0]
        linear.weight.zero_()
        linear.bias.zero_()
    loss = SoftOptionCriticLoss(actor, make_option_qvalue(1, (), in_features=obs + 2),
                                make_termination(1, (), in_features=obs), num_options=1, alpha_init=1e-9,
                                fixed_alpha=True)
    for params in (loss.qvalue_network_params, loss.target_qvalue_network_params):
        weight, bias = params.values(True, True)
        weight.data.copy_(torch.tensor([*u, *v]).expand_as(weight))
        bias.data.fill_(b)
    return loss


def _demos(observations, actions):
    n = len(actions)
    return TensorDict({"observation": torch.tensor(observations), "action": torch.tensor(actions),
                       "option": torch.zeros(n, 1, dtype=torch.int64)}, [n])


def test_the_q_filter_keeps_exactly_the_demonstrations_the_critic_rates_above_the_actor():
    """Q(s, a) = a_0 - a_1 + 0.5 and mu = (0, 0), so Q(s, mu) = 0.5: the demonstrated actions' values are
    0.8, 0.0, 1.2 and 0.5, the mask (strictly above) 1, 0, 1, 0; the squared errors ||a||^2 are 0.17, 0.13, 0.29,
    0.02, so the filtered term is w (0.17 + 0.29) / 4 and the plain one w (0.17 + 0.13 + 0.29 + 0.02) / 4."""
    loss = _one_option_loss(u=[0.0, 0.0, 0.0], v=[1.0, -1.0], b=0.5)
    batch = _demos([[0.0, 0.0, 0.0]] * 4, [[0.4, 0.1], [-0.3, 0.2], [0.2, -0.5], [0.1, 0.1]])
    filtered = behaviour_cloning(loss, 4, 2.0, q_filter=True)(batch)
    assert filtered["loss_actor_bc"].item() == pytest.approx(2.0 * (0.17 + 0.29) / 4, rel=1e-6)
    assert filtered["bc_accepted"].item() == 0.5
    plain = behaviour_cloning(loss, 4, 2.0, q_filter=False)(batch)
    assert plain["loss_actor_bc"].item() == pytest.approx(2.0 * (0.17 + 0.13 + 0.29 + 0.02) / 4, rel=1e-6)
    assert plain["bc_accepted"].item() == 1.0


def test_the_cloning_weight_is_scaled_by_one_over_td3_bc_lambda():
    """Q(s, a) = s_0 - 1 at the actor's action mu = (0, 0): at s_0 = 2, -2, 1.5, 3.5 it is 1, -3, 0.5, 2.5, so
    mean|Q| = 1.75 and, with alpha = 3.5, lambda = alpha / mean|Q| = 2: the term is w / 2 times the squared error."""
    loss = _one_option_loss(u=[1.0, 0.0, 0.0], v=[0.0, 0.0], b=-1.0)
    actions = [[0.4, 0.1], [-0.3, 0.2], [0.2, -0.5], [0.1, 0.1]]
    batch = _demos([[2.0, 0, 0], [-2.0, 0, 0], [1.5, 0, 0], [3.5, 0, 0]], actions)
    out = behaviour_cloning(loss, 4, 3.0, alpha=3.5)(batch)
    assert out["bc_scale"].item() == pytest.approx(1 / 2, rel=1e-6)
    assert out["loss_actor_bc"].item() == pytest.approx(3.0 / 2 * (0.17 + 0.13 + 0.29 + 0.02) / 4, rel=1e-6)
    doubled = batch.clone()
    doubled["observation"] = 2 * doubled["observation"]  # Q(s, mu) = 3, -5, 2, 6: mean|Q| = 4, lambda = 0.875
    assert behaviour_cloning(loss, 4, 3.0, alpha=3.5)(doubled)["bc_scale"].item() == pytest.approx(4 / 3.5, rel=1e-6)
    with pytest.raises(ValueError, match="alpha must be > 0"):
        behaviour_cloning(loss, 4, 3.0, alpha=0.0)


def test_the_method_clones_q_filtered_at_td3_bc_scale_by_default(source_run):
    from drltg.transfer import get_method

    cfg = config_lib.resolve({}, TINY + [f"transfer.source={source_run}", "transfer.method=demonstrations",
                                         "transfer.demo_episodes=1"], task="fourrooms/northeast-shifted")
    assert (cfg.transfer.bc_q_filter, cfg.transfer.bc_alpha, cfg.transfer.bc_weight) == (True, 2.5, 1.0)
    env = make_env("fourrooms/northeast-shifted", batch_size=(4,), horizon=20)
    term = get_method("demonstrations").build(cfg, make_agent(env, cfg), env, resuming=False).loss_terms
    assert (term.q_filter, float(term.alpha)) == (True, 2.5)
