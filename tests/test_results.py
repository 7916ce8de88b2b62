"""The committed reference results are re-analysable: their curves give back their reports."""
import json
import math
import os
from pathlib import Path

import numpy as np
import pytest
import yaml

from drltg.analysis.report import transfer_report

RESULTS = Path(__file__).resolve().parents[1] / "results"
GRADED = RESULTS / "sweep-fourrooms-graded" / "fourrooms-near" / "sac"
GRID = RESULTS / "sweep-gridrooms" / "gridrooms-far" / "sac"


def same(a, b) -> bool:
    """Equal, floats to 12 significant digits: numpy's sums may round the last bits differently on
    another CPU (vector width), nothing more."""
    if isinstance(a, float) or isinstance(b, float):
        return a is not None and b is not None and math.isclose(a, b, rel_tol=1e-12, abs_tol=1e-12)
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    return a == b


@pytest.mark.parametrize("experiment, method", [(GRADED, "model-reuse"), (GRADED, "policy-reuse"),
                                                (GRADED, "value-shaping"), (GRID, "model-reuse")])
def test_a_committed_report_is_reproduced_from_its_committed_curves(experiment, method, tmp_path):
    committed = json.loads((experiment / method / "report" / "transfer_metrics.json").read_text())
    result = transfer_report(experiment / "baseline", experiment / method / "transfer", tmp_path,
                             threshold=committed["settings"]["threshold"],
                             baseline_label="no transfer", transfer_label=method)
    assert same(result["metrics"], committed["metrics"])
    rebuilt = json.loads((tmp_path / "transfer_metrics.json").read_text())["per_seed"]

    def scores(per_seed):  # every per-seed number; "source" is the path the curve was read from
        return {side: [{k: v for k, v in row.items() if k != "source"} for row in rows]
                for side, rows in per_seed.items()}

    assert same(scores(rebuilt), scores(committed["per_seed"]))


@pytest.mark.parametrize("folder, count", [
    ("sweep-fourrooms-graded", 260),  # 10 sources, 50 baselines, 4 methods x 50 transfers
    ("sweep-gridrooms", 110),  # 10 sources, 20 baselines, 4 methods x 20 transfers
    ("sweep-options", 50),  # per K: 5 sources, 10 baselines, 10 transfers
    ("sweep-lift-demonstrations", 12),  # 3 baselines, 3 methods x 3 transfers
    ("sweep-lift-to-place", 12),  # per target: 3 baselines, 3 transfers
    ("lift-dense", 2),  # 2 seeds
    ("lift-dense-study", 8),  # 6 variants, 2 of them on 2 seeds
    ("demo", 21),  # `drltg demo`: 1 source, 10 baselines, 10 transfers
])
def test_every_committed_run_keeps_its_curve_and_config(folder, count):
    runs = [p.parent for p in (RESULTS / folder).glob("**/summary.json")]
    assert len(runs) == count
    for run in runs:
        assert (run / "eval.csv").is_file() and (run / "config.yaml").is_file()


def test_the_seed_tasks_progress_table_is_generated_from_its_kept_curves():
    import importlib.util

    spec = importlib.util.spec_from_file_location("progress", RESULTS / "seed-tasks" / "progress.py")
    progress = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(progress)
    text = (RESULTS / "seed-tasks" / "README.md").read_text()
    assert progress.filled(text) == text, "run python results/seed-tasks/progress.py"
    assert "earlier SAC (1 run)" in text and "| 10,000 |" in text


def test_the_hold_rule_is_read_as_a_test_of_the_success_probability():
    """One evaluation of 10 episodes passes with 9 or 10 successes (mean >= 0.9); one-episode evaluations pass
    only with a success each (>= 0.7); two evaluations of 10 episodes need 7 or more each and 18 together,
    the pairs of counts enumerated."""
    import importlib.util

    from scipy.stats import binom

    spec = importlib.util.spec_from_file_location("progress", RESULTS / "seed-tasks" / "progress.py")
    progress = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(progress)
    assert progress.pass_probability(0.9, 1, 10) == pytest.approx(binom.sf(8, 10, 0.9), abs=1e-12)
    assert progress.pass_probability(0.8, 3, 1) == pytest.approx(0.8 ** 3, abs=1e-12)
    pmf = {k: binom.pmf(k, 10, 0.9) for k in range(7, 11)}
    by_hand = sum(pmf[a] * pmf[b] for a in pmf for b in pmf if a + b >= 18)
    assert progress.pass_probability(0.9, 2, 10) == pytest.approx(by_hand, abs=1e-12)
    assert progress.pass_probability(1.0, 7, 10) == pytest.approx(1.0) and progress.pass_probability(0.5, 7, 10) < 1e-6


