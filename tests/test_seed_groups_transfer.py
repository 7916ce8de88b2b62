"""Seed groups of transfer runs: each seed transfers from its own source, on its own block of envs."""
import pytest
import torch

from drltg import config as config_lib
from drltg.errors import UsageError
from drltg.experiments.executor import Run, execute, seed_groups
from drltg.store.rundir import MODEL_REUSE, load_checkpoint
from drltg.training import grouping, loop, seeds
from drltg.transfer import TransferMethod, get_method
from tests.test_seed_groups import TINY, tiny_cfg


@pytest.fixture(scope="module")
def sources(tmp_path_factory):
    """Two finished source runs (seeds 50 and 51) on the source task, a few updates each."""
    root = tmp_path_factory.mktemp("sources")
    return seeds.train_seeds(tiny_cfg(task="fourrooms/southwest", frames=192, seed=50), root, 2, progress=False)


def transfer_cfgs(method, sources, frames=192, **overrides):
    """Seeds 3 and 4 of ``method`` on fourrooms/northeast, seed k reading source k (as an experiment plans them)."""
    return [tiny_cfg(seed=3 + k, frames=frames, **{"transfer.method": method, "transfer.source": str(src), **overrides})
            for k, src in enumerate(sources)]


def _stacked(params, name, k):
    return params.get(tuple(name.split(".")))[k]


@pytest.mark.parametrize("freeze", [[], ["actor_network_params"]])
def test_model_reuse_a_seed_in_a_group_starts_from_its_own_source_as_alone(sources, freeze, tmp_path, monkeypatch):
    starts = {}

    class Recorded(seeds.SeedGroup):  # the stacked parameters the group starts from
        def __init__(self, agents, **kw):
            super().__init__(agents, **kw)
            starts["group"] = self.params.detach().clone()

    class RecordedAlone(loop.AgentLearner):  # the parameters a run alone starts from
        def __init__(self, agent, *args, **kw):
            starts.setdefault("alone", []).append({k: v.clone() for k, v in agent.loss.state_dict().items()})
            super().__init__(agent, *args, **kw)

    monkeypatch.setattr(seeds, "SeedGroup", Recorded)
    monkeypatch.setattr(loop, "AgentLearner", RecordedAlone)
    cfgs = transfer_cfgs("model-reuse", sources, **{"transfer.freeze": freeze})
    dirs = seeds.train_group(cfgs, [tmp_path / f"seed-{c.seed}" for c in cfgs], progress=False)
    alone = [loop.train(c, tmp_path / f"alone-{c.seed}", progress=False) for c in cfgs]
    source_loss = [load_checkpoint(s)["loss"] for s in sources]
    assert any(not torch.equal(a, b) for a, b in zip(source_loss[0].values(), source_loss[1].values()))
    for k, (d, a) in enumerate(zip(dirs, alone)):
        for name, value in starts["alone"][k].items():
            assert torch.equal(_stacked(starts["group"], name, k), value), name
            assert torch.equal(value, source_loss[k][name]), name  # seed k loaded its own source
        assert (d / MODEL_REUSE).read_text() == (a / MODEL_REUSE).read_text()
        grouped = load_checkpoint(d)
        assert grouped["updates"] > 0
        for name in source_loss[k]:
            frozen = any(name.startswith(p) for p in freeze)
            if name.startswith(("actor_network_params", "qvalue_network_params")):
                assert torch.equal(grouped["loss"][name], source_loss[k][name]) == frozen, name


@pytest.mark.parametrize("method, options", [
    ("policy-reuse", {"transfer.psi": 0.8, "transfer.upsilon": 0.9}),
    ("jumpstart", {"transfer.guide_steps": 3, "transfer.guide_stages": 1, "transfer.guide_frames": 1000,
                   "env.horizon": 7})])
