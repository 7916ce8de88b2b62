"""Seed groups: one vmapped update equals each seed's own update; a group is reproducible, its seeds differ
from each other, and grouped or not a config gives the same distribution of results; group runs."""
import copy

import pytest
import torch
from torchrl.envs import ExplorationType, TransformedEnv, set_exploration_type

from drltg import config as config_lib
from drltg.learners import UpdateStep, make_agent
from drltg.training.loop import build_env
from drltg.training.seeds import SeedGroup

SMALL = ["network.hidden=[16,16]"]
LEARNERS = [("gridrooms/northeast", "sac"), ("fourrooms/northeast", "sac"), ("fourrooms/northeast", "td3"),
            ("fourrooms/northeast", "soc")]


def _agents_and_batches(task, algo, seeds=3, batch=32):
    cfg = config_lib.resolve({}, SMALL, task=task, algo=algo)
    probe = build_env(cfg, seed=0)
    agents = []
    for seed in range(seeds):
        torch.manual_seed(seed)
        agents.append(make_agent(probe, cfg))
    env = TransformedEnv(build_env(cfg, batch_size=(16,), seed=1))
    for t in agents[0].env_transforms:
        env.append_transform(t.clone())
    torch.manual_seed(5)
    data = env.rollout(8, break_when_any_done=False).reshape(-1)
    batches = [data[torch.randperm(data.numel())[:batch]] for _ in range(seeds)]
    return agents, batches


@pytest.mark.parametrize("task, algo", LEARNERS)
@pytest.mark.parametrize("update_actor", [True, False])
def test_one_vmapped_update_is_each_seeds_own_update(task, algo, update_actor):
    agents, batches = _agents_and_batches(task, algo)
    group = SeedGroup(agents, randomness="same")  # stacks copies: the agents keep their parameters
    torch.manual_seed(11)
    grouped = group.update(torch.stack(batches), update_actor=update_actor)
    group_grads = [p.grad for p in group.optimizer.param_groups[0]["params"]]
    for k, (agent, batch) in enumerate(zip(agents, batches)):
        torch.manual_seed(11)  # the same random draws as the group's shared ("same") draw
        single = UpdateStep(agent)(batch, update_actor=update_actor)
        assert sorted(single.keys()) == sorted(grouped.keys())
        for key in single.keys():
            torch.testing.assert_close(grouped[key][k], single[key], atol=1e-5, rtol=1e-5)
        for (name, p), g in zip(agent.loss.named_parameters(), group_grads):
            assert (p.grad is None) == (g is None), name
            if g is not None:
                torch.testing.assert_close(g[k], p.grad, atol=1e-5, rtol=1e-5)
        after = {name: value for name, value in agent.loss.state_dict().items()}
        for name, value in after.items():
            stacked = group.params.get(tuple(name.split(".")))
            torch.testing.assert_close(stacked[k], value, atol=1e-5, rtol=1e-5, msg=name)


def test_the_actors_tanh_normal_draws_torchrls_numbers_and_vmap_draws_one_per_seed():
    from torchrl.modules import TanhNormal as TorchRLTanhNormal

    from drltg.modules import TanhNormal

    loc, scale, low, high = torch.randn(5, 3), torch.rand(5, 3) + 0.1, -torch.ones(3), 2 * torch.ones(3)
    draws = []
    for cls in (TorchRLTanhNormal, TanhNormal):
        torch.manual_seed(0)
        dist = cls(loc, scale, low=low, high=high)
        draws.append((dist.rsample(), *dist.rsample_and_log_prob(), dist.rsample((4,))))
    for ours, theirs in zip(*draws):
        assert torch.equal(ours, theirs)
    per_seed = torch.vmap(lambda m, s: TanhNormal(m, s).rsample(), randomness="different")(
        torch.zeros(2, 5, 3), torch.ones(2, 5, 3))
    assert not torch.equal(per_seed[0], per_seed[1])


