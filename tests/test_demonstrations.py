"""Learning from demonstrations: collecting demonstrator episodes and the mixed batches."""
import json

import pytest
import torch
from tensordict import TensorDict
from tensordict.nn import TensorDictModule
from torchrl.data import LazyTensorStorage, ReplayBuffer

from drltg.envs import make_env
from drltg.methods.demonstrations import collect_demonstrations, demonstration_buffer, mixed_batches


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
from drltg.train import read_eval_csv, train  # noqa: E402

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
    weights = [torch.load(run / "checkpoints" / "last.pt", weights_only=False)["loss"] for run in (a, b, c)]
    same = [all(torch.equal(w[k], weights[0][k]) for k in w) for w in weights]
    assert same == [True, True, False]  # the same demonstrations each time; the updates saw them


def test_demonstrations_need_a_learner_without_options():
    with pytest.raises(UsageError, match="which works with algo sac or td3, not .soc."):
        config_lib.resolve({}, TINY + ["transfer.method=demonstrations"], task="fourrooms/northeast", algo="soc")


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
