import csv
import io
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from drltg import report
from drltg.analysis import order_stats, stats
from drltg.cli import report as report_cli
from drltg.errors import UsageError
from drltg.report import catalogue, outputs
from drltg.report.curves import Curve

FILES = {"transfer_metrics.json", "transfer_metrics.csv", "transfer_plot.png", "transfer_plot.svg"}



def write_run(run_dir: Path, frames, values, task=None) -> Path:
    run_dir.mkdir(parents=True, exist_ok=True)
    rows = "".join(f"{f},{v},0.0,8,\n" for f, v in zip(frames, values))
    (run_dir / "eval.csv").write_text("frames,return_mean,return_std,episodes,success_rate\n" + rows)
    if task:
        (run_dir / "config.yaml").write_text(f"task: {task}\nseed: 0\n")
    return run_dir


def linear(frames, a):
    """y = a + f / 5: its trapezoid area over [0, 40] is exactly 40 a + 160."""
    return [a + f / 5 for f in frames]


@pytest.fixture
def two_by_two(tmp_path):
    """Two seeds per side on uneven grids; one baseline seed runs longer (to 50)."""
    b = tmp_path / "baseline"
    t = tmp_path / "transfer"
    write_run(b / "seed_0", [0, 10, 20, 40], linear([0, 10, 20, 40], 0), "fourrooms/near")
    write_run(b / "seed_1", [0, 20, 40, 50], linear([0, 20, 40, 50], 2), "fourrooms/near")
    write_run(t / "seed_0", [0, 5, 10, 40], linear([0, 5, 10, 40], 4), "fourrooms/near")
    write_run(t / "seed_1", [0, 10, 40], linear([0, 10, 40], 6), "fourrooms/near")
    return b, t


def test_hand_computed_metrics_with_seeds_and_uneven_grids(two_by_two, tmp_path):
    b, t = two_by_two
    out = tmp_path / "out"
    res = report.transfer_report(b, t, out, threshold=9, asymptote_window=0.5)
    m, st = res["metrics"], res["settings"]
    assert (st["start"], st["budget"]) == (0, 40)  # shortest run's last evaluation
    assert st["task"] == "fourrooms/near"
    assert any("truncated to the common budget of 40" in w for w in st["warnings"])
    assert m["n_seeds_baseline"] == m["n_seeds_transfer"] == 2
    # areas 160, 240 (baseline) and 320, 400 (transfer)
    assert m["total_reward_baseline"] == pytest.approx(200)
    assert m["total_reward_transfer"] == pytest.approx(360)
    assert m["transfer_ratio"] == pytest.approx(160 / 200)
    # first evaluations 0, 2 vs 4, 6
    assert m["jumpstart"] == pytest.approx(4)
    # window [20, 40]: baseline evaluations (4, 8) and (6, 10); transfer only the one at 40: 12, 14
    assert m["final_performance_baseline"] == pytest.approx(7)
    assert m["final_performance_transfer"] == pytest.approx(13)
    assert m["asymptotic_performance"] == pytest.approx(6)
    # threshold 9: baseline seed 0 never reaches it (8 at the budget; 12 at 50 lies past it); the others
    # first reach it at the budget, their last evaluation in it: no later evaluation confirms it is sustained
    assert m["time_to_threshold_baseline"] is None and m["threshold_reached_baseline"] == 0
    assert m["time_to_threshold_transfer"] is None and m["threshold_reached_transfer"] == 0
    first = report.compute(_read(b), _read(t), threshold=9, asymptote_window=0.5, crossing="first")["metrics"]
    assert first["time_to_threshold_baseline"] is None and first["threshold_reached_baseline"] == 0.5
    assert first["time_to_threshold_transfer"] == 40 and first["threshold_reached_transfer"] == 1.0
    for name in ("probability_of_improvement", "probability_of_improvement_initial",
                 "probability_of_improvement_final"):
        assert m[name] == 1.0
    assert m["jumpstart_iqm"] == pytest.approx(m["jumpstart"])  # n = 2: IQM is the mean
    # average returns over the budget: areas / 40 = 4, 6 and 8, 10
    assert m["mean_return_gain"] == pytest.approx(9 - 5)
    # two seeds per side: no interval, and the settings say why
    assert not any(k.endswith("_ci") for k in m)
    assert any("at least 3 seeds per side" in w for w in st["warnings"])
    assert st["paired"] is False and "do not match one to one" in st["pairing"]  # every run says seed 0
    saved = json.loads((out / "transfer_metrics.json").read_text())
    assert saved["metrics"] == json.loads(json.dumps(m))
    assert saved["metrics"]["time_to_threshold_baseline"] is None
    assert set(os.listdir(out)) == FILES


def test_jumpstart_window_budget_and_fraction_threshold(two_by_two, tmp_path):
    b, t = two_by_two
    m = report.compute(_read(b), _read(t), jumpstart_window=2, budget="20", threshold="40%",
                       asymptote_window=0.5, sustain=2)
    # means of the first two evaluations: baseline (0+2)/2, (2+6)/2; transfer (4+5)/2, (6+8)/2
    assert m["metrics"]["jumpstart"] == pytest.approx((4.5 + 7) / 2 - (1 + 4) / 2)
    # budget 20: areas of y = a + f/5 over [0, 20] = 20 a + 40
    assert m["metrics"]["total_reward_baseline"] == pytest.approx((40 + 80) / 2)
    assert m["settings"]["budget_source"] == "--budget"
    # best baseline mean within [0, 20] is (4 + 6) / 2 = 5, so 40 % of it is 2
    assert m["settings"]["threshold"] == pytest.approx(2)
    # two evaluations in a row at or above it: seed 0 at 10 and 20, seed 1 at 0 and 20
    assert [s["time_to_threshold"] for s in m["per_seed"]["baseline"]] == [10, 0]
    # the upper median of (0, 10): by frame 10 both seeds have crossed (the mean, 5, is no run's frame)
    assert m["metrics"]["time_to_threshold_baseline"] == 10


def _read(path):
    from drltg.report.curves import read_curves

    return read_curves(path)


def test_smoothing_shapes_time_to_threshold_only():
    f = np.arange(6) * 100.0
    b = Curve(f, [0, 9, 0, 5, 6, 7], "b.csv", "b")
    t = Curve(f, [0, 0, 0, 8, 8, 8], "t.csv", "t")
    raw = report.compute([b], [t], threshold=5, crossing="first")
    smooth = report.compute([b], [t], threshold=5, smooth=2, sustain=2)
    assert raw["metrics"]["time_to_threshold_baseline"] == 100  # a single noisy spike
    # sustained (the default): from 300 on the run stays >= 5
    assert report.compute([b], [t], threshold=5)["metrics"]["time_to_threshold_baseline"] == 300
    assert smooth["metrics"]["time_to_threshold_baseline"] == 400
    assert smooth["metrics"]["time_to_threshold_transfer"] == 400  # (0 + 8) / 2 = 4 < 5 at 300
    assert raw["metrics"]["total_reward_baseline"] == smooth["metrics"]["total_reward_baseline"]
    assert "_ci" not in "".join(raw["metrics"])  # one seed per side: no intervals
    assert any("at least 3 seeds" in w for w in raw["settings"]["warnings"])


def test_a_report_written_twice_is_the_same_bytes(two_by_two, tmp_path):
    """Its plot included: the SVG's element ids do not change from one writing to the next."""
    b, t = two_by_two
    for out in ("first", "second"):
        assert report_cli.main(["--baseline", str(b), "--transfer", str(t), "--out", str(tmp_path / out)]) == 0
    for name in FILES:
        assert (tmp_path / "first" / name).read_bytes() == (tmp_path / "second" / name).read_bytes(), name


def test_bootstrap_is_reproducible_and_seeded(tmp_path):
    rng = np.random.default_rng(0)
    f = np.arange(0, 101, 10.0)
    base = [Curve(f, f / 10 + rng.normal(0, 1, f.size), f"b{i}", f"b{i}") for i in range(5)]
    tran = [Curve(f, f / 8 + rng.normal(0, 1, f.size), f"t{i}", f"t{i}") for i in range(4)]
    a = report.compute(base, tran, interval="bca", bootstrap=1000, seed=1)["metrics"]
    b = report.compute(base, tran, interval="bca", bootstrap=1000, seed=1)["metrics"]
    c = report.compute(base, tran, interval="bca", bootstrap=1000, seed=2)["metrics"]
    assert a == b
    assert a["asymptotic_performance_ci"] != c["asymptotic_performance_ci"]
    lo, hi = a["asymptotic_performance_ci"]
    assert lo < a["asymptotic_performance"] < hi


def test_negative_and_near_zero_baseline_areas():
    f = [0.0, 10.0]
    worse = Curve(f, [-2.0, -2.0], "b", "b")
    better = Curve(f, [-1.0, -1.0], "t", "t")
    assert report.compute([worse], [better])["metrics"]["transfer_ratio"] == pytest.approx(0.5)
    flat = Curve(f, [-0.001, 0.001], "b", "b")
    res = report.compute([flat], [better])
    assert res["metrics"]["transfer_ratio"] is None
    assert any("within 1% of the largest possible area" in w and "transfer_ratio is undefined" in w
               for w in res["settings"]["warnings"])
    zero = report.compute([Curve(f, [0.0, 0.0], "b", "b")], [Curve(f, [0.0, 0.0], "t", "t")])
    assert zero["metrics"]["transfer_ratio"] is None
    assert ("every curve is 0 at every evaluation in the window, so transfer_ratio is undefined (null); compare "
            "mean_return_gain instead.") in zero["settings"]["warnings"]


