"""The jumpstart method end to end: at every evaluation the combined policy (the guide for H steps, then the
learner) is evaluated too, and JSRL's curriculum is told its return; the stage is logged, kept in checkpoints and
resumed, and in a seed group each seed's curriculum hears its own seed's return."""
import pytest
import torch

from drltg import config as config_lib
from drltg.collectors import JumpStart
from drltg.store.rundir import load_checkpoint, read_eval_csv
from drltg.training import loop, seeds
from drltg.transfer import get_method
from tests.test_methods import _source_run
from tests.test_seed_groups import TINY

# horizon 20, H from 20 to 0 in 4 stages, a tolerance of half the best's size
JUMPSTART = {"transfer.method": "jumpstart", "transfer.guide_steps": 20, "transfer.guide_stages": 4,
             "transfer.guide_tolerance": 0.5, "env.horizon": 20, "eval.every": 128}


def _cfg(source, seed=3, **changes):
    options = {**JUMPSTART, "transfer.source": str(source), **changes}
    return config_lib.resolve({}, TINY + [f"{k}={v}" for k, v in options.items()], task="fourrooms/northeast",
                              frames=640, seed=seed)


def _logged(run, name):
    (path,) = (run / "logs" / "csv").rglob(f"{name}.csv")
    return [(int(step), float(value)) for step, value in (line.split(",") for line in path.read_text().split())]


def _replayed(returns, steps=20, stages=4, tolerance=0.5):
    """The horizons JumpStart gives after each of ``returns``, by its rule."""
    schedule = JumpStart(steps, stages=stages, tolerance=tolerance)
    return [(schedule.evaluated(value), schedule.horizon)[1] for value in returns]


@pytest.fixture(scope="module")
def source(tmp_path_factory):
    torch.manual_seed(0)
    return _source_run(tmp_path_factory.mktemp("src") / "run")[0]


@pytest.fixture
def steady(monkeypatch):
    """The combined policy's evaluations made to return -0.2 each (what the untrained learner's failing episodes
    of 20 steps mostly return): at tolerance 0.5 the curriculum then moves at every evaluation after the first,
    20, 15, 10, 5, 0. The learner's own evaluations are left as they are."""
    from drltg.collectors import PolicyReuse

    real = loop.evaluate

    def combined_returns_steady(env, policy, *args, **kwargs):
        row = real(env, policy, *args, **kwargs)
        combined = any(isinstance(m, PolicyReuse) for m in policy.modules())  # the learner's actor, then the mixer
        return {**row, "return_mean": -0.2} if combined else row

    monkeypatch.setattr(loop, "evaluate", combined_returns_steady)


def test_each_evaluation_tells_the_curriculum_the_combined_policys_return(source, tmp_path):
    """Unpatched: the horizons logged are those JSRL's rule gives for the combined returns logged with them."""
    run = loop.train(_cfg(source), tmp_path / "run", progress=False)
    returns, horizons = _logged(run, "guided_return_mean"), _logged(run, "horizon")
    frames = [r["frames"] for r in read_eval_csv(run / "eval.csv")]
    assert frames == [0, 128, 256, 384, 512, 640]
    assert [f for f, _ in returns] == [f for f, _ in horizons] == frames
    assert [h for _, h in horizons] == _replayed([v for _, v in returns])
    assert horizons[0][1] == 20 and load_checkpoint(run)["transfer"]["stage"] == 4 - horizons[-1][1] // 5


def test_the_guide_acts_for_the_stages_horizon_and_stops_at_the_last_stage(source, steady, tmp_path):
    run = loop.train(_cfg(source), tmp_path / "run", progress=False)
    assert [h for _, h in _logged(run, "horizon")] == [20, 15, 10, 5, 0, 0]
    reused = dict(_logged(run, "reused_fraction"))  # logged every 128 frames, after the 128 warm-up frames
    assert reused[256] > 0 and reused[640] == 0  # H = 15 from frame 128; H = 0 from frame 512
    assert load_checkpoint(run)["transfer"]["stage"] == 4


def test_the_combined_policy_is_evaluated_on_an_env_of_its_own(source, tmp_path):
    """With H at least the horizon the guide acts throughout: the combined policy's return is the source actor's
    own on an env seeded seed + GUIDED_EVAL_SEED_OFFSET, while the learner's evaluation stays the learner's."""
    from drltg.learners import make_agent
    from drltg.transfer.source import source_actor

    cfg = _cfg(source, **{"transfer.guide_steps": 40})
    probe = loop.build_env(cfg, seed=cfg.seed)
    agent = make_agent(probe, cfg)
    transfer = get_method("jumpstart").build(cfg, agent, probe, resuming=False)

    def guided_env():
        return loop.make_eval_env(cfg, cfg.eval.episodes, cfg.seed + loop.GUIDED_EVAL_SEED_OFFSET,
                                  loop.primers(transfer))

    learner = loop.AgentLearner(agent, None, None, transfer, guided_env=guided_env())
    (logged,) = learner.evaluate_guided()
    alone = loop.evaluate(guided_env(), source_actor(cfg, probe))
    assert logged == {"eval/guided_return_mean": alone["return_mean"], "jumpstart/horizon": 40}
    plain = loop.AgentLearner(agent, None, None, get_method("none").build(cfg, agent, probe, resuming=False))
    assert plain.evaluate_guided() == []