def test_the_side_by_side_averages_the_seeds_at_a_frame_and_draws_the_earlier_runs_per_10k_frames(tmp_path):
    """An earlier run evaluated every 5k frames is drawn as the mean of its evaluations in each (end - 10k,
    end], cut at its last evaluation and at the budget; the figure is a PNG the README shows. A table cell is
    the mean over the seeds that reached the frames, says how many where not all did, and "n/a" for a rate the
    task does not record."""
    import importlib.util

    from drltg.analysis.curves import Curve

    spec = importlib.util.spec_from_file_location("progress", RESULTS / "seed-tasks" / "progress.py")
    progress = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(progress)
    frames = np.arange(0, 30_001, 5_000)  # 0, 5k, ..., 30k
    curve = Curve(frames=frames, values=frames / 1_000, source=Path("x"), label="x")  # 0, 5, ..., 30
    ends, means = progress.binned(curve)
    assert ends.tolist() == [10_000, 20_000, 30_000]
    assert means.tolist() == [7.5, 17.5, 27.5]  # (5 + 10) / 2, (15 + 20) / 2, (25 + 30) / 2
    long = Curve(frames=np.arange(0, 1_000_001, 500), values=np.ones(2001), source=Path("x"), label="x")
    assert progress.binned(long)[0][-1] == progress.BUDGET
    assert progress.figure()[:8] == b"\x89PNG\r\n\x1a\n"
    row = tmp_path / "row"
    for seed, (ret, success) in {10: (100.0, 0.2), 11: (50.0, 0.7)}.items():  # seed 12 not trained yet
        (row / f"seed-{seed}").mkdir(parents=True)
        (row / f"seed-{seed}" / "eval.csv").write_text(
            f"frames,return_mean,return_std,episodes,success_rate,lifted_rate\n0,0,0,10,0,0\n10000,{ret},0,10,{success},1\n")
    assert progress._mean_at(row, 10_000, "return_mean") == "75.0 (2 seeds)"
    assert progress._mean_at(row, 10_000, "success_rate", "pushed_rate", "lifted_rate") == "0.45 / n/a / 1.00 (2 seeds)"
    assert progress._mean_at(row, 20_000, "success_rate", "lifted_rate") == "— / —"
    assert "![" in (RESULTS / "seed-tasks" / "README.md").read_text().split("<!-- side-by-side -->")[0]


def _study():
    import importlib.util

    spec = importlib.util.spec_from_file_location("seed_study", RESULTS / "seed-tasks" / "study.py")
    study = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(study)
    return study