def test_done_when_command_on_real_sb3_runs(sb3_runs, tmp_path, capsys):
    out = tmp_path / "rep"
    code = report_cli.main(["--baseline", str(sb3_runs / "liftplace_sac"),
                        "--transfer", str(sb3_runs / "liftplace_sac_policyreuse"),
                        "--threshold", "150", "--out", str(out)])
    assert code == 0
    assert set(os.listdir(out)) == FILES
    obj = json.loads((out / "transfer_metrics.json").read_text())
    m, st = obj["metrics"], obj["settings"]
    assert m["n_seeds_baseline"] == m["n_seeds_transfer"] == 1
    assert st["budget"] == 1_322_500  # the pi-reuse run is the shorter one
    assert st["threshold"] == 150 and st["threshold_basis"] == "absolute"
    for key in ("jumpstart", "asymptotic_performance", "total_reward_baseline", "total_reward_transfer",
                "transfer_ratio", "time_to_threshold_baseline", "time_to_threshold_transfer"):
        assert key in m
    assert m["jumpstart"] == pytest.approx(24.81896 - 4.3869472)  # first evaluations, at frame 500
    assert m["transfer_ratio"] == pytest.approx(
        (m["total_reward_transfer"] - m["total_reward_baseline"]) / abs(m["total_reward_baseline"]))
    rows = list(csv.reader(io.StringIO((out / "transfer_metrics.csv").read_text())))
    assert rows[0] == ["metric", "value", "ci_low", "ci_high", "p_value", "p_adjusted"]
    by_name = {r[0]: r for r in rows[1:]}
    assert float(by_name["jumpstart"][1]) == pytest.approx(m["jumpstart"])
    printed = capsys.readouterr()
    assert "jumpstart" in printed.out and "truncated" in printed.err
    _assert_real_plot(out / "transfer_plot.png")
    assert (out / "transfer_plot.svg").read_text().lstrip().startswith("<?xml")


def _assert_real_plot(png: Path):
    import matplotlib.image as mpimg

    assert png.stat().st_size > 30_000
    img = mpimg.imread(png)
    h, w = img.shape[:2]
    assert w > 800 and h > 500
    colours = np.unique((img[..., :3] * 255).astype(np.uint8).reshape(-1, 3), axis=0)
    assert len(colours) > 100  # not a blank or single-colour image
    # both side colours (blue #0072B2, vermillion #D55E00) are drawn
    px = (img[..., :3] * 255).astype(int).reshape(-1, 3)
    for rgb in ((0x00, 0x72, 0xB2), (0xD5, 0x5E, 0x00)):
        assert (np.abs(px - rgb).sum(axis=1) < 20).sum() > 500


def test_multi_seed_plot_with_band(two_by_two, tmp_path):
    b, t = two_by_two
    report.transfer_report(b, t, tmp_path / "o", threshold=9, baseline_label="scratch",
                           transfer_label="reuse")
    _assert_real_plot(tmp_path / "o" / "transfer_plot.png")
    assert "reuse vs scratch" in (tmp_path / "o" / "transfer_plot.svg").read_text()


def test_labels_with_dollar_signs_are_drawn_as_text(two_by_two, tmp_path):
    """A pair of ``$`` would be read as mathematics: ``cost$5 vs $10`` drawn in italics, and an unbalanced
    ``\\frac{`` between two of them fails to parse."""
    import matplotlib

    b, t = two_by_two
    report.transfer_report(b, t, tmp_path / "o", threshold=9, baseline_label="cost$5 vs $10",
                           transfer_label="reuse $\\frac{1}{$")
    _assert_real_plot(tmp_path / "o" / "transfer_plot.png")
    assert "reuse $\\frac{1}{$ vs cost$5 vs $10" in (tmp_path / "o" / "transfer_plot.svg").read_text()
    assert matplotlib.rcParams["text.parse_math"]  # the user's own settings are left as they were


def test_the_plot_names_the_tag_it_compares(tmp_path):
    for side, rate in (("baseline", 0.0), ("transfer", 0.5)):
        for seed in range(3):
            run = tmp_path / side / f"seed_{seed}"
            run.mkdir(parents=True)
            (run / "eval.csv").write_text("frames,return_mean,success_rate\n" + f"0,0.0,0.0\n10,1.0,{rate}\n")
            (run / "config.yaml").write_text("task: fourrooms/northeast\n")  # no seed: unpaired
    report.transfer_report(tmp_path / "baseline", tmp_path / "transfer", tmp_path / "o", tag="success_rate")
    svg = (tmp_path / "o" / "transfer_plot.svg").read_text()
    assert "mean success_rate gain +0.25" in svg and "return gain" not in svg


def test_default_out_dir_is_fresh_and_named_after_the_runs(two_by_two, tmp_path, monkeypatch):
    b, t = two_by_two
    monkeypatch.chdir(tmp_path)
    first = Path(report.transfer_report(b, t)["out_dir"])
    second = Path(report.transfer_report(b, t)["out_dir"])
    assert first.name == "report-transfer-vs-baseline" and second.name == "report-transfer-vs-baseline-2"
    assert first.parent == second.parent == tmp_path
    assert not (tmp_path / "transfer_metrics.json").exists()


def _bad_report(tmp_path, baseline, transfer, **settings):
    out = tmp_path / "never"
    with pytest.raises(UsageError) as err:
        report.transfer_report(baseline, transfer, out, **settings)
    assert not out.exists()
    assert not list(tmp_path.rglob("transfer_*"))
    return str(err.value)


def test_bad_inputs_write_nothing(two_by_two, tmp_path):
    b, t = two_by_two
    empty = tmp_path / "empty"
    empty.mkdir()
    assert "holds no runs" in _bad_report(tmp_path, b, empty)
    broken = tmp_path / "broken"
    write_run(broken, [0, 10, 10], [1, 2, 3])
    msg = _bad_report(tmp_path, b, broken)
    assert "appears twice" in msg and str(broken / "eval.csv") in msg
    header_only = tmp_path / "header_only"
    header_only.mkdir()
    (header_only / "eval.csv").write_text("frames,return_mean,return_std,episodes,success_rate\n")
    assert "header but no rows" in _bad_report(tmp_path, header_only, t)
    other = write_run(tmp_path / "other_task", [0, 10, 40], [0, 1, 2], "gridrooms/far")
    msg = _bad_report(tmp_path, b, other)
    assert "different tasks" in msg and "fourrooms/near" in msg and "gridrooms/far" in msg
    mixed = tmp_path / "mixed"
    write_run(mixed / "a", [0, 40], [0, 1], "fourrooms/near")
    write_run(mixed / "b", [0, 40], [0, 1], "fourrooms/far")
    assert "mix tasks" in _bad_report(tmp_path, mixed, t)
    long = write_run(tmp_path / "long", [0, 100, 200], [0, 1, 2], "fourrooms/near")
    msg = _bad_report(tmp_path, b, long)
    assert "lengths differ too much" in msg and "--budget" in msg
    assert "before the budget of 45" in _bad_report(tmp_path, b, t, budget=45)
    sparse = write_run(tmp_path / "sparse", [0, 10, 50], [0, 1, 2], "fourrooms/near")
    assert "no evaluation in the asymptote window" in _bad_report(tmp_path, b, sparse, asymptote_window=0.1)
    assert "--jumpstart-window" in _bad_report(tmp_path, b, t, jumpstart_window=4)
    assert "neither a number" in _bad_report(tmp_path, b, t, threshold="lots")
    assert "not a number of frames" in _bad_report(tmp_path, b, t, budget="soon")
    assert "no column 'reward'" in _bad_report(tmp_path, b, t, tag="reward")


def test_fraction_threshold_needs_a_positive_best(tmp_path):
    f = [0.0, 10.0]
    neg = Curve(f, [-3.0, -1.0], "b", "b")
    with pytest.raises(UsageError, match="not positive"):
        report.compute([neg], [neg], threshold="80%")