def test_a_resumed_run_continues_its_curriculum(source, steady, tmp_path, monkeypatch):
    """Stopped after its checkpoint at frame 256 (H = 10 then), the resumed run's next evaluation moves it to 5,
    as the uninterrupted run's does, not back to the first stage."""
    real = loop._episode_stats

    def crash_after_first_checkpoint(data, stats):
        if (tmp_path / "run" / "checkpoints" / "last.pt").exists():
            raise KeyboardInterrupt
        return real(data, stats)

    cfg = _cfg(source)
    monkeypatch.setattr(loop, "_episode_stats", crash_after_first_checkpoint)
    with pytest.raises(KeyboardInterrupt):
        loop.train(cfg, tmp_path / "run", progress=False)
    assert load_checkpoint(tmp_path / "run")["frames"] == 256
    monkeypatch.setattr(loop, "_episode_stats", real)
    run = loop.train(cfg, tmp_path / "run", resume=True, progress=False)
    returns, horizons = _logged(run, "guided_return_mean"), _logged(run, "horizon")
    assert [f for f, _ in horizons] == [0, 128, 256, 384, 512, 640]
    assert [h for _, h in horizons] == _replayed([v for _, v in returns]) == [20, 15, 10, 5, 0, 0]


def test_in_a_seed_group_each_seed_hears_its_own_return(tmp_path, monkeypatch):
    """The group evaluates its policy once on a blocked env; seed k's curriculum must hear block k's return. The
    evaluation is made to give seed 3 -0.2 throughout (it moves at every evaluation after the first) and seed 4
    1.0, 0.2, 0.2, 1.0, 0.2, 1.0 (0.2 is below 1.0 - 0.5: it moves at the 4th and 6th only)."""
    from drltg.collectors import PolicyReuse

    given = {3: [-0.2] * 6, 4: [1.0, 0.2, 0.2, 1.0, 0.2, 1.0]}
    real = seeds.evaluate_seeds

    def combined_returns_given(env, policy, n, **kw):
        rows = real(env, policy, n, **kw)
        if any(isinstance(m, PolicyReuse) for m in policy.modules()):  # the collector's policy, not the actors
            for row, seed in zip(rows, given):
                row["return_mean"] = given[seed].pop(0)
        return rows

    monkeypatch.setattr(seeds, "evaluate_seeds", combined_returns_given)
    sources = [_source_run(tmp_path / f"src-{k}")[0] for k in range(2)]
    cfgs = [_cfg(sources[0], seed=3), _cfg(sources[1], seed=4)]
    dirs = seeds.train_group(cfgs, [tmp_path / f"seed-{c.seed}" for c in cfgs], progress=False)
    horizons = {d.name: [h for _, h in _logged(d, "horizon")] for d in dirs}
    assert horizons == {"seed-3": [20, 15, 10, 5, 0, 0], "seed-4": [20, 20, 20, 15, 15, 10]}
    assert [v for _, v in _logged(dirs[1], "guided_return_mean")] == [1.0, 0.2, 0.2, 1.0, 0.2, 1.0]
    assert [load_checkpoint(d)["transfer"]["stage"].item() for d in dirs] == [4, 2]


def test_combined_with_shaping_the_curriculum_still_hears_the_return_and_the_guided_env_is_unshaped(source):
    """reward-shaping+jumpstart: the joined transfer passes on_eval and state through, and the env the combined
    policy is evaluated on gets the primer alone, not the shaping (its return is the task's)."""
    from torchrl.envs import TensorDictPrimer

    from drltg.learners import make_agent
    from drltg.transforms import PotentialShaping

    cfg = _cfg(source, **{"transfer.method": "reward-shaping+jumpstart"})
    probe = loop.build_env(cfg, seed=cfg.seed)
    transfer = get_method(cfg.transfer.method).build(cfg, make_agent(probe, cfg), probe, resuming=False)
    assert {type(t) for t in transfer.train_transforms} == {PotentialShaping, TensorDictPrimer}
    assert [type(t) for t in loop.primers(transfer)] == [TensorDictPrimer]
    assert isinstance(transfer.state, JumpStart)
    assert [transfer.on_eval(v) for v in (-0.2, -0.2)] == [{"jumpstart/horizon": 20}, {"jumpstart/horizon": 15}]
