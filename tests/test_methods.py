"""Transfer methods as units: the registry's contract, and the methods that read a source run."""
import pytest
import torch
import yaml
from tensordict import TensorDict
from tensordict.nn import TensorDictModule
from torchrl.envs import ExplorationType, set_exploration_type

from drltg import config as config_lib
from drltg.collectors import JumpStart, PolicyReuse
from drltg.envs import make_env
from drltg.errors import UsageError
from drltg.learners import make_agent
from drltg.modules import min_over_critics
from drltg.transfer import METHODS, Transfer, get_method
from drltg.transforms import PotentialShaping, SourceValue

SMALL = ["network.hidden=[8,8]", "collector.num_envs=2", "collector.frames_per_batch=8"]


def _cfg(task="fourrooms/northeast", *overrides, algo="sac"):
    return config_lib.resolve({}, [*SMALL, *overrides], task=task, algo=algo)


def _source_run(path, task="fourrooms/northeast", algo="sac"):
    """A finished source run directory holding an untrained learner of ``algo``."""
    cfg = _cfg(task, algo=algo)
    agent = make_agent(make_env(task), cfg)
    (path / "checkpoints").mkdir(parents=True)
    torch.save({"loss": agent.loss.state_dict(), "frames": 0}, path / "checkpoints" / "last.pt")
    (path / "config.yaml").write_text(config_lib.dump(cfg))
    (path / "summary.json").write_text("{}")
    return path, agent


@pytest.mark.parametrize("name", sorted(METHODS))
def test_every_method_builds_a_transfer_for_a_run(name, tmp_path):
    method = get_method(name)
    overrides = [f"transfer.method={name}", "transfer.demo_episodes=1", "transfer.sf_frames=16",
                 "transfer.sf_updates=1"]
    if method.source is not None:
        overrides.append(f"transfer.source={_source_run(tmp_path / 'src')[0]}")
    cfg = _cfg("fourrooms/northeast", *overrides)
    env = make_env("fourrooms/northeast")
    transfer = method.build(cfg, make_agent(env, cfg), env, resuming=False)
    assert isinstance(transfer, Transfer)
    changed = {k for k, v in vars(transfer).items() if v not in (None, [], {}, False)}
    expected = {
        "none": set(), "reward-shaping": {"train_transforms"}, "value-shaping": {"train_transforms"},
        "policy-reuse": {"train_transforms", "mixer", "on_frames"},
        "jumpstart": {"train_transforms", "mixer", "on_frames", "on_eval", "state"},
        "model-reuse": {"files"}, "demonstrations": {"batches", "loss_terms", "summary"},
        "kickstarting": {"loss_terms", "on_frames", "summary"},
        "sf-gpi": {"mixer", "mixer_reads_learner", "pretraining", "summary"},
    }
    assert changed == expected[name]


def test_min_over_critics_is_the_elementwise_minimum_without_gradients():
    """Two linear critics, Q_1(x) = x_0 and Q_2(x) = x_1 + 1: their minimum by hand, and no graph kept."""
    critic = TensorDictModule(torch.nn.Linear(2, 1), in_keys=["observation"], out_keys=["state_action_value"])
    params = TensorDict.from_module(critic).expand(2).clone()
    params["module", "weight"] = torch.tensor([[[1.0, 0.0]], [[0.0, 1.0]]]).requires_grad_()
    params["module", "bias"] = torch.tensor([[0.0], [1.0]])
    td = TensorDict({"observation": torch.tensor([[3.0, 5.0], [4.0, -3.0]])}, batch_size=[2])
    value = min_over_critics(critic, params, td)
    assert value.tolist() == [[3.0], [-2.0]] and not value.requires_grad
    assert "state_action_value" not in td.keys()


def test_source_value_is_the_smaller_critic_at_the_source_action(tmp_path):
    run, agent = _source_run(tmp_path / "src")
    cfg = _cfg("fourrooms/northeast", "transfer.method=value-shaping", f"transfer.source={run}",
               "transfer.value_scale=2.0")
    env = make_env("fourrooms/northeast", batch_size=(5,), seed=1)
    (shaping,) = get_method("value-shaping").build(cfg, agent, env, resuming=False).train_transforms
    assert isinstance(shaping, PotentialShaping) and isinstance(shaping.potential, SourceValue)
    obs = env.reset()["observation"]
    loss = agent.loss
    td = TensorDict({"observation": obs}, batch_size=[5])
    with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
        td = loss.actor_network(td)
        q = []
        for params in loss.qvalue_network_params.unbind(0):
            with params.to_module(loss.qvalue_network):
                q.append(loss.qvalue_network(td.clone())["state_action_value"])
    assert torch.allclose(shaping.potential(obs), 2.0 * torch.minimum(*q))


def test_source_value_of_discrete_sac_is_the_greedy_actions_q(tmp_path):
    run, agent = _source_run(tmp_path / "src", task="gridrooms/northeast")
    potential = SourceValue(agent.loss, discrete=True)
    obs = make_env("gridrooms/northeast", batch_size=(3,), seed=0).reset()["observation"]
    td = TensorDict({"observation": obs}, batch_size=[3])
    with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
        greedy = agent.loss.actor_network(td.clone())["action"].argmax(-1, keepdim=True)
        q = []
        for params in agent.loss.qvalue_network_params.unbind(0):
            with params.to_module(agent.loss.qvalue_network):
                q.append(agent.loss.qvalue_network(td.clone())["action_value"].gather(-1, greedy))
    assert torch.allclose(potential(obs), torch.minimum(*q))