@pytest.mark.parametrize("algo", ["sac", "td3"])
def test_the_groups_soft_update_moves_every_seeds_targets_toward_its_own_parameters(algo):
    agents, _ = _agents_and_batches("fourrooms/northeast", algo, seeds=2)
    group = SeedGroup(agents)
    keys = [k for k in group.params.keys(True, True) if k[0].startswith("target_")
            and isinstance(group.params.get((k[0][len("target_"):], *k[1:])), torch.nn.Parameter)]
    assert keys
    before = {k: group.params.get(k).clone() for k in keys}
    with torch.no_grad():
        for k in keys:
            shift = torch.arange(2.0).reshape(2, *[1] * (before[k].dim() - 1))
            group.params.get((k[0][len("target_"):], *k[1:])).add_(shift)
    group.step.agent.target_updater.step()
    tau = 1 - agents[0].target_updater.eps
    for k in keys:
        source = group.params.get((k[0][len("target_"):], *k[1:]))
        torch.testing.assert_close(group.params.get(k), before[k] + tau * (source - before[k]), rtol=0, atol=1e-7)


def test_different_randomness_draws_independent_noise_per_seed():
    agents, batches = _agents_and_batches("fourrooms/northeast", "sac", seeds=1)
    twins = [agents[0], copy.deepcopy(agents[0])]  # identical parameters and batch: only the noise can differ
    group = SeedGroup(twins, randomness="different")
    losses = group.update(torch.stack([batches[0], batches[0]]))
    assert losses["loss_actor"][0] != losses["loss_actor"][1]
    same = SeedGroup(twins, randomness="same").update(torch.stack([batches[0], batches[0]]))
    assert same["loss_actor"][0] == same["loss_actor"][1]


def _action_change(agent, obs, before):
    with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
        return float((agent.actor(obs.clone())["action"] - before).norm())


def _actions(agent, obs):
    with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
        return agent.actor(obs.clone())["action"]


def _changes(seeds, data, obs, grouped, lr=None, updates=5, batch=32):
    """Each seed's change of its deterministic action on ``obs`` after ``updates`` SAC updates on minibatches
    of ``data``, its seeds trained alone (``UpdateStep``) or as one group."""
    cfg = config_lib.resolve({}, SMALL + ([f"optim.lr={lr}"] if lr else []), task="fourrooms/northeast", algo="sac")
    probe = build_env(cfg, seed=0)
    agents = []
    for seed in seeds:
        torch.manual_seed(seed)
        agents.append(make_agent(probe, cfg))
    before = [_actions(a, obs) for a in agents]
    if grouped:
        torch.manual_seed(seeds[0])
        group = SeedGroup(agents)
        for _ in range(updates):
            group.update(torch.stack([data[torch.randint(data.numel(), (batch,))] for _ in seeds]))
        group.sync()
    else:
        for seed, agent in zip(seeds, agents):
            torch.manual_seed(seed)
            step = UpdateStep(agent)
            for _ in range(updates):
                step(data[torch.randint(data.numel(), (batch,))])
    return [_action_change(a, obs, b) for a, b in zip(agents, before)]


def test_grouped_or_alone_a_config_gives_the_same_distribution_of_updates():
    """Over 20 seeds each way (disjoint seed sets, so the samples are independent), the change of each seed's
    deterministic action after 5 updates has the same distribution grouped as alone (two-sample exact KS
    test at 1%); the same test tells apart a group with ten times the learning rate."""
    from scipy.stats import ks_2samp

    env = TransformedEnv(build_env(config_lib.resolve({}, SMALL, task="fourrooms/northeast"), batch_size=(16,), seed=1))
    torch.manual_seed(5)
    data = env.rollout(8, break_when_any_done=False).reshape(-1)
    obs = data[:8].select("observation")
    alone = _changes(range(20), data, obs, grouped=False)
    grouped = _changes(range(100, 120), data, obs, grouped=True)
    assert ks_2samp(alone, grouped, method="exact").pvalue > 0.01
    faster = _changes(range(100, 120), data, obs, grouped=True, lr=3e-3)
    assert ks_2samp(alone, faster, method="exact").pvalue < 0.01


def test_the_seeds_of_a_group_start_in_different_envs_and_explore_apart():
    from drltg.training.seeds import GroupPolicy, _group_env

    cfg = tiny_cfg()
    env = _group_env(cfg, [3, 103], 4, 0)
    starts = env.reset()["position"].reshape(2, 4, 2)
    assert not torch.equal(starts[0], starts[1])
    torch.manual_seed(0)
    agent = make_agent(build_env(cfg, seed=0), cfg)
    twins = SeedGroup([agent, copy.deepcopy(agent)])  # identical parameters: only the noise can differ
    policy = GroupPolicy(agent.actor, twins.params["actor_network_params"])
    obs = env.reset()[:4]
    with set_exploration_type(ExplorationType.RANDOM):
        actions = policy(torch.cat([obs, obs]).clone())["action"].reshape(2, 4, 2)
    assert not torch.equal(actions[0], actions[1])


