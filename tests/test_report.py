import csv
import io
import json
import os
from pathlib import Path

import numpy as np
import pytest

from drltg import report
from drltg.curves import Curve
from drltg.errors import UsageError

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
    # threshold 9: baseline seed 0 never reaches it (8 at the budget; 12 at 50 lies past it)
    assert m["time_to_threshold_baseline"] is None and m["threshold_reached_baseline"] == 0.5
    assert m["time_to_threshold_transfer"] == 40 and m["threshold_reached_transfer"] == 1.0
    assert [s["time_to_threshold"] for s in res["per_seed"]["baseline"]] == [None, 40]
    for name in ("probability_of_improvement", "probability_of_improvement_initial",
                 "probability_of_improvement_final"):
        assert m[name] == 1.0
    assert m["jumpstart_iqm"] == pytest.approx(m["jumpstart"])  # n = 2: IQM is the mean
    # bootstrap over two seeds per side: every extreme has probability 1/16 > 2.5 %
    assert m["jumpstart_ci"] == pytest.approx([2, 6])
    assert m["transfer_ratio_ci"] == pytest.approx([(320 - 240) / 240, (400 - 160) / 160])
    saved = json.loads((out / "transfer_metrics.json").read_text())
    assert saved["metrics"] == json.loads(json.dumps(m))
    assert saved["metrics"]["time_to_threshold_baseline"] is None
    assert set(os.listdir(out)) == FILES


def test_jumpstart_window_budget_and_fraction_threshold(two_by_two, tmp_path):
    b, t = two_by_two
    m = report.compute(_read(b), _read(t), jumpstart_window=2, budget="20", threshold="40%",
                       asymptote_window=0.5)
    # means of the first two evaluations: baseline (0+2)/2, (2+6)/2; transfer (4+5)/2, (6+8)/2
    assert m["metrics"]["jumpstart"] == pytest.approx((4.5 + 7) / 2 - (1 + 4) / 2)
    # budget 20: areas of y = a + f/5 over [0, 20] = 20 a + 40
    assert m["metrics"]["total_reward_baseline"] == pytest.approx((40 + 80) / 2)
    assert m["settings"]["budget_source"] == "--budget"
    # best baseline mean within [0, 20] is (4 + 6) / 2 = 5, so 40 % of it is 2
    assert m["settings"]["threshold"] == pytest.approx(2)
    assert [s["time_to_threshold"] for s in m["per_seed"]["baseline"]] == [10, 0]
    assert m["metrics"]["time_to_threshold_baseline"] == pytest.approx(5)  # median of 10 and 0


def _read(path):
    from drltg.curves import read_curves

    return read_curves(path)


def test_smoothing_shapes_time_to_threshold_only():
    f = np.arange(6) * 100.0
    b = Curve(f, [0, 9, 0, 5, 6, 7], "b.csv", "b")
    t = Curve(f, [0, 0, 0, 8, 8, 8], "t.csv", "t")
    raw = report.compute([b], [t], threshold=5)
    smooth = report.compute([b], [t], threshold=5, smooth=2)
    assert raw["metrics"]["time_to_threshold_baseline"] == 100  # a single noisy spike
    assert smooth["metrics"]["time_to_threshold_baseline"] == 400
    assert smooth["metrics"]["time_to_threshold_transfer"] == 400  # (0 + 8) / 2 = 4 < 5 at 300
    assert raw["metrics"]["total_reward_baseline"] == smooth["metrics"]["total_reward_baseline"]
    assert "_ci" not in "".join(raw["metrics"])  # one seed per side: no intervals
    assert any("at least 2 seeds" in w for w in raw["settings"]["warnings"])


def test_bootstrap_is_reproducible_and_seeded(tmp_path):
    rng = np.random.default_rng(0)
    f = np.arange(0, 101, 10.0)
    base = [Curve(f, f / 10 + rng.normal(0, 1, f.size), f"b{i}", f"b{i}") for i in range(5)]
    tran = [Curve(f, f / 8 + rng.normal(0, 1, f.size), f"t{i}", f"t{i}") for i in range(4)]
    a = report.compute(base, tran, bootstrap=1000, seed=1)["metrics"]
    b = report.compute(base, tran, bootstrap=1000, seed=1)["metrics"]
    c = report.compute(base, tran, bootstrap=1000, seed=2)["metrics"]
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
    assert any("transfer_ratio is undefined" in w for w in res["settings"]["warnings"])


def test_done_when_command_on_real_sb3_runs(sb3_runs, tmp_path, capsys):
    out = tmp_path / "rep"
    code = report.main(["--baseline", str(sb3_runs / "liftplace_sac"),
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
    assert rows[0] == ["metric", "value", "ci_low", "ci_high"]
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
    assert report.main(["--baseline", str(tmp_path / "nope"), "--transfer", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("drltg report: error: ") and "does not exist" in err and "\n" not in err
    assert report.main(["--baseline", str(tmp_path)]) == 2


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
    assert report.main(["--matrix", str(grid), "--metric", "jumpstart", "--out", str(out)]) == 0
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
