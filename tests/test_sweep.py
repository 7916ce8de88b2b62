"""`drltg sweep`: spec expansion and validation, the local pool, resuming, failure isolation, Ray."""
import contextlib
import csv
import io
import json
import re
import shutil
from pathlib import Path

import pytest
import yaml

from drltg import config as config_lib
from drltg.cli import main
from drltg.experiments import summary, sweep
from drltg.store import rundir
from drltg.training.loop import train

TINY = {"network.hidden": [16, 16], "collector.num_envs": 4, "collector.frames_per_batch": 16,
        "collector.init_random_frames": 64, "optim.updates_per_batch": 1, "buffer.batch_size": 32,
        "eval.every": 128, "eval.episodes": 4, "log.tensorboard": False}
GRID = {"pairs": ["fourrooms-near", "fourrooms-far"], "methods": ["model-reuse", "reward-shaping"],
        "seeds": 1, "frames": 256, "threshold": 0, "overrides": TINY}


def write_spec(path, data):
    path.write_text(yaml.safe_dump(data))
    return path


# ------------------------------------------------------------------------------------ expansion
def test_expansion_shares_runs_and_spaces_seeds(tmp_path):
    spec = sweep.parse_spec({"pairs": ["fourrooms-near", "fourrooms-far"],
                             "methods": ["reward-shaping", "policy-reuse", "model-reuse"],
                             "seeds": 2, "frames": 1024, "source_frames": 2048})
    runs, cells = sweep.plan(spec, tmp_path)
    by_role = {role: [r for r in runs if r.role == role] for role in ("source", "baseline", "transfer")}
    # both pairs start from fourrooms/northeast: one source per seed serves every pair and method
    assert [r.cfg.seed for r in by_role["source"]] == [50, 150]
    assert {r.cfg.frames for r in by_role["source"]} == {2048}
    assert len(by_role["baseline"]) == 2 * 2 and len(by_role["transfer"]) == 2 * 3 * 2
    assert len({r.path for r in runs}) == len({sweep._key(r.cfg) for r in runs}) == len(runs) == 18
    assert {r.cfg.seed for r in by_role["baseline"]} == {0, 100}
    assert not {r.cfg.seed for r in by_role["source"]} & {r.cfg.seed for r in by_role["baseline"]}
    order = [r.path for r in runs]
    for r in by_role["transfer"]:
        if r.cfg.transfer.method == "reward-shaping":
            assert r.needs is None
        else:  # trained from the source run with the spaced seed, which comes earlier in the plan
            assert r.cfg.transfer.source == str(r.needs) == str(tmp_path / "fourrooms-near" / "sac"
                                                                       / "source" / f"seed-{r.cfg.seed + 50}")
            assert order.index(r.needs) < order.index(r.path)
    assert len(cells) == 6
    near = [c for c in cells if c.pair == "fourrooms-near"]
    assert near[0].baseline == near[1].baseline == near[2].baseline  # every method, one baseline
    assert near[1].report == tmp_path / "fourrooms-near" / "sac" / "policy-reuse" / "report"


def test_a_task_alone_is_a_target_when_the_source_is_given(tmp_path):
    spec = sweep.parse_spec({"pairs": ["fourrooms/southwest"], "methods": ["reward-shaping", "policy-reuse"],
                             "seeds": 2, "frames": 1024, "overrides": {"transfer.source": "runs/source"}})
    runs, cells = sweep.plan(spec, tmp_path)
    assert sorted((r.role, r.cfg.task) for r in runs) == [("baseline", "fourrooms/southwest")] * 2 + [
        ("transfer", "fourrooms/southwest")] * 4
    assert all(r.needs is None for r in runs) and len(cells) == 2
    alone = sweep.parse_spec({"pairs": ["fourrooms/southwest"], "methods": ["model-reuse"], "frames": 1024})
    with pytest.raises(sweep.UsageError, match="'fourrooms/southwest' is a task, not a pair: model-reuse on it needs"):
        sweep.plan(alone, tmp_path)