def test_the_seed_study_queues_its_sources_before_the_rows_that_reuse_them(tmp_path):
    """6 sources and 5 rows of 3 seeds x 2 sides, a job a run; a row's transfer run of seed s waits for source
    seed s + 50 of its learner, and only for it, its baseline for nothing; no two jobs train the same run; model
    reuse, which copies the SAC source's LayerNorm critics, has LayerNorm baselines of its own."""
    from drltg import config as config_lib

    study = _study()
    jobs = study.jobs(tmp_path)
    assert [j.name for j in jobs][:4] == ["lift-dense-sac-seed-60", "lift-dense-sac-seed-61", "lift-dense-sac-seed-62",
                                          "pi-reuse-place-seed-seed-10-baseline"]
    assert len(jobs) == 6 + 5 * 3 * 2 and not any(j.finished() for j in jobs)
    assert len({run for j in jobs for run in j.outputs}) == len(jobs)
    ready = {j.name for j in jobs if j.ready()}
    assert ready == {f"{name}-seed-{s}" for name in ("lift-dense-sac", "lift-dense-soc4") for s in (60, 61, 62)} | {
        f"{row}-seed-{s}-baseline" for row in study.row.ROWS for s in (10, 11, 12)} | {
        f"shaping-lift-seed-seed-{s}-transfer" for s in (10, 11, 12)}
    done = tmp_path / "sources" / "lift-dense-soc4" / "seed-61"
    done.mkdir(parents=True)
    (done / "summary.json").write_text("{}")
    ready_now = {j.name for j in study.jobs(tmp_path) if j.ready()} - ready
    assert ready_now == {"soc-model-reuse-place-seed-seed-11-transfer"}
    source_61 = next(j for j in study.jobs(tmp_path) if j.name == "lift-dense-soc4-seed-61")
    assert not source_61.finished()  # trained, but its best.pt is not yet scored on fresh episodes
    (done / "evaluate-best-seed30061-50ep.json").write_text("{}")
    assert source_61.finished()

    def source(name):
        import shlex

        job = next(j for j in jobs if j.name == f"{name}-seed-60")
        trained, evaluate = job.argv[2].split(" && ")  # sh -c "{ [ -f summary.json ] || train; } && evaluate"
        train, evaluate = shlex.split(trained.split(" || ")[1].removesuffix("; }")), shlex.split(evaluate)
        assert evaluate[1:] == ["evaluate", str(tmp_path / "sources" / name / "seed-60"), "--checkpoint", "best",
                                "--episodes", "50"]
        flags = train[train.index("lift-dense") + 1:]
        overrides = [v for f, v in zip(flags, flags[1:]) if f == "-o"]
        return config_lib.resolve(None, overrides, task="lift-dense", algo="soc" if "soc" in flags else "sac",
                                  seed=60, frames=int(flags[flags.index("--frames") + 1]))

    sac, soc = source("lift-dense-sac"), source("lift-dense-soc4")
    assert config_lib.config_changes(sac, soc) == ["algo", "network.layer_norm", "transfer.demo_ratio"]
    assert sac.transfer.method == "demonstrations" and sac.checkpoint.keep_best and sac.frames == 60_000
    model = study.row.sides("model-reuse-place-seed", tmp_path)
    assert all(c.network.layer_norm == "critics" for side in model.values() for c in side[0])
    assert model["baseline"][1][0] == tmp_path / "lift-place-seed" / "sac" / "baseline-ln" / "seed-10"
    pi = study.row.sides("pi-reuse-place-seed", tmp_path)
    assert pi["baseline"][1][0] == tmp_path / "lift-place-seed" / "sac" / "baseline" / "seed-10"
    assert pi["baseline"][0][0].network.layer_norm == "none"


def test_stopping_the_seed_study_stops_each_job_s_processes_and_waits_for_them(tmp_path, capsys):
    """A source job is ``sh -c "... drltg train ..."``: SIGTERM to the shell alone would leave its run
    training. ``stop`` signals the job's whole process group and returns once the run has unwound."""
    import shlex
    import sys
    import time

    study = _study()
    unwound = tmp_path / "unwound"
    run = (f"import pathlib, signal, sys, time\n"
           f"def unwind(signum, frame):\n"
           f"    time.sleep(1)  # a checkpoint being saved\n"
           f"    pathlib.Path({str(unwound)!r}).write_text('saved')\n"
           f"    sys.exit(128 + signum)\n"
           f"signal.signal(signal.SIGTERM, unwind)\n"
           f"print('training', flush=True)\n"
           f"time.sleep(60)\n")
    job = study.Job("source-seed-60", ["sh", "-c", f"{shlex.quote(sys.executable)} -c {shlex.quote(run)}; sleep 60"],
                    outputs=[], needs=[], frames=1)
    proc = study.start(job, 0, tmp_path)
    log = tmp_path / "source-seed-60.log"
    deadline = time.monotonic() + 60
    while "training" not in log.read_text():
        assert proc.poll() is None and time.monotonic() < deadline, log.read_text()
        time.sleep(0.05)
    study.stop({0: (job, proc)}, timeout=30)
    assert unwound.read_text() == "saved"
    assert "source-seed-60: stopped" in capsys.readouterr().out