# ------------------------------------------------------------------------------------- group runs
TINY = ["network.hidden=[16,16]", "collector.num_envs=4", "collector.frames_per_batch=16",
        "collector.init_random_frames=128", "optim.updates_per_batch=1", "buffer.batch_size=32", "eval.every=256",
        "eval.episodes=4", "checkpoint.every=256", "log.every=128", "log.tensorboard=false"]


def tiny_cfg(**kw):
    return config_lib.resolve({}, TINY, **{"task": "fourrooms/northeast", "frames": 512, "seed": 3, **kw})


@pytest.fixture(scope="module")
def group_run(tmp_path_factory):
    from drltg.training.seeds import train_seeds

    root = tmp_path_factory.mktemp("group")
    train_seeds(tiny_cfg(), root, 2, progress=False)
    return root


def test_a_group_writes_one_ordinary_run_directory_per_seed(group_run):
    import json

    import yaml

    from drltg.store.rundir import read_eval_csv

    assert sorted(p.name for p in group_run.iterdir()) == ["seed-103", "seed-3"]
    for seed in (3, 103):
        run = group_run / f"seed-{seed}"
        assert yaml.safe_load((run / "config.yaml").read_text()) == tiny_cfg(seed=seed).model_dump()
        rows = read_eval_csv(run / "eval.csv")
        assert [r["frames"] for r in rows] == [0, 256, 512]
        summary = json.loads((run / "summary.json").read_text())
        assert summary["seed"] == seed and summary["seed_group"] == {"seeds": [3, 103]}
        assert summary["final_eval"] == rows[-1]


def test_a_group_is_reproduced_by_the_same_group(group_run, tmp_path):
    from drltg.training.seeds import train_seeds

    train_seeds(tiny_cfg(), tmp_path, 2, progress=False)
    curves = []
    for seed in (3, 103):
        name = f"seed-{seed}/eval.csv"
        assert (tmp_path / name).read_text() == (group_run / name).read_text()
        ckpt, again = (torch.load(d / f"seed-{seed}" / "checkpoints" / "last.pt", weights_only=True)
                       for d in (group_run, tmp_path))
        for key, value in ckpt["loss"].items():
            assert torch.equal(value, again["loss"][key]), key
        curves.append((group_run / name).read_text())
    assert curves[0] != curves[1]  # the seeds of one group are different runs


def test_a_group_resumes_from_its_seeds_checkpoints(group_run, tmp_path, monkeypatch):
    import drltg.training.loop as loop
    from drltg.store.rundir import read_eval_csv
    from drltg.training.seeds import train_seeds

    real, calls = loop._episode_stats, {"n": 0}

    def crash_after_first_checkpoint(data, stats):
        calls["n"] += 1
        if (tmp_path / "seed-103" / "checkpoints" / "last.pt").exists():
            raise KeyboardInterrupt
        return real(data, stats)

    monkeypatch.setattr(loop, "_episode_stats", crash_after_first_checkpoint)
    with pytest.raises(KeyboardInterrupt):
        train_seeds(tiny_cfg(), tmp_path, 2, progress=False)
    assert not (tmp_path / "seed-3" / "summary.json").exists()
    monkeypatch.setattr(loop, "_episode_stats", real)
    train_seeds(tiny_cfg(), tmp_path, 2, resume=True, progress=False)
    for seed in (3, 103):
        rows = read_eval_csv(tmp_path / f"seed-{seed}" / "eval.csv")
        ref = read_eval_csv(group_run / f"seed-{seed}" / "eval.csv")
        assert [r["frames"] for r in rows] == [0, 256, 512]
        assert rows[:2] == ref[:2]  # identical up to the checkpoint at 256 frames
        assert (tmp_path / f"seed-{seed}" / "summary.json").is_file()


