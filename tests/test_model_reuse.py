import pytest
import torch
from tensordict import TensorDict
from torch import nn
from torchrl.envs.utils import ExplorationType, set_exploration_type

from drltg.config import resolve
from drltg.envs import FourRoomsEnv
from drltg.errors import UsageError
from drltg.learners import make_agent
from drltg.modules import load_weights
from drltg.transfer import load_from_run


def agent(algo="sac", observe_goal=False, seed=0):
    torch.manual_seed(seed)
    cfg = resolve(task="fourrooms/northeast", algo=algo, overrides=["network.hidden=[16, 16]"])
    return make_agent(FourRoomsEnv(observe_goal=observe_goal), cfg)


def greedy(actor, obs):
    with set_exploration_type(ExplorationType.DETERMINISTIC), torch.no_grad():
        return actor(TensorDict(observation=obs, batch_size=obs.shape[:1]))["action"]


def q_values(loss, obs, action):
    """Both critics' Q(s, a), read through the loss module's own (stacked) parameters."""
    td = TensorDict(observation=obs, action=action, batch_size=obs.shape[:1])
    values = []
    for params in loss.qvalue_network_params.unbind(0):
        with params.to_module(loss.qvalue_network), torch.no_grad():
            values.append(loss.qvalue_network(td.clone())["state_action_value"])
    return torch.stack(values)


@pytest.mark.parametrize("algo", ["sac", "td3"])
def test_equal_shapes_copy_every_entry(algo):
    source, target = agent(algo, seed=0), agent(algo, seed=1)
    report = load_weights(target.loss, source.loss.state_dict())
    assert not report.widened and not report.skipped and not report.unused
    for name, value in source.loss.state_dict().items():
        assert torch.equal(target.loss.state_dict()[name], value), name
    obs = torch.rand(8, 2) * 2 - 1
    torch.testing.assert_close(greedy(target.actor, obs), greedy(source.actor, obs))


def test_widened_layers_compute_the_source_function_on_shared_inputs():
    source, target = agent(seed=0), agent(observe_goal=True, seed=1)
    report = load_weights(target.loss, source.loss.state_dict())
    assert report.input_map == [0, 1, None, None]
    assert set(report.widened) == {
        "actor_network_params.module.0.module.0.0.weight",
        "qvalue_network_params.module.0.weight",
        "target_qvalue_network_params.module.0.weight",
    }
    obs, action = torch.rand(32, 4) * 2 - 1, torch.rand(32, 2) * 2 - 1
    torch.testing.assert_close(greedy(target.actor, obs), greedy(source.actor, obs[:, :2]))
    torch.testing.assert_close(q_values(target.loss, obs, action), q_values(source.loss, obs[:, :2], action))
    assert (q_values(target.loss, obs, action) != q_values(target.loss, -obs, action)).all()


def test_explicit_input_map_places_the_shared_inputs():
    source, target = agent(seed=0), agent(observe_goal=True, seed=1)
    load_weights(target.loss, source.loss.state_dict(), input_map=[None, 0, 1, None])
    obs, action = torch.rand(32, 4) * 2 - 1, torch.rand(32, 2) * 2 - 1
    torch.testing.assert_close(greedy(target.actor, obs), greedy(source.actor, obs[:, 1:3]))
    torch.testing.assert_close(q_values(target.loss, obs, action), q_values(source.loss, obs[:, 1:3], action))


def test_narrowed_layers_drop_the_removed_inputs():
    source, target = agent(observe_goal=True, seed=0), agent(seed=1)
    report = load_weights(target.loss, source.loss.state_dict())
    assert len(report.narrowed) == 3 and report.input_map == [0, 1]
    obs, action = torch.rand(32, 2) * 2 - 1, torch.rand(32, 2) * 2 - 1
    removed_at_zero = torch.cat([obs, torch.zeros(32, 2)], dim=-1)
    torch.testing.assert_close(greedy(target.actor, obs), greedy(source.actor, removed_at_zero))
    torch.testing.assert_close(q_values(target.loss, obs, action), q_values(source.loss, removed_at_zero, action))