def test_a_study_job_that_ignores_sigterm_is_killed_after_the_timeout(tmp_path, capsys):
    import sys
    import time

    study = _study()
    run = ("import signal, time\n"
           "signal.signal(signal.SIGTERM, signal.SIG_IGN)\n"
           "print('training', flush=True)\n"
           "time.sleep(60)\n")
    job = study.Job("stuck-seed-61", [sys.executable, "-c", run], outputs=[], needs=[], frames=1)
    proc = study.start(job, 0, tmp_path)
    deadline = time.monotonic() + 60
    while "training" not in (tmp_path / "stuck-seed-61.log").read_text():
        assert proc.poll() is None and time.monotonic() < deadline
        time.sleep(0.05)
    began = time.monotonic()
    study.stop({0: (job, proc)}, timeout=1)
    assert time.monotonic() - began < 30
    assert proc.returncode == -9
    assert "stuck-seed-61: killed, still running 1 s after SIGTERM (exit -9)" in capsys.readouterr().out


def test_a_kept_transfer_run_names_its_kept_source(tmp_path):
    """A transfer run in ``runs/`` names its source relative to itself; kept in ``results/seed-tasks/ROW``,
    its config names the source's kept folder instead, so the report counts the source's frames."""
    row = _study().row
    runs = tmp_path / "runs"
    run = runs / "lift-place-seed" / "sac" / "pi-reuse-place-seed" / "seed-10"
    run.mkdir(parents=True)
    config = "task: lift-place-seed\nenv:\n  source: keep/me\ntransfer:\n  method: policy-reuse\n  source: {}\n"
    (run / "config.yaml").write_text(config.format("../../../../sources/lift-dense-sac/seed-60"))
    (run / "eval.csv").write_text("frames,return_mean\n0,1.0\n")
    kept = tmp_path / "kept" / "transfer" / "seed-10"
    row.keep(run, kept, runs)
    assert (kept / "eval.csv").read_text() == "frames,return_mean\n0,1.0\n"
    source = os.path.relpath(RESULTS / "seed-tasks" / "sources" / "lift-dense-sac" / "seed-60", kept)
    assert (kept / "config.yaml").read_text() == config.format(source)
    assert (kept / source / "config.yaml").is_file()
    # restored by another checkout of the study, the run names that checkout's kept source: kept here, this one's
    elsewhere = "/elsewhere/results/seed-tasks/sources/lift-dense-sac/seed-60"
    (run / "config.yaml").write_text(config.format(elsewhere))
    row.keep(run, kept, runs)
    assert (kept / "config.yaml").read_text() == config.format(source)
    (run / "config.yaml").write_text(config.format("/elsewhere/sources/lift-dense-sac/seed-99"))  # kept nowhere
    row.keep(run, kept, runs)
    assert "  source: /elsewhere/sources/lift-dense-sac/seed-99\n" in (kept / "config.yaml").read_text()