def test_policy_reuse_a_seed_in_a_group_mixes_in_its_own_source(sources, method, options, tmp_path):
    """Seed k's mixer holds seed k's source policy (and acts on seed k's envs: the next test); over the
    group's seeds the sources act some of the time after the warm-up, not always."""
    cfgs = [config_lib.updated(c, {"log.every": 16}) for c in transfer_cfgs(method, sources, **options)]
    dirs = seeds.train_group(cfgs, [tmp_path / f"seed-{c.seed}" for c in cfgs], progress=False)
    values = [float(line.split(",")[-1]) for d in dirs  # the fractions logged after the warm-up
              for line in sorted(d.rglob("reused_fraction.csv"))[0].read_text().splitlines()[128 // 16:]]
    assert 0 < max(values) and min(values) < 1
    mixers = [_transfer(c).mixer for c in cfgs]
    actors = [load_checkpoint(s)["loss"] for s in sources]
    for mixer, source in zip(mixers, actors):
        own = {k: v for k, v in source.items() if k.startswith("actor_network_params")}
        mine = dict(mixer.state_dict())
        assert any(torch.equal(v, w) for v in own.values() for w in mine.values())


def test_seed_blocks_route_each_block_through_its_own_module():
    from tensordict import TensorDict
    from tensordict.nn import TensorDictModule

    modules = [TensorDictModule(lambda x, k=k: x + 10 * k, in_keys=["x"], out_keys=["y"]) for k in range(3)]
    td = TensorDict({"x": torch.arange(6.0).unsqueeze(-1)}, batch_size=[6])
    out = seeds.SeedBlocks(modules)(td)
    assert out["y"].squeeze(-1).tolist() == [0.0, 1.0, 12.0, 13.0, 24.0, 25.0]


def test_a_model_reuse_group_resumes_with_its_frozen_parameters_still_its_sources(sources, tmp_path, monkeypatch):
    from drltg.store.rundir import read_eval_csv

    real = loop._episode_stats

    def crash_after_first_checkpoint(data, stats):
        if (tmp_path / "seed-4" / "checkpoints" / "last.pt").exists():
            raise KeyboardInterrupt
        return real(data, stats)

    cfgs = [config_lib.updated(c, {"checkpoint.every": 128, "eval.every": 128})  # TINY's override the keywords
            for c in transfer_cfgs("model-reuse", sources, frames=256, **{"transfer.freeze": ["actor_network_params"]})]
    dirs = [tmp_path / f"seed-{c.seed}" for c in cfgs]
    monkeypatch.setattr(loop, "_episode_stats", crash_after_first_checkpoint)
    with pytest.raises(KeyboardInterrupt):
        seeds.train_group(cfgs, dirs, progress=False)
    monkeypatch.setattr(loop, "_episode_stats", real)
    seeds.train_group(cfgs, dirs, resume=True, progress=False)
    for d, src in zip(dirs, sources):
        assert [r["frames"] for r in read_eval_csv(d / "eval.csv")] == [0, 128, 256]
        loss, source_loss = load_checkpoint(d)["loss"], load_checkpoint(src)["loss"]
        for name, value in source_loss.items():
            if name.startswith(("actor_network_params", "qvalue_network_params")):
                assert torch.equal(loss[name], value) == name.startswith("actor_network_params"), name


def _transfer(cfg):
    probe, agent = loop.check_config(cfg)
    return get_method(cfg.transfer.method).build(cfg, agent, probe, resuming=False)


@pytest.mark.parametrize("method", ["reward-shaping", "value-shaping"])
def test_shaping_gives_each_seeds_block_its_own_potential(sources, method):
    """On block k, r' = r + gamma * Phi_k(s') - Phi_k(s) (0 for Phi_k(s') at a termination), Phi_k seed k's
    own potential; the task's reward is kept beside it."""
    cfgs = transfer_cfgs(method, sources, **{"env.horizon": 7})
    transfers = [_transfer(c) for c in cfgs]
    torch.manual_seed(0)
    together = seeds.group_train_env(cfgs, (), transfers).rollout(30, break_when_any_done=False)
    per_seed = cfgs[0].collector.num_envs
    for k, t in enumerate(transfers):
        block, shaping = together[k * per_seed:(k + 1) * per_seed], t.train_transforms[0]
        nxt = block["next"]
        phi_next = shaping.potential_of(nxt).reshape(nxt["reward"].shape)
        assert torch.allclose(nxt["potential"], phi_next)
        expected = (nxt["task_reward"] + shaping.gamma * phi_next.masked_fill(nxt["terminated"], 0.0)
                    - block["potential"])
        torch.testing.assert_close(nxt["reward"], expected)
        assert not torch.equal(nxt["reward"], nxt["task_reward"])  # it shapes
    assert int(together["next", "done"].sum()) > 0  # resets within the frames compared


def test_value_shaping_shapes_each_block_with_its_own_sources_value(sources):
    cfgs = transfer_cfgs("value-shaping", sources)
    transfers = [_transfer(c) for c in cfgs]
    env = seeds.group_train_env(cfgs, (), transfers)
    td = env.reset()
    per_seed = cfgs[0].collector.num_envs
    for k, t in enumerate(transfers):
        block = td[k * per_seed:(k + 1) * per_seed]
        assert torch.equal(block["potential"], t.train_transforms[0].potential(block["observation"]))
    other = transfers[1].train_transforms[0].potential(td[:per_seed]["observation"])
    assert not torch.equal(td[:per_seed]["potential"], other)  # seed 3's block is not shaped by seed 4's source


def test_a_group_s_members_may_differ_in_their_method_s_member_options(sources, tmp_path):
    """Runs that differ in options each seed's own parts read (a tuning grid's settings) are one seed group:
    seed 3 never reuses (psi 0) while seed 4, in the same group, always does (psi 1, upsilon 1); value shaping's
    block k is shaped by its own scale."""
    cfgs = transfer_cfgs("policy-reuse", sources)
    cfgs = [config_lib.updated(c, {"log.every": 16, "transfer.psi": psi, "transfer.upsilon": 1.0})
            for c, psi in zip(cfgs, (0.0, 1.0))]
    assert grouping.same_but_seed(*cfgs) and not grouping.same_but_seed(
        cfgs[0], config_lib.updated(cfgs[1], {"optim.lr": 1e-3}))
    dirs = seeds.train_group(cfgs, [tmp_path / f"seed-{c.seed}" for c in cfgs], progress=False)
    fractions = [[float(line.split(",")[-1]) for line in sorted(d.rglob("reused_fraction.csv"))[0].read_text()
                  .splitlines()[128 // 16:]] for d in dirs]
    assert set(fractions[0]) == {0.0} and set(fractions[1]) == {1.0}
    scaled = [config_lib.updated(c, {"transfer.value_scale": v})
              for c, v in zip(transfer_cfgs("value-shaping", sources), (1.0, 4.0))]
    assert grouping.same_but_seed(*scaled)
    transfers = [_transfer(c) for c in scaled]
    td = seeds.group_train_env(scaled, (), transfers).reset()
    per_seed = scaled[0].collector.num_envs
    for k, t in enumerate(transfers):
        block = td[k * per_seed:(k + 1) * per_seed]
        assert torch.equal(block["potential"], t.train_transforms[0].potential(block["observation"]))
    with pytest.raises(UsageError, match="member_options names 'lr', which is not one of its options"):
        TransferMethod("x", "x", lambda *a, **k: None, member_options=("lr",))


@pytest.mark.parametrize("method, grouped", [("none", True), ("reward-shaping", True), ("value-shaping", True),
                                             ("model-reuse", True), ("policy-reuse", True), ("jumpstart", True),
                                             ("demonstrations", True), ("kickstarting", True), ("sf-gpi", True),
                                             ("model-reuse+reward-shaping", True),
                                             ("reward-shaping+policy-reuse", True),
                                             ("model-reuse+demonstrations", True)])
def test_a_method_groups_only_if_it_and_every_part_declare_it(method, grouped):
    assert get_method(method).grouped is grouped
    reason = grouping.group_support(tiny_cfg(**{"transfer.method": method}))
    assert reason == (None if grouped else f"transfer method {method} has no grouped form")


def test_a_method_without_a_grouped_form_says_why_in_the_plan(tmp_path):
    from drltg.experiments.executor import Run, plan_of
    from drltg.transfer import Transfer, register_method
    from drltg.transfer.registry import METHODS

    why = "its policy replaces the collector's"
    try:
        register_method(TransferMethod("test-alone", "x", lambda *a, **k: Transfer(), alone=why))
        cfg = tiny_cfg(**{"transfer.method": "test-alone"})
        assert grouping.group_support(cfg) == f"transfer method test-alone has no grouped form: {why}"
        runs = [Run("transfer", cfg.model_copy(update={"seed": s}), tmp_path / f"seed-{s}", tmp_path / f"{s}.log")
                for s in (0, 100)]
        first = plan_of(runs).summary(runs, 0)[0]
        assert first.endswith(f"2 runs alone (transfer method test-alone has no grouped form: {why})")
    finally:
        METHODS.pop("test-alone", None)


@pytest.mark.parametrize("method", ["policy-reuse", "jumpstart", "kickstarting", "demonstrations", "value-shaping",
                                    "sf-gpi"])
def test_a_methods_tuning_settings_are_one_seed_group(method):
    """Every setting of a method's search differs only in options its seeds' own parts read: ``drltg bench tune``
    trains the whole grid with its seeds as one group."""
    settings = get_method(method).settings
    assert len(settings) > 1
    cfgs = [tiny_cfg(seed=k, **{"transfer.method": method, "transfer.source": "src", **setting})
            for k, setting in enumerate(settings)]
    assert all(grouping.same_but_seed(cfgs[0], other) for other in cfgs[1:])


def test_a_user_method_trains_alone_unless_it_declares_a_grouped_form():
    from drltg.transfer import Transfer, TransferMethod, register_method
    from drltg.transfer.registry import METHODS

    try:
        plain = register_method(TransferMethod("test-plain", "nothing", lambda *a, **k: Transfer()))
        assert not plain.grouped
        assert grouping.group_support(tiny_cfg(**{"transfer.method": "test-plain"})) is not None
    finally:
        METHODS.pop("test-plain", None)


SWEEP = """
pairs: [fourrooms-near]
methods: [reward-shaping, value-shaping, policy-reuse, model-reuse]
seeds: 2
frames: 64
overrides: {%s}
""" % ", ".join(f"{k}: {v}" for k, v in (o.split("=") for o in TINY))


def test_a_sweep_groups_the_transfer_runs_that_differ_only_in_their_seed(tmp_path):
    from drltg.experiments.sweep import load_spec, plan

    (tmp_path / "spec.yaml").write_text(SWEEP)
    out = tmp_path / "out"
    runs, _ = plan(load_spec(tmp_path / "spec.yaml"), out)
    units = [[str(r.path.relative_to(out / "fourrooms-near" / "sac")) for r in unit] for unit in seed_groups(runs)]
    assert sorted(units) == sorted([
        ["baseline/seed-0", "baseline/seed-100"], ["source/seed-50", "source/seed-150"],
        ["reward-shaping/transfer/seed-0", "reward-shaping/transfer/seed-100"],
        ["value-shaping/transfer/seed-0", "value-shaping/transfer/seed-100"],
        ["model-reuse/transfer/seed-0", "model-reuse/transfer/seed-100"],
        ["policy-reuse/transfer/seed-0", "policy-reuse/transfer/seed-100"]])
    by_path = {r.path: r for r in runs}
    for method in ("value-shaping", "policy-reuse", "model-reuse"):  # each seed reads its own seed's source run
        for seed in (0, 100):
            run = by_path[out / "fourrooms-near" / "sac" / method / "transfer" / f"seed-{seed}"]
            assert run.needs == out / "fourrooms-near" / "sac" / "source" / f"seed-{seed + 50}"
            assert run.cfg.transfer.source == str(run.needs)


class Instant:
    """A backend that finishes every unit at once, recording what it was given; a run named in ``fail`` fails."""

    capacity = 8

    def __init__(self, fail=()):
        self.units, self.fail = [], set(fail)

    def submit_group(self, runs):
        self.units.append([r.path.name for r in runs])
        return len(self.units) - 1

    def submit(self, run):
        return self.submit_group([run])

    def wait(self, handles, timeout):
        return [(h, [("failed", "x") if name in self.fail else ("done", "") for name in self.units[h]])
                for h in handles]


def test_a_transfer_group_starts_once_each_seeds_source_is_done_and_loses_only_a_failed_sources_seed(tmp_path):
    cfg = tiny_cfg(frames=64)
    sources = [Run("source", config_lib.updated(cfg, {"seed": s}), tmp_path / f"s{s}", tmp_path / f"s{s}.log")
               for s in (50, 150, 250)]
    transfer = [Run("transfer", config_lib.updated(cfg, {"seed": s.cfg.seed - 50, "transfer.method": "model-reuse",
                                                         "transfer.source": str(s.path)}),
                    tmp_path / f"t{s.cfg.seed - 50}", tmp_path / f"t{s.cfg.seed - 50}.log", needs=s.path)
                for s in sources]
    backend = Instant(fail={"s150"})
    status = execute(transfer + sources, backend, poll=0.01)  # the transfer runs are listed first
    assert backend.units == [["s50", "s150", "s250"], ["t0", "t200"]]
    assert status[tmp_path / "t100"] == ("failed", f"not run: the run it needs failed ({tmp_path / 's150'})")
    assert status[tmp_path / "t0"] == status[tmp_path / "t200"] == ("done", "")


@pytest.mark.parametrize("spec, counts", [("fourrooms", (45, 9, 9, 45)), ("fourrooms-graded", (260, 26, 26, 260))])
def test_the_fourrooms_reference_sweeps_group_as_the_readme_says(spec, counts, tmp_path):
    from pathlib import Path

    from drltg.experiments.sweep import load_spec, plan

    runs, _ = plan(load_spec(Path(__file__).parents[1] / "examples" / "sweeps" / f"{spec}.yaml"), tmp_path)
    units = seed_groups(runs)
    groups = [u for u in units if len(u) > 1]
    assert (len(runs), len(units), len(groups), sum(map(len, groups))) == counts
    seeds = load_spec(Path(__file__).parents[1] / "examples" / "sweeps" / f"{spec}.yaml").seeds
    assert all(len(u) == seeds for u in units)  # every run in a group of all its seeds


def test_an_experiment_with_kept_per_seed_sources_groups_its_transfer_runs(tmp_path):
    """``-o transfer.source=DIR/seed-{seed}``: each transfer run reads its own seed's kept run and needs no planned
    run; its seeds still form one group."""
    from drltg.experiments.experiment import as_runs, plan_runs

    planned = plan_runs("fourrooms/northeast", "model-reuse", frames=64, out=tmp_path / "out", seeds=3,
                        overrides=[f"transfer.source={tmp_path}/kept/seed-{{seed}}"])
    units = seed_groups(as_runs(planned, tmp_path / "out"))
    assert [[(r.role, r.cfg.seed, r.needs) for r in unit] for unit in units] == [
        [("baseline", s, None) for s in (0, 100, 200)], [("transfer", s, None) for s in (0, 100, 200)]]
    assert [r.cfg.transfer.source for r in units[1]] == [str(tmp_path / "kept" / f"seed-{s}") for s in (0, 100, 200)]
