"""Suite v2's protocol: the tier's own sources shared by every row, and a baseline tuned on the same budget."""
import hashlib
import json

import numpy as np
import pytest
import yaml

from drltg import config as config_lib
from drltg.bench import sources, suite
from drltg.bench.suite import Group, Sources, Tier
from drltg.cli import main
from drltg.envs import get_pair
from drltg.envs.registry import TASKS
from drltg.transfer import TUNING_BUDGET

TINY = Tier("tiny", "one FourRooms pair at tiny budgets", (Group("rooms", {
    "pairs": ["fourrooms-near"], "algos": ["sac"], "seeds": 2, "seed": 0, "frames": 192, "threshold": 0.5,
    "overrides": {"eval.every": 96, "eval.episodes": 2, "collector.num_envs": 4, "collector.frames_per_batch": 32,
                  "collector.init_random_frames": 64, "optim.updates_per_batch": 1, "log.tensorboard": False}},
    Sources(192, 0.9), {"sac.alpha_init": (0.01, 0.1)}),))


def _area(run_dir, frames, value_range):
    """The mean return over the budget by the trapezoid rule, normalised: computed here from eval.csv."""
    rows = np.genfromtxt(run_dir / "eval.csv", delimiter=",", names=True)
    inside = rows["frames"] <= frames
    lo, hi = value_range
    return (np.trapz(rows["return_mean"][inside], rows["frames"][inside]) / frames - lo) / (hi - lo)


def test_v2_declares_one_source_task_per_group_and_a_baseline_search_from_the_defaults():
    tier = suite.get_tier("v2", "quick")
    for group in tier.groups:
        assert group.sources is not None and "source_frames" not in group.spec
        assert len({get_pair(p).source for p in group.pairs}) == 1
        settings = group.baseline_settings
        assert 1 < len(settings) <= TUNING_BUDGET
        for pair in group.pairs:  # the search starts at the defaults of the group's tasks
            defaults = config_lib.resolve({}, [], task=get_pair(pair).target)
            assert settings[0] == {k: getattr(getattr(defaults, k.split(".")[0]), k.split(".")[1]) for k in settings[0]}


def test_the_committed_v2_sources_are_the_ones_the_suite_declares_and_met_its_criterion():
    from pathlib import Path

    tier = suite.get_tier("v2", "quick")
    folder = Path(__file__).parents[1] / "results" / "bench" / "v2" / "quick"
    declared = suite.declared_sources(tier)
    assert len(declared) == 3 * 13  # 10 leaderboard and 3 tuning seeds per group
    assert sources.use_sources(tier, folder, None, smoke=False)[1] is True
    listed = json.loads((folder / "sources" / "sources.json").read_text())
    for key, entry in listed.items():
        group = next(g for g in tier.groups if g.name == key.split("/")[0])
        assert entry["met"] is (True if group.sources.success is not None else None)
        assert entry["frames"] <= group.sources.frames + 1024  # a last batch may overshoot by less than a round