def test_a_new_clone_restores_the_kept_finished_runs_and_trains_only_what_is_left(tmp_path):
    """``--restore`` copies each finished row run kept in ``results/seed-tasks/`` back to its folder in RUNS,
    naming the kept source training it reused: keeping it a second time gives the kept files back. A folder
    that already holds a run is left alone."""
    study = _study()
    runs = tmp_path / "runs"
    busy = runs / "lift-place-barrier-seed" / "sac" / "baseline" / "seed-10"
    busy.mkdir(parents=True)
    (busy / "config.yaml").write_text("mine\n")
    restored = study.restore(runs)
    assert (busy / "config.yaml").read_text() == "mine\n" and busy not in restored
    kept_runs = {}  # every finished row run kept here, by the folder its own config trains it in
    for summary in sorted(study.HERE.glob("*/**/summary.json")):
        kept = summary.parent
        part = kept.relative_to(study.HERE).parts
        if part[0] == "sources":
            continue
        if part[0] not in study.row.ROWS:  # a run kept where it trains, while its row is in progress
            kept_runs.setdefault(runs.joinpath(*part), kept)
            continue
        cfg = yaml.safe_load((kept / "config.yaml").read_text())
        side = part[0] if part[1] == "transfer" else "baseline-ln" if cfg["network"]["layer_norm"] != "none" \
            else "baseline"
        kept_runs.setdefault(runs / cfg["task"] / cfg["algo"] / side / part[2], kept)
    assert set(restored) - {j.keep for j in study.jobs(runs)} == set(kept_runs) - {busy}
    place = runs / "lift-place-seed" / "sac"
    run = place / "model-reuse-place-seed" / "seed-11"
    source = RESULTS / "seed-tasks" / "sources" / "lift-dense-sac" / "seed-61"
    assert f"  source: {source}\n" in (run / "config.yaml").read_text()  # the training it reused, kept
    assert "  source: null\n" in (place / "baseline-ln" / "seed-11" / "config.yaml").read_text()
    for run, kept in kept_runs.items():  # the kept files again, the source named from the new place
        if run == busy:
            continue
        again = tmp_path / "again" / run.relative_to(runs)
        study.row.keep(run, again, runs)
        sources = os.path.relpath(RESULTS / "seed-tasks" / "sources", kept) + "/"
        assert (again / "config.yaml").read_text() == (kept / "config.yaml").read_text().replace(
            sources, os.path.relpath(RESULTS / "seed-tasks" / "sources", again) + "/")
        for name in ("eval.csv", "summary.json"):
            assert (again / name).read_bytes() == (kept / name).read_bytes(), name
    jobs = {j.name: j for j in study.jobs(runs)}
    assert all(jobs[f"{row}-seed-{s}-{side}"].finished() for row in ("pi-reuse-place-seed", "model-reuse-place-seed")
               for s in (10, 11, 12) for side in ("baseline", "transfer"))
    only = study.jobs(runs, ["shaping-lift-seed-seed-11-transfer", "lift-dense-sac-seed-62"])
    assert [j.name for j in only] == ["lift-dense-sac-seed-62", "shaping-lift-seed-seed-11-transfer"]  # queue order


def test_the_study_s_dry_run_counts_the_frames_each_run_reached_and_those_left(tmp_path, capsys):
    """A run in progress counts to its last evaluation, a finished one to its budget; the last line sums what
    is left of the whole study (6 sources of 60k frames and 5 rows of 3 seeds x 2 sides x 300k) and the time
    it takes at the rates logged so far."""
    from drltg.store.rundir import write_eval_csv

    study = _study()
    runs = tmp_path / "runs"
    source = runs / "sources" / "lift-dense-sac" / "seed-61"
    source.mkdir(parents=True)
    (source / "summary.json").write_text("{}")
    transfer = runs / "lift-place-barrier-seed" / "sac" / "pi-reuse-barrier-seed" / "seed-11"
    transfer.mkdir(parents=True)
    write_eval_csv(transfer / "eval.csv", [{"frames": 0, "return_mean": 1.0, "return_std": 0.0, "episodes": 10},
                                           {"frames": 10_000, "return_mean": 2.0, "return_std": 0.0, "episodes": 10}])
    fps = transfer / "logs" / "csv" / "scalars" / "train" / "fps.csv"
    fps.parent.mkdir(parents=True)
    fps.write_text("".join(f"{1000 * i},{900.0 if i < 3 else 50.0}\n" for i in range(1, 14)))  # 50 logged last
    study.dry_run(runs)
    lines = dict(line.split(maxsplit=1) for line in capsys.readouterr().out.splitlines())
    assert lines["pi-reuse-barrier-seed-seed-11-baseline"] == "ready: 0 of 300,000 frames"
    assert lines["pi-reuse-barrier-seed-seed-11-transfer"] == "ready: 10,000 of 300,000 frames"
    assert lines["pi-reuse-barrier-seed-seed-12-transfer"].startswith("waits for its source: ")
    assert lines["lift-dense-sac-seed-61"] == "ready: 60,000 of 60,000 frames"  # trained, best.pt not scored yet
    # the transfer's 290k frames at the 50 frames/s it logged last, its row's other 5 runs at the same 50; the
    # other 5 sources' and 4 rows' runs have no run that logged a rate yet
    hours = (290_000 + 5 * 300_000) / 50 / 3600
    assert lines["left"] == (f"to train: about {6 * 60_000 + 5 * 3 * 2 * 300_000 - 10_000 - 60_000:,} frames; at the "
                             f"frames/s the runs trained at, about {hours:.1f} core-hours, {hours:.1f} h on 1 core "
                             "(29 runs with nothing yet to time them by left out)")
    study.dry_run(runs, cores=2)
    assert capsys.readouterr().out.splitlines()[-1].endswith(f", {hours / 2:.1f} h on 2 cores (29 runs with nothing "
                                                             "yet to time them by left out)")
    # once a run of the row has finished, its whole-run rate (warm-up included) times the row's others: a run's
    # own logged rate is frames over seconds since its process started, inflated early on by the warm-up
    finished = transfer.parent.parent / "baseline" / "seed-10"
    finished.mkdir(parents=True)
    (finished / "summary.json").write_text('{"frames_per_s": 40.0}')
    study.dry_run(runs)
    hours = (290_000 + 4 * 300_000) / 40 / 3600
    assert capsys.readouterr().out.splitlines()[-1].startswith(
        f"left to train: about {6 * 60_000 + 5 * 3 * 2 * 300_000 - 10_000 - 60_000 - 300_000:,} frames; at the "
        f"frames/s the runs trained at, about {hours:.1f} core-hours")