def test_runs_are_those_of_drltg_experiment(tmp_path):
    """Every run of ``drltg experiment`` with the same settings is a sweep run with the same config."""
    from drltg.experiments.experiment import plan_runs

    spec = sweep.parse_spec(GRID)
    runs, _ = sweep.plan(spec, tmp_path / "sweep")

    def key(cfg, role):
        return role, sweep._key(config_lib.updated(cfg, {"transfer.source": None}))

    planned = {key(r.cfg, r.role) for r in runs}
    overrides = [f"{k}={json.dumps(v)}" for k, v in TINY.items()]
    for pair in GRID["pairs"]:
        for method in GRID["methods"]:
            plan = plan_runs(pair, method, seeds=1, frames=256, overrides=overrides, out=tmp_path / pair / method)
            assert {key(cfg, role) for role, cfg, _ in plan} <= planned


def test_swept_axes_name_the_variant_directories(tmp_path):
    spec = sweep.parse_spec({"pairs": "fourrooms-near", "methods": "model-reuse", "seeds": 1,
                             "frames": [1000, 2000], "source_frames": 3000, "grid": {"optim.lr": [0.001, 0.01]}})
    runs, cells = sweep.plan(spec, tmp_path)
    assert [c.variant for c in cells] == ["frames=1000,optim.lr=0.001", "frames=1000,optim.lr=0.01",
                                          "frames=2000,optim.lr=0.001", "frames=2000,optim.lr=0.01"]
    # the source does not depend on the target budget: 2 sources (one per lr), 4 baselines, 4 transfers
    assert sorted(r.role for r in runs).count("source") == 2 and len(runs) == 10
    lrs = {r.path.relative_to(tmp_path).parts[2]: r.cfg.optim.lr for r in runs}
    assert all(lr == float(name.rsplit("=", 1)[1]) for name, lr in lrs.items())


