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
            "per_seed": {side: [{"seed": 100 * i, "mean_return": x} for i, x in enumerate(xs)]
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


def _write(root: Path, rows: dict, tests: dict | None = None) -> None:
    """A tier folder as bench run leaves it: bench.json and each pair's report, with made-up scores (and, in
    ``tests``, made-up verdicts ``{(method, pair): (verdict, p)}``)."""
    methods = {}
    for method, (entry, areas) in rows.items():
        methods[method] = {"versions": VERSIONS, "smoke": False, "groups": {"g": SPEC}, "left_out": {}, **entry}
        for pair in ("p1", "p2"):
            folder = root / "g" / pair / "sac" / method / "report"
            folder.mkdir(parents=True)
            verdict, p = (tests or {}).get((method, pair), ("undecided", 0.5))
            report = _report([0.0] * len(areas[pair]), areas[pair], verdict=verdict, p=p)
            (folder / "transfer_metrics.json").write_text(json.dumps(report))
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
    # rows off protocol (a smoke row among them) get no verdict against the full rows
    assert all("against_best" not in rows[(m, "yours")] for m in ("other-torch", "other-budget", "quick-look"))
    # every seed of "mine" is 0.1 below "good" on both pairs: 12 pairs of differences, all one sign, so the
    # stratified exact sign-flip test gives 2 / 2^12, and each pair's own test 2 / 2^6
    against = rows[("mine", "yours")]["against_best"]
    assert against["verdict"] == "lower" and against["p"] == pytest.approx(2 / 2**12)
    assert all(v["verdict"] == "lower" and v["p"] == pytest.approx(2 / 2**6) for v in against["pairs"].values())
    # Holm within the row over its 2 per-pair tests: both 2 / 2^6 become 2 x 2 / 2^6 = 0.0625, above 0.05
    assert all(v["p_holm"] == pytest.approx(4 / 2**6) and v["verdict_holm"] == "undecided"
               for v in against["pairs"].values())
    # "good" against no transfer: every seed higher on both pairs
    none = rows[("good", "reference")]["aggregate"]["against_none"]
    assert none["verdict"] == "higher" and none["p"] == pytest.approx(2 / 2**12)
    from drltg.bench.report import board_markdown

    text = board_markdown(board, TIER)
    assert "The top row is good: IQM of FT" in text and "It is the best reference row" in text
    # 12 paired seeds in all: every sign pattern counted, so the p-value is exact and said to be
    assert "over 2 pairs, higher than no transfer (p = 0.00049, stratified sign-flip over pairs, exact)" in text
    assert "| not compared | untuned (defaults) | smoke budgets |" in text
    iqm, (low, high) = rows[("good", "reference")]["aggregate"]["ft_iqm"]
    assert low <= iqm <= high


GOOD = [0.8, 0.9, 0.7, 0.8, 0.9, 0.6]  # over the range [-1, 1] against baselines at 0, each seed's FT is its value
FAIR = [0.2, 0.3, 0.1, 0.4, 0.2, 0.3]


def test_rows_are_ranked_by_score_over_the_pairs_they_cover_not_by_coverage(tmp_path):
    narrow = {"left_out": {"p2": "cannot run there"}}
    _write(tmp_path / "ref" / "v9" / "tiny", {"wide": ({}, {"p1": FAIR, "p2": FAIR}),
                                              "narrow": (narrow, {"p1": GOOD, "p2": GOOD})})
    board = leaderboard(TIER, "v9", reference=tmp_path / "ref", reps=200)
    rows = {r["method"]: r for r in board["rows"]}
    # narrow covers one pair of two, with a higher IQM there (+0.80: the mean of the middle four FTs): first
    assert [r["method"] for r in board["rows"]] == ["narrow", "wide"] and board["best_reference"] == "narrow"
    assert rows["narrow"]["marks"] == [] and rows["narrow"]["aggregate"]["pairs"] == ["p1"]
    assert rows["narrow"]["aggregate"]["ft_iqm"][0] == pytest.approx(0.8)
    from drltg.bench.board import board_table
    from drltg.bench.report import board_markdown

    table = board_table(board)
    assert "| 1 | narrow | 1 of 2, ranked on these | +0.80 [" in table
    # wide against narrow on the one pair both cover: every seed 0.6 below, exact sign-flip 2 / 2^6
    assert rows["wide"]["against_best"]["p"] == pytest.approx(2 / 2**6)
    assert "| lower (p = 0.031, on the one pair both cover) |" in table
    assert ("The top row is narrow: IQM of FT +0.80 [" in board_markdown(board, TIER)
            and "over the 1 of 2 pairs it covers, higher than no transfer (p = 0.031, stratified sign-flip over "
                "pairs, exact). It is the best reference row" in board_markdown(board, TIER))


def test_per_pair_arrows_are_holm_adjusted_within_each_row(tmp_path):
    areas = {"p1": GOOD, "p2": FAIR}
    _write(tmp_path / "ref" / "v9" / "tiny", {"a": ({}, areas), "b": ({}, areas)},
           tests={("a", "p1"): ("higher", 0.01), ("a", "p2"): ("higher", 0.04),
                  ("b", "p1"): ("higher", 0.03), ("b", "p2"): ("higher", 0.04)})
    board = leaderboard(TIER, "v9", reference=tmp_path / "ref", reps=200)
    rows = {r["method"]: r for r in board["rows"]}
    # a: 2 x 0.01 = 0.02, then max(0.02, 0.04) = 0.04, both below 0.05; b: 2 x 0.03 = 0.06, then max(0.06, 0.04)
    assert [rows["a"]["pairs"][p]["p_holm"] for p in ("p1", "p2")] == pytest.approx([0.02, 0.04])
    assert [rows["b"]["pairs"][p]["p_holm"] for p in ("p1", "p2")] == pytest.approx([0.06, 0.06])
    assert rows["b"]["pairs"]["p1"]["verdict"] == "higher"  # the report's own, kept beside the adjusted one
    from drltg.bench.board import pair_table
    from drltg.bench.report import board_markdown

    assert "| a | +0.78 ↑ | +0.25 ↑ |" in pair_table(board) and "| b | +0.78 · | +0.25 · |" in pair_table(board)
    assert "Holm-adjusted within the row (the family: that row's per-pair tests against no transfer, at most 2)" in (
        board_markdown(board, TIER))


def test_a_monte_carlo_p_value_at_its_floor_is_written_as_a_bound(tmp_path):
    from drltg.bench.board import p_text
    from drltg.bench.report import board_markdown

    assert p_text(2 / 2**12) == "p = 0.00049"  # exact
    assert p_text(1 / 100_000, 99_999, 1 / 100_000) == "p ≤ 1e-05 (99,999 draws)"
    assert p_text(3e-4, 99_999, 1 / 100_000) == "p = 0.0003"  # a Monte Carlo value above its floor
    # 24 seeds on each of 2 pairs: 48 paired seeds, past the 40 whose sign patterns are counted, and 2^24
    # patterns a pair, past the per-pair test's 9,999 draws
    many = [0.5 + 0.01 * i for i in range(24)]
    _write(tmp_path / "ref" / "v9" / "tiny", {"good": ({}, {"p1": many, "p2": many}),
                                              "less": ({}, {p: [x - 0.1 for x in many] for p in ("p1", "p2")})})
    board = leaderboard(TIER, "v9", reference=tmp_path / "ref", reps=200)
    none = board["rows"][0]["aggregate"]["against_none"]
    assert none["p"] == pytest.approx(1 / 100_000) and none["draws"] == 99_999
    assert none["test"] == "stratified sign-flip over pairs, Monte Carlo"
    against = board["rows"][1]["against_best"]
    assert all(v["p"] == pytest.approx(2 / 10_000) and v["draws"] == 9_999 for v in against["pairs"].values())
    text = board_markdown(board, TIER)
    assert "| higher (p ≤ 1e-05 (99,999 draws)) | - |" in text
    assert "| lower (p ≤ 1e-05 (99,999 draws)) |" in text
    assert "p = 1e-05" not in text and "draws), exact" not in text
    assert "Monte Carlo (9,999 draws, floor 0.0002; 99,999 draws, floor 1e-05)" in text


def test_a_row_off_protocol_is_on_the_profile_figure(tmp_path, monkeypatch):
    import drltg.analysis.plot as plot
    from drltg.bench.report import bench_report

    drawn = []
    monkeypatch.setattr(plot, "plot_profiles", lambda entries, over, **_: drawn.extend(entries) or {"png": b"png"})
    monkeypatch.setitem(suite.SUITES, "v9", {"tiny": TIER})
    _write(tmp_path / "ref" / "v9" / "tiny", {"good": ({}, {"p1": GOOD, "p2": GOOD})})
    _write(tmp_path / "mine" / "v9" / "tiny-smoke", {"quick-look": ({"smoke": True}, {"p1": FAIR, "p2": FAIR})})
    board, folder = bench_report(out=tmp_path / "mine", reference=tmp_path / "ref", version="v9", tier="tiny",
                                 reps=200)
    assert [e["method"] for e in drawn] == ["good", "quick-look (yours, off protocol)"]
    assert (folder / "profile.png").read_bytes() == b"png"


@pytest.mark.parametrize("n, reference, sentence", [
    (0, None, "no source or baseline runs were copied (no reference)"),
    (0, "results/bench", "no source or baseline runs were copied from results/bench"),
    (1, "results/bench", "1 source or baseline run was copied from results/bench"),
    (6, "results/bench", "6 source and baseline runs were copied from results/bench"),
])
def test_the_closing_sentence_of_a_bench_run_reads_as_a_sentence(n, reference, sentence):
    from drltg.cli.bench import copied_sentence

    assert copied_sentence(n, reference) == sentence


def test_a_pair_the_method_cannot_run_on_is_left_out_with_its_sentence(tmp_path):
    from drltg.bench.run import applicable_pairs

    gridrooms, pendulum = suite.get_tier("v1", "quick").groups[1:]
    kept, left_out = applicable_pairs(gridrooms, "demonstrations", False, tmp_path)
    assert kept == [] and all("discrete actions" in why for why in left_out.values())
    assert applicable_pairs(pendulum, "sf-gpi", False, tmp_path)[1]["pendulum-heavier"].startswith("sf-gpi needs")
    assert applicable_pairs(pendulum, "model-reuse", False, tmp_path) == (["pendulum-heavier"], {})


def test_only_a_method_that_reads_a_source_is_given_the_suites_sources(tmp_path):
    """Reward shaping reads no source: its runs are planned without ``transfer.source`` and run on every pair
    with a shaping potential (the suite's sources are the reusing rows' alone)."""
    from drltg.bench.run import applicable_pairs, group_spec

    fourrooms = suite.get_tier("v2", "quick").groups[0]
    given = {fourrooms.name: str(tmp_path / "sources" / "seed-{seed}")}
    assert "transfer.source" not in group_spec(fourrooms, "reward-shaping", False, given, {})["overrides"]
    spec = group_spec(fourrooms, "policy-reuse", False, given, {})
    assert spec["overrides"]["transfer.source"] == given[fourrooms.name]
    kept, left_out = applicable_pairs(fourrooms, "reward-shaping", False, tmp_path,
                                      group_spec(fourrooms, "reward-shaping", False, given, {}))
    assert kept == list(fourrooms.pairs) and left_out == {}


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
    root = tmp_path / suite.LATEST / "quick"
    root.mkdir(parents=True)
    (root / "bench.json").write_text("[1, 2]")
    assert main(["bench", "report", "--out", str(tmp_path), "--reference", "none"]) == 2
    assert "is not a bench record" in capsys.readouterr().err


TINY_TIER = Tier("tiny", "two FourRooms pairs at tiny budgets", (Group("rooms", {
    "pairs": ["fourrooms-near", "fourrooms-far"], "algos": ["sac"], "seeds": 2, "seed": 0, "frames": 192,
    "source_frames": 192, "threshold": 0.5,
    "overrides": {"eval.every": 96, "eval.episodes": 2, "collector.num_envs": 4, "collector.frames_per_batch": 32,
                  "collector.init_random_frames": 64, "optim.updates_per_batch": 1, "log.tensorboard": False}}),))


def test_a_plugin_method_joins_the_board_beside_a_reference_row(tmp_path, monkeypatch, capsys, request, page_size):
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
    # 2 sources (shared), 2 x 2 baselines
    assert "6 source and baseline runs were copied from" in capsys.readouterr().out
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
    paper = tmp_path / "paper"  # the board's figures for a page: 5 in wide, PDF beside each PNG
    assert main(["bench", "report", "--out", str(mine), "--reference", str(ref), "--suite", "test", "--tier", "tiny",
                 "--reps", "200", "--board", str(paper), "--figure-size", "5", "--figure-format", "pdf"]) == 0
    assert sorted(p.name for p in paper.glob("*.pdf")) == [
        "curves-fourrooms-far.pdf", "curves-fourrooms-near.pdf", "profile.pdf"]
    assert all(page_size(pdf)[0] == pytest.approx(5 * 72) for pdf in paper.glob("*.pdf"))


def test_a_second_method_in_a_shared_folder_keeps_the_first_methods_summaries(tmp_path, monkeypatch):
    """A bench run of one method into a folder that holds another summarised the new method alone: the
    group's summary, runs table and aggregates lost the first method's rows."""
    import csv

    monkeypatch.setitem(suite.SUITES, "test", {"tiny": TINY_TIER})
    common = ["--suite", "test", "--tier", "tiny", "--no-progress", "--workers", "2", "--out", str(tmp_path),
              "--reference", "none"]
    group = tmp_path / "test" / "tiny" / "rooms"
    assert main(["bench", "run", "--method", "model-reuse", *common]) == 0
    with open(group / "summary.csv") as f:
        first = [row for row in csv.DictReader(f)]
    assert {row["method"] for row in first} == {"model-reuse"}
    assert main(["bench", "run", "--method", "reward-shaping", *common]) == 0
    with open(group / "summary.csv") as f:
        both = [row for row in csv.DictReader(f)]
    assert sorted((row["pair"], row["method"]) for row in both) == sorted(
        (pair, method) for pair in ("fourrooms-near", "fourrooms-far") for method in ("model-reuse", "reward-shaping"))
    assert [row for row in both if row["method"] == "model-reuse"] == first  # the same numbers, not retrained
    with open(group / "runs.csv") as f:
        roles = [row["role"] for row in csv.DictReader(f)]
    assert roles.count("transfer") == 2 * 2 * 2 and roles.count("source") == 2  # sources shared by both methods


def test_rows_paired_by_seed_must_have_learned_from_one_source(tmp_path, monkeypatch, capsys):
    """A user's row beside the reference's shares its sources (copied as data), and each run names the source
    it loaded by digest; a slot whose two runs loaded different source networks is refused in one sentence."""
    import hashlib

    monkeypatch.setitem(suite.SUITES, "test", {"tiny": TINY_TIER})
    common = ["--suite", "test", "--tier", "tiny", "--no-progress", "--workers", "2"]
    ref, mine = tmp_path / "ref", tmp_path / "mine"
    assert main(["bench", "run", "--method", "model-reuse", "--out", str(ref), "--reference", "none", *common]) == 0
    assert main(["bench", "run", "--method", "policy-reuse", "--out", str(mine), "--reference", str(ref), *common]) == 0
    report = ["bench", "report", "--out", str(mine), "--reference", str(ref), "--suite", "test", "--tier", "tiny",
              "--reps", "200"]
    assert main([*report, "--board", str(tmp_path / "shared")]) == 0
    board = json.loads((tmp_path / "shared" / "leaderboard.json").read_text())
    cell = ref / "test" / "tiny" / "rooms" / "fourrooms-near" / "sac"
    networks = hashlib.sha256((cell / "source" / "seed-50" / "checkpoints" / "last.safetensors").read_bytes())
    assert {r["pairs"]["fourrooms-near"]["sources"]["0"]["networks_sha256"] for r in board["rows"]} == {
        networks.hexdigest()}
    assert all(not r["unverified"] for r in board["rows"])
    assert "not verified by digest" not in (tmp_path / "shared" / "leaderboard.md").read_text()
    capsys.readouterr()

    # the user's seed-0 run says it loaded seed 100's source (seed-150): the slot holds two teachers
    run = mine / "test" / "tiny" / "rooms" / "fourrooms-near" / "sac" / "policy-reuse" / "transfer" / "seed-0"
    summary = json.loads((run / "summary.json").read_text())
    other = hashlib.sha256((cell / "source" / "seed-150" / "checkpoints" / "last.safetensors").read_bytes())
    summary["source"]["networks_sha256"] = other.hexdigest()
    (run / "summary.json").write_text(json.dumps(summary))
    assert main([*report, "--board", str(tmp_path / "mixed")]) == 2
    err = capsys.readouterr().err
    mine_theirs = f"{networks.hexdigest()[:12]}... and {other.hexdigest()[:12]}..."
    assert err.count("\n") == 1 and (
        "model-reuse and policy-reuse (yours) are paired by seed on fourrooms-near seed 0, but their runs loaded "
        f"different source networks (SHA-256 {mine_theirs})" in err), err
    assert not (tmp_path / "mixed").exists()
