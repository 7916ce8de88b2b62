"""A diverged run is finished: its summary says so, per seed in a seed group, and a rerun does not train it again."""
import json

import pytest
import torch

from drltg.cli import main
from drltg.store import rundir
from drltg.training import health
from tests.test_reliability import nan_reward_task, one_sentence, train_args  # noqa: F401  (fixture)

NAN = "test/nan-reward"  # the task the fixture registers


def test_group_losses_name_the_seeds_that_diverged():
    losses = {"loss_actor": torch.tensor([0.5, 1.0, 2.0]), "loss_qvalue": torch.tensor([1.0, float("nan"), 3.0])}
    with pytest.raises(health.Diverged, match="loss term 'loss_qvalue' became nan at frame 7") as err:
        health.check_losses(losses, 7, seeds=3)
    assert err.value.seeds == (1,)
    with pytest.raises(health.Diverged) as err:
        health.check_losses({"loss": torch.tensor(float("inf"))}, 7)
    assert err.value.seeds is None


@pytest.mark.usefixtures("nan_reward_task")
def test_a_diverged_seed_group_writes_each_seed_diverged_and_a_resume_refuses(tmp_path, capsys):
    group = tmp_path / "group"
    one_sentence(capsys, main(train_args(group, "--seeds", "2", task=NAN, frames=128)), 1,
                 "the run diverged: the loss term 'loss_qvalue' became nan at frame 32")
    summaries = [json.loads((group / f"seed-{k}" / "summary.json").read_text()) for k in (0, 100)]
    assert [(s["status"], s["seed"]) for s in summaries] == [("diverged", 0), ("diverged", 100)]
    assert [rundir.summary_status(group / f"seed-{k}")[0] for k in (0, 100)] == ["diverged", "diverged"]
    before = {p: p.read_bytes() for p in group.rglob("*") if p.is_file()}

    err = one_sentence(capsys, main(train_args(group, "--seeds", "2", "--resume", task=NAN,
                                               frames=128)), 1, "status diverged", "train it anew")
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert {p: p.read_bytes() for p in group.rglob("*") if p.is_file()} == before  # nothing trained again


@pytest.mark.usefixtures("nan_reward_task")
def test_resuming_a_diverged_run_exits_non_zero_in_one_sentence(tmp_path, capsys):
    run = tmp_path / "run"
    assert main(train_args(run, task=NAN, frames=128)) == 1
    capsys.readouterr()
    err = one_sentence(capsys, main(train_args(run, "--resume", task=NAN, frames=128)), 1,
                       f"cannot resume '{run}': its summary.json says status diverged (the run diverged: ",
                       "train it anew into another --run-dir")
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err


@pytest.mark.usefixtures("nan_reward_task")
def test_the_executor_records_a_diverged_group_and_a_rerun_skips_it(tmp_path):
    from drltg.experiments.executor import Run, execute, run_group
    from tests.test_seed_groups import tiny_cfg

    cfgs = [tiny_cfg(task=NAN, seed=s, frames=128) for s in (0, 100)]
    dirs = [tmp_path / "baseline" / f"seed-{c.seed}" for c in cfgs]
    logs = [tmp_path / "logs" / f"seed-{c.seed}.log" for c in cfgs]
    statuses = run_group(cfgs, [str(d) for d in dirs], [str(p) for p in logs])
    assert [s for s, _ in statuses] == ["diverged", "diverged"]
    assert [rundir.summary_status(d) for d in dirs] == statuses

    class NoTraining:  # a rerun must not submit a finished run
        capacity = 1

        def submit_group(self, runs):
            raise AssertionError("a diverged run was trained again")

        submit = submit_group

    runs = [Run("baseline", c, d, p) for c, d, p in zip(cfgs, dirs, logs)]
    assert execute(runs, NoTraining(), poll=0.01) == dict(zip(dirs, statuses))


@pytest.mark.parametrize("seeds", [[], ["--seeds", "2"]])
def test_a_run_directory_whose_name_is_not_utf8_is_refused_in_one_sentence(seeds, tmp_path, capsys):
    import os

    run = os.fsdecode(os.fsencode(str(tmp_path)) + b"/bad\xff/run")
    one_sentence(capsys, main(train_args(run, *seeds)), 2, "is not valid UTF-8; choose a name in UTF-8",
                 "bad\\xff")
    assert list(tmp_path.iterdir()) == []


def test_a_bogus_mujoco_gl_is_refused_in_one_sentence_before_anything_is_imported(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("MUJOCO_GL", "bogus")
    one_sentence(capsys, main(train_args(tmp_path / "run")), 2, "MUJOCO_GL='bogus' is not a MuJoCo GL backend",
                 "egl, osmesa")
    assert not (tmp_path / "run").exists()
    monkeypatch.setenv("MUJOCO_GL", " EGL ")  # what MuJoCo accepts is accepted
    from drltg.cli import check_mujoco_gl

    check_mujoco_gl()


@pytest.mark.parametrize("interval", ["t", "welch", "studentized", "bca", "percentile"])
def test_a_report_of_identical_runs_is_strict_json_with_every_number_finite_or_null(interval, tmp_path, capsys):
    import math
    import shutil

    from tests.test_reliability import fake_run

    def strict(text):  # NaN or Infinity in the file raise here
        return json.loads(text, parse_constant=lambda name: pytest.fail(f"{name} in the report's JSON"))

    base = [fake_run(tmp_path / "b" / f"seed-{i}", [0.1 * i + 0.01 * k for k in range(21)], seed=i) for i in range(3)]
    for run in base:
        shutil.copytree(run, tmp_path / "t" / run.name)
    out = tmp_path / "r"
    assert main(["report", "--baseline", *map(str, base), "--transfer", *(str(tmp_path / "t" / r.name) for r in base),
                 "--out", str(out), "--interval", interval, "--threshold", "0.15"]) == 0
    report = strict((out / "transfer_metrics.json").read_text())
    metrics = report["metrics"]

    def numbers(x):
        if isinstance(x, (list, tuple)):
            return [n for v in x for n in numbers(v)]
        return [x] if isinstance(x, (int, float)) and not isinstance(x, bool) else []

    assert all(math.isfinite(n) for v in metrics.values() for n in numbers(v))
    assert metrics["mean_return_gain"] == 0 and metrics.get("mean_return_gain_ci") is None
    assert ("mean_return_gain has no interval: every pair gives the same difference (0), so there is no spread "
            "to scale.") in json.dumps(report["settings"])
