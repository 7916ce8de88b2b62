"""Combined transfer methods (``transfer.method=a+b``): what each part adds survives, conflicts are refused."""
import os

import pytest
import torch
import yaml

from drltg import config as config_lib
from drltg.cli import main
from drltg.envs import make_env
from drltg.errors import UsageError
from drltg.learners import make_agent
from drltg.transfer import Transfer, TransferMethod, combine, get_method

SMALL = ["network.hidden=[8,8]", "collector.num_envs=2", "collector.frames_per_batch=8"]
TASK = "fourrooms/northeast"


def _cfg(*overrides):
    return config_lib.resolve({}, [*SMALL, *overrides], task=TASK, algo="sac")


@pytest.fixture
def source_run(tmp_path):
    """A finished source run holding an untrained learner whose weights are all 0.25."""
    agent = make_agent(make_env(TASK), _cfg())
    with torch.no_grad():
        for p in agent.loss.parameters():
            p.fill_(0.25)
    (tmp_path / "src" / "checkpoints").mkdir(parents=True)
    torch.save({"loss": agent.loss.state_dict(), "frames": 0}, tmp_path / "src" / "checkpoints" / "last.pt")
    (tmp_path / "src" / "config.yaml").write_text(config_lib.dump(_cfg()))
    (tmp_path / "src" / "summary.json").write_text("{}")
    return tmp_path / "src"


def _build(method, source_run):
    cfg = _cfg(f"transfer.method={method}", f"transfer.source={source_run}", "transfer.demo_episodes=1")
    env = make_env(TASK)
    agent = make_agent(env, cfg)
    return agent, get_method(method).build(cfg, agent, env, resuming=False)


def test_model_reuse_plus_demonstrations_loads_the_weights_and_mixes_the_batches(source_run):
    agent, transfer = _build("model-reuse+demonstrations", source_run)
    assert all(torch.all(p == 0.25) for p in agent.loss.actor_network_params.values(True, True))
    assert transfer.batches is not None and transfer.loss_terms is not None
    assert set(transfer.files) == {"model_reuse.txt"}
    assert transfer.summary["demonstration_frames"] > 0
    assert transfer.policy is None and transfer.mixer is None and transfer.train_transforms == []


def test_shaping_plus_policy_reuse_keeps_the_transform_and_the_mixer(source_run):
    _, transfer = _build("reward-shaping+policy-reuse", source_run)
    # the shaping transform, then the mixer's primer (which carries the episode's choice of past policy)
    assert [type(t).__name__ for t in transfer.train_transforms] == ["PotentialShaping", "TensorDictPrimer"]
    assert set(transfer.train_transforms[1].primers.keys()) == {"reuse_index"}
    assert transfer.mixer is not None and transfer.on_frames is not None


def test_every_part_is_told_the_frames():
    told = []
    a = TransferMethod("a", "", lambda *a, **k: Transfer(on_frames=lambda n: told.append(("a", n))))
    b = TransferMethod("b", "", lambda *a, **k: Transfer(on_frames=lambda n: told.append(("b", n))))
    combine(a, b).build({}, None, None, resuming=False).on_frames(96)
    assert told == [("a", 96), ("b", 96)]


@pytest.mark.parametrize("method, sentence", [
    ("policy-reuse+jumpstart", "policy-reuse and jumpstart both set the collector's policy"),
    ("reward-shaping+reward-shaping", "two or more different methods"),
    ("none+model-reuse", "none of them 'none'"),
    ("reward-shaping+bogus", "unknown transfer method 'bogus'"),
])
def test_a_conflicting_combination_is_one_sentence(method, sentence):
    with pytest.raises(UsageError, match=sentence):
        _cfg(f"transfer.method={method}")