def test_value_shaping_refuses_an_options_source(tmp_path):
    run, agent = _source_run(tmp_path / "src", algo="soc")
    with pytest.raises(UsageError, match="reads a SAC, discrete-SAC or TD3 source"):
        SourceValue(agent.loss, discrete=False)


def test_jumpstart_on_a_frame_clock_guides_for_the_configured_steps(tmp_path):
    run, _ = _source_run(tmp_path / "src")
    cfg = _cfg("fourrooms/northeast", "transfer.method=jumpstart", f"transfer.source={run}",
               "transfer.guide_steps=40", "transfer.guide_stages=4", "transfer.guide_curriculum=frames",
               "transfer.guide_frames=1000")
    env = make_env("fourrooms/northeast")
    transfer = get_method("jumpstart").build(cfg, make_agent(env, cfg), env, resuming=False)
    mixer = transfer.mixer
    assert isinstance(mixer, PolicyReuse) and isinstance(mixer.schedule, JumpStart)
    assert transfer.on_eval is None  # the clock needs no evaluation of the combined policy
    horizons = []
    for frames in (0, 249, 250, 500, 999, 1000, 5000):
        transfer.on_frames(frames)
        horizons.append(mixer.schedule.horizon)
    assert horizons == [40, 40, 30, 20, 10, 0, 0]  # H_k = 40 (4 - k) // 4, one stage per 250 frames


def test_jumpstart_advances_on_the_evaluated_return_by_default(tmp_path):
    """guide_tolerance 0.05: returns 0.8 (best 0.8), 0.78 (>= 0.8 - 0.04: stage 1), 0.5 (below 0.76: stays),
    0.79 (stage 2, best still 0.8), 0.9 (stage 3, best 0.9); the frames never move it."""
    run, _ = _source_run(tmp_path / "src")
    cfg = _cfg("fourrooms/northeast", "transfer.method=jumpstart", f"transfer.source={run}",
               "transfer.guide_steps=40", "transfer.guide_stages=4")
    assert (cfg.transfer.guide_curriculum, cfg.transfer.guide_tolerance, cfg.transfer.guide_window) == \
        ("return", 0.05, 1)
    env = make_env("fourrooms/northeast")
    transfer = get_method("jumpstart").build(cfg, make_agent(env, cfg), env, resuming=False)
    assert transfer.mixer.mix_deterministic and transfer.state is transfer.mixer.schedule
    transfer.on_frames(10**6)
    logged = [transfer.on_eval(value) for value in (0.8, 0.78, 0.5, 0.79, 0.9)]
    assert logged == [{"jumpstart/horizon": h} for h in (40, 30, 30, 20, 10)]


def test_resumed_model_reuse_keeps_its_frozen_parameters_frozen(tmp_path):
    run, _ = _source_run(tmp_path / "src")
    cfg = _cfg("fourrooms/northeast", "transfer.method=model-reuse", f"transfer.source={run}",
               "transfer.freeze=[actor_network_params]")
    env = make_env("fourrooms/northeast")
    for resuming in (False, True):
        agent = make_agent(env, cfg)
        get_method("model-reuse").build(cfg, agent, env, resuming=resuming)
        frozen = {n for n, p in agent.loss.named_parameters() if not p.requires_grad}
        assert frozen and all(n.startswith("actor_network_params") for n in frozen)


def test_a_run_is_a_source_in_one_silent_call(tmp_path, capsys):
    from drltg.transfer import load_actor, load_critic

    run, agent = _source_run(tmp_path / "src")
    actor, value = load_actor(run), load_critic(run, scale=2.0)
    assert capsys.readouterr() == ("", "")
    td = TensorDict({"observation": make_env("fourrooms/northeast", batch_size=(4,), seed=0).reset()["observation"]},
                    batch_size=[4])
    with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
        torch.testing.assert_close(actor(td.clone())["action"], agent.actor(td.clone())["action"])
    torch.testing.assert_close(value(td["observation"]), SourceValue(agent.loss, discrete=False, scale=2.0)(
        td["observation"]))


def test_a_source_that_cannot_be_built_says_why_in_one_sentence(tmp_path):
    from drltg.transfer import load_actor

    with pytest.raises(UsageError, match=r"is not a drltg run directory: it holds no config.yaml\.$"):
        load_actor(tmp_path)
    run, _ = _source_run(tmp_path / "src")
    cfg = yaml.safe_load((run / "config.yaml").read_text())
    (run / "config.yaml").write_text(yaml.safe_dump({**cfg, "network": {**cfg["network"], "hidden": [16, 16]}}))
    with pytest.raises(UsageError, match=r"does not fit the sac learner its config.yaml describes \(.*\)\.$") as err:
        load_actor(run)
    assert "\n" not in str(err.value)
    (run / "config.yaml").write_text(yaml.safe_dump({**cfg, "task": "nowhere/lost"}))
    with pytest.raises(UsageError, match=r"cannot be rebuilt: unknown task 'nowhere/lost'"):
        load_actor(run)