def test_freeze_stops_gradients_of_the_frozen_layers_only():
    source, target = agent(seed=0), agent(seed=1)
    report = load_weights(target.loss, source.loss.state_dict(), freeze=["actor_network_params"])
    params = dict(target.loss.named_parameters())
    assert report.frozen and all(n.startswith("actor_network_params") for n in report.frozen)
    assert all(not params[n].requires_grad for n in report.frozen)
    assert params["qvalue_network_params.module.0.weight"].requires_grad

    env = FourRoomsEnv(batch_size=(4,), seed=0)
    with set_exploration_type(ExplorationType.RANDOM):
        batch = env.rollout(8, target.actor).reshape(-1)
    losses = target.loss(batch)
    (losses["loss_actor"] + losses["loss_qvalue"]).backward()
    assert all(params[n].grad is None for n in report.frozen)
    assert params["qvalue_network_params.module.0.weight"].grad is not None


def test_exclude_keeps_entries_as_initialised():
    source, target = agent(seed=0), agent(seed=1)
    before = target.loss.log_alpha.clone()
    report = load_weights(target.loss, source.loss.state_dict(), exclude=["log_alpha", "actor_network_params.*.4.*"])
    assert "log_alpha" in report.skipped and len(report.skipped) == 3
    assert torch.equal(target.loss.log_alpha, before)


def test_refuses_different_action_sizes():
    source = nn.Sequential(nn.Linear(4, 8), nn.ReLU(), nn.Linear(8, 2))
    target = nn.Sequential(nn.Linear(4, 8), nn.ReLU(), nn.Linear(8, 3))
    with pytest.raises(UsageError, match="'2.weight'"):
        load_weights(target, source.state_dict())
    report = load_weights(target, source.state_dict(), exclude=["2"])
    assert report.loaded == ["0.weight", "0.bias"] and report.skipped == ["2.weight", "2.bias"]


def test_refuses_a_partial_load_across_learners_unless_asked():
    source, target = agent("td3", seed=0), agent("sac", seed=1)
    with pytest.raises(UsageError, match=r"lacks trainable ones \(log_alpha, actor_network_params\)"):
        load_weights(target.loss, source.loss.state_dict())
    report = load_weights(target.loss, source.loss.state_dict(), partial=True)
    assert all(name.startswith("qvalue") or name.startswith("target_qvalue") or name == "_value_estimator.gamma"
               for name in report.loaded)
    assert "actor_network_params.module.0.module.0.0.weight" in report.skipped
    assert report.summary() == str(report).splitlines()[0]


def test_refuses_when_nothing_matches():
    with pytest.raises(UsageError, match="no entry"):
        load_weights(nn.Linear(2, 2), nn.Sequential(nn.Linear(2, 2)).state_dict())
    with pytest.raises(UsageError, match="matches no entry"):
        load_weights(nn.Linear(2, 2), nn.Linear(2, 2).state_dict(), freeze=["actor"])
    with pytest.raises(UsageError, match="source observation has 2"):
        load_weights(nn.Linear(3, 2), nn.Linear(2, 2).state_dict(), input_map=[0, 1, 2])


def test_load_from_run_reads_a_run_without_networks_file_from_its_checkpoint(tmp_path):
    """A run written before networks files: a checkpoint, no manifest."""
    source, target = agent(seed=0), agent(observe_goal=True, seed=1)
    (tmp_path / "checkpoints").mkdir()
    torch.save({"loss": source.loss.state_dict(), "frames": 10}, tmp_path / "checkpoints" / "last.pt")
    report = load_from_run(target.loss, tmp_path)
    assert len(report.widened) == 3 and "log_alpha" in report.loaded
    assert "3 widened" in str(report)
    with pytest.raises(UsageError, match="no checkpoints/last.pt"):
        load_from_run(target.loss, tmp_path / "missing")
    torch.save({"frames": 10}, tmp_path / "checkpoints" / "last.pt")
    with pytest.raises(UsageError, match="no 'loss' entry"):
        load_from_run(target.loss, tmp_path)