def test_the_parts_options_and_learners_are_joined():
    method = get_method("value-shaping+demonstrations")
    assert method.algos == ("sac", "td3") and method.source == "run"
    assert {"value_scale", "demo_ratio", "bc_weight"} <= set(method.options)
    assert get_method("reward-shaping+policy-reuse").source == "policy"
    assert get_method("reward-shaping+demonstrations").algos == ("sac", "td3", "soc")
    assert config_lib.resolve({}, [*SMALL, "transfer.method=reward-shaping+demonstrations"], task=TASK, algo="soc")
    with pytest.raises(UsageError, match="works with algo sac or td3, not 'soc'"):
        config_lib.resolve({}, [*SMALL, "transfer.method=value-shaping+demonstrations"], task=TASK, algo="soc")


def test_a_demonstrator_cannot_feed_a_method_that_reuses_weights(tmp_path, capsys):
    code = main(["train", "lift", "--run-dir", str(tmp_path / "r"), "--no-progress",
                 "-o", "transfer.method=model-reuse+demonstrations", "-o", "transfer.source=demonstrator:lift"])
    assert code == 2
    assert "a demonstrator has no weights to reuse; model-reuse+demonstrations needs a source run directory" \
        in capsys.readouterr().err
    assert not (tmp_path / "r").exists()


def test_combined_run_trains_and_resumes_with_a_relative_source(source_run, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    args = ["train", TASK, "--frames", "32", "--seed", "1", "--run-dir", "target", "--no-progress",
            *[x for o in [*SMALL, "collector.init_random_frames=16", "eval.every=16", "eval.episodes=2",
                          "log.tensorboard=false", "transfer.method=model-reuse+policy-reuse",
                          f"transfer.source={os.path.relpath(source_run, tmp_path)}"] for x in ("-o", o)]]
    assert main(args) == 0
    saved = yaml.safe_load((tmp_path / "target" / "config.yaml").read_text())
    assert saved["transfer"]["method"] == "model-reuse+policy-reuse"
    assert main([*args, "--resume"]) == 0  # the same relative source is the same run
    assert "differs" not in capsys.readouterr().err


def test_a_sweep_names_combinations_and_refuses_a_conflict():
    from drltg.experiments.spec import parse_spec

    spec = parse_spec({"pairs": ["fourrooms-near"], "methods": ["model-reuse+policy-reuse"], "frames": 100})
    assert spec.methods == ["model-reuse+policy-reuse"]
    with pytest.raises(UsageError, match="sweep spec: transfer.method 'policy-reuse\\+jumpstart': policy-reuse and"):
        parse_spec({"pairs": ["fourrooms-near"], "methods": ["policy-reuse+jumpstart"], "frames": 100})


@pytest.mark.parametrize("method", ["reward-shaping+demonstrations", "demonstrations+reward-shaping"])
def test_shaping_plus_demonstrations_shapes_the_demonstrated_rewards_too(method, source_run, monkeypatch):
    """Either order: the demonstrations are collected through the shaping transform, so every demonstrated
    reward is the task's plus gamma Phi(s') (1 - terminated) - Phi(s), as the learner's own are."""
    import drltg.collectors as collectors
    from drltg.envs import get_task

    collected = []

    def keep(env, policy, episodes, **options):
        collected.append(real(env, policy, episodes, **options))
        return collected[-1]

    real = collectors.collect_demonstrations
    monkeypatch.setattr(collectors, "collect_demonstrations", keep)
    _, transfer = _build(method, source_run)
    data = collected[0]
    from drltg.transforms import PotentialShaping

    spec = get_task(TASK)
    gamma = _cfg().optim.gamma
    phi = PotentialShaping(spec.potential(dict(spec.defaults)), gamma=gamma).potential_of
    reward = data["next", "reward"]
    alive = 1.0 - data["next", "terminated"].float()
    shaping = gamma * phi(data["next"]).reshape(reward.shape) * alive - phi(data).reshape(reward.shape)
    assert torch.allclose(reward, data["next", "task_reward"] + shaping)
    assert not torch.equal(reward, data["next", "task_reward"])
    assert len(transfer.train_transforms) == 1  # the learner's env is shaped once, by the shaping part
