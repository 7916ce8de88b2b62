"""The training loop's speed-ups leave results unchanged: the same draws, the same loss values and
gradients (to float32 rounding), bit-identical optimizer and target updates, the same curve."""
import functools

import pytest
import torch
from tensordict import TensorDict
from torchrl.data import LazyTensorStorage, ReplayBuffer

import drltg.train as train_mod
from drltg import config as config_lib
from drltg.agents import make_agent
from drltg.envs import make_env
from drltg.fast import DirectSACForward, UpdateStep, loss_total, sample_batches, soft_update_fn
from drltg.train import read_eval_csv, train

TASK = "fourrooms/northeast"


@pytest.fixture(autouse=True)
def one_thread():
    """Small nets on a shared machine: one thread, as ``train`` runs them (cfg ``threads``)."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


def agent_for(algo="sac", task=TASK, hidden=(32, 32), seed=0, **explicit):
    cfg = config_lib.resolve({}, [f"network.hidden={list(hidden)}"], task=task, algo=algo, **explicit)
    torch.manual_seed(seed)
    return make_agent(make_env(task, seed=0, **cfg["env"]), cfg)


def random_batch(n=64, obs=2, act=2, seed=1, terminated_every=5):
    g = torch.Generator().manual_seed(seed)
    terminated = (torch.arange(n) % terminated_every == 0).unsqueeze(-1)
    return TensorDict(
        {
            "observation": torch.rand(n, obs, generator=g) * 2 - 1,
            "action": torch.rand(n, act, generator=g) * 2 - 1,
            "next": {
                "observation": torch.rand(n, obs, generator=g) * 2 - 1,
                "reward": torch.randn(n, 1, generator=g),
                "terminated": terminated,
                "done": terminated.clone(),
            },
        },
        [n],
    )


def close(a, b):
    return torch.allclose(a, b, rtol=1e-5, atol=1e-6)


def test_direct_forward_matches_sacloss_values_gradients_and_draws():
    ref, fast = agent_for(), agent_for()
    direct = DirectSACForward.for_loss(fast.loss)
    assert direct is not None
    batch = random_batch()
    b_ref, b_fast = batch.clone(), batch.clone()
    torch.manual_seed(7)
    out_ref = ref.loss(b_ref)
    after_ref = torch.rand(4)
    torch.manual_seed(7)
    out_fast = direct(b_fast)
    after_fast = torch.rand(4)
    assert torch.equal(after_ref, after_fast)  # the same number of random draws, in the same order
    assert set(out_ref.keys()) == set(out_fast.keys())
    for key in out_ref.keys():
        assert close(out_ref[key], out_fast[key]), key
    assert close(b_ref["td_error"], b_fast["td_error"])
    loss_total(out_ref).backward()
    loss_total(out_fast).backward()
    grads = dict(fast.loss.named_parameters())
    for name, p in ref.loss.named_parameters():
        assert close(p.grad, grads[name].grad), name


def test_direct_forward_only_where_it_is_exact():
    assert DirectSACForward.for_loss(agent_for("td3").loss) is None
    assert DirectSACForward.for_loss(agent_for("soc").loss) is None
    assert DirectSACForward.for_loss(agent_for("sac", task="gridrooms/northeast").loss) is None  # discrete SAC
    agent = agent_for()
    direct = DirectSACForward.for_loss(agent.loss)
    weighted = random_batch().set("priority_weight", torch.linspace(0.1, 1.0, 64))
    torch.manual_seed(3)
    expected = agent.loss(weighted.clone())
    torch.manual_seed(3)
    got = direct(weighted.clone())  # prioritised weights: TorchRL's own forward, exactly
    assert all(torch.equal(expected[k], got[k]) for k in expected.keys())


def test_soft_update_fn_is_softupdate_bit_for_bit():
    a, b = agent_for(), agent_for()
    for loss in (a.loss, b.loss):
        with torch.no_grad():
            for p in loss.qvalue_network_params.values(True, True):
                p.add_(0.5)
    step = soft_update_fn(b.target_updater)
    for _ in range(3):
        a.target_updater.step()
        step()
    targets_b = b.loss.target_qvalue_network_params
    for key, t in a.loss.target_qvalue_network_params.items(True, True):
        assert torch.equal(t, targets_b[key]), key
    assert not torch.equal(t, a.loss.qvalue_network_params[key])  # the targets did move, only part way


def test_agent_adam_is_the_for_loop_adam_bit_for_bit():
    agent = agent_for()
    params = [p.detach().clone().requires_grad_() for p in agent.loss.parameters()]
    reference = torch.optim.Adam(params, lr=3e-4, foreach=False)
    g = torch.Generator().manual_seed(0)
    for _ in range(5):
        for p, q in zip(agent.loss.parameters(), params):
            p.grad = torch.randn(p.shape, generator=g)
            q.grad = p.grad.clone()
        agent.optimizer.step()
        reference.step()
    assert all(torch.equal(p, q) for p, q in zip(agent.loss.parameters(), params))


def test_sample_batches_draws_what_repeated_sampling_draws():
    buffer = ReplayBuffer(storage=LazyTensorStorage(1000), batch_size=32)
    buffer.extend(TensorDict({"i": torch.arange(700)}, [700]))
    torch.manual_seed(11)
    one_by_one = [buffer.sample()["i"] for _ in range(8)]
    torch.manual_seed(11)
    at_once = [b["i"] for b in sample_batches(buffer, 8)]
    assert len(at_once) == 8 and all(b.shape == (32,) for b in at_once)
    assert all(torch.equal(x, y) for x, y in zip(one_by_one, at_once))


@pytest.mark.parametrize("algo", ["sac", "td3"])
def test_update_step_follows_the_reference_step(algo):
    """Twenty gradient steps on the same batches: parameters and losses stay equal to rounding
    (bit for bit for TD3, which has no direct path), actor delay included."""
    ref, fast = agent_for(algo), agent_for(algo)
    ref_step, fast_step = UpdateStep(ref, direct=False), UpdateStep(fast)
    for i in range(20):
        batch = random_batch(seed=100 + i)
        delay = i % ref.actor_delay == 0
        torch.manual_seed(i)
        lr = ref_step(batch.clone(), update_actor=delay)
        torch.manual_seed(i)
        lf = fast_step(batch.clone(), update_actor=delay)
        for key in lr.keys():
            assert close(lr[key], lf[key]), (i, key)
    same = torch.equal if algo == "td3" else functools.partial(torch.allclose, rtol=1e-4, atol=1e-6)
    fast_params = dict(fast.loss.named_parameters())
    for name, p in ref.loss.named_parameters():
        assert same(p, fast_params[name]), name
    for (name, t), u in zip(ref.loss.named_buffers(), fast.loss.buffers()):
        assert same(t, u), name


TINY = [
    "network.hidden=[16,16]",
    "collector.num_envs=4",
    "collector.frames_per_batch=16",
    "collector.init_random_frames=256",
    "optim.updates_per_batch=4",
    "buffer.batch_size=32",
    "eval.every=512",
    "eval.episodes=4",
    "checkpoint.every=1024",
    "log.every=256",
    "log.tensorboard=false",
]


def test_training_curve_unchanged(tmp_path, monkeypatch):
    """A short run gives the same evaluation curve with the fast step as with TorchRL's own
    forward, target update and one ``sample()`` per step."""
    cfg = config_lib.resolve({}, TINY, task=TASK, frames=1024, seed=5)
    fast = read_eval_csv(train(cfg, tmp_path / "fast", progress=False) / "eval.csv")
    monkeypatch.setattr(train_mod, "UpdateStep", functools.partial(UpdateStep, direct=False))
    monkeypatch.setattr(train_mod, "sample_batches", lambda buffer, n: [buffer.sample() for _ in range(n)])
    reference = read_eval_csv(train(cfg, tmp_path / "reference", progress=False) / "eval.csv")
    assert [r["frames"] for r in fast] == [0, 512, 1024]
    assert fast == reference