def test_a_run_kept_unfinished_is_not_restored_and_trains_again(tmp_path, monkeypatch):
    """A run whose curves are kept while it trains (no ``summary.json`` yet) is not restored: its job is left
    to train, from its checkpoint where this machine has one."""
    study = _study()
    kept = tmp_path / "kept" / "lift-place-seed" / "sac" / "model-reuse-place-seed" / "seed-12"
    kept.mkdir(parents=True)
    (kept / "config.yaml").write_text("task: lift-place-seed\n")
    (kept / "eval.csv").write_text("frames,return_mean\n0,1.0\n")
    monkeypatch.setattr(study, "HERE", tmp_path / "kept")
    runs = tmp_path / "runs"
    assert study.restore(runs) == []
    assert not (runs / "lift-place-seed" / "sac" / "model-reuse-place-seed" / "seed-12").exists()
    assert not {j.name: j for j in study.jobs(runs)}["model-reuse-place-seed-seed-12-transfer"].finished()


def test_a_finished_source_is_kept_with_the_networks_the_rows_reuse_and_a_clone_reuses_it(tmp_path, monkeypatch):
    """A source's ``best.pt`` is kept as its networks alone, which rebuild the same learner; a second training
    of the seed is kept beside the first (``-retrained``), a transfer kept later names the training it reused,
    and a new clone's queue restores the last training and reuses it instead of training the source again."""
    import torch

    from drltg import config as config_lib
    from drltg.store.rundir import load_checkpoint
    from drltg.training.loop import train
    from drltg.transfer.source import rebuild

    study = _study()
    kept_root = tmp_path / "kept"
    monkeypatch.setattr(study, "HERE", kept_root)
    monkeypatch.setattr(study.row, "HERE", kept_root)
    runs = tmp_path / "runs"
    run = runs / "sources" / "lift-dense-sac" / "seed-60"
    tiny = ["network.hidden=[16,16]", "collector.num_envs=4", "collector.frames_per_batch=16", "eval.every=128",
            "collector.init_random_frames=64", "buffer.batch_size=32", "eval.episodes=2", "checkpoint.keep_best=true",
            "log.tensorboard=false"]
    train(config_lib.resolve({}, tiny, task="fourrooms/northeast", frames=256, seed=3), run, progress=False)
    job = study.source_job("lift-dense-sac", 60, runs)
    study.keep(job)
    assert not (kept_root / "sources").exists()  # not finished: best.pt is not scored on fresh episodes yet
    (run / "evaluate-best-seed30060-50ep.json").write_text("{}")
    study.keep(job)
    first = kept_root / "sources" / "lift-dense-sac" / "seed-60"
    weights, full = load_checkpoint(first, checkpoint="best"), load_checkpoint(run, checkpoint="best")
    assert set(weights) == set(study.SOURCE_WEIGHTS) and "buffer" in full
    assert all(torch.equal(weights["loss"][k], v) for k, v in full["loss"].items())
    rebuilt = rebuild(first, checkpoint="best")
    assert rebuilt.frames == full["frames"]
    from drltg.transfer.source import check

    check(config_lib.resolve({}, tiny + ["transfer.method=model-reuse", f"transfer.source={first}",
                                         "transfer.source_checkpoint=best"], task="fourrooms/northeast", seed=4))
    assert all(torch.equal(v, full["loss"][k]) for k, v in rebuilt.agent.loss.state_dict().items())

    study.keep(job)  # the same training again: kept where it is
    with open(run / "eval.csv", "a") as f:  # another training of the seed
        f.write("256,1.0,0.0,2,1.0\n")
    study.keep(job)
    again = first.with_name("seed-60-retrained")
    assert sorted(p.name for p in first.parent.iterdir()) == ["seed-60", "seed-60-retrained"]
    assert (again / "eval.csv").read_bytes() == (run / "eval.csv").read_bytes() != (first / "eval.csv").read_bytes()

    clone = tmp_path / "clone"
    assert clone / "sources" / "lift-dense-sac" / "seed-60" in study.restore(clone)
    restored = next(j for j in study.jobs(clone) if j.name == "lift-dense-sac-seed-60")
    assert restored.finished() and (restored.keep / "eval.csv").read_bytes() == (again / "eval.csv").read_bytes()
    assert next(j for j in study.jobs(clone) if j.name == "pi-reuse-place-seed-seed-10-transfer").ready()
    transfer = clone / "lift-place-seed" / "sac" / "pi-reuse-place-seed" / "seed-10"
    transfer.mkdir(parents=True)
    (transfer / "config.yaml").write_text("transfer:\n  source: ../../../../sources/lift-dense-sac/seed-60\n")
    study.row.keep(transfer, tmp_path / "row" / "seed-10", clone)
    assert (tmp_path / "row" / "seed-10" / "config.yaml").read_text() == (
        f"transfer:\n  source: {os.path.relpath(again, tmp_path / 'row' / 'seed-10')}\n")


