"""Every learner is built and stepped the same way, and that way is TorchRL's own: the losses as built
(critic copies in a loop, ``deactivate_vmap=True``) give TorchRL's default (``torch.vmap``) losses,
gradients and random draws; ``UpdateStep`` is the sota loop; ``sample_batches`` draws what repeated
sampling draws; the training curve is that of the reference step."""

import os
import subprocess
import sys

import pytest
import torch
from tensordict import TensorDict
from torchrl.data import LazyTensorStorage, ReplayBuffer

import drltg.training.loop as train_mod
from drltg import config as config_lib
from drltg import learners
from drltg.envs import make_env
from drltg.learners import UpdateStep, loss_total, make_agent, sample_batches
from drltg.training.loop import read_eval_csv, train

TASK = "fourrooms/northeast"
LEARNERS = {  # name: (algo, task)
    "sac": ("sac", TASK),
    "discrete_sac": ("sac", "gridrooms/northeast"),
    "td3": ("td3", TASK),
    "soc": ("soc", TASK),
}


@pytest.fixture(autouse=True)
def one_thread():
    """Small nets on a shared machine: one thread, as ``train`` runs them (cfg ``threads``)."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


def agent_for(algo="sac", task=TASK, hidden=(32, 32), seed=0, vmap=False, device="cpu", **explicit):
    """The agent of ``algo`` as drltg builds it; ``vmap=True``: with TorchRL's default ``torch.vmap`` critics."""
    overrides = [f"network.hidden={list(hidden)}", f"device={device}"]
    overrides += ["soc.num_options=3"] if algo == "soc" else []
    cfg = config_lib.resolve({}, overrides, task=task, algo=algo, **explicit)
    torch.manual_seed(seed)
    deactivate = learners.DEACTIVATE_VMAP
    learners.DEACTIVATE_VMAP = not vmap
    try:
        return make_agent(make_env(task, seed=0, device=cfg.device, **cfg.env), cfg)
    finally:
        learners.DEACTIVATE_VMAP = deactivate


def random_batch(task=TASK, n=64, seed=1, options=3):
    """``n`` random transitions of ``task`` (random actions from random states), with random rewards, every
    fifth one terminal, and a random option."""
    env = make_env(task, batch_size=(n,), seed=seed)
    torch.manual_seed(seed)
    td = env.rand_step(env.reset())
    g = torch.Generator().manual_seed(seed)
    terminated = (torch.arange(n) % 5 == 0).unsqueeze(-1)
    td.set(("next", "reward"), torch.randn(n, 1, generator=g))
    td.set(("next", "terminated"), terminated)
    td.set(("next", "done"), terminated.clone())
    td.set("option", torch.randint(options, (n, 1), generator=g))
    return td


