"""Learning from demonstrations: collecting demonstrator episodes and the mixed batches."""
import pytest
import torch
from tensordict import TensorDict
from tensordict.nn import TensorDictModule
from torchrl.data import LazyTensorStorage, ReplayBuffer

from drltg.collectors.demonstrations import collect_demonstrations, demonstration_buffer, mixed_batches
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
