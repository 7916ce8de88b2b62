"""`drltg bench tune`: a method's declared settings tried on tuning seeds, its choice applied by `bench run`."""
import json

import pytest
from pydantic import Field

from drltg.bench import suite
from drltg.bench.board import pair_score
from drltg.bench.suite import Group, Tier
from drltg.cli import main
from drltg.config import Float
from drltg.errors import UsageError
from drltg.transfer import TUNING_BUDGET, Transfer, TransferMethod, get_method

TINY = Tier("tiny", "one FourRooms pair at tiny budgets", (Group("rooms", {
    "pairs": ["fourrooms-near"], "algos": ["sac"], "seeds": 2, "seed": 0, "frames": 192, "source_frames": 192,
    "threshold": 0.5,
    "overrides": {"eval.every": 96, "eval.episodes": 2, "collector.num_envs": 4, "collector.frames_per_batch": 32,
                  "collector.init_random_frames": 64, "optim.updates_per_batch": 1, "log.tensorboard": False}}),))


def _method(search, **options):
    return TransferMethod("tunable", "test", lambda *a, **k: Transfer(), search=search,
                          options={k: (Float, Field(v, ge=0)) for k, v in options.items()})


def test_a_search_space_is_a_small_grid_of_the_method_s_own_options_from_their_defaults():
    assert _method({"scale": (1.0, 2.0), "rate": (0.5, 0.1)}, scale=1.0, rate=0.5).settings == [
        {"transfer.scale": 1.0, "transfer.rate": 0.5}, {"transfer.scale": 1.0, "transfer.rate": 0.1},
        {"transfer.scale": 2.0, "transfer.rate": 0.5}, {"transfer.scale": 2.0, "transfer.rate": 0.1}]
    assert get_method("reward-shaping").settings == [{}]
    assert len(get_method("policy-reuse").settings) <= TUNING_BUDGET
    for search, sentence in [
        ({"other": (1.0,)}, "its search names 'other', which is not one of its options"),
        ({"scale": (2.0, 1.0)}, "must list distinct values, the default 1.0 first"),
        ({"scale": (1.0, 1.0)}, "must list distinct values"),
        ({"scale": (1.0, -1.0)}, "config key 'transfer.scale' must be a number >= 0, got -1.0"),
        ({"scale": (1.0, 2.0, 3.0), "rate": (0.5, 0.1)},
         f"holds 6 settings; the budget every row gets is {TUNING_BUDGET}"),
    ]:
        with pytest.raises(UsageError, match=sentence):
            _method(search, scale=1.0, rate=0.5)


def test_tune_tries_each_setting_on_its_own_seeds_and_bench_run_applies_the_choice(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(suite.SUITES, "test", {"tiny": TINY})
    monkeypatch.setattr(suite, "TUNE_SEEDS", 2)
    common = ["--method", "value-shaping", "--suite", "test", "--tier", "tiny", "--no-progress", "--workers", "2",
              "--out", str(tmp_path)]
    assert main(["bench", "tune", *common, "--dry-run"]) == 0  # the work, before any of it: nothing written
    assert capsys.readouterr().out.splitlines() == [
        "rooms: 12 runs, 4 reports; 3 units of work to train: 3 seed groups of 12 runs (2 or 8 runs each), "
        "0 runs alone",  # the settings' transfer runs are one seed group: they differ in member options only
        "rooms: left to train: about 2,304 of 2,304 frames (12 not started)",
        "the tier: about 2,304 of 2,304 frames left to train"]
    assert not tmp_path.joinpath("test").exists()
    assert main(["bench", "tune", *common]) == 0
    root = tmp_path / "test" / "tiny" / "tuning" / "value-shaping"
    record = json.loads((root / "tuning.json").read_text())
    settings = get_method("value-shaping").settings
    assert [s["setting"] for s in record["settings"]] == settings and record["budget"] == len(settings) == 4
    assert record["seeds"] == [5000, 5100]  # no leaderboard run (seeds 0 + 100 i, sources + 50) has one
    pair = root / "rooms" / "fourrooms-near" / "sac"
    assert sorted(p.parent.name for p in pair.rglob("baseline/seed-*/summary.json")) == ["seed-5000", "seed-5100"]
    assert len(list(pair.rglob("source/seed-*/summary.json"))) == 2  # one baseline and source set for all four
    for tried in record["settings"]:
        name = ",".join(f"{k}={v}" for k, v in tried["setting"].items())
        report = json.loads((pair / name / "value-shaping" / "report" / "transfer_metrics.json").read_text())
        assert tried["per_pair"] == {"fourrooms-near": pair_score(report)["ft"]} == {"fourrooms-near": tried["score"]}
    scores = [s["score"] for s in record["settings"]]
    assert record["choice"] == settings[scores.index(max(scores))]  # the first of the best
    assert f"chose transfer.value_scale={record['choice']['transfer.value_scale']} of 4 settings" in \
        capsys.readouterr().out

    assert main(["bench", "run", *common, "--reference", str(tmp_path / "tuning-as-reference"), "--dry-run"]) == 0
    assert capsys.readouterr().out.splitlines()[1] == \
        "rooms: left to train: about 1,152 of 1,152 frames (6 not started)"
    assert main(["bench", "run", *common, "--reference", "none"]) == 0
    tier = tmp_path / "test" / "tiny"
    entry = json.loads((tier / "bench.json").read_text())["methods"]["value-shaping"]
    assert entry["tuning"]["choice"] == record["choice"] and entry["tuning"]["budget"] == 4
    for run in (tier / "rooms" / "fourrooms-near" / "sac" / "value-shaping" / "transfer").glob("seed-*"):
        assert f"value_scale: {record['choice']['transfer.value_scale']}" in (run / "config.yaml").read_text()
    assert main(["bench", "report", "--out", str(tmp_path), "--reference", "none", "--suite", "test", "--tier",
                 "tiny", "--reps", "100"]) == 0
    board = json.loads((tier / "board" / "leaderboard.json").read_text())
    assert not any("overrides" in mark for row in board["rows"] for mark in row["marks"])  # its setting is its own


def test_a_tuning_record_that_chooses_no_declared_setting_is_refused(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(suite.SUITES, "test", {"tiny": TINY})
    root = tmp_path / "test" / "tiny" / "tuning" / "value-shaping"
    root.mkdir(parents=True)
    (root / "tuning.json").write_text(json.dumps({"method": "value-shaping", "choice": {"transfer.value_scale": 9.0}}))
    assert main(["bench", "run", "--method", "value-shaping", "--suite", "test", "--tier", "tiny", "--out",
                 str(tmp_path), "--reference", "none", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "is not a tuning record of value-shaping choosing one of its declared settings" in err
    assert not (tmp_path / "test" / "tiny" / "rooms").exists()