def test_cli_errors_exit_2_with_one_sentence(tmp_path, capsys):
    assert report_cli.main(["--baseline", str(tmp_path / "nope"), "--transfer", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("drltg report: error: ") and "does not exist" in err and "\n" not in err
    assert report_cli.main(["--baseline", str(tmp_path)]) == 2


def test_transfer_matrix(sb3_runs, tmp_path, capsys):
    grid = tmp_path / "grid"
    for source, target, base, tran in [
        ("lift", "liftplace", "liftplace_sac", "liftplace_sac_policyreuse"),
        ("lift", "liftplacebarrier", "liftplacebarrier_sac", "liftplacebarrier_sac_policyreuse"),
        ("liftplace", "liftplacebarrier", "liftplacebarrier_sac", "liftplacebarrier_sac_policyreuse"),
    ]:
        cell = grid / source / target
        cell.mkdir(parents=True)
        (cell / "baseline").symlink_to(sb3_runs / base)
        (cell / "transfer").symlink_to(sb3_runs / tran)
    out = tmp_path / "matrix"
    assert report_cli.main(["--matrix", str(grid), "--metric", "jumpstart", "--out", str(out)]) == 0
    assert set(os.listdir(out)) == {f"transfer_matrix.{e}" for e in ("png", "svg", "csv", "json")}
    rows = list(csv.reader(io.StringIO((out / "transfer_matrix.csv").read_text())))
    assert rows[0] == ["source", "liftplace", "liftplacebarrier"]
    assert rows[2][0] == "liftplace" and rows[2][1] == ""  # no liftplace -> liftplace cell
    cells = json.loads((out / "transfer_matrix.json").read_text())["cells"]
    one = next(c for c in cells if c["target"] == "liftplace")
    assert float(rows[1][1]) == pytest.approx(one["metrics"]["jumpstart"])
    assert float(rows[1][2]) == pytest.approx(float(rows[2][2]))  # same runs, same number
    assert (out / "transfer_matrix.png").stat().st_size > 10_000
    assert "liftplacebarrier" in capsys.readouterr().out
    with pytest.raises(UsageError, match="unknown --metric"):
        report.transfer_matrix(report.find_matrix_cells(grid), tmp_path / "m2", metric="speed")
    assert not (tmp_path / "m2").exists()
    with pytest.raises(UsageError, match="holds no <source>/<target>"):
        report.find_matrix_cells(tmp_path / "matrix")


def test_a_matrix_gives_one_verdict_across_its_cells(tmp_path):
    """The stratified sign-flip test over the cells, a stratum a cell (hand-counted in tests/test_metrics.py):
    gains 1, 2, 3 | 4, 5, 6, 7, every pair up: p = 2/2^7; gains 3, 6, -3 | 2, 4: p = 8/32."""
    def cells(*gains):
        return {("src", f"t{j}"): (flat([0.0] * len(g), seeds=list(range(len(g))), prefix="b"),
                                   flat([float(x) for x in g], seeds=list(range(len(g))), prefix="t"))
                for j, g in enumerate(gains)}

    up = report.transfer_matrix(cells([1, 2, 3], [4, 5, 6, 7]), tmp_path / "up")["across_cells"]
    assert (up["pairs"], up["seed_pairs"], up["p"], up["verdict"]) == (
        ["src -> t0", "src -> t1"], 7, pytest.approx(2 / 128), "higher")
    assert up["mean_difference"] == pytest.approx((2 + 5.5) / 2)
    mixed = report.transfer_matrix(cells([3, 6, -3], [2, 4]), tmp_path / "mixed")["across_cells"]
    assert (mixed["p"], mixed["verdict"]) == (pytest.approx(0.25), "undecided")
    assert json.loads((tmp_path / "mixed" / "transfer_matrix.json").read_text())["across_cells"]["p"] == 0.25
    # rliable's aggregates over the cells, of raw mean returns (no range given) and the first 3 runs of each cell (the
    # fewest a cell has): gains 1, 2, 3 and 4, 5, 6 over baselines of 0, so the mean over cells differs by (2 + 5) / 2
    aggregates = report.transfer_matrix(cells([1, 2, 3], [4, 5, 6, 7]), tmp_path / "agg")["aggregates"]
    assert aggregates["runs_per_pair"] == 3 and not aggregates["normalised"]
    assert aggregates["difference"]["mean"][0] == pytest.approx((2 + 5) / 2)
    assert aggregates["probability_of_improvement"][0] == 1.0


# ------------------------------------------------------------------------- statistics of issue 13
def flat(values, seeds=None, frames=(0, 10, 20, 30), prefix="run", **config):
    """One constant curve per value: every per-seed score (initial, final, mean return) is the value."""
    return [Curve(frames, [v] * len(frames), f"{prefix}{i}", f"{prefix}{i}",
                  config=None if seeds is None else {"seed": seeds[i], **config})
            for i, v in enumerate(values)]


def test_paired_by_seed_uses_the_per_pair_differences():
    b = flat([1.0, 2.0, 3.0], seeds=[0, 100, 200], prefix="b")
    t = flat([6.0, 2.0, 4.0], seeds=[200, 0, 100], prefix="t")  # listed in another order
    res = report.compute(b, t, interval="t")
    m, st = res["metrics"], res["settings"]
    assert st["paired"] is True and "paired by seed" in st["pairing"]
    assert [r["seed"] for r in res["per_seed"]["transfer"]] == [0, 100, 200]  # aligned with the baseline
    # pairs (1, 2), (2, 4), (3, 6): d = 1, 2, 3, mean 2, s_d = 1; t_{0.975, 2} = 4.302653
    half = 4.302653 / np.sqrt(3)
    assert m["mean_return_gain"] == pytest.approx(2)
    assert m["mean_return_gain_ci"] == pytest.approx([2 - half, 2 + half], abs=1e-5)
    assert m["jumpstart_ci"] == pytest.approx(m["mean_return_gain_ci"])
    # every pair improves: P = 1, Clopper-Pearson lower bound 0.025^(1/3); the sign test's p = 2 / 2^3
    assert m["probability_of_improvement"] == 1.0
    assert m["probability_of_improvement_ci"] == pytest.approx([0.025 ** (1 / 3), 1.0], abs=1e-6)
    assert m["probability_of_improvement_p_value"] == pytest.approx(0.25)
    # the paired t test behind the interval: t = 2 / (1 / sqrt 3) on 2 df
    assert m["mean_return_gain_p_value"] == pytest.approx(0.07418, abs=1e-5)
    # areas 30, 60, 90 vs 60, 120, 180: ratio 1, but the baseline mean area's interval contains 0
    assert m["transfer_ratio"] == pytest.approx(1.0)
    assert "transfer_ratio_ci" not in m
    assert any("transfer_ratio has no interval" in w and "contains 0" in w for w in st["warnings"])


def test_unpaired_uses_welch_standard_error_with_hsu_degrees_of_freedom():
    b = flat([1.0, 2.0, 3.0], prefix="b")
    t = flat([2.0, 4.0, 6.0], prefix="t")
    res = report.compute(b, t, interval="t")
    m, st = res["metrics"], res["settings"]
    assert st["paired"] is False and "foreign logs" in st["pairing"]
    # se = sqrt(1/3 + 4/3); df = min(3, 3) - 1 = 2
    half = 4.302653 * np.sqrt(5 / 3)
    assert m["mean_return_gain_ci"] == pytest.approx([2 - half, 2 + half], abs=1e-5)
    # all 9 (b, t) combinations: 7 wins and one tie (2, 2) -> 7.5 / 9
    assert m["probability_of_improvement"] == pytest.approx(7.5 / 9)
    lo, hi = m["probability_of_improvement_ci"]
    assert 0 < lo < 7.5 / 9 < hi < 1
    forced = report.compute(b, t, paired=True, interval="t")
    assert forced["settings"]["paired"] and "in the order given" in forced["settings"]["pairing"]
    assert forced["metrics"]["mean_return_gain_ci"] == pytest.approx(
        [2 - 4.302653 / np.sqrt(3), 2 + 4.302653 / np.sqrt(3)], abs=1e-5)
    with pytest.raises(UsageError, match="as many transfer runs as baseline runs"):
        report.compute(b, t[:2], paired=True)


def test_seeds_that_do_not_match_are_unpaired_and_refused_with_paired():
    b = flat([1.0, 2.0, 3.0], seeds=[0, 1, 2], prefix="b")
    t = flat([2.0, 4.0, 6.0], seeds=[0, 1, 5], prefix="t")
    st = report.compute(b, t)["settings"]
    assert st["paired"] is False and "[0, 1, 2]" in st["pairing"] and "[0, 1, 5]" in st["pairing"]
    with pytest.raises(UsageError, match="--paired cannot pair these runs"):
        report.compute(b, t, paired=True)


def test_no_degenerate_intervals():
    # policy reuse: each transfer run starts where its baseline twin starts, so the jumpstart is 0
    f = (0, 10, 20, 30)
    b = [Curve(f, [v, 1, 2, 3], f"b{i}", f"b{i}", config={"seed": i}) for i, v in enumerate([0.1, 0.5, 0.2])]
    t = [Curve(f, [v, 2, 3, 5 + i], f"t{i}", f"t{i}", config={"seed": i}) for i, v in enumerate([0.1, 0.5, 0.2])]
    res = report.compute(b, t, interval="t")
    m, st = res["metrics"], res["settings"]
    assert m["jumpstart"] == 0 and "jumpstart_ci" not in m
    assert any("jumpstart has no interval: every pair gives the same difference (0)" in w for w in st["warnings"])
    # the same difference in every pair, from curves whose areas differ only in round-off: no interval
    # and no p-value (the t test's would be ~1e-32)
    g = (0, 5, 10, 15)
    b = [Curve(g, [0, 0, v, 0], f"b{i}", f"b{i}", config={"seed": i}) for i, v in enumerate([0.1, 0.0, 0.0])]
    t = [Curve(g, [1, 0, v, 0], f"t{i}", f"t{i}", config={"seed": i}) for i, v in enumerate([0.1, 0.0, 0.0])]
    res = report.compute(b, t, paired=True, threshold=None, interval="t")
    m = res["metrics"]
    assert m["mean_return_gain"] == pytest.approx(1 / 6)
    assert "mean_return_gain_ci" not in m and "mean_return_gain_p_value" not in m
    assert "mean_return_gain has no interval: every pair gives the same difference (0.1667)" in \
        res["settings"]["warnings"][0]
    # every run of each side identical: no spread at all
    same = report.compute(flat([1.0] * 3, prefix="b"), flat([2.0] * 3, prefix="t"), interval="t")
    assert "mean_return_gain_ci" not in same["metrics"]
    assert any("identical values" in w for w in same["settings"]["warnings"])
    table = report.format_table(same)
    assert "[1, 1]" not in table and "[2, 2]" not in table
    # P(T > B) = 1 keeps an interval that is not [1, 1]
    assert same["metrics"]["probability_of_improvement_ci"][0] < 1


def test_mean_return_gain_is_offset_free_and_the_ratio_is_not():
    b = flat([1.0, 2.0, 3.0], prefix="b")
    t = flat([2.0, 4.0, 6.0], prefix="t")
    shifted_b = flat([11.0, 12.0, 13.0], prefix="b")
    shifted_t = flat([12.0, 14.0, 16.0], prefix="t")
    m, s = report.compute(b, t, interval="t")["metrics"], report.compute(shifted_b, shifted_t, interval="t")["metrics"]
    assert m["mean_return_gain"] == pytest.approx(s["mean_return_gain"]) == pytest.approx(2)
    assert m["mean_return_gain_ci"] == pytest.approx(s["mean_return_gain_ci"])
    assert m["transfer_ratio"] == pytest.approx(1.0) and s["transfer_ratio"] == pytest.approx(2 / 12)
    assert report.metrics_rows(m)[0][0] == "mean_return_gain"


def test_sustained_crossing_by_default_first_on_request():
    f = np.arange(9) * 100.0
    y = [0, 6, 0, 6, 6, 0, 6, 6, 6]
    b, t = [Curve(f, y, "b", "b")], [Curve(f, [6] * 9, "t", "t")]
    assert report.compute(b, t, threshold=5)["metrics"]["time_to_threshold_baseline"] == 600
    assert report.compute(b, t, threshold=5, sustain=2)["metrics"]["time_to_threshold_baseline"] == 300
    first = report.compute(b, t, threshold=5, crossing="first")
    assert first["metrics"]["time_to_threshold_baseline"] == 100
    assert first["settings"]["time_to_threshold_rule"].startswith("first evaluation at or above")
    with pytest.raises(UsageError, match="--sustain applies to a sustained crossing"):
        report.compute(b, t, threshold=5, crossing="first", sustain=2)


def test_median_time_is_a_frame_a_run_had():
    f = np.arange(7) * 100.0
    runs = [Curve(f, [0] * i + [9] * (7 - i), f"b{i}", f"b{i}") for i in (1, 2, 3)]
    runs.append(Curve(f, [0] * 7, "b9", "b9"))  # never reaches it
    res = report.compute(runs, flat([9.0], frames=tuple(f)), threshold=5)
    assert [r["time_to_threshold"] for r in res["per_seed"]["baseline"]] == [100, 200, 300, None]
    # upper median: by frame 300, 3 of 4 runs (a strict majority) stay above; the mean of 200 and 300
    # would be a frame no run was evaluated at
    assert res["metrics"]["time_to_threshold_baseline"] == 300
    assert "upper median" in res["settings"]["median_rule"]


def test_a_curve_still_rising_at_the_budget_is_flagged():
    f = np.arange(0, 101, 5.0)
    rising = [Curve(f, f / 10 + 0.1 * i, f"b{i}", f"b{i}") for i in range(3)]
    level = flat([1.0, 2.0, 3.0], frames=tuple(f), prefix="t")
    res = report.compute(rising, level)
    st, m = res["settings"], res["metrics"]
    # last 25 % = frames 75..100 (6 evaluations) on a line of slope 0.1 per frame: +2.5 over the window;
    # the transfer runs are flat, so their mean curve has nothing left to change
    assert st["convergence"] == {"baseline": "still rising", "transfer": "converged"}
    assert m["final_trend_baseline"] == pytest.approx(2.5)
    assert any("baseline mean curve is still rising" in w and "not asymptotes" in w for w in st["warnings"])
    assert "final performance, not an asymptote: baseline still rising" in report.format_table(res)


def _source_run(path: Path, frames: int) -> Path:
    path.mkdir(parents=True)
    (path / "config.yaml").write_text(f"task: fourrooms/source\nseed: 50\nframes: {frames}\n")
    return path


def test_total_time_counts_the_source_frames(tmp_path):
    source = _source_run(tmp_path / "source" / "seed-50", frames=10)
    f = [0, 10, 20, 30]
    write_run(tmp_path / "b" / "seed-0", f, [0, 0, 3, 3], "fourrooms/near")
    t = write_run(tmp_path / "t" / "seed-0", f, [0, 1, 2, 3], "fourrooms/near")
    (t / "config.yaml").write_text(
        f"task: fourrooms/near\nseed: 0\ntransfer:\n  method: policy-reuse\n  source: {source}\n")
    res = report.compute(_read(tmp_path / "b"), _read(tmp_path / "t"), threshold=2, crossing="first")
    m, st = res["metrics"], res["settings"]
    assert st["source_frames"] == [10]
    # target frames only: areas 15 + 30 = 45 and 45 over 30 frames, no gain
    assert m["mean_return_gain"] == pytest.approx(0)
    # equal total frames: the baseline over [10, 30] (area 45, mean 2.25) against the transfer run's
    # first 20 target frames (area 20, mean 1), which follow its 10 source frames
    assert res["per_seed"]["baseline"][0]["mean_return_total_time"] == pytest.approx(2.25)
    assert res["per_seed"]["transfer"][0]["mean_return_total_time"] == pytest.approx(1)
    assert m["mean_return_gain_with_source"] == pytest.approx(-1.25)
    # the transfer run first reaches 2 at target frame 20, within its 20 target frames: 20 + 10
    assert m["time_to_threshold_baseline"] == 20 and m["time_to_threshold_transfer"] == 20
    assert m["time_to_threshold_transfer_with_source"] == 30
    assert res["per_seed"]["transfer"][0]["source_frames"] == 10
    assert "total time: source frames counted" in report.format_table(res)
    foreign = report.compute([Curve(f, [0, 0, 3, 3], "b", "b")], [Curve(f, [0, 1, 2, 3], "t", "t")],
                             threshold=2, source_frames="10")
    assert foreign["metrics"]["mean_return_gain_with_source"] == pytest.approx(-1.25)
    assert "whole budget" in " ".join(report.compute(
        [Curve(f, [0, 0, 3, 3], "b", "b")], [Curve(f, [0, 1, 2, 3], "t", "t")],
        source_frames=30)["settings"]["warnings"])
    assert foreign["settings"]["source_frames_basis"] == "--source-frames"
    without = report.compute([Curve(f, [1] * 4, "b", "b")], [Curve(f, [0, 1, 2, 3], "t", "t")])
    assert "mean_return_gain_with_source" not in without["metrics"]
    assert "--source-frames" in without["settings"]["source_frames_basis"]


def test_a_demonstrator_source_costs_no_frames(tmp_path):
    f = [0, 10, 20, 30]
    write_run(tmp_path / "b" / "seed-0", f, [1, 1, 1, 1], "lift")
    t = write_run(tmp_path / "t" / "seed-0", f, [0, 1, 2, 3], "lift")
    (t / "config.yaml").write_text(
        "task: lift\nseed: 0\ntransfer:\n  method: policy-reuse\n  source: demonstrator:lift\n")
    res = report.compute(_read(tmp_path / "b"), _read(tmp_path / "t"))
    assert res["settings"]["source_frames"] == [0]
    assert "no source training" in res["settings"]["source_frames_basis"]


def test_the_same_run_twice_is_refused(two_by_two, tmp_path):
    b, t = two_by_two
    msg = _bad_report(tmp_path, [b / "seed_0", b / "seed_0" / "eval.csv", b / "seed_1"], t)
    assert "is given twice among the baseline runs" in msg
    assert "both a baseline and a transfer run" in _bad_report(tmp_path, b, [t, b / "seed_1"])


def test_runs_of_different_configs_under_one_side(tmp_path):
    f = [0, 10, 20]
    for i, lr in enumerate(["0.001", "0.001", "0.0003"]):
        run = write_run(tmp_path / "b" / f"seed-{i}", f, [0, 1, 2])
        (run / "config.yaml").write_text(f"task: x\nseed: {i}\noptim:\n  lr: {lr}\n")
        run = write_run(tmp_path / "t" / f"seed-{i}", f, [1, 2, 3])
        (run / "config.yaml").write_text(f"task: x\nseed: {i}\noptim:\n  lr: 0.001\n"
                                         f"transfer:\n  method: policy-reuse\n  source: /src/{i}\n")
    msg = _bad_report(tmp_path, tmp_path / "b", tmp_path / "t")
    assert "the baseline runs mix configurations" in msg and "optim.lr" in msg and "--allow-mixed" in msg
    res = report.compute(_read(tmp_path / "b"), _read(tmp_path / "t"), allow_mixed=True,
                         source_frames=0)
    assert any("accepted by --allow-mixed" in w for w in res["settings"]["warnings"])


def test_a_config_saved_before_its_keys_existed_is_the_same_configuration(tmp_path):
    """Keys an older config lacks stand for their defaults (env settings saved in full, a method's
    later options), as when such a run is resumed; a key set otherwise still splits the side."""
    import yaml

    from drltg import config

    full = config.resolve(None, ["transfer.source=demonstrator:x"], task="fourrooms/northeast", algo="sac").model_dump()
    old = {**full, "env": {}, "transfer": {k: v for k, v in full["transfer"].items() if k != "bc_weight"}}
    changed = {**full, "env": {**full["env"], "horizon": 60}}
    for name, cfg in [("seed-0", old), ("seed-1", full), ("seed-2", full)]:
        for side, values in (("b", [0, 1, 2]), ("t", [1, 2, 3])):
            run = write_run(tmp_path / side / name, [0, 10, 20], values)
            (run / "config.yaml").write_text(yaml.safe_dump({**cfg, "seed": int(name[-1])}))
    assert report.compute(_read(tmp_path / "b"), _read(tmp_path / "t"))["metrics"]["n_seeds_baseline"] == 3
    (tmp_path / "b" / "seed-2" / "config.yaml").write_text(yaml.safe_dump({**changed, "seed": 2}))
    assert "env.horizon" in _bad_report(tmp_path, tmp_path / "b", tmp_path / "t")


def test_out_that_is_a_file_exits_2(two_by_two, tmp_path, capsys):
    b, t = two_by_two
    afile = tmp_path / "afile"
    afile.write_text("keep")
    for out in (afile, afile / "sub"):
        assert report_cli.main(["--baseline", str(b), "--transfer", str(t), "--out", str(out)]) == 2
        err = capsys.readouterr().err.strip()
        assert "is a file, not a folder" in err and "\n" not in err
    assert afile.read_text() == "keep"


def test_settings_define_the_cli_options(capsys):
    import argparse

    parser = argparse.ArgumentParser()
    report_cli.add_arguments(parser)
    args = parser.parse_args(["--baseline", "b", "--transfer", "t", "--paired", "--source-frames", "40k",
                              "--sustain", "3"])
    s = report.ReportSettings.from_args(args)
    assert (s.crossing, s.paired, s.source_frames, s.sustain, s.interval) == ("sustained", True, 40_000, 3, "auto")
    assert report.ReportSettings.from_args(parser.parse_args(["--crossing", "first"])).crossing == "first"
    for bad, text in ((["--sustain", "1"], "--sustain must be at least 2"),
                      (["--trend-window", "2"], "--trend-window must lie in (0, 1]"),
                      (["--source-frames", "lots"], "--source-frames 'lots' is not a number")):
        assert report_cli.main(["--baseline", "b", "--transfer", "t", *bad]) == 2
        assert text in capsys.readouterr().err


def test_sb3_fixture_first_crossing_reproduces(sb3_runs, tmp_path):
    """``--crossing first`` keeps the earlier implementation's rule: the first evaluation at or above 150."""
    import csv as csv_

    res = report.compute(_read(sb3_runs / "liftplace_sac"), _read(sb3_runs / "liftplace_sac_policyreuse"),
                         threshold=150, crossing="first")
    budget = res["settings"]["budget"]
    for side, name in (("baseline", "liftplace_sac"), ("transfer", "liftplace_sac_policyreuse")):
        with open(sb3_runs / name / "progress.csv", newline="") as fh:
            rows = [(float(r["time/total_timesteps"]), float(r["eval/mean_reward"]))
                    for r in csv_.DictReader(fh) if r["eval/mean_reward"] != ""]
        expected = next((x for x, y in rows if y >= 150 and x <= budget), None)
        assert res["metrics"][f"time_to_threshold_{side}"] == expected
    assert res["metrics"]["jumpstart"] == pytest.approx(24.81896 - 4.3869472)
    assert res["settings"]["paired"] is False


def test_out_that_cannot_be_written_exits_2(two_by_two, tmp_path, capsys, monkeypatch):
    b, t = two_by_two
    locked = tmp_path / "locked"
    locked.mkdir()
    monkeypatch.setattr(outputs.os, "access", lambda path, mode: Path(path) != locked)
    assert report_cli.main(["--baseline", str(b), "--transfer", str(t), "--out", str(locked / "rep")]) == 2
    err = capsys.readouterr().err.strip()
    assert "cannot be written" in err and "read-only" in err and "\n" not in err
    assert list(locked.iterdir()) == []


# ------------------------------------------------------------------------------ the pipeline's shape
def test_per_seed_scores_are_one_frame_with_side_and_pair():
    b = flat([1.0, 2.0, 3.0], seeds=[0, 100, 200], prefix="b")
    t = flat([6.0, 2.0, 4.0], seeds=[200, 0, 100], prefix="t")
    scores = report.compute(b, t)["scores"]
    assert list(scores.columns[:3]) == ["side", "pair", "label"]
    assert scores["side"].tolist() == ["baseline"] * 3 + ["transfer"] * 3
    assert scores["pair"].tolist() == [0, 1, 2, 0, 1, 2]
    assert scores["seed"].tolist() == [0, 100, 200, 0, 100, 200]  # transfer rows in their pair's order
    assert scores["mean_return"].tolist() == [1.0, 2.0, 3.0, 2.0, 4.0, 6.0]  # flat curves: the value itself
    assert scores["total_reward"].tolist() == [30.0, 60.0, 90.0, 60.0, 120.0, 180.0]
    unpaired = report.compute(b, t, paired=False)["scores"]
    assert unpaired["pair"].isna().all() and unpaired["label"].tolist()[3:] == ["t0", "t1", "t2"]


def test_a_new_metric_is_one_entry(monkeypatch):
    """An entry of METRICS reaches the JSON metrics, the CSV rows and the text table."""
    entry = report.Metric("total_reward_gain", "difference", "total_reward", iqm=True, note="area, not mean")
    monkeypatch.setattr(catalogue, "METRICS", catalogue.METRICS + (entry,))
    res = report.compute(flat([1.0, 2.0, 3.0], prefix="b"), flat([2.0, 4.0, 6.0], prefix="t"), interval="t")
    m = res["metrics"]
    assert m["total_reward_gain"] == pytest.approx(60.0)  # areas 30, 60, 90 vs 60, 120, 180
    assert m["total_reward_gain_iqm"] == pytest.approx(60.0)
    assert m["total_reward_gain_ci"] == pytest.approx([30 * x for x in m["mean_return_gain_ci"]])  # span 30
    rows = report.metrics_rows(m)
    assert [r[0] for r in rows][-2:] == ["total_reward_gain", "total_reward_gain_iqm"]  # after TABLE_ROWS
    table = report.format_table(res)
    assert "total_reward_gain" in table and "area, not mean" in table
    report.check_metric("total_reward_gain")


def test_json_keys_keep_their_published_order():
    res = report.compute(flat([1.0, 2.0, 3.0], seeds=[0, 1, 2], prefix="b"),
                         flat([2.0, 4.0, 7.0], seeds=[0, 1, 2], prefix="t"), threshold=1.5)
    keys = [k for k in res["metrics"] if not k.endswith(("_ci", "_iqm", "_p_value", "_p_adjusted", "_p_exact",
                                                         "_verdict", "_verdict_test", "_verdict_p",
                                                         "_pairs_for_80_power", "_assumes", "_median",
                                                         "_interval", "_interval_level"))]
    assert keys == [
        "n_seeds_baseline", "n_seeds_transfer", "mean_return_gain", "jumpstart", "asymptotic_performance",
        "transfer_ratio", "probability_of_improvement", "probability_of_improvement_initial",
        "probability_of_improvement_final",
        "total_reward_baseline", "initial_performance_baseline", "final_performance_baseline",
        "time_to_threshold_baseline", "threshold_reached_baseline",
        "total_reward_transfer", "initial_performance_transfer", "final_performance_transfer",
        "time_to_threshold_transfer", "threshold_reached_transfer",
        "final_trend_baseline", "final_trend_transfer"]
    assert [r[0] for r in report.metrics_rows(res["metrics"])][:4] == [
        "mean_return_gain", "jumpstart", "asymptotic_performance", "transfer_ratio"]


@pytest.mark.parametrize("gains, paired, verdict, p", [
    ([1, 2, 3, 1, 2, 3], True, "higher", 2 / 2**6),   # every pair above: the two extreme sign patterns of 64
    ([1, 2, 3, 1, 2], True, "undecided", 2 / 2**5),   # 5 pairs can give no p below 0.0625
    ([-1, -2, -3, -1, -2, -3, -4], True, "lower", 2 / 2**7),
    # sum 8 of |d| 12: a pattern reaches |sum| >= 8 by flipping |d|s summing to <= 2 (6 subsets) or >= 10 (6)
    ([1, -2, 3, 1, 2, 3], True, "undecided", 12 / 64),
    ([5, 5, 5, 5], False, "higher", 2 / 70),           # 4 + 4 runs fully separated: 2 of C(8, 4) = 70 splits
])
def test_every_comparison_carries_the_exact_test_s_verdict(gains, paired, verdict, p):
    """Hand-counted: the sign-flip test over n pairs has 2^n equally likely sign patterns under no effect,
    and the two-sided p counts those whose |mean| is at least the observed one."""
    n = len(gains)
    base = [float(i % 3) for i in range(n)]
    seeds = list(range(n)) if paired else None
    b = flat(base, seeds=seeds, prefix="b")
    t = flat([x + g for x, g in zip(base, gains)], seeds=seeds if paired else [100 + i for i in range(n)], prefix="t")
    m = report.compute(b, t, value_range=(-10.0, 10.0))["metrics"]
    for name in ("mean_return_gain", "jumpstart", "asymptotic_performance"):
        assert m[f"{name}_verdict"] == verdict
        assert m[f"{name}_verdict_test"] == ("sign-flip" if paired else "permutation")
        assert m[f"{name}_verdict_p"] == pytest.approx(p)


def test_each_magnitude_says_what_it_assumes():
    """7 pairs with differences 3, -1, 4, 1, 5, 9, 2 (sorted -1, 1, 2, 3, 4, 5, 9): the order-statistic interval of
    their median is [d_(1), d_(7)] = [-1, 9] at 1 - 2/128 (P(Bin(7, 1/2) <= 1) = 8/128 is too likely for k = 2); the
    paired t interval is 23/7 +- t_{0.975, 6} s_d / sqrt 7; the betting interval is the worst case over the range."""
    gains = [3.0, -1.0, 4.0, 1.0, 5.0, 9.0, 2.0]
    base = [float(i % 3) for i in range(7)]
    b = flat(base, seeds=list(range(7)), prefix="b")
    t = flat([x + g for x, g in zip(base, gains)], seeds=list(range(7)), prefix="t")
    res = report.compute(b, t, value_range=(-20.0, 20.0))
    m = res["metrics"]
    assert m["mean_return_gain_median"] == 3.0
    assert m["mean_return_gain_median_interval"] == [-1.0, 9.0]
    assert m["mean_return_gain_median_interval_level"] == pytest.approx(1 - 2 / 128)
    assert m["mean_return_gain_median_interval_assumes"] == "independent pairs, any shape"
    half = 2.446912 * np.std(gains, ddof=1) / np.sqrt(7)
    assert m["mean_return_gain_t_interval"] == pytest.approx([23 / 7 - half, 23 / 7 + half], abs=1e-5)
    assert m["mean_return_gain_t_interval_assumes"] == "normal differences"
    assert m["mean_return_gain_ci_assumes"] == "only the declared range (worst case over it)"
    assert m["probability_of_improvement_ci_assumes"] == "independent pairs, any shape"
    # the verdict is the sign-flip test's, not any interval's: of |d| 3, 1, 4, 1, 5, 9, 2 (sum 25), flipping a sum
    # F <= 1 ({}, either 1) keeps |sum| >= 23, as do the 3 mirror patterns: p = 6/128 < 0.05
    assert m["mean_return_gain_verdict"] == "higher"
    assert m["mean_return_gain_verdict_p"] == pytest.approx(6 / 128)
    # every interval of the report carries its label
    assert all(f"{k}_assumes" in m for k in m if k.endswith(("_ci", "_interval")))
    table = report.format_table(res)
    assert "worst case over the declared range [-20, 20]" in table and "assumes normal differences" in table
    assert "assumes independent pairs, any shape" in table and "3 [-1, 9]" in table
    # the table leads with the verdict; the metric table after it says its intervals are each metric's own
    assert table.index("verdict: each mean difference's exact test") < table.index("every metric with its own")
    from drltg.analysis.plot import summary_lines

    shown = summary_lines(m, res["settings"], {})
    assert shown[:4] == ["verdict: mean return gain +3.29, higher with transfer",
                         "  exact sign-flip test, 7 pairs: p = 0.0469",
                         f"  mean [{23 / 7 - half:+.3g}, {23 / 7 + half:+.3g}] (paired t, 95%)",
                         f"  median +3 [-1, +9] (order statistics, {100 * (1 - 2 / 128):.1f}%)"]
    assert "transfer - baseline [worst case over the declared range, 95%], paired" in shown
    unpaired = report.compute(flat(base, prefix="b"), flat(gains, prefix="t"), value_range=(-20.0, 20.0))["metrics"]
    assert unpaired["mean_return_gain_t_interval_assumes"] == "normal scores on each side"
    # unpaired, the Hodges-Lehmann shift of the flat curves' values and its Mann-Whitney interval
    shift, lo, hi, level = order_stats.shift_interval(base, gains)
    assert unpaired["mean_return_gain_median"] == shift and unpaired["mean_return_gain_median_interval"] == [lo, hi]
    assert unpaired["mean_return_gain_median_interval_level"] == level > 0.95
    assumes = unpaired["mean_return_gain_median_interval_assumes"]
    assert assumes == "independent runs, the sides differing by a shift, any shape"
    ranged_t = report.compute(b, t, interval="t")["metrics"]
    assert ranged_t["mean_return_gain_ci_assumes"] == "normal differences"
    assert ranged_t["mean_return_gain_ci"] == pytest.approx(ranged_t["mean_return_gain_t_interval"])


def test_runs_of_two_methods_under_one_side_need_allow_mixed(tmp_path, capsys):
    for i, method in enumerate(["policy-reuse", "policy-reuse", "model-reuse"]):
        write_run(tmp_path / "b" / f"seed-{i}", [0, 10, 20], [0, 1, 2])
        (tmp_path / "b" / f"seed-{i}" / "config.yaml").write_text(f"task: x\nseed: {i}\n")
        run = write_run(tmp_path / "t" / f"seed-{i}", [0, 10, 20], [1, 2, 3])
        (run / "config.yaml").write_text(f"task: x\nseed: {i}\ntransfer:\n  method: {method}\n")
    args = ["--baseline", str(tmp_path / "b"), "--transfer", str(tmp_path / "t"), "--out", str(tmp_path / "r")]
    assert report_cli.main(args) == 2
    err = capsys.readouterr().err.strip()
    assert "the transfer runs mix configurations" in err and "transfer.method=model-reuse" in err
    assert "\n" not in err and not (tmp_path / "r").exists()
    assert report_cli.main(args + ["--allow-mixed"]) == 0
    assert "accepted by --allow-mixed" in capsys.readouterr().err


def test_other_modules_use_only_public_report_names():
    import ast

    root = Path(report.__file__).resolve().parents[1]
    for path in [*root.glob("drltg/**/*.py"), *root.glob("results/*.py")]:
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module in ("drltg.report", "drltg.analysis.tables"):
                assert not [a.name for a in node.names if a.name.startswith("_")], path


RESULTS = Path(__file__).resolve().parents[1] / "results"
NO_TORCH = ("torch", "drltg.envs", "drltg.transfer")


def test_the_analysis_package_imports_no_torch():
    """Nor the methods or the task registry; ``import drltg`` itself reads the task registry (no torch) to
    register the tasks' Gymnasium ids, so the registry counts only if the analysis is what brought it."""
    code = ("import sys, drltg\nbefore = set(sys.modules)\n"
            "import drltg.analysis, drltg.report, drltg.analysis.plot\n"
            f"leaked = [m for m in {NO_TORCH!r} if m in sys.modules and (m == 'torch' or m not in before)]\n"
            "assert not leaked, leaked")
    subprocess.run([sys.executable, "-c", code], check=True)


def test_a_report_on_run_directories_imports_no_torch(tmp_path):
    """The committed runs' configs differ in the method options they hold (saved as methods were added):
    each method's own options model fills in its defaults (the method modules, loaded through the registry,
    import torch only when a run is built), so a report imports no torch (nor does the task registry, read
    for the runs' return range)."""
    cell = RESULTS / "sweep-fourrooms-graded" / "fourrooms-near" / "sac"
    argv = ["report", "--baseline", str(cell / "baseline"), "--transfer", str(cell / "value-shaping" / "transfer"),
            "--threshold", "0.5", "--out", str(tmp_path / "out")]
    code = ("import sys\nfrom drltg.cli import main\n"
            f"assert main({argv!r}) == 0\n"
            f"leaked = [m for m in {('torch', 'torchrl')!r} if m in sys.modules]\nassert not leaked, leaked")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert "mix configurations" not in done.stdout + done.stderr
    assert json.loads((tmp_path / "out" / "transfer_metrics.json").read_text())["metrics"]["n_seeds_baseline"] == 10


def test_every_metric_with_an_interval_has_a_p_value_adjusted_over_the_report_s_family():
    b = flat([1.0, 2.0, 3.0, 2.5, 1.5], seeds=[0, 1, 2, 3, 4], prefix="b")
    t = flat([2.0, 4.0, 6.0, 3.0, 1.6], seeds=[0, 1, 2, 3, 4], prefix="t")
    res = report.compute(b, t, threshold=1.5, interval="t")
    m, family = res["metrics"], res["settings"]["family"]
    with_ci = [k.removesuffix("_ci") for k in m if k.endswith("_ci")]
    assert family["metrics"] == with_ci and family["size"] == len(with_ci) > 5
    ps = [m[f"{k}_p_value"] for k in with_ci]
    assert [m[f"{k}_p_adjusted"] for k in with_ci] == pytest.approx(stats.holm(ps))
    assert all(m[f"{k}_p_adjusted"] >= m[f"{k}_p_value"] for k in with_ci)
    # 5 pairs all improving: the sign test cannot reach 0.05 (p = 1/16), nor can the exact permutation test
    assert m["probability_of_improvement_p_value"] == pytest.approx(1 / 16)
    assert m["mean_return_gain_p_exact"] == pytest.approx(2 / 32)
    assert "family: " in report.format_table(res) and "p (Holm)" in report.format_table(res)


def test_skewed_per_seed_differences_take_the_exact_test_s_p_value():
    seeds = list(range(10))
    b = flat([0.0] * 10, seeds=seeds, prefix="b")
    t = flat([0.1, 0.2, 0.1, 0.3, 0.2, 0.1, 0.2, 0.3, 0.1, 9.0], seeds=seeds, prefix="t")  # one seed far out
    res = report.compute(b, t, interval="t")
    m = res["metrics"]
    assert m["mean_return_gain_p_value"] == m["mean_return_gain_p_exact"] == pytest.approx(2 / 2 ** 10)
    assert any("look skewed" in w and "exact permutation" in w for w in res["settings"]["warnings"])
    normal = report.compute(flat([0.0] * 3, seeds=[0, 1, 2], prefix="b"), flat([1.0, 2.0, 3.0], seeds=[0, 1, 2],
                                                                             prefix="t"), interval="t")["metrics"]
    assert normal["mean_return_gain_p_value"] != normal["mean_return_gain_p_exact"]  # the t test's, < 8 seeds


def test_a_success_rate_s_intervals_stay_in_their_range(tmp_path):
    """Rates in [0, 1]: differences' intervals within [-1, 1], probabilities within [0, 1]."""
    f = list(range(0, 101, 10))
    for side, rates in (("b", [0.0, 0.0, 1.0]), ("t", [1.0, 1.0, 0.0])):
        for i, r in enumerate(rates):
            run = tmp_path / side / f"seed-{i}"
            run.mkdir(parents=True)
            rows = "".join(f"{x},0.0,0.0,8,{r if x > 0 else 0.0}\n" for x in f)
            (run / "eval.csv").write_text("frames,return_mean,return_std,episodes,success_rate\n" + rows)
            (run / "config.yaml").write_text("task: fourrooms/northeast\n")  # no seed: unpaired
    res = report.transfer_report(tmp_path / "b", tmp_path / "t", tmp_path / "out", tag="success_rate", interval="t")
    m = res["metrics"]
    assert res["settings"]["value_range"] == [0, 1]
    assert m["asymptotic_performance_ci"][1] == 1.0 and m["asymptotic_performance_ci"][0] == -1.0  # cut to range
    unbounded = stats.t_interval(np.array([0.0, 0.0, 1.0]), np.array([1.0, 1.0, 0.0]))
    assert unbounded[1] > 1 and unbounded[0] < -1  # what the plain t interval would say
    for key, (lo, hi) in ((k, v) for k, v in m.items() if k.endswith("_ci")):
        assert (0.0 if "probability" in key else -1.0) <= lo <= hi <= 1.0, key


def test_the_default_interval_is_a_betting_interval_within_the_range_and_none_without_one():
    b = flat([0.0, 0.1, 0.0, 0.2, 0.1], seeds=range(5), prefix="b")
    t = flat([0.9, 1.0, 0.8, 1.0, 0.9], seeds=range(5), prefix="t")
    unknown = report.compute(b, t)
    m, st = unknown["metrics"], unknown["settings"]
    assert not any(k.endswith("_ci") and "probability" not in k for k in m)  # P(T > B) keeps its exact interval
    assert m["mean_return_gain_p_exact"] == pytest.approx(2 / 2 ** 5) and "mean_return_gain_p_value" not in m
    assert sum("no mean difference has an interval" in w for w in st["warnings"]) == 1
    ranged = report.compute(b, t, value_range="0,1")
    m, st = ranged["metrics"], ranged["settings"]
    lo, hi, p = stats.betting_interval(np.array([0.0, 0.1, 0.0, 0.2, 0.1]), np.array([0.9, 1.0, 0.8, 1.0, 0.9]),
                                       (0, 1), paired=True)
    assert m["mean_return_gain_ci"] == pytest.approx([lo, hi]) and m["mean_return_gain_p_value"] == pytest.approx(p)
    assert lo < 0 < m["mean_return_gain"] < hi  # 5 pairs: no betting interval excludes 0
    assert st["interval_method"] == "auto" and "from the values' range [0, 1] alone" in st["interval"]
    for bad in ("1,0", "0", "a,b", "0,inf"):
        with pytest.raises(UsageError, match="--value-range"):
            report.compute(b, t, value_range=bad)


def test_drltg_runs_bound_their_returns_by_the_range_their_task_declares():
    from drltg.envs.registry import TASKS

    assert TASKS["fourrooms/northeast"].return_range() == (-1.0, 1.0)  # 100 steps at 0.01, or the goal's +1
    assert TASKS["gridrooms/northeast"].return_range({"horizon": 200, "step_cost": 0.02}) == (-4.0, 1.0)
    assert TASKS["lift-place-seed"].return_range() == (0.0, 500.0)  # at most 1 a step for 500 steps
    assert TASKS["pendulum/g15"].return_range()[0] == pytest.approx(-(np.pi ** 2 + 6.4 + 0.004) * 200)

    def runs(side, values, **env):
        config = {"task": "fourrooms/northeast", "env": env}
        return [Curve((0, 10, 20), [v] * 3, f"{side}/seed-{i}/eval.csv", f"{side}{i}", config={"seed": i, **config})
                for i, v in enumerate(values)]

    b, t = runs("b", [-1.0, -0.8, -0.9]), runs("t", [0.5, 0.6, -1.0000001])  # float32 round-off of -1 is inside
    st = report.compute(b, t)["settings"]
    assert st["value_range"] == [-1.0, 1.0] and "[-1, 1] alone" in st["interval"]
    longer = report.compute(runs("b", [-1.5, -0.8, -0.9], horizon=150), runs("t", [0.5, 0.6, 0.7], horizon=150))
    assert longer["settings"]["value_range"] == [-1.5, 1.0]
    foreign = report.compute(flat([0.0, 0.1, 0.2], seeds=[0, 1, 2], prefix="b"), flat([1.0, 2.0, 3.0], seeds=[0, 1, 2],
                                                                                   prefix="t"))
    assert foreign["settings"]["value_range"] is None  # no task to ask: no interval (see the warnings)
    outside = report.compute(runs("b", [-1.0, -0.8, -0.9]), runs("t", [0.5, 0.6, 1.5]))  # a shaped return, say
    assert outside["settings"]["value_range"] is None
    assert any("has values outside [-1, 1]" in w for w in outside["settings"]["warnings"])


def test_convergence_needs_the_equivalence_test():
    f = np.arange(0, 101, 5.0)
    rng = np.random.default_rng(0)
    plateau = [Curve(f, np.minimum(f / 20, 2.0) + rng.normal(0, 0.01, f.size), f"p{i}", f"p{i}") for i in range(3)]
    noisy = [Curve(f, np.minimum(f / 20, 2.0) + rng.normal(0, 1.0, f.size), f"n{i}", f"n{i}") for i in range(3)]
    res = report.compute(plateau, noisy)
    conv = res["settings"]["convergence"]
    # the plateau's change over frames 75..100 is shown within 0.1 x its range (about 2): converged;
    # the noisy one is neither shown flat nor shown to move: a flat slope estimate does not make it converged
    assert conv["baseline"] == "converged"
    assert conv["transfer"].startswith("undetermined (the change is neither shown within")
    assert "TOST" in res["settings"]["convergence_rule"]
    short = report.compute(flat([1.0, 2.0, 3.0], frames=(0, 10, 20, 30)), flat([1.0, 2.0, 3.0], frames=(0, 10, 20, 30)))
    assert short["settings"]["convergence"]["baseline"].startswith("undetermined (too few evaluations")


def test_a_learner_section_that_a_run_does_not_read_is_no_mismatch():
    """A SAC run's ``soc.*`` keys are defaults that never reach its learner: against SOC runs only ``algo`` and
    the sections both read are named; within one side, SAC runs that differ only there are one configuration."""
    def runs(name, algo, options, **sac):
        return [Curve((0, 10, 20), [0, 1, 2], f"{name}{i}", f"{name}{i}",
                      config={"seed": i, "algo": algo, "soc": {"num_options": options}, "sac": sac})
                for i in range(3)]

    sac, soc = runs("b", "sac", 4), runs("t", "soc", 2)
    warnings = report.compute(sac, soc, allow_mismatch=True)["settings"]["warnings"]
    assert "baseline and transfer settings differ (--allow-mismatch): algo (sac vs soc)" in warnings
    hot = runs("t", "soc", 2, alpha_init=0.5)  # the sac section: SOC's action temperature, read by both
    with pytest.raises(UsageError, match=r"algo \(sac vs soc\), sac.alpha_init \(\(unset\) vs 0.5\);"):
        report.compute(sac, hot)
    mixed = sac[:2] + runs("b", "sac", 8)[2:]
    warnings = report.compute(mixed, runs("t", "sac", 4))["settings"]["warnings"]
    assert not any("mix configurations" in w for w in warnings)
    with pytest.raises(UsageError, match=r"mix configurations: .* soc.num_options=2 .* soc.num_options=8"):
        report.compute(soc[:2] + runs("t", "soc", 8)[2:], sac)


def test_runs_on_different_grids_or_episode_counts_are_named():
    coarse = [Curve((0, 20, 40), [0, 1, 2], f"c{i}", f"c{i}", config={"seed": i, "eval": {"episodes": 8}})
              for i in range(3)]
    fine = [Curve((0, 10, 20, 30, 40), [0, 1, 2, 3, 4], f"f{i}", f"f{i}", config={"seed": i, "eval": {"episodes": 16}})
            for i in range(3)]
    with pytest.raises(UsageError, match=r"change what a curve means: eval.episodes \(8 vs 16\)"):
        report.compute(coarse, fine)
    warnings = report.compute(coarse, fine, allow_mismatch=True)["settings"]["warnings"]
    assert "baseline and transfer settings differ (--allow-mismatch): eval.episodes (8 vs 16)" in warnings
    assert any("different grids" in w and "'f0'" in w and "'c0'" in w and "every 20" in w for w in warnings)
    assert any("different numbers of episodes" in w and "'c0' (c0) 8" in w and "'f0' (f0) 16" in w for w in warnings)


def test_foreign_logs_are_compared_over_their_whole_overlap():
    short = [Curve((100, 200, 300), [0, 1, 2], f"s{i}", f"s{i}") for i in range(2)]
    long = [Curve((0, 200, 400, 600, 800), [0, 1, 2, 3, 4], f"l{i}", f"l{i}") for i in range(2)]
    st = report.compute(short, long, asymptote_window=0.5)["settings"]
    assert (st["start"], st["budget"]) == (100, 300)
    assert "the range every run covers" in st["budget_source"] and "'s0'" in st["budget_source"]
    with pytest.raises(UsageError, match="run lengths differ too much"):  # drltg runs: refused
        report.compute([Curve(c.frames, c.values, c.source, c.label, config={"seed": i}) for i, c in enumerate(short)],
                       [Curve(c.frames, c.values, c.source, c.label, config={"seed": i}) for i, c in enumerate(long)],
                       asymptote_window=0.5)


@pytest.mark.parametrize("row", sorted(p.name for p in (Path(__file__).parents[1] / "results/manipulation/earlier")
                                       .iterdir()))
def test_the_earlier_rows_in_results_are_the_report_of_their_logs(row, tmp_path, capsys):
    """results/manipulation/earlier/ROW (README's side-by-side table) is what the report computes from the
    earlier implementation's logs now, over their whole length and cut at 100k frames."""
    root = Path(__file__).parents[1]
    for sub, budget in (("", []), ("at-100k", ["--budget", "100000"])):
        kept = json.loads((root / "results/manipulation/earlier" / row / sub / "transfer_metrics.json").read_text())
        logs = [str(root / Path(kept["settings"][side][0]).parent) for side in ("baseline", "transfer")]
        args = ["--baseline", logs[0], "--transfer", logs[1], *budget, "--out", str(tmp_path / row)]
        assert report_cli.main(args) == 0
        fresh = json.loads((tmp_path / row / "transfer_metrics.json").read_text())
        assert fresh["settings"]["budget"] == kept["settings"]["budget"]
        for key in ("mean_return_gain", "final_performance_baseline", "final_performance_transfer"):
            assert fresh["metrics"][key] == pytest.approx(kept["metrics"][key], rel=1e-12)


def test_identical_sides_write_a_report_without_an_undefined_p_value(tmp_path):
    """Transfer runs that equal their baselines (a method that changed nothing yet): every paired
    difference is 0, so the ratio's t test has no spread; the report says so and is still written."""
    b = [Curve([0, 160, 320], [-1.0, -0.9 + 0.1 * i, -0.8], f"b{i}", f"b{i}", config={"seed": i}) for i in range(3)]
    t = [Curve(c.frames, c.values, f"t{i}", f"t{i}", config={"seed": i}) for i, c in enumerate(b)]
    res = report.transfer_report(b, t, tmp_path / "rep", interval="t")
    assert "transfer_ratio_p_value" not in res["metrics"] and res["metrics"]["mean_return_gain"] == 0.0
    assert any("no spread" in w for w in res["settings"]["warnings"])
    assert json.loads((tmp_path / "rep" / "transfer_metrics.json").read_text())["metrics"]["transfer_ratio"] == 0.0


def test_foreign_logs_in_seed_folders_are_paired_by_their_folder_names(tmp_path):
    """Stable-Baselines3 logs kept one folder per seed (seed-0, seed-1, ...) pair by seed, in any order, as
    drltg runs pair by their configs; without such folders they stay unpaired unless --paired."""
    def sb3(path: Path, values):
        path.mkdir(parents=True)
        rows = "".join(f"{f},{v}\n" for f, v in zip((0, 100, 200), values))
        (path / "progress.csv").write_text("time/total_timesteps,eval/mean_reward\n" + rows)

    for seed, level in ((0, 1.0), (1, 5.0), (2, 9.0)):
        sb3(tmp_path / "b" / f"seed-{seed}", [level] * 3)
        sb3(tmp_path / "t" / f"seed-{2 - seed}", [11.0 - level] * 3)  # listed in the other order
    res = report.compute(report.read_runs(str(tmp_path / "b"), report.ReportSettings()),
                         report.read_runs(str(tmp_path / "t"), report.ReportSettings()))
    assert res["settings"]["paired"] is True and "seed-N folders" in res["settings"]["pairing"]
    assert res["scores"]["pair"].tolist() == [0, 1, 2, 0, 1, 2]
    assert res["scores"]["seed"].tolist() == [0, 1, 2, 0, 1, 2]
    assert res["scores"]["mean_return"].tolist() == [1.0, 5.0, 9.0, 2.0, 6.0, 10.0]  # each pair differs by 1
    assert res["metrics"]["mean_return_gain"] == pytest.approx(1.0)
    (tmp_path / "b" / "seed-0").rename(tmp_path / "b" / "first")
    res = report.compute(report.read_runs(str(tmp_path / "b"), report.ReportSettings()),
                         report.read_runs(str(tmp_path / "t"), report.ReportSettings()))
    assert res["settings"]["paired"] is False


def test_a_difference_within_float32_rounding_of_the_curves_is_drawn_as_zero(tmp_path):
    """Two sides that start equal, logged in float32, can differ by eps * |y| at frame 0; the kept metric stays
    exact and the plot reads +0 rather than +4.77e-06 (returns near 40)."""
    start = float(np.float32(40.0))
    for side, nudge, slope in (("baseline", 0.0, 1.0), ("transfer", float(np.spacing(np.float32(40.0))), 2.0)):
        write_run(tmp_path / side / "seed_0", [0, 10, 20], [start + nudge, 41.0, 40.0 + slope],
                  task="fourrooms/northeast")
    result = report.transfer_report(tmp_path / "baseline", tmp_path / "transfer", tmp_path / "o")
    assert result["metrics"]["jumpstart"] == pytest.approx(3.814697265625e-06)
    svg = (tmp_path / "o" / "transfer_plot.svg").read_text()
    assert "jumpstart +0" in svg
    assert "e-06" not in svg


def test_report_from_curves_is_the_report_of_the_same_curves(tmp_path):
    from drltg.report import report_from_curves

    frames = [0, 10, 20, 30]
    b = [[0.0, 0.1, 0.2, 0.3], [0.0, 0.3, 0.3, 0.4], [0.1, 0.1, 0.2, 0.5]]
    t = [[0.2, 0.4, 0.6, 0.6], [0.1, 0.2, 0.5, 0.8], [0.0, 0.3, 0.3, 0.4]]
    for i, (x, y) in enumerate(zip(b, t)):
        write_run(tmp_path / "b" / f"seed-{i}", frames, x)
        write_run(tmp_path / "t" / f"seed-{i}", frames, y)
        for side in "bt":
            (tmp_path / side / f"seed-{i}" / "config.yaml").write_text(f"task: x\nseed: {i}\n")
    from_files = report.transfer_report(tmp_path / "b", tmp_path / "t", tmp_path / "r", threshold=0.3)
    from_arrays = report_from_curves(frames, b, t, threshold=0.3)
    assert from_arrays["settings"]["paired"] and from_arrays["metrics"] == from_files["metrics"]
    unpaired = report_from_curves(frames, b, t[:2], paired=False)["metrics"]
    assert unpaired["n_seeds_transfer"] == 2 and unpaired["mean_return_gain_verdict_test"] == "permutation"
    with pytest.raises(UsageError, match=r"^transfer must be seeds x evaluations with 4 evaluations"):
        report_from_curves(frames, b, [[0.0, 1.0]])
    with pytest.raises(UsageError, match="paired curves need as many baseline as transfer seeds, got 3 and 2"):
        report_from_curves(frames, b, t[:2])


def test_table_rows_follow_the_tag_the_curves_are():
    """With --tag success_rate the headline said "mean success rate gain" and the table mean_return_gain."""
    b, t = flat([0.0, 0.2, 0.1], seeds=[0, 1, 2], prefix="b"), flat([0.5, 0.6, 0.9], seeds=[0, 1, 2], prefix="t")
    res = report.compute(b, t, value_range=(0.0, 1.0))
    res["settings"]["tag"] = "success_rate"
    table = report.format_table(res)
    assert "\nmean_success_rate_gain " in table and "mean_return_gain" not in table
    assert outputs.row_label("mean_return_gain", {"tag": "eval/mean_reward"}) == "mean_return_gain"
    assert outputs.row_label("jumpstart", {"tag": "success_rate"}) == "jumpstart"


def test_a_comparison_where_no_run_reached_the_threshold_says_it_measures_nothing():
    """A sparse task under the defaults: every run of both sides fails; the report said "+0.00: undecided" and
    planned more pairs, never that nothing learned."""
    from drltg.analysis.claims import headline

    b = flat([-1.0, -0.9, -1.0], seeds=[0, 1, 2], prefix="b")
    t = flat([-1.0, -0.8, -0.95], seeds=[0, 1, 2], prefix="t")
    res = report.compute(b, t, threshold=0.5, value_range=(-1.0, 1.0))
    said = [w for w in res["settings"]["warnings"] if w.startswith("no run of either side")]
    assert said == ["no run of either side ever reached the threshold 0.5 (the best evaluation of all 6 runs is "
                    "-0.8): neither learned the task within the budget, so this comparison measures nothing about "
                    "transfer; train longer, or check the task's reward and the learner's settings (a sparse reward "
                    "may need a lower sac.alpha_init, docs/gymnasium.md)."]
    assert res["settings"]["learned_nothing"] is True
    assert headline(res).endswith("; but no run of either side reached the threshold, so neither learned the task "
                                  "and this measures nothing.")
    learned = report.compute(b, flat([-1.0, 0.5, -0.95], seeds=[0, 1, 2], prefix="t"), threshold=0.5,
                             value_range=(-1.0, 1.0))
    assert learned["settings"]["learned_nothing"] is False and "measures nothing" not in headline(learned)


def test_sources_that_never_succeeded_are_named(tmp_path):
    from drltg.experiments.experiment import never_succeeded

    for name, rates in (("seed-50", [0.0, 0.0]), ("seed-150", [0.0, 0.25]), ("seed-250", None)):
        run = tmp_path / name
        run.mkdir()
        head = "frames,return_mean" + (",success_rate" if rates else "")
        lines = [f"{i * 10},-1.0" + (f",{r}" if rates else "") for i, r in enumerate(rates or [0, 0])]
        (run / "eval.csv").write_text("\n".join([head, *lines]) + "\n")
    assert never_succeeded([tmp_path / n for n in ("seed-50", "seed-150", "seed-250")]) == [str(tmp_path / "seed-50")]


def test_runs_paired_by_seed_that_learned_from_two_sources_are_refused_in_one_sentence(tmp_path, capsys):
    """Two transfer methods head to head: seed 100's runs reused different teachers, which pairing would hide."""
    from drltg.cli import main

    frames = [0, 10, 20, 30, 40]
    sides = {}
    for side, digests in (("a", ["1" * 64, "2" * 64]), ("b", ["1" * 64, "3" * 64])):
        for seed, digest in zip((0, 100), digests):
            run = write_run(tmp_path / side / f"seed-{seed}", frames, linear(frames, seed / 100))
            (run / "config.yaml").write_text(f"task: fourrooms/northeast\nseed: {seed}\nframes: 40\n")
            (run / "summary.json").write_text(json.dumps({"status": "complete", "frames": 40, "source": {
                "networks_sha256": digest, "config_sha256": "0" * 64}}))
        sides[side] = tmp_path / side
    assert main(["report", "--baseline", str(sides["a"]), "--transfer", str(sides["b"]), "--out",
                 str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert "the pair of seed 100 learned from two sources" in err and "compare teachers, not methods" in err
    assert err.count("\n") == 1 and not (tmp_path / "r").exists()
    (sides["b"] / "seed-100" / "summary.json").write_text(json.dumps({"status": "complete", "frames": 40, "source": {
        "networks_sha256": "2" * 64, "config_sha256": "0" * 64}}))  # the same teacher: the pairs stand
    assert main(["report", "--baseline", str(sides["a"]), "--transfer", str(sides["b"]), "--out",
                 str(tmp_path / "r")]) == 0