def test_rows_share_the_suite_s_sources_and_train_at_the_tuned_baseline(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(suite.SUITES, "test", {"tiny": TINY})
    monkeypatch.setattr(suite, "TUNE_SEEDS", 2)
    common = ["--suite", "test", "--tier", "tiny", "--no-progress", "--workers", "2", "--out", str(tmp_path)]
    run = ["bench", "run", "--method", "value-shaping", "--reference", "none", *common]
    assert main(run) == 2
    assert "of the tier's 4 sources are not finished" in capsys.readouterr().err
    assert main(["bench", "sources", *common]) == 0
    folder = tmp_path / "test" / "tiny" / "sources"
    listed = json.loads((folder / "sources.json").read_text())
    assert sorted(listed) == ["rooms/seed-0", "rooms/seed-100", "rooms/seed-5000", "rooms/seed-5100"]
    for key, entry in listed.items():
        run_dir = folder / key
        assert entry["networks_sha256"] == hashlib.sha256(
            (run_dir / "checkpoints" / "last.safetensors").read_bytes()).hexdigest()
        saved = yaml.safe_load((run_dir / "config.yaml").read_text())
        assert saved["seed"] == int(key.split("-")[-1]) + 50 and saved["task"] == get_pair("fourrooms-near").source
        assert saved["eval"]["stop_at_success"] == 0.9 and entry["met"] is False and entry["declared"] is None
    assert "0 of 4 sources met their success criterion; their digests are in" in capsys.readouterr().out

    assert main(run) == 2
    assert "tunes its baseline before any row: run `drltg bench tune --method none" in capsys.readouterr().err
    assert main(["bench", "tune", "--method", "none", *common]) == 0
    record = json.loads((tmp_path / "test" / "tiny" / "tuning" / "none" / "tuning.json").read_text())
    assert [(s["group"], s["setting"]) for s in record["settings"]] == [("rooms", {"sac.alpha_init": 0.01}),
                                                                         ("rooms", {"sac.alpha_init": 0.1})]
    value_range = TASKS[get_pair("fourrooms-near").target].return_range({})
    base = tmp_path / "test" / "tiny" / "tuning" / "none" / "rooms" / "fourrooms-near" / "sac"
    for tried in record["settings"]:
        runs = [base / f"sac.alpha_init={tried['setting']['sac.alpha_init']}" / "baseline" / f"seed-{s}"
                for s in (5000, 5100)]
        assert tried["score"] == pytest.approx(np.mean([_area(r, 192, value_range) for r in runs]))
    assert record["choice"] == {"rooms": max(record["settings"], key=lambda s: s["score"])["setting"]}

    assert main(["bench", "tune", "--method", "model-reuse", *common]) == 0  # no search: a budget of 1
    assert "nothing to try (a budget of 1)" in capsys.readouterr().out
    kept = tmp_path / "test" / "tiny" / "tuning" / "model-reuse"
    assert json.loads((kept / "tuning.json").read_text())["choice"] == {} and not (kept / "rooms").exists()
    assert main(["bench", "tune", "--method", "value-shaping", *common]) == 0
    chosen = base / f"sac.alpha_init={record['choice']['rooms']['sac.alpha_init']}" / "baseline"
    copies = list((tmp_path / "test" / "tiny" / "tuning" / "value-shaping").rglob("baseline/seed-*/eval.csv"))
    assert len(copies) == 2  # the baseline's own tuning runs at its choice, copied as data, not trained again
    assert all(c.read_bytes() == (chosen / c.parent.name / "eval.csv").read_bytes() for c in copies)
    assert not list((tmp_path / "test" / "tiny" / "tuning" / "value-shaping").rglob("logs/**/baseline/*.log"))

    assert main(run) == 0
    tier = tmp_path / "test" / "tiny"
    pair = tier / "rooms" / "fourrooms-near" / "sac"
    for seed in (0, 100):
        transfer = pair / "value-shaping" / "transfer" / f"seed-{seed}"
        saved = yaml.safe_load((transfer / "config.yaml").read_text())
        assert (transfer / saved["transfer"]["source"]).resolve() == (folder / "rooms" / f"seed-{seed}").resolve()
        loaded = json.loads((transfer / "summary.json").read_text())["source"]
        assert loaded["networks_sha256"] == listed[f"rooms/seed-{seed}"]["networks_sha256"]
        baseline = yaml.safe_load((pair / "baseline" / f"seed-{seed}" / "config.yaml").read_text())
        assert baseline["sac"]["alpha_init"] == record["choice"]["rooms"]["sac.alpha_init"]
    assert not (pair / "source").exists()  # no row trains a source of its own
    report = ["bench", "report", "--out", str(tmp_path), "--reference", "none", "--suite", "test", "--tier", "tiny",
              "--reps", "100"]
    assert main(report) == 0
    board = json.loads((tier / "board" / "leaderboard.json").read_text())
    assert board["rows"][0]["marks"] == [] and board["rows"][0]["rank"] == 1  # the suite's sources, tuned baseline
    text = (tier / "board" / "leaderboard.md").read_text()
    assert "at most 2 per group on seeds 5000, 5100" in text
    assert f"rooms: sac.alpha_init={record['choice']['rooms']['sac.alpha_init']}. Every row trained at them." in text

    # the same folder, had the suite declared other teachers: the row is marked, not ranked
    monkeypatch.setattr(sources, "declared_sources", lambda t: {k: {"networks_sha256": "0" * 64,
                                                                    "config_sha256": "0" * 64} for k in listed})
    assert main(run) == 0
    assert main(report) == 0
    row = json.loads((tier / "board" / "leaderboard.json").read_text())["rows"][0]
    assert row["rank"] is None and any("sources not the suite's" in m for m in row["marks"])