def test_the_retrained_sources_paragraph_states_the_kept_numbers():
    """The seed study's README and docs/training.md say how far a second training of SAC source seed 60 was
    from its first before any update, and what a kept source's best.pt weighs: the kept files' numbers."""
    import re

    from drltg.store.rundir import read_eval_csv

    sources = RESULTS / "seed-tasks" / "sources" / "lift-dense-sac"
    again, first = (read_eval_csv(sources / name / "eval.csv")[0] for name in ("seed-60-retrained", "seed-60"))
    assert again["frames"] == first["frames"] == 0
    said = f"mean return {again['return_mean']:.3f} against {first['return_mean']:.3f} before any update"
    readme = " ".join((RESULTS / "seed-tasks" / "README.md").read_text().split())
    assert said in readme and said in " ".join((RESULTS.parent / "docs" / "training.md").read_text().split())
    weighs = (sources / "seed-60-retrained" / "checkpoints" / "best.pt").stat().st_size / 1e6
    assert re.search(r"reduced to the networks the rows reuse \((\S+) MB for SAC", readme)[1] == f"{weighs:.1f}"


def test_a_row_run_is_kept_as_soon_as_it_finishes(tmp_path, monkeypatch):
    """A row keeps each finished run at once (its seed's transfer run may outlast the session that trained
    its baseline); a run that was finished before is not copied again, and an unfinished one is not kept."""
    import drltg.training.loop as loop

    row = _study().row
    monkeypatch.setattr(row, "HERE", tmp_path / "kept")
    runs = tmp_path / "runs"
    trained = []

    def train(cfg, run, resume, progress):
        trained.append(run)
        run.mkdir(parents=True)
        (run / "config.yaml").write_text("transfer:\n  source: null\n")
        (run / "eval.csv").write_text("frames,return_mean\n0,1.0\n")
        if run.name != "seed-12":  # stopped before its end
            (run / "summary.json").write_text("{}")

    monkeypatch.setattr(loop, "train", train)
    cfgs, dirs = row.sides("shaping-lift-seed", runs)["transfer"]
    dirs[0].mkdir(parents=True)
    (dirs[0] / "summary.json").write_text("{}")  # finished before
    row.train_runs(cfgs, dirs, runs)
    assert trained == dirs[1:]
    kept = [tmp_path / "kept" / d.relative_to(runs) for d in dirs]
    assert [k.is_dir() for k in kept] == [False, True, False]
    assert (kept[1] / "eval.csv").read_text() == "frames,return_mean\n0,1.0\n"


