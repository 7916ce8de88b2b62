"""`drltg experiment`: source, baseline and transfer runs over seeds, then the report."""
import json
import os
import shutil
from pathlib import Path

import pytest
import yaml

from drltg.cli import main

TINY = ["-o", "network.hidden=[16,16]", "-o", "collector.num_envs=4", "-o", "collector.frames_per_batch=16",
        "-o", "collector.init_random_frames=128", "-o", "optim.updates_per_batch=1",
        "-o", "buffer.batch_size=32", "-o", "eval.every=256", "-o", "eval.episodes=4",
        "-o", "log.tensorboard=false"]


@pytest.fixture(scope="module")
def experiment(tmp_path_factory):
    out = tmp_path_factory.mktemp("exp") / "near"
    args = ["experiment", "fourrooms-near", "--method", "model-reuse", "--seeds", "2", "--frames", "512",
            "--out", str(out), "--threshold", "0"] + TINY
    assert main(args) == 0
    return out, args


def test_layout_seeds_and_report(experiment):
    out, _ = experiment
    assert sorted(p.name for p in (out / "source").iterdir()) == ["seed-150", "seed-50"]
    assert sorted(p.name for p in (out / "baseline").iterdir()) == ["seed-0", "seed-100"]
    assert sorted(p.name for p in (out / "transfer").iterdir()) == ["seed-0", "seed-100"]
    report = json.loads((out / "report" / "transfer_metrics.json").read_text())
    assert report["metrics"]["n_seeds_baseline"] == report["metrics"]["n_seeds_transfer"] == 2
    assert (out / "report" / "transfer_plot.png").stat().st_size > 10_000
    # every transfer run starts from its own source run's weights
    assert "22 loaded" in (out / "transfer" / "seed-0" / "model_reuse.txt").read_text()


def test_rerun_reuses_completed_runs(experiment, capsys):
    out, args = experiment
    stamps = {p: p.stat().st_mtime_ns for p in out.glob("*/seed-*/summary.json")}
    assert len(stamps) == 6
    assert main(args) == 0
    assert stamps == {p: p.stat().st_mtime_ns for p in out.glob("*/seed-*/summary.json")}


def test_the_experiment_prints_the_warnings_its_report_prints(experiment, tmp_path, capsys):
    out, args = experiment
    assert main(args) == 0
    said = [line for line in capsys.readouterr().err.splitlines() if line.startswith("warning:")]
    assert main(["report", "--baseline", str(out / "baseline"), "--transfer", str(out / "transfer"),
                 "--threshold", "0", "--out", str(tmp_path / "rep")]) == 0
    assert said and said == [line for line in capsys.readouterr().err.splitlines() if line.startswith("warning:")]


def test_the_python_function_is_the_command(experiment, capsys):
    """drltg.experiment, called from a script on the command's folder, reuses its runs and returns the
    report the command wrote; a frame count may be written as text."""
    import drltg

    out, args = experiment
    stamps = {p: p.stat().st_mtime_ns for p in out.glob("*/seed-*/summary.json")}
    overrides = [args[i + 1] for i, a in enumerate(args) if a == "-o"]
    report = drltg.experiment("fourrooms-near", "model-reuse", seeds=2, frames="0.512k", out=out, threshold=0,
                              overrides=overrides, progress=False)
    assert stamps == {p: p.stat().st_mtime_ns for p in out.glob("*/seed-*/summary.json")}
    saved = json.loads((out / "report" / "transfer_metrics.json").read_text())
    assert report["metrics"] == pytest.approx(saved["metrics"], nan_ok=True)
    assert report["out_dir"] == str(out / "report") and report["diverged"] == []
    assert capsys.readouterr().out == ""  # a library call prints nothing; the command prints the table
    with pytest.raises(ValueError, match="--seeds and --frames must be positive"):
        drltg.experiment("fourrooms-near", "model-reuse", seeds=0, frames=512, out=out)


