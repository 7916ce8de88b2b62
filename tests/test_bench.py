"""drltg bench: the score of a pair by hand, the leaderboard's ranks, verdicts and marks on made-up reports, and
the path a user takes: a reference row, then a plugin method run beside it with one command and placed on the
board (tiny budgets on a test tier)."""
import json
import os
from pathlib import Path

import pytest

from drltg.bench import suite
from drltg.bench.board import leaderboard, pair_score
from drltg.bench.suite import Group, Tier
from drltg.cli import main

PLUGIN_DIR = Path(__file__).resolve().parents[1] / "examples" / "plugin"
SEEDS = [0, 100, 200, 300, 400, 500]


def _report(baseline, transfer, value_range=(-1.0, 1.0), verdict="undecided", p=0.5):
    return {"settings": {"value_range": list(value_range)},
            "per_seed": {side: [{"seed": s, "mean_return": x} for s, x in zip(SEEDS, xs)]
                         for side, xs in (("baseline", baseline), ("transfer", transfer))},
            "metrics": {"mean_return_gain_verdict": verdict, "mean_return_gain_verdict_p": p,
                        "mean_return_gain_verdict_test": "sign-flip"}}


def test_the_score_of_a_pair_is_continual_worlds_forward_transfer():
    # normalised by [-1, 1]: baseline areas 0.5 and 0.75 (mean 0.625), transfer 0.75 and 1.0
    score = pair_score(_report([0.0, 0.5], [0.5, 1.0]))
    assert score["ft_seeds"] == pytest.approx([0.25 / 0.375, 0.25 / 0.375])
    assert score["ft"] == pytest.approx(2 / 3)
    # the mean of the seeds' scores is (mean AUC_T - mean AUC_B) / (1 - mean AUC_B)
    score = pair_score(_report([-1.0, 0.0], [0.0, 0.6], value_range=(-1.0, 1.0)))
    assert score["ft"] == pytest.approx((0.65 - 0.25) / 0.75)


def test_a_pair_whose_baseline_is_at_the_maximum_has_no_score():
    score = pair_score(_report([1.0, 1.0], [1.0, 0.5]))
    assert score["ft"] is None and "maximum" in score["note"]


SPEC = {"pairs": ["p1", "p2"], "algos": ["sac"], "seeds": 6, "seed": 0, "frames": 1000, "source_frames": 1000,
        "overrides": {"eval.every": 100}}
TIER = Tier("tiny", "two made-up pairs", (Group("g", SPEC),))
VERSIONS = {"drltg": "0.1.0", "torch": "2.13.0"}


def _write(root: Path, rows: dict) -> None:
    """A tier folder as bench run leaves it: bench.json and each pair's report, with made-up scores."""
    methods = {}
    for method, (entry, areas) in rows.items():
        methods[method] = {"versions": VERSIONS, "smoke": False, "groups": {"g": SPEC}, "left_out": {}, **entry}
        for pair in ("p1", "p2"):
            folder = root / "g" / pair / "sac" / method / "report"
            folder.mkdir(parents=True)
            (folder / "transfer_metrics.json").write_text(json.dumps(_report([0.0] * 6, areas[pair])))
    (root / "bench.json").write_text(json.dumps({"methods": methods}))


def test_the_board_ranks_rows_on_protocol_and_marks_the_others(tmp_path):
    good = {"p1": [0.8, 0.9, 0.7, 0.8, 0.9, 0.6], "p2": [0.5, 0.6, 0.4, 0.5, 0.7, 0.5]}
    fair = {"p1": [0.2, 0.3, 0.1, 0.4, 0.2, 0.3], "p2": [0.1, 0.0, 0.2, 0.1, 0.3, 0.1]}
    worse = {p: [x - 0.1 for x in xs] for p, xs in good.items()}
    _write(tmp_path / "ref" / "v9" / "tiny", {"good": ({}, good), "fair": ({}, fair)})
    _write(tmp_path / "mine" / "v9" / "tiny", {
        "mine": ({}, worse),
        "other-torch": ({"versions": {**VERSIONS, "torch": "9.9"}}, good),
        "other-budget": ({"groups": {"g": {**SPEC, "frames": 500}}}, good)})
    _write(tmp_path / "mine" / "v9" / "tiny-smoke", {"quick-look": ({"smoke": True}, good)})
    board = leaderboard(TIER, "v9", out=tmp_path / "mine", reference=tmp_path / "ref", reps=200)
    rows = {(r["method"], r["kind"]): r for r in board["rows"]}
    assert board["best_reference"] == "good"
    assert [r["method"] for r in board["rows"] if r["rank"]] == ["good", "mine", "fair"]
    assert rows[("other-torch", "yours")]["marks"] == ["torch 9.9 (reference 2.13.0)"]
    assert rows[("other-budget", "yours")]["marks"] == ["g frames 500 (suite 1000)"]
    assert rows[("quick-look", "yours")]["marks"] == ["smoke budgets"]
    assert all(rows[(m, "yours")]["rank"] is None for m in ("other-torch", "other-budget", "quick-look"))
    # every seed of "mine" is 0.1 below "good" on both pairs: 12 pairs of differences, all one sign, so the
    # stratified exact sign-flip test gives 2 / 2^12, and each pair's own test 2 / 2^6
    against = rows[("mine", "yours")]["against_best"]
    assert against["verdict"] == "lower" and against["p"] == pytest.approx(2 / 2**12)
    assert all(v["verdict"] == "lower" and v["p"] == pytest.approx(2 / 2**6) for v in against["pairs"].values())
    # "good" against no transfer: every seed higher on both pairs
    none = rows[("good", "reference")]["aggregate"]["against_none"]
    assert none["verdict"] == "higher" and none["p"] == pytest.approx(2 / 2**12)
    from drltg.bench.report import board_markdown

    assert "The best reference row is good: IQM of FT" in board_markdown(board, TIER)
    assert "pairs, higher than no transfer (p = 0.00049" in board_markdown(board, TIER)
    iqm, (low, high) = rows[("good", "reference")]["aggregate"]["ft_iqm"]
    assert low <= iqm <= high