def test_a_row_process_trains_only_the_sides_and_seeds_it_is_given(tmp_path, monkeypatch, capsys):
    """``row.py ROW --seeds 12 --sides transfer`` trains that one run; a row with runs left is not reported."""
    import sys

    import drltg.training.loop as loop

    row = _study().row
    monkeypatch.setattr(row, "HERE", tmp_path / "kept")
    runs = tmp_path / "runs"
    trained = []
    monkeypatch.setattr(loop, "train", lambda cfg, run, resume, progress: trained.append((cfg.seed, run)))
    monkeypatch.setattr(sys, "argv", ["row.py", "shaping-lift-seed", "--seeds", "12", "--sides", "transfer",
                                      "--runs", str(runs)])
    row.main()
    assert trained == [(12, runs / "lift" / "sac" / "shaping-lift-seed" / "seed-12")]
    assert "other runs of the row are not finished yet" in capsys.readouterr().out
    assert not (tmp_path / "kept").exists()


def test_of_two_processes_finishing_a_row_at_once_one_reports_it(tmp_path, monkeypatch, capsys):
    """The row's folder is locked while a process reports it; a second process leaves the report to it."""
    from drltg.store.lock import lock

    row = _study().row
    monkeypatch.setattr(row, "HERE", tmp_path / "results")
    reported = []
    monkeypatch.setattr(row, "keep_and_report", lambda name, groups, runs: reported.append(name))
    folder = tmp_path / "results" / "shaping-lift-seed"
    folder.mkdir(parents=True)
    with lock(folder):
        row.report_once("shaping-lift-seed", {}, tmp_path / "runs")
    assert reported == [] and "another process is reporting the row" in capsys.readouterr().out
    row.report_once("shaping-lift-seed", {}, tmp_path / "runs")
    assert reported == ["shaping-lift-seed"] and list(folder.iterdir()) == []  # the lock is gone with its owner


def test_a_finished_shaping_row_is_reported_on_lifts_success_alone(tmp_path, monkeypatch):
    """Shaping's two sides are paid by different rewards (dense against sparse Lift), so its row is reported
    on the success rate only, and its kept runs name no source."""
    row = _study().row
    monkeypatch.setattr(row, "HERE", tmp_path / "results")
    monkeypatch.chdir(tmp_path)
    groups = row.sides("shaping-lift-seed", tmp_path / "runs")
    for side, (_, dirs) in groups.items():
        for d, seed in zip(dirs, row.SEEDS):
            d.mkdir(parents=True)
            shaping = "true" if side == "transfer" else "false"
            (d / "config.yaml").write_text(f"task: lift\nseed: {seed}\nframes: 20\nenv:\n  reward_shaping: {shaping}\n")
            rate = 0.5 if side == "transfer" else 0.0
            (d / "eval.csv").write_text("frames,return_mean,success_rate,lifted_rate\n"
                                        f"0,0.0,0.0,0.0\n10,{seed},{rate},{rate}\n20,{seed},{rate},{rate}\n")
            (d / "summary.json").write_text("{}")
    row.keep_and_report("shaping-lift-seed", groups, tmp_path / "runs")
    out = tmp_path / "results" / "shaping-lift-seed"
    assert sorted(p.name for p in out.iterdir()) == ["baseline", "report-success", "transfer"]
    metrics = json.loads((out / "report-success" / "transfer_metrics.json").read_text())
    assert metrics["settings"]["transfer"][0] == "results/shaping-lift-seed/transfer/seed-10/eval.csv"
    assert metrics["metrics"]["asymptotic_performance"] == pytest.approx(0.5)
    assert (out / "transfer" / "seed-12" / "config.yaml").read_text().endswith("reward_shaping: true\n")