def test_a_moved_experiment_finds_its_sources_and_reuses_its_runs(experiment, tmp_path):
    from drltg.store import rundir

    out, args = experiment
    assert yaml.safe_load((out / "transfer" / "seed-0" / "config.yaml").read_text())["transfer"]["source"] == \
        "../../source/seed-50"
    moved = tmp_path / "elsewhere"
    shutil.copytree(out, moved)
    stamps = {p: p.stat().st_mtime_ns for p in moved.glob("*/seed-*/summary.json")}
    assert main([a if a != str(out) else str(moved) for a in args]) == 0
    assert stamps == {p: p.stat().st_mtime_ns for p in moved.glob("*/seed-*/summary.json")}
    assert rundir.read_config(moved / "transfer" / "seed-100")["transfer"]["source"] == str(
        moved / "source" / "seed-150"
    )


def test_other_settings_in_same_dir_refused_naming_each(experiment, capsys):
    out, args = experiment
    changed = [a if a != "512" else "1024" for a in args]
    assert main(changed) == 2
    assert "other settings (frames is 512 there, 1024 now); run it with its settings (only --seeds may change" in \
        capsys.readouterr().err


def test_an_experiment_grows_by_its_new_seeds_alone(tmp_path, capsys):
    """The report said more pairs would decide: the same command with more --seeds trains the new seeds'
    runs only, and reports every pair."""
    out = tmp_path / "grow"
    args = ["experiment", "gridrooms/northeast", "--method", "reward-shaping", "--frames", "64", "--out", str(out),
            "--threshold", "0", "--no-progress", *TINY]
    assert main([*args, "--seeds", "1"]) == 0
    kept = {p: p.read_bytes() for p in out.glob("*/seed-0/**/*") if p.is_file()}
    assert main([*args, "--seeds", "2"]) == 0
    assert {p: p.read_bytes() for p in out.glob("*/seed-0/**/*") if p.is_file()} == kept  # not trained again
    assert sorted(p.name for p in (out / "transfer").iterdir()) == ["seed-0", "seed-100"]
    report = json.loads((out / "report" / "transfer_metrics.json").read_text())
    assert report["metrics"]["n_seeds_baseline"] == report["metrics"]["n_seeds_transfer"] == 2
    assert yaml.safe_load((out / "experiment.yaml").read_text())["seeds"] == 2


def test_reward_shaping_needs_no_source(tmp_path):
    out = tmp_path / "shaping"
    assert main(["experiment", "gridrooms/northeast", "--method", "reward-shaping", "--seeds", "1",
                 "--frames", "256", "--out", str(out)] + TINY) == 0
    assert not (out / "source").exists()
    assert (out / "transfer" / "seed-0" / "config.yaml").read_text().count("method: reward-shaping") == 1


def test_unknown_pair(tmp_path, capsys):
    assert main(["experiment", "fourrooms-nera", "--method", "policy-reuse", "--frames", "10",
                 "--out", str(tmp_path / "x")]) == 2
    assert "did you mean 'fourrooms-near'" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


SCRIPT = '''
import sys
import drltg
from drltg.envs import register_pair, register_task
from drltg.envs.fourrooms import FourRoomsEnv


def corridor(**options):  # a factory of the script's own, at its top level
    return FourRoomsEnv(**options)


def main(out, factory):
    register_task("mine/a", factory, "the script's source task", goal=(8.0, 8.0), horizon=40)
    register_task("mine/b", factory, "the script's target task", goal=(8.0, 7.0), horizon=40)
    register_pair("mine-near", "mine/a", "mine/b", "registered inside main()")
    report = drltg.experiment("mine-near", "model-reuse", seeds=1, frames=64, out=out, progress=False,
                              overrides=OVERRIDES)
    print("gain", report["metrics"]["mean_return_gain"])


OVERRIDES = %r
if __name__ == "__main__":
    main(sys.argv[1], corridor if sys.argv[2] == "top" else (lambda **o: FourRoomsEnv(**o)))
'''