def close(a, b):
    return torch.allclose(a, b, rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize("name", LEARNERS)
def test_loss_as_built_is_torchrl_default_loss(name):
    """Same loss values, TD errors, gradients and random draws as with TorchRL's ``torch.vmap`` critics."""
    algo, task = LEARNERS[name]
    ref, built = agent_for(algo, task, vmap=True), agent_for(algo, task)
    assert not ref.loss.deactivate_vmap and built.loss.deactivate_vmap
    batch = random_batch(task)
    b_ref, b_built = batch.clone(), batch.clone()
    torch.manual_seed(7)
    out_ref = ref.loss(b_ref)
    after_ref = torch.rand(4)
    torch.manual_seed(7)
    out_built = built.loss(b_built)
    after_built = torch.rand(4)
    assert torch.equal(after_ref, after_built)  # the same number of random draws, in the same order
    assert set(out_ref.keys()) == set(out_built.keys())
    for key in out_ref.keys():
        assert close(out_ref[key], out_built[key]), key
    assert close(b_ref["td_error"], b_built["td_error"])
    loss_total(out_ref).backward()
    loss_total(out_built).backward()
    grads = dict(built.loss.named_parameters())
    for param_name, p in ref.loss.named_parameters():
        if p.grad is None:
            assert grads[param_name].grad is None, param_name
        else:
            assert close(p.grad, grads[param_name].grad), param_name


def test_every_learner_has_the_same_optimiser_and_target_update():
    for name, (algo, task) in LEARNERS.items():
        agent = agent_for(algo, task)
        assert agent.loss.deactivate_vmap, name
        assert type(agent.optimizer) is torch.optim.Adam and agent.optimizer.defaults["foreach"], name
        assert type(agent.target_updater).__name__ == "SoftUpdate", name


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


def sota_step(agent, batch, update_actor):
    """TorchRL's sota SAC loop, written out: loss, backward, Adam step, soft target update."""
    losses = agent.loss(batch)
    agent.optimizer.zero_grad(set_to_none=True)
    sum(v for k, v in losses.items() if k.startswith("loss_") and (update_actor or k != "loss_actor")).backward()
    agent.optimizer.step()
    if update_actor:
        agent.target_updater.step()
    return losses.detach()


@pytest.mark.parametrize("name", LEARNERS)
def test_update_step_follows_the_reference_step(name):
    """Twenty gradient steps on the same batches: ``UpdateStep`` on the agent as built against the sota
    loop on TorchRL's default (vmap) losses; losses, parameters and buffers stay equal to rounding, the
    actor delay included."""
    algo, task = LEARNERS[name]
    ref, built = agent_for(algo, task, vmap=True), agent_for(algo, task)
    step = UpdateStep(built)
    for i in range(20):
        batch = random_batch(task, seed=100 + i)
        update_actor = i % ref.actor_delay == 0
        torch.manual_seed(i)
        lr = sota_step(ref, batch.clone(), update_actor)
        torch.manual_seed(i)
        lb = step(batch.clone(), update_actor=update_actor)
        for key in lr.keys():
            assert close(lr[key], lb[key]), (i, key)
    built_params = dict(built.loss.named_parameters())
    for param_name, p in ref.loss.named_parameters():
        assert torch.allclose(p, built_params[param_name], rtol=1e-4, atol=1e-6), param_name
    for (buffer_name, t), u in zip(ref.loss.named_buffers(), built.loss.buffers()):
        assert torch.allclose(t, u, rtol=1e-4, atol=1e-6), buffer_name


@pytest.mark.parametrize("name", LEARNERS)
def test_a_learner_reads_only_the_sections_of_its_algorithm(name):
    """A report takes a difference in a section that a run's algorithm does not read (``ALGO_SECTIONS``) for
    no difference at all: building a learner and stepping it must never read one."""
    from drltg.config.sections import ALGO_SECTIONS

    class Unread:
        def __getattr__(self, key):
            if key.startswith("__"):
                raise AttributeError(key)
            raise AssertionError(f"{name} read {key} of a section its algorithm does not read")

    algo, task = LEARNERS[name]
    cfg = config_lib.resolve({}, ["network.hidden=[32, 32]"], task=task, algo=algo)
    unread = {s for sections in ALGO_SECTIONS.values() for s in sections} - set(ALGO_SECTIONS[algo])
    assert unread, algo
    cfg = cfg.model_copy(update={s: Unread() for s in unread})
    agent = make_agent(make_env(task, seed=0, **cfg.env), cfg)
    UpdateStep(agent)(random_batch(task), update_actor=True)


cuda = pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")


@cuda
@pytest.mark.parametrize("cudagraphs", [False, True])
@pytest.mark.parametrize("name", LEARNERS)
def test_every_learner_builds_and_updates_on_cuda(name, cudagraphs):
    """Built on the env's device; five steps, the last two replayed from a captured graph with
    ``cudagraphs`` (three eager warm-ups, then the capture)."""
    algo, task = LEARNERS[name]
    agent = agent_for(algo, task, device="cuda")
    assert {p.device.type for p in agent.loss.parameters()} == {"cuda"}
    step = UpdateStep(agent, cudagraphs=cudagraphs)
    for i in range(5):
        before = [p.detach().clone() for p in agent.loss.parameters()]
        losses = step(random_batch(task, seed=i).to("cuda"))
        assert all(torch.isfinite(v).all() for v in losses.values())
        assert any(not torch.equal(a, b) for a, b in zip(before, agent.loss.parameters())), i


@cuda
@pytest.mark.parametrize("cudagraphs", ["false", "true"])
def test_a_run_trains_and_evaluates_on_cuda(tmp_path, cudagraphs):
    cfg = config_lib.resolve({}, TINY + ["device=cuda", f"optim.cudagraphs={cudagraphs}"], task=TASK, frames=1024,
                             seed=5)
    rows = read_eval_csv(train(cfg, tmp_path / "run", progress=False) / "eval.csv")
    assert [r["frames"] for r in rows] == [0, 512, 1024]


def test_update_step_is_the_sota_loop_bit_for_bit():
    """On one and the same loss, ``UpdateStep`` is exactly the sota loop (TD3: with its policy delay)."""
    ref, built = agent_for("td3"), agent_for("td3")
    step = UpdateStep(built)
    for i in range(6):
        batch = random_batch(seed=200 + i)
        torch.manual_seed(i)
        sota_step(ref, batch.clone(), i % 2 == 0)
        torch.manual_seed(i)
        step(batch.clone(), update_actor=i % 2 == 0)
    assert all(torch.equal(p, q) for p, q in zip(ref.loss.parameters(), built.loss.parameters()))
    assert all(torch.equal(p, q) for p, q in zip(ref.loss.buffers(), built.loss.buffers()))


def test_losses_import_nothing_from_the_learners():
    code = "import sys, drltg.losses, drltg.modules; print('drltg.learners' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


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
    """A short run gives the same evaluation curve as with TorchRL's default (vmap) losses and one
    ``sample()`` per step."""
    cfg = config_lib.resolve({}, TINY, task=TASK, frames=1024, seed=5)
    built = read_eval_csv(train(cfg, tmp_path / "built", progress=False) / "eval.csv")
    monkeypatch.setattr(learners, "DEACTIVATE_VMAP", False)
    monkeypatch.setattr(train_mod, "sample_batches", lambda buffer, n: [buffer.sample() for _ in range(n)])
    reference = read_eval_csv(train(cfg, tmp_path / "reference", progress=False) / "eval.csv")
    assert [r["frames"] for r in built] == [0, 512, 1024]
    assert built == reference


@pytest.mark.parametrize("layer_norm, critic, actor", [("none", 0, 0), ("critics", 2, 0), ("all", 2, 2)])
@pytest.mark.parametrize("algo", ["sac", "td3"])
def test_layer_norm_goes_after_every_hidden_layer_of_the_networks_asked(algo, layer_norm, critic, actor):
    from torch import nn

    cfg = config_lib.resolve({}, ["network.hidden=[8,8]", f"network.layer_norm={layer_norm}"],
                             task="fourrooms/northeast", algo=algo)
    loss = make_agent(make_env("fourrooms/northeast"), cfg).loss
    count = lambda module: sum(isinstance(m, nn.LayerNorm) for m in module.modules())  # noqa: E731
    assert (count(loss.qvalue_network), count(loss.actor_network)) == (critic, actor)
    layers = list(loss.qvalue_network.module.modules()) if critic else []
    kinds = [type(m).__name__ for m in layers if type(m).__name__ in ("Linear", "LayerNorm", "ReLU")]
    assert kinds[:3] == (["Linear", "LayerNorm", "ReLU"] if critic else [])


def test_layer_norm_is_refused_for_the_soft_option_critic():
    from drltg.errors import UsageError

    with pytest.raises(UsageError, match="network.layer_norm applies to sac and td3"):
        config_lib.resolve({}, ["network.layer_norm=critics"], task="fourrooms/northeast", algo="soc")


USER_LOOP = """
import torch
from drltg import UpdateStep, make_agent, make_env, resolve

if torch.get_num_threads() == 1:
    torch.set_num_threads(2)  # a one-core machine: as torch's default is on two
default = torch.get_num_threads()

env = make_env("fourrooms/northeast", batch_size=(8,), seed=0)
agent = make_agent(env, resolve(task="fourrooms/northeast"))
seen = []
agent.loss.qvalue_network.register_forward_pre_hook(lambda module, args: seen.append(torch.get_num_threads()))
update = UpdateStep(agent)
for _ in range(2):
    update(env.rollout(32, break_when_any_done=False).reshape(-1))
print(sorted(set(seen)), torch.get_num_threads() == default > 1)
"""


def test_a_users_own_loop_updates_in_one_thread_without_asking():
    """A script that never calls ``torch.set_num_threads`` (torch's default: a thread per core): its
    ``UpdateStep`` runs in one thread (many threads on small networks are many times slower once a core
    is busy, ``python -m benchmarks threads``) and leaves the process's setting as it found it."""
    env = {k: v for k, v in os.environ.items() if k not in ("OMP_NUM_THREADS", "MKL_NUM_THREADS")}
    out = subprocess.run([sys.executable, "-c", USER_LOOP], capture_output=True, text=True, env=env, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split("\n")[-2] == "[1] True"


def test_update_step_threads_none_keeps_torchs_setting():
    agent = agent_for("sac")
    seen = []
    agent.loss.qvalue_network.register_forward_pre_hook(lambda module, args: seen.append(torch.get_num_threads()))
    before = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        UpdateStep(agent, threads=None)(random_batch())
        UpdateStep(agent, threads=3)(random_batch())
        assert set(seen[:1]) == {2} and set(seen[-1:]) == {3} and torch.get_num_threads() == 2
    finally:
        torch.set_num_threads(before)