def test_a_pair_the_method_cannot_run_on_is_left_out_with_its_sentence(tmp_path):
    from drltg.bench.run import applicable_pairs

    gridrooms, pendulum = suite.get_tier("v1", "quick").groups[1:]
    kept, left_out = applicable_pairs(gridrooms, "demonstrations", False, tmp_path)
    assert kept == [] and all("discrete actions" in why for why in left_out.values())
    assert applicable_pairs(pendulum, "sf-gpi", False, tmp_path)[1]["pendulum-heavier"].startswith("sf-gpi needs")
    assert applicable_pairs(pendulum, "model-reuse", False, tmp_path) == (["pendulum-heavier"], {})


@pytest.mark.parametrize("argv, sentence", [
    (["bench", "run", "--method", "none"], "'none' is the baseline"),
    (["bench", "run", "--method", "model-reuse", "--tier", "quik"], "did you mean 'quick'"),
    (["bench", "run", "--method", "no-such-method"], "unknown transfer method"),
    (["bench", "report", "--reference", "none"], "no bench rows"),
])
def test_bad_bench_input_is_one_sentence(tmp_path, capsys, argv, sentence):
    assert main([*argv, "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert sentence in err and err.count("\n") == 1


def test_a_broken_bench_record_is_one_sentence(tmp_path, capsys):
    root = tmp_path / "v1" / "quick"
    root.mkdir(parents=True)
    (root / "bench.json").write_text("[1, 2]")
    assert main(["bench", "report", "--out", str(tmp_path), "--reference", "none"]) == 2
    assert "is not a bench record" in capsys.readouterr().err


TINY_TIER = Tier("tiny", "two FourRooms pairs at tiny budgets", (Group("rooms", {
    "pairs": ["fourrooms-near", "fourrooms-far"], "algos": ["sac"], "seeds": 2, "seed": 0, "frames": 192,
    "source_frames": 192, "threshold": 0.5,
    "overrides": {"eval.every": 96, "eval.episodes": 2, "collector.num_envs": 4, "collector.frames_per_batch": 32,
                  "collector.init_random_frames": 64, "optim.updates_per_batch": 1, "log.tensorboard": False}}),))


def test_a_plugin_method_joins_the_board_beside_a_reference_row(tmp_path, monkeypatch, capsys, request):
    import sys

    from drltg.config.registry import METHODS
    from drltg.envs import registry

    monkeypatch.setitem(suite.SUITES, "test", {"tiny": TINY_TIER})
    # the plugin registers its tasks, pair and method in this process: all of them undone after the test
    monkeypatch.setattr(registry, "TASKS", dict(registry.TASKS))
    monkeypatch.setattr(registry, "PAIRS", dict(registry.PAIRS))
    sys.modules.pop("drltg_example_plugin", None)
    request.addfinalizer(lambda: (METHODS.pop("critic-reuse", None), sys.modules.pop("drltg_example_plugin", None)))
    monkeypatch.syspath_prepend(str(PLUGIN_DIR))
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(PLUGIN_DIR), os.environ.get("PYTHONPATH", "")]))
    monkeypatch.setenv("DRLTG_IMPORT", "")  # --import adds the plugin here for the workers: undone after the test
    common = ["--suite", "test", "--tier", "tiny", "--no-progress", "--workers", "2"]
    ref, mine = tmp_path / "ref", tmp_path / "mine"
    assert main(["bench", "run", "--method", "model-reuse", "--out", str(ref), "--reference", "none", *common]) == 0
    assert main(["bench", "run", "--method", "critic-reuse", "--import", "drltg_example_plugin", "--out", str(mine),
                 "--reference", str(ref), *common]) == 0
    assert "6 source and baseline runs taken from" in capsys.readouterr().out  # 2 sources (shared), 2 x 2 baselines
    logs = mine / "test" / "tiny" / "rooms" / "logs"
    assert sorted(p.relative_to(logs).parts[2] for p in logs.rglob("*.log")) == ["critic-reuse"] * 4
    assert main(["bench", "report", "--out", str(mine), "--reference", str(ref), "--suite", "test", "--tier",
                 "tiny", "--reps", "200"]) == 0
    shown = capsys.readouterr().out
    assert "critic-reuse (yours)" in shown and "model-reuse" in shown
    board_dir = mine / "test" / "tiny" / "board"
    board = json.loads((board_dir / "leaderboard.json").read_text())
    assert {(r["method"], r["kind"]) for r in board["rows"]} == {("model-reuse", "reference"),
                                                                   ("critic-reuse", "yours")}
    assert all(r["rank"] and not r["marks"] for r in board["rows"])
    assert board["best_reference"] == "model-reuse"
    for name in ("leaderboard.md", "profile.png", "curves-fourrooms-near.png", "curves-fourrooms-far.png"):
        assert (board_dir / name).stat().st_size > 0