@pytest.mark.parametrize("factory", ["top", "lambda"])
def test_tasks_registered_inside_a_script_s_function_reach_the_workers(tmp_path, factory):
    """A script registers its task pair inside main() and runs an experiment in spawned worker processes:
    the runs train on its tasks; a factory no worker can import (a lambda) is refused before any work."""
    import subprocess
    import sys

    overrides = [TINY[i + 1] for i in range(0, len(TINY), 2)]
    (tmp_path / "script.py").write_text(SCRIPT % (overrides,))
    done = subprocess.run([sys.executable, "script.py", str(tmp_path / "out"), factory], cwd=tmp_path,
                          capture_output=True, text=True, timeout=600, env={**os.environ, "RL_WARNINGS": "False"})
    if factory == "top":
        assert done.returncode == 0, done.stderr[-2000:]
        assert "gain" in done.stdout
        assert yaml.safe_load((tmp_path / "out" / "transfer" / "seed-0" / "config.yaml").read_text())["task"] == \
            "mine/b"
    else:
        assert done.returncode != 0
        last = done.stderr.strip().splitlines()[-1]
        assert "the task 'mine/a' cannot reach the worker processes" in last and "--import" in last, last
        assert not (tmp_path / "out").exists()


# ----------------------------------------------------------------------------- seeds until decided
def test_seeds_auto_runs_the_plan_s_looks_and_records_why_it_stopped(tmp_path, capsys):
    """A real (tiny) experiment capped at 2 pairs: one look, at the whole level, that 2 pairs cannot pass."""
    out = tmp_path / "auto"
    args = ["experiment", "fourrooms-near", "--method", "model-reuse", "--seeds", "auto", "--max-seeds", "2",
            "--frames", "256", "--out", str(out)] + TINY
    assert main(args) == 0
    printed = capsys.readouterr()
    report = json.loads((out / "report" / "transfer_metrics.json").read_text())
    seq = report["settings"]["sequential"]
    assert seq["looks"] == [{"pairs": 2, "alpha": 0.05}] and seq["stopped"] == "cap" and seq["pairs"] == 2
    assert report["metrics"]["mean_return_gain_verdict"] == "undecided"
    assert report["metrics"]["mean_return_gain_verdict_test"] == "sign-flip, sequential"
    assert "undecided at the cap of 2 pairs (exact sign-flip test at look 1 of 1, 2 pairs" in printed.out
    assert "look 1 of 1: 2 pairs" in printed.err
    assert yaml.safe_load((out / "experiment.yaml").read_text())["seeds"] == "auto"


@pytest.mark.parametrize("p_values, stopped, pairs, verdict", [
    ([0.2, 0.004], "decided", 12, "higher"),        # look 2 of 4 passes its share 0.0125
    ([0.2, 0.02, 0.3, 0.04], "cap", 20, "undecided"),  # 0.04 < 0.05 alone, not below its share
])
def test_seeds_auto_stops_at_the_first_look_below_its_share(monkeypatch, tmp_path, p_values, stopped, pairs, verdict):
    from drltg.experiments import experiment as ex

    trained = []

    def fake_run(pair, method, frames, out, seeds, *rest, value_range=None, source_success=None):
        trained.append(seeds)
        folder = tmp_path / "report"
        folder.mkdir(exist_ok=True)
        metrics = {"mean_return_gain": 0.5, "mean_return_gain_verdict_p": p_values[len(trained) - 1],
                   "n_seeds_baseline": seeds, "n_seeds_transfer": seeds}
        (folder / "transfer_metrics.json").write_text(json.dumps({"metrics": metrics, "settings": {}}))
        return {"metrics": dict(metrics), "settings": {}, "out_dir": str(folder), "diverged": []}

    monkeypatch.setattr(ex, "_run", fake_run)
    result = ex.experiment("fourrooms-near", "model-reuse", frames=256, out=tmp_path / "x", seeds="auto",
                           progress=False)
    assert trained == [8, 12, 16, 20][:len(p_values)]
    seq = result["settings"]["sequential"]
    assert (seq["stopped"], seq["pairs"], result["metrics"]["mean_return_gain_verdict"]) == (stopped, pairs, verdict)
    saved = json.loads((tmp_path / "report" / "transfer_metrics.json").read_text())
    assert saved["settings"]["sequential"] == seq and saved["metrics"]["mean_return_gain_verdict"] == verdict