def test_a_group_stopped_inside_an_evaluation_saves_each_seed_there_and_evaluates_first_on_resume(
        tmp_path, monkeypatch):
    """Ctrl-C inside the group's evaluation at frame 256 (checkpoints every 128): every seed's checkpoint is at
    256, and the resumed group makes that evaluation before it trains the 256 frames left."""
    import os
    import signal

    import drltg.training.loop as loop
    import drltg.training.seeds as seeds_mod
    from drltg.store.rundir import load_checkpoint, read_eval_csv

    real_evaluate, real_stats, calls = seeds_mod.evaluate_seeds, loop._episode_stats, {"n": 0}

    def interrupt_second_evaluation(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] == 2:
            os.kill(os.getpid(), signal.SIGINT)  # held until the evaluation's first step checks for it
        return real_evaluate(*args, **kwargs)

    monkeypatch.setattr(seeds_mod, "evaluate_seeds", interrupt_second_evaluation)
    cfg = config_lib.resolve({}, TINY + ["checkpoint.every=128"], task="fourrooms/northeast", frames=512, seed=3)
    with pytest.raises(KeyboardInterrupt):
        seeds_mod.train_seeds(cfg, tmp_path, 2, progress=False)
    assert [load_checkpoint(tmp_path / f"seed-{s}")["frames"] for s in (3, 103)] == [256, 256]
    trained = []
    monkeypatch.setattr(loop, "_episode_stats", lambda data, stats: (trained.append(data.numel()),
                                                                      real_stats(data, stats)))
    seeds_mod.train_seeds(cfg, tmp_path, 2, resume=True, progress=False)
    assert sum(trained) == 2 * (512 - 256)  # both seeds' pieces of every batch, from frame 256 on
    for seed in (3, 103):
        assert [r["frames"] for r in read_eval_csv(tmp_path / f"seed-{seed}" / "eval.csv")] == [0, 256, 512]


def test_a_method_without_a_grouped_form_trains_its_seeds_one_after_another(tmp_path, capsys):
    from drltg.training.seeds import train_seeds
    from drltg.transfer import Transfer, TransferMethod, register_method
    from drltg.transfer.registry import METHODS

    try:
        register_method(TransferMethod("test-alone", "nothing", lambda *a, **k: Transfer()))
        cfg = tiny_cfg(frames=64, **{"transfer.method": "test-alone", "eval.every": 64})
        dirs = train_seeds(cfg, tmp_path, 2, progress=False)
    finally:
        METHODS.pop("test-alone", None)
    err = capsys.readouterr().err
    assert "transfer method test-alone has no grouped form; training the 2 seeds one after another" in err
    assert [d.name for d in dirs] == ["seed-3", "seed-103"] and all((d / "summary.json").is_file() for d in dirs)


@pytest.mark.parametrize("args, message", [(["--seeds", "0"], "--seeds must be between 1 and 1000, got 0."),
                                           (["--no-group"], "--no-group applies to --seeds N; add --seeds.")])
def test_cli_seed_options_bad_input_is_one_sentence(args, message, tmp_path, capsys):
    from drltg.cli import main

    code = main(["train", "fourrooms/northeast", "--run-dir", str(tmp_path / "runs"), *args])
    err = capsys.readouterr().err
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "runs").exists()


def test_a_seed_of_an_interrupted_group_resumes_alone(group_run, tmp_path, monkeypatch, capsys):
    import drltg.training.loop as loop
    from drltg.store.rundir import read_eval_csv
    from drltg.training.seeds import train_seeds

    real = loop._episode_stats

    def crash_after_first_checkpoint(data, stats):
        if (tmp_path / "seed-103" / "checkpoints" / "last.pt").exists():
            raise KeyboardInterrupt
        return real(data, stats)

    monkeypatch.setattr(loop, "_episode_stats", crash_after_first_checkpoint)
    with pytest.raises(KeyboardInterrupt):
        train_seeds(tiny_cfg(), tmp_path, 2, progress=False)
    monkeypatch.setattr(loop, "_episode_stats", real)
    loop.train(tiny_cfg(seed=103), tmp_path / "seed-103", resume=True, progress=False)  # its checkpoint is a run's
    rows = read_eval_csv(tmp_path / "seed-103" / "eval.csv")
    assert [r["frames"] for r in rows] == [0, 256, 512]
    assert rows[:2] == read_eval_csv(group_run / "seed-103" / "eval.csv")[:2]
    train_seeds(tiny_cfg(), tmp_path, 2, resume=True, progress=False)  # the seeds now differ: one by one
    assert "resuming them one after another" in capsys.readouterr().err
    assert (tmp_path / "seed-3" / "summary.json").is_file()