@pytest.mark.parametrize("change, message", [
    ({"pair": ["fourrooms-near"]}, "unknown key 'pair'; did you mean 'pairs'?"),
    ({"pairs": []}, "'pairs' is an empty list"),
    ({"pairs": ["fourrooms-nera"]}, "did you mean 'fourrooms-near'?"),
    ({"methods": ["policy-reus"]}, "unknown method 'policy-reus'; did you mean 'policy-reuse'?"),
    ({"seeds": "five"}, "'seeds' must be an integer"),
    ({"frames": [1000, "lots"]}, "'frames' must hold int values, got 'lots'"),
    ({"grid": {"optim.lr": []}}, "grid key 'optim.lr' must be a non-empty list"),
    ({"overrides": {"seed": 3}}, "may not set 'seed'"),
    ({"overrides": {"optim.lrr": 0.1}}, "unknown config key 'optim.lrr'; did you mean 'optim.lr'?"),
    ({"overrides": {"eval.every": "often"}}, "'eval.every' must be 'auto' or an integer"),
    ({"primary_metric": "mean_return_gian"}, "unknown primary_metric 'mean_return_gian'"),
    ({"primary_metric": "n_seeds_baseline"}, "primary_metric 'n_seeds_baseline' is not a comparison"),
    ({"resources": {"gpus": 1}}, "unknown resource 'gpus'; did you mean 'num_gpus'?"),
    ({"name": "mine"}, "unknown key 'name'; choose from: pairs, methods, algos, seeds"),
    ({"overrides": {"eval.every": 512, "eval": {"every": 256}}},
     "': 'overrides' ('eval', then 'eval.every'); give it once."),
    ({"grid": {"optim.lr": [0.1, 0.2], "optim": [{"lr": 0.3}]}},
     "': 'grid' ('optim', then 'optim.lr'); give it once."),
])
def test_spec_errors_are_one_sentence_and_write_nothing(tmp_path, capsys, change, message):
    data = {k: v for k, v in GRID.items() if k not in ("pairs",) or "pair" not in change}
    spec = write_spec(tmp_path / "spec.yaml", {**data, **change})
    assert main(["sweep", str(spec), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert not (tmp_path / "out").exists()


def test_missing_spec_file(tmp_path, capsys):
    assert main(["sweep", str(tmp_path / "nope.yaml"), "--out", str(tmp_path / "out")]) == 2
    assert "does not exist" in capsys.readouterr().err


# ---------------------------------------------------------------------------------- local pool
def _curves(out):
    return {str(p.relative_to(out)): p.read_text() for p in sorted(out.glob("fourrooms-*/**/eval.csv"))}


@pytest.fixture(scope="module")
def local(tmp_path_factory):
    root = tmp_path_factory.mktemp("sweep")
    spec, out = write_spec(root / "tiny.yaml", GRID), root / "local"
    assert main(["sweep", str(spec), "--out", str(out), "--workers", "2"]) == 0
    return spec, out, _curves(out)


def test_local_grid_trains_each_run_once_and_reports(local):
    spec, out, curves = local
    runs = sorted(str(p.parent.relative_to(out)) for p in out.glob("fourrooms-*/**/summary.json"))
    assert runs == ["fourrooms-far/sac/baseline/seed-0", "fourrooms-far/sac/model-reuse/transfer/seed-0",
                    "fourrooms-far/sac/reward-shaping/transfer/seed-0", "fourrooms-near/sac/baseline/seed-0",
                    "fourrooms-near/sac/model-reuse/transfer/seed-0",
                    "fourrooms-near/sac/reward-shaping/transfer/seed-0",
                    "fourrooms-near/sac/source/seed-50"]
    assert len(curves) == 7 and all(c.count("\n") == 4 for c in curves.values())  # frames 0, 128, 256
    far = out / "fourrooms-far/sac/model-reuse/transfer/seed-0"
    assert yaml.safe_load((far / "config.yaml").read_text())["transfer"]["source"] == \
        "../../../../../fourrooms-near/sac/source/seed-50"  # relative to the run: the folder can move
    assert rundir.read_config(far)["transfer"]["source"] == str(out / "fourrooms-near/sac/source/seed-50")
    for run in runs:
        assert "complete" in (out / "logs" / f"{run}.log").read_text()
        text = (out / "logs" / f"{run}.log").read_bytes()
        assert b"[torchrl][INFO]" in text and b"\x1b" not in text  # TorchRL's lines there, uncoloured
    with open(out / "summary.csv") as f:
        rows = list(csv.DictReader(f))
    assert [(r["pair"], r["method"]) for r in rows] == [
        ("fourrooms-near", "model-reuse"), ("fourrooms-near", "reward-shaping"),
        ("fourrooms-far", "model-reuse"), ("fourrooms-far", "reward-shaping")]
    for r in rows:
        report = json.loads((out / r["pair"] / "sac" / r["method"] / "report" / "transfer_metrics.json").read_text())
        assert float(r["transfer_ratio"]) == pytest.approx(report["metrics"]["transfer_ratio"])
        assert r["seeds"] == "1+1"
    summary_md = (out / "summary.md").read_text()
    assert sum(line.startswith("| fourrooms-") for line in summary_md.splitlines()) == 4  # a row per report
    across = json.loads((out / "across_targets.json").read_text())  # a method over its 2 targets, 1 seed each
    assert [(e["method"], e["pairs"], e["seed_pairs"]) for e in across] == [
        (m, ["fourrooms-near", "fourrooms-far"], 2) for m in ("model-reuse", "reward-shaping")]
    assert (out / "transfer_matrix.png").read_bytes()[:4] == b"\x89PNG"


def test_the_python_function_is_the_command(local, capsys):
    """drltg.sweep on the command's folder, with the spec as a mapping: it reuses every run and returns the
    summary the command wrote, one row per report; a library call prints nothing."""
    import drltg

    _, out, curves = local
    result = drltg.sweep(GRID, out, workers=2, progress=False)
    assert _curves(out) == curves
    assert set(state for state, _ in result["status"].values()) == {"skipped"} and len(result["status"]) == 7
    assert result["summary"] == (out / "summary.md").read_text()
    assert [(r["pair"], r["method"]) for r in result["rows"]] == [
        ("fourrooms-near", "model-reuse"), ("fourrooms-near", "reward-shaping"),
        ("fourrooms-far", "model-reuse"), ("fourrooms-far", "reward-shaping")]
    assert capsys.readouterr().out == ""
    assert yaml.safe_load((out / "sweep.yaml").read_text()) == GRID


def test_every_figure_of_a_sweep_takes_the_figure_options(local, tmp_path, page_size):
    """``--figure one-column`` on a finished sweep: its runs are reused, every report's plot, the summary's
    heatmap and its performance profiles are redrawn as one-column PDFs (a 3.3 in page) beside their PNGs."""
    import matplotlib.image as mpimg

    spec, out, curves = local
    mine = tmp_path / "sweep"
    shutil.copytree(out, mine)
    assert main(["sweep", str(spec), "--out", str(mine), "--workers", "1", "--figure", "one-column",
                 "--no-progress"]) == 0
    assert _curves(mine) == curves
    pdfs = sorted(str(p.relative_to(mine)) for p in mine.rglob("*.pdf"))
    assert pdfs == ["fourrooms-far/sac/model-reuse/report/transfer_plot.pdf",
                    "fourrooms-far/sac/reward-shaping/report/transfer_plot.pdf",
                    "fourrooms-near/sac/model-reuse/report/transfer_plot.pdf",
                    "fourrooms-near/sac/reward-shaping/report/transfer_plot.pdf", "performance_profiles.pdf",
                    "transfer_matrix.pdf"]
    for pdf in pdfs:
        assert page_size(mine / pdf)[0] == pytest.approx(3.3 * 72)
        assert mpimg.imread((mine / pdf).with_suffix(".png")).shape[1] == 990  # 3.3 in at 300 dpi
    assert main(["sweep", str(spec), "--out", str(mine), "--figure-dpi", "1"]) == 2  # checked before anything runs


@pytest.fixture(scope="module")
def rerun(local, tmp_path_factory):
    """The local sweep after a kill mid-run, a broken source, and a lost run; then re-run."""
    spec, out, _ = local
    killed = out / "fourrooms-far/sac/baseline/seed-0"
    cfg = yaml.safe_load((killed / "config.yaml").read_text())
    half = tmp_path_factory.mktemp("half") / "run"
    train(config_lib.build({**cfg, "frames": 128}), half, progress=False)  # the state a kill after frame 128 leaves
    (half / "summary.json").unlink()
    shutil.rmtree(killed)
    shutil.copytree(half, killed)
    (killed / "config.yaml").write_text(yaml.safe_dump(cfg, sort_keys=False))
    source = out / "fourrooms-near/sac/source/seed-50"
    (source / "summary.json").unlink()
    (source / "checkpoints" / "last.pt").write_bytes(b"not a checkpoint")
    lost = out / "fourrooms-near/sac/reward-shaping/transfer/seed-0"
    for d in [lost] + [out / p / "sac/model-reuse/transfer/seed-0" for p in ("fourrooms-near", "fourrooms-far")]:
        shutil.rmtree(d)
    untouched = [out / "fourrooms-near/sac/baseline/seed-0", out / "fourrooms-far/sac/reward-shaping/transfer/seed-0"]
    stamps = {d: (d / "summary.json").stat().st_mtime_ns for d in untouched}
    with contextlib.redirect_stdout(io.StringIO()) as printed:
        code = main(["sweep", str(spec), "--out", str(out), "--workers", "2"])
    return out, code, printed.getvalue(), stamps, killed, half, lost


def test_killed_run_resumes_from_its_checkpoint(rerun):
    out, _, _, _, killed, half, _ = rerun
    rows = (killed / "eval.csv").read_text().splitlines()
    assert [r.split(",")[0] for r in rows[1:]] == ["0", "128", "256"]
    assert rows[:3] == (half / "eval.csv").read_text().splitlines()  # the evaluations before the kill are kept
    assert json.loads((killed / "summary.json").read_text())["frames"] == 256
    assert "resume" in (out / "logs/fourrooms-far/sac/baseline/seed-0.log").read_text()


def test_complete_runs_are_skipped_and_a_failure_is_isolated(rerun):
    out, code, printed, stamps, _, _, lost = rerun
    log = out / "logs/fourrooms-near/sac/source/seed-50.log"
    assert code == 1
    assert "7 runs: 2 done, 3 failed, 2 skipped" in printed
    assert "failed: fourrooms-near/sac/source/seed-50: cannot read" in printed
    assert "does not match its SHA-256" in printed
    assert f"log: {log}" in printed
    assert "does not match its SHA-256" in log.read_text() and "Traceback" not in log.read_text()
    assert stamps == {d: (d / "summary.json").stat().st_mtime_ns for d in stamps}
    assert (lost / "summary.json").is_file()  # trained although the source run failed
    assert not any((out / p / "sac/model-reuse/transfer/seed-0").exists() for p in ("fourrooms-near", "fourrooms-far"))
    with open(out / "summary.csv") as f:
        notes = {(r["pair"], r["method"]): r["note"] for r in csv.DictReader(f)}
    assert notes[("fourrooms-near", "model-reuse")] == "1 run(s) incomplete"
    assert notes[("fourrooms-far", "model-reuse")] == "1 run(s) incomplete"
    assert notes[("fourrooms-near", "reward-shaping")] == notes[("fourrooms-far", "reward-shaping")] == ""
    with open(out / "runs.csv") as f:
        states = {r["run"]: r["status"] for r in csv.DictReader(f)}
    assert sorted(states.values()) == ["done", "done", "failed", "failed", "failed", "skipped", "skipped"]
    assert states["fourrooms-far/sac/model-reuse/transfer/seed-0"] == "failed"  # its source failed


def test_a_dry_run_says_what_each_run_holds_and_what_is_left(tmp_path, capsys):
    """``--dry-run`` on a sweep's folder tells finished, started (its last evaluation) and untouched runs
    apart and sums the frames left, writing nothing; a fresh folder has everything left."""
    spec = write_spec(tmp_path / "spec.yaml", {**GRID, "pairs": ["fourrooms-near"], "methods": ["model-reuse"]})
    out = tmp_path / "out"
    assert main(["sweep", str(spec), "--out", str(out), "--dry-run"]) == 0
    assert capsys.readouterr().out.splitlines()[-1] == "left to train: about 768 of 768 frames (3 not started)"
    assert not out.exists()
    source, baseline, transfer = sweep.plan(sweep.load_spec(spec), out)[0]
    train(source.cfg, source.path, progress=False)
    train(config_lib.build({**baseline.cfg.model_dump(), "frames": 128}), baseline.path, progress=False)
    (baseline.path / "summary.json").unlink()  # what a kill after the evaluation at frame 128 leaves
    assert main(["sweep", str(spec), "--out", str(out), "--dry-run"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [re.split(r"\s{2,}", line.strip()) for line in lines[:3]] == [
        ["source", "256 frames", "fourrooms-near/sac/source/seed-50", "finished"],
        ["baseline", "256 frames", "fourrooms-near/sac/baseline/seed-0", "started: last evaluated at 128 frames"],
        ["transfer", "256 frames", "fourrooms-near/sac/model-reuse/transfer/seed-0", "not started"]]
    assert lines[-1] == "left to train: about 384 of 768 frames (1 finished, 1 started, 1 not started)"
    assert not transfer.path.exists()


# ----------------------------------------------------------------------------------------- Ray
def test_ray_backend_gives_the_same_runs_and_curves(local, tmp_path, capsys):
    spec, _, curves = local
    out = tmp_path / "ray"
    assert main(["sweep", str(spec), "--out", str(out), "--backend", "ray", "--workers", "2"]) == 0
    import ray

    assert "ray: a local instance on 127.0.0.1 with 2 CPUs" in capsys.readouterr().err
    assert not ray.is_initialized()
    assert _curves(out) == curves


SPECS = sorted((Path(__file__).resolve().parents[1] / "examples" / "sweeps").glob("*.yaml"))


@pytest.mark.parametrize("spec_file", SPECS, ids=lambda p: p.stem)
def test_every_shipped_sweep_spec_plans(spec_file, tmp_path):
    runs, cells = sweep.plan(sweep.load_spec(spec_file), tmp_path)
    assert cells and all(r.role in ("source", "baseline", "transfer") for r in runs)
    assert all(r.needs is None or r.needs in {q.path for q in runs} for r in runs)


def _row(method, gain, p, poi=None, poi_p=None):
    metrics = {"n_seeds_baseline": 5, "n_seeds_transfer": 5, "mean_return_gain": gain,
               "mean_return_gain_ci": [gain - 1, gain + 1], "mean_return_gain_p_value": p}
    if poi is not None:
        metrics.update(probability_of_improvement=poi, probability_of_improvement_ci=[0.1, 0.9],
                       probability_of_improvement_p_value=poi_p)
    return {"pair": "p", "algo": "sac", "variant": "", "method": method, "report": "r", "metrics": metrics}


def test_the_summary_counts_findings_after_holm_over_its_named_family():
    rows = [_row("a", 1.0, 0.001, 1.0, 0.0625), _row("b", -2.0, 0.02, 0.0, 0.0625), _row("c", 0.5, 0.04),
            {"pair": "p", "algo": "sac", "variant": "", "method": "d", "report": "r", "metrics": None}]
    adjusted, headline = summary.sweep_family(rows, "mean_return_gain")
    # three p-values 0.001, 0.02, 0.04: Holm 0.003, 0.04, 0.04 -> all three below 0.05
    assert adjusted == pytest.approx({(0, "mean_return_gain"): 0.003, (1, "mean_return_gain"): 0.04,
                                      (2, "mean_return_gain"): 0.04})
    assert "primary metric mean_return_gain (named in the spec) in 3 report(s)" in headline
    assert "3 finding(s) at 0.05 (2 positive, 1 negative); 3 before adjustment" in headline
    # no primary metric: all five p-values together; Holm 0.005, 0.08, 0.08, 0.1875, 0.1875 -> one finding
    adjusted, headline = summary.sweep_family(rows)
    assert len(adjusted) == 5 and "the spec named no primary_metric" in headline
    assert "1 finding(s) at 0.05 (1 positive, 0 negative); 3 before adjustment" in headline
    csv_text, md_text = summary.summary_tables(rows, "mean_return_gain")
    assert md_text.startswith("Family: the primary metric")
    assert "| 1 [0, 2]* |" in md_text and "| -2 [-3, -1]* |" in md_text
    header = csv_text.splitlines()[0].split(",")
    assert "mean_return_gain_p_value" in header and "mean_return_gain_p_holm_sweep" in header


def _scored(pair, method, gains, seeds=None):
    seeds = list(range(len(gains))) if seeds is None else seeds
    return {"pair": pair, "algo": "sac", "variant": "", "method": method, "report": "r",
            "metrics": {"n_seeds_baseline": len(gains), "n_seeds_transfer": len(gains), "mean_return_gain": 0.0},
            "per_seed": {"baseline": [{"seed": i, "mean_return": 1.0} for i in range(len(gains))],
                         "transfer": [{"seed": s, "mean_return": 1.0 + g} for s, g in zip(seeds, gains)]}}


def test_the_summary_gives_each_method_one_verdict_across_its_targets():
    """Hand-counted stratified sign-flip tests: method a, pairs 1, 2, 3 on near and 4, 5, 6, 7 on far, every pair
    up: 2 of 2^7 patterns, p = 1/64; method b, (3, 6, -3) and (2, 4): p = 8/32 (tests/test_metrics.py). Holm over the
    two: 1/32 and 1/4, so a is higher than no transfer and b undecided."""
    rows = [_scored("near", "a", [1, 2, 3]), _scored("far", "a", [4, 5, 6, 7]), _scored("near", "b", [3, 6, -3]),
            _scored("far", "b", [2, 4]), _scored("mid", "b", [1, 1], seeds=[7, 8])]  # shares no seed: left out
    a, b = summary.across_targets(rows)
    assert (a["method"], a["pairs"], a["seed_pairs"], a["p"], a["p_holm"], a["verdict"]) == (
        "a", ["near", "far"], 7, pytest.approx(1 / 64), pytest.approx(1 / 32), "higher")
    assert a["mean_difference"] == pytest.approx((2 + 5.5) / 2) and a["test"] == "stratified sign-flip, exact"
    assert (b["p"], b["p_holm"], b["verdict"], b["unpaired"]) == (pytest.approx(0.25), pytest.approx(0.25),
                                                                  "undecided", ["mid"])
    md = summary.summary_tables(rows)[1]
    assert "Across targets:" in md and "| sac | a | near, far | 7 | +3.75 | 0.016 | 0.031 | higher |" in md


def test_the_summary_names_what_its_intervals_assume():
    row = _row("a", 1.0, 0.001)
    row["metrics"]["mean_return_gain_ci_assumes"] = "only the declared range (worst case over it)"
    md = summary.summary_tables([row], "mean_return_gain")[1]
    assert "Each interval is its report's, assuming only the declared range (worst case over it)." in md
    assert "assuming" not in summary.summary_tables([_row("a", 1.0, 0.001)], "mean_return_gain")[1]