def test_seeds_is_a_count_or_auto(tmp_path, capsys):
    code = main(["experiment", "fourrooms-near", "--method", "model-reuse", "--seeds", "many", "--frames", "256",
                 "--out", str(tmp_path / "x")])
    assert code == 2 and "--seeds: must be a whole number or 'auto', got 'many'" in capsys.readouterr().err
    code = main(["experiment", "fourrooms-near", "--method", "model-reuse", "--seeds", "auto", "--max-seeds", "0",
                 "--frames", "256", "--out", str(tmp_path / "x")])
    assert code == 2 and "--max-seeds must be a whole number from 1" in capsys.readouterr().err


def test_a_source_path_with_yaml_characters_is_the_path_itself(tmp_path):
    """plan_runs turned each source back into a `transfer.source=<path>` override and parsed it as YAML:
    with --out "/tmp/x #1" the transfer runs silently read the source '/tmp/x' (a comment cut the rest)."""
    from drltg.experiments.experiment import plan_runs

    out = tmp_path / "x #1: y"
    runs = plan_runs("fourrooms-near", "model-reuse", frames=512, out=out, seeds=2)
    sources = {path for role, _, path in runs if role == "source"}
    transfers = [cfg for role, cfg, _ in runs if role == "transfer"]
    assert [cfg.transfer.source for cfg in transfers] == [str(out / "source" / "seed-50"),
                                                          str(out / "source" / "seed-150")]
    assert {Path(cfg.transfer.source) for cfg in transfers} == sources
    assert all(cfg.transfer.source is None for role, cfg, _ in runs if role != "transfer")


def test_ctrl_c_stops_an_experiment_cleanly(tmp_path):
    """Ctrl-C in a terminal signals the whole process group: the workers leave it to the parent, which stops
    them; nothing is left behind that Python's resource tracker would warn about (the replay buffers' and
    tqdm's semaphores, 11 of them, were), and the run's log says it was interrupted."""
    import signal
    import subprocess
    import sys
    import time

    out = tmp_path / "near"
    cmd = [sys.executable, "-m", "drltg.cli", "experiment", "fourrooms-near", "--method", "model-reuse", "--seeds", "2",
           "--frames", "100000", "--out", str(out)] + TINY
    child = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
                             preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.monotonic() + 120

    def frames() -> int:  # what the workers report, once they train
        return max((int(p.read_text() or 0) for p in (out / "logs").rglob("*.frames")), default=0)

    while frames() < 1000 and time.monotonic() < deadline and child.poll() is None:
        time.sleep(0.2)
    os.killpg(child.pid, signal.SIGINT)
    _, err = child.communicate(timeout=120)
    assert child.returncode == 130, err[-2000:]
    assert "interrupted" in err and "leaked" not in err, err[-2000:]
    logs = list((out / "logs" / "source").glob("*.log"))
    assert logs and all("interrupted; a rerun continues it" in log.read_text() for log in logs[:1])


def test_a_source_written_with_seed_serves_each_transfer_run_from_its_own_seed(tmp_path):
    from drltg.experiments.experiment import plan_runs

    runs = plan_runs("fourrooms/northeast-shifted", "model-reuse", frames=100, out=tmp_path, seeds=3, seed=7,
                     overrides=["transfer.source=kept/seed-{seed}"])
    got = [(role, cfg.seed, cfg.transfer.source) for role, cfg, _ in runs]
    kept = Path.cwd() / "kept"
    assert got == [("baseline", 7, None), ("transfer", 7, str(kept / "seed-7")),
                   ("baseline", 107, None), ("transfer", 107, str(kept / "seed-107")),
                   ("baseline", 207, None), ("transfer", 207, str(kept / "seed-207"))]
    # a source without {seed} serves every transfer run; the baselines have none either way
    runs = plan_runs("fourrooms/northeast-shifted", "model-reuse", frames=100, out=tmp_path, seeds=2,
                     overrides=["transfer.source=kept/one"])
    assert {(role, cfg.transfer.source) for role, cfg, _ in runs} == {("baseline", None),
                                                                             ("transfer", "kept/one")}