# ------------------------------------------------------------------------------- experiments
def test_runs_that_differ_only_in_their_seed_form_one_unit(tmp_path):
    from drltg.experiments.executor import Run, seed_groups

    def run(name, needs=None, **kw):
        return Run("baseline", tiny_cfg(**kw), tmp_path / name, tmp_path / f"{name}.log", needs)

    baseline = [run("b0", seed=0), run("b100", seed=100)]
    source = [run("s50", seed=50, task="fourrooms/southwest"), run("s150", seed=150, task="fourrooms/southwest")]
    transfer = [run("t0", needs=tmp_path / "s50", seed=0), run("t100", needs=tmp_path / "s150", seed=100)]
    soc = [run("o0", seed=0, algo="soc"), run("o100", seed=100, algo="soc")]  # grouped too
    shaped = [run("r0", seed=0, **{"transfer.method": "reward-shaping"}),
              run("r100", seed=100, **{"transfer.method": "reward-shaping"})]
    reused = [run(f"p{s}", needs=tmp_path / f"s{s + 50}", seed=s,
                  **{"transfer.method": "demonstrations", "transfer.source": str(tmp_path / f"s{s + 50}")})
              for s in (0, 100)]  # each seed's demonstrations and behaviour-cloning term: grouped too
    units = seed_groups([baseline[0], source[0], transfer[0], soc[0], shaped[0], reused[0], baseline[1], source[1],
                         transfer[1], soc[1], shaped[1], reused[1]])
    assert [[r.path.name for r in unit] for unit in units] == [
        ["b0", "b100"], ["s50", "s150"], ["t0", "t100"], ["o0", "o100"], ["r0", "r100"], ["p0", "p100"]]


def test_an_experiment_leaves_worker_process_groups_to_train_seeds(tmp_path):
    from drltg.experiments.executor import Run, seed_groups
    from drltg.training.grouping import group_support

    lift = [Run("baseline", tiny_cfg(seed=s, task="lift"), tmp_path / f"l{s}", tmp_path / f"l{s}.log")
            for s in (0, 100)]
    assert group_support(lift[0].cfg) is None  # `drltg train lift --seeds 2` groups them
    assert [[r.path.name for r in unit] for unit in seed_groups(lift)] == [["l0"], ["l100"]]


def test_gymnasium_runs_group_in_this_process_each_seed_s_envs_seeded_as_alone(tmp_path):
    """A Gymnasium task's batch is a SerialEnv of single envs in this process: a group steps one such batch per
    seed side by side (no worker processes), each reset as its run alone resets, so a sweep groups them."""
    from torchrl.envs import SerialEnv

    from drltg.experiments.executor import Run, seed_groups
    from drltg.training import loop
    from drltg.training.grouping import in_process
    from drltg.training.seeds import _group_env

    cfgs = [config_lib.resolve({}, ["collector.num_envs=2"], task="pendulum/g10", seed=s) for s in (0, 100)]
    assert in_process(cfgs[0])
    runs = [Run("baseline", c, tmp_path / f"b{c.seed}", tmp_path / f"b{c.seed}.log") for c in cfgs]
    assert [[r.path.name for r in unit] for unit in seed_groups(runs)] == [["b0", "b100"]]
    together = _group_env(cfgs[0], [0, 100], 2, 0)
    assert isinstance(together.base_env.base_env, SerialEnv)
    first = together.reset()["observation"]
    for k, c in enumerate(cfgs):
        alone = loop.build_env(c, batch_size=(2,), seed=c.seed)
        torch.testing.assert_close(first[2 * k:2 * k + 2], alone.reset()["observation"])
        alone.close()
    together.close()


def test_run_group_trains_an_experiments_seeds_together(tmp_path):
    import json

    from drltg.experiments.executor import run_group

    cfgs = [tiny_cfg(seed=0, frames=128), tiny_cfg(seed=100, frames=128)]
    dirs = [tmp_path / "baseline" / "seed-0", tmp_path / "baseline" / "seed-100"]
    logs = [tmp_path / "logs" / "seed-0.log", tmp_path / "logs" / "seed-100.log"]
    assert run_group(cfgs, [str(d) for d in dirs], [str(p) for p in logs]) == [("done", ""), ("done", "")]
    for d in dirs:
        assert json.loads((d / "summary.json").read_text())["seed_group"] == {"seeds": [0, 100]}
    assert "output in" in logs[1].read_text()


@pytest.mark.parametrize("task, algo", [("gridrooms/northeast", "sac"), ("fourrooms/northeast", "td3"),
                                       ("fourrooms/northeast", "soc")])
