"""eval.stop_at_success: a run ends at its first evaluation whose success rate reaches the criterion (the source
criterion of `drltg experiment --source-success` and a sweep's ``source_success``).

Evaluations are scripted by frame (as in tests/test_best.py), so the frame a run must stop at is known.
"""
import json

import pytest
import torch

import drltg.training.loop as loop
import drltg.training.seeds as seeds_mod
from drltg import config as config_lib
from drltg.errors import UsageError
from drltg.experiments.experiment import experiment, plan_runs
from drltg.experiments.spec import parse_spec
from drltg.report.align import _frames_of_run
from drltg.training.loop import read_eval_csv, train
from drltg.training.seeds import train_seeds

TINY = ["network.hidden=[16,16]", "collector.num_envs=4", "collector.frames_per_batch=16",
        "collector.init_random_frames=128", "optim.updates_per_batch=1", "buffer.batch_size=32", "eval.every=256",
        "eval.episodes=4", "checkpoint.every=512", "log.every=128", "log.tensorboard=false"]


def cfg(*overrides, frames=1024, seed=3):
    return config_lib.resolve({}, [*TINY, *overrides], task="fourrooms/northeast", frames=frames, seed=seed)


def row(success):
    return {"return_mean": -1.0, "return_std": 0.0, "episodes": 4, "success_rate": success}


def script(monkeypatch, learner, by_frame):
    """Every evaluation returns, for seed k, ``by_frame[k][frames]``; records each seed's weights there."""
    weights = {}

    def evaluate(self, check=lambda: None):
        buffers = getattr(self, "buffers", None) or [self.buffer]
        frames = len(buffers[0])  # every collected frame is stored (buffer.size exceeds the run)
        agents = self.group.agents if hasattr(self, "group") else [self.agent]
        if hasattr(self, "group"):
            self.group.sync()
        for k, agent in enumerate(agents):
            weights[k, frames] = {n: v.detach().clone() for n, v in agent.loss.state_dict().items()}
        return [row(series[frames]) for series in by_frame]

    monkeypatch.setattr(learner, "evaluate", evaluate)
    return weights


def summary(run):
    return json.loads((run / "summary.json").read_text())


def last_checkpoint(run):
    return torch.load(run / "checkpoints" / "last.pt", weights_only=True)


def test_a_run_stops_at_the_first_evaluation_meeting_the_criterion(monkeypatch, tmp_path):
    weights = script(monkeypatch, loop.AgentLearner, [{0: 0.0, 256: 0.5, 512: 0.75, 768: 1.0, 1024: 1.0}])
    run = train(cfg("eval.stop_at_success=0.75"), tmp_path / "run", progress=False)
    assert [r["frames"] for r in read_eval_csv(run / "eval.csv")] == [0, 256, 512]
    s = summary(run)
    assert s["status"] == "complete" and s["frames"] == 512
    assert s["stop_at_success"] == {
        "target": 0.75, "met": True, "frames": 512, "success_rate": 0.75,
        "reason": "success rate 0.75 reached eval.stop_at_success=0.75 at frame 512"}
    ckpt = last_checkpoint(run)
    assert ckpt["frames"] == 512  # the policy reused is the one evaluated at the stop
    for name, value in ckpt["loss"].items():
        assert torch.equal(value, weights[0, 512][name]), name
    # a finished run is not trained again: resuming it changes nothing
    before = (run / "summary.json").read_bytes()
    train(cfg("eval.stop_at_success=0.75"), run, resume=True, progress=False)
    assert (run / "summary.json").read_bytes() == before


def test_a_run_that_never_meets_it_trains_its_budget_and_says_so(monkeypatch, tmp_path):
    script(monkeypatch, loop.AgentLearner, [{f: 0.5 if f == 512 else 0.25 for f in range(0, 1025, 256)}])
    run = train(cfg("eval.stop_at_success=0.9"), tmp_path / "run", progress=False)
    assert [r["frames"] for r in read_eval_csv(run / "eval.csv")] == [0, 256, 512, 768, 1024]
    stop = summary(run)["stop_at_success"]
    assert stop == {"target": 0.9, "met": False, "frames": 1024, "best_success_rate": 0.5,
                    "reason": "success rate never reached eval.stop_at_success=0.9 (best 0.5): trained the whole "
                              "budget of 1,024 frames"}
    assert last_checkpoint(run)["frames"] == 1024


def test_without_a_criterion_nothing_stops_and_the_summary_has_no_entry(monkeypatch, tmp_path):
    script(monkeypatch, loop.AgentLearner, [{f: 1.0 for f in range(0, 1025, 256)}])
    run = train(cfg(), tmp_path / "run", progress=False)
    assert summary(run)["frames"] == 1024 and "stop_at_success" not in summary(run)