def test_every_grouped_learner_trains_its_seeds_from_their_initial_networks(task, algo, tmp_path, capsys):
    """Each seed's first evaluation is its own initial networks' (built as its run alone builds them) on its
    block of the group's evaluation env."""
    from drltg.learners import make_agent
    from drltg.modules import make_option_policy
    from drltg.store.rundir import read_eval_csv
    from drltg.training.loop import EVAL_SEED_OFFSET, evaluate_seeds
    from drltg.training.seeds import GroupPolicy, SeedLoopPolicy, _group_env, train_seeds

    cfg = tiny_cfg(task=task, algo=algo, frames=192, **({"soc.num_options": 2} if algo == "soc" else {}))
    train_seeds(cfg, tmp_path, 2, progress=False)
    assert "note:" not in capsys.readouterr().err  # grouped, not one after another
    agents = []
    for seed in (3, 103):
        alone_cfg = config_lib.updated(cfg, {"seed": seed})
        torch.manual_seed(seed)
        agents.append(make_agent(build_env(alone_cfg, seed=seed), alone_cfg))
    group = SeedGroup(agents)
    actor = (SeedLoopPolicy(group, make_option_policy) if algo == "soc"
             else GroupPolicy(agents[0].actor, group.params["actor_network_params"]))
    eval_env = _group_env(cfg, [3, 103], cfg.eval.episodes, EVAL_SEED_OFFSET, agents[0].env_transforms)
    expected = evaluate_seeds(eval_env, actor, 2)
    for seed, first in zip((3, 103), expected):
        rows = read_eval_csv(tmp_path / f"seed-{seed}" / "eval.csv")
        assert [r["frames"] for r in rows] == [0, 192]
        assert rows[0] == {"frames": 0, **first}


def test_cli_resumes_a_finished_group_from_its_folder_alone(group_run, capsys):
    from drltg.cli import main

    stamps = {p: p.stat().st_mtime_ns for p in group_run.glob("seed-*/summary.json")}
    assert main(["train", "--seeds", "2", "--seed", "3", "--resume", "--run-dir", str(group_run), "--no-progress"]) == 0
    assert f"{group_run}/seed-3, {group_run}/seed-103" in capsys.readouterr().out
    assert stamps == {p: p.stat().st_mtime_ns for p in stamps}  # complete: nothing trained or written again


def test_seeds_with_cuda_graphs_train_one_after_another(monkeypatch):
    """A group's vmapped update is not captured: ``optim.cudagraphs`` seeds are not grouped, not silently eager."""
    from drltg.training.grouping import group_support

    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    monkeypatch.setattr(torch.cuda, "device_count", lambda: 1)
    cfg = config_lib.resolve({}, TINY + ["device=cuda", "optim.cudagraphs=true"], task="fourrooms/northeast")
    assert "CUDA graph" in group_support(cfg)
    assert group_support(config_lib.updated(cfg, {"optim.cudagraphs": False})) is None


def test_a_lift_groups_seed_workers_step_their_envs_themselves(monkeypatch):
    """On 2 cores a group of 3 Lift seeds with 2 envs each starts 3 worker processes, not 3 + 6: a seed's
    worker steps its own envs (robosuite's parallel=False), unless env.parallel is given or every env of
    the group has a core of its own."""
    from drltg import config as config_lib
    from drltg.envs import limits
    from drltg.training import seeds as group_training

    built = []

    class Workers:  # stands in for ParallelEnv: what each seed's worker would build
        def __init__(self, n, make, create_env_kwargs, mp_start_method):
            built.append(make.keywords)

    monkeypatch.setattr(group_training, "ParallelEnv", Workers)
    monkeypatch.setattr(group_training, "TransformedEnv", lambda env, transform: env)
    for cores, overrides, expected in ((2, [], {"batch_size": (2,), "parallel": False}),
                                       (6, [], {"batch_size": (2,)}),
                                       (2, ["env.parallel=true"], {"batch_size": (2,)})):
        monkeypatch.setattr(limits, "usable_cpus", lambda cores=cores: cores)
        group_training._worker_env(config_lib.resolve(None, overrides, task="lift"), [0, 1, 2], 2, 0)
        assert built.pop() == expected


def test_usable_cpus_are_the_process_affinity():
    import os

    from drltg.envs.limits import usable_cpus

    assert usable_cpus() == len(os.sched_getaffinity(0))