def test_a_seed_group_stops_each_seed_on_its_own_and_leaves_the_others_unchanged(monkeypatch, tmp_path):
    """Seed 0 meets the criterion at frame 256; seed 1 never does and trains on, its weights those it gets
    in the same group without a criterion (the stopped seed's networks still step, unrecorded)."""
    by_frame = [{f: 1.0 if f >= 256 else 0.0 for f in range(0, 1025, 256)},
                {f: 0.5 for f in range(0, 1025, 256)}]
    script(monkeypatch, seeds_mod.GroupLearner, by_frame)
    a, b = train_seeds(cfg("eval.stop_at_success=0.9"), tmp_path / "stop", 2, progress=False)
    assert summary(a)["frames"] == 256 and summary(a)["stop_at_success"]["met"] is True
    assert [r["frames"] for r in read_eval_csv(a / "eval.csv")] == [0, 256]
    assert last_checkpoint(a)["frames"] == 256
    assert summary(b)["frames"] == 1024 and summary(b)["stop_at_success"]["met"] is False
    plain = train_seeds(cfg("eval.stop_at_success=null"), tmp_path / "plain", 2, progress=False)[1]
    assert read_eval_csv(b / "eval.csv") == read_eval_csv(plain / "eval.csv")
    for name, value in last_checkpoint(b)["loss"].items():
        assert torch.equal(value, last_checkpoint(plain)["loss"][name]), name


def test_the_criterion_is_a_success_rate_of_a_task_that_reports_success(tmp_path):
    with pytest.raises(UsageError, match="eval.stop_at_success"):
        cfg("eval.stop_at_success=1.5")
    with pytest.raises(UsageError, match="eval.stop_at_success"):
        cfg("eval.stop_at_success=0")
    with pytest.raises(UsageError, match="reports no success"):
        loop.check_config(config_lib.resolve({}, ["eval.stop_at_success=0.9"], task="pendulum/g15"))


def test_an_experiment_sets_it_on_its_source_runs_only(tmp_path):
    runs = plan_runs("fourrooms-near", "model-reuse", frames=512, seeds=2, source_frames=4096,
                     source_success=0.9, out=tmp_path)
    by_role = {}
    for role, c, _ in runs:
        by_role.setdefault(role, set()).add(c.eval.stop_at_success)
    assert by_role == {"source": {0.9}, "baseline": {None}, "transfer": {None}}
    assert {c.frames for role, c, _ in runs if role == "source"} == {4096}
    with pytest.raises(UsageError, match="may not set 'eval.stop_at_success'.*--source-success"):
        plan_runs("fourrooms-near", "model-reuse", frames=512, out=tmp_path, overrides=["eval.stop_at_success=0.9"])
    with pytest.raises(UsageError, match="--source-success must be a success rate"):
        plan_runs("fourrooms-near", "model-reuse", frames=512, out=tmp_path, source_success=1.2)
    with pytest.raises(UsageError, match="trains none"):
        experiment("fourrooms-near", "reward-shaping", frames=512, out=tmp_path / "x", source_success=0.9)
    assert not (tmp_path / "x").exists()


def test_a_sweep_spec_gives_it_as_source_success(tmp_path):
    spec = parse_spec({"pairs": ["fourrooms-near"], "methods": ["model-reuse"], "frames": 512,
                       "source_success": 0.9})
    assert spec.source_success == 0.9
    for bad in (0, 1.5, True, "high"):
        with pytest.raises(UsageError, match="'source_success' must be a success rate"):
            parse_spec({"pairs": ["fourrooms-near"], "methods": ["model-reuse"], "frames": 512,
                        "source_success": bad})
    with pytest.raises(UsageError, match="may not set 'eval.stop_at_success'.*'source_success'"):
        parse_spec({"pairs": ["fourrooms-near"], "methods": ["model-reuse"], "frames": 512,
                    "overrides": {"eval.stop_at_success": 0.9}})


def test_a_report_counts_the_frames_a_stopped_source_trained(tmp_path):
    source = tmp_path / "source"
    source.mkdir()
    (source / "config.yaml").write_text("frames: 40000\n")
    assert _frames_of_run(tmp_path, str(source)) == (40000.0, False)
    (source / "summary.json").write_text(json.dumps({"frames": 40000, "stop_at_success": {"met": False,
                                                                                          "frames": 40000}}))
    assert _frames_of_run(tmp_path, str(source)) == (40000.0, False)
    (source / "summary.json").write_text(json.dumps({"frames": 12000, "stop_at_success": {"met": True,
                                                                                          "frames": 12000}}))
    assert _frames_of_run(tmp_path, str(source)) == (12000.0, True)
