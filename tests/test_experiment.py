"""`drltg experiment`: source, baseline and transfer runs over seeds, then the report."""
import argparse
import json
import os
import shutil
from pathlib import Path

import pytest
import yaml

from drltg.cli import main
from drltg.errors import UsageError

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
    reported = [line for line in capsys.readouterr().err.splitlines() if line.startswith("warning:")]
    sources = [line for line in said if "source run(s) never succeeded" in line]  # the experiment knows its sources
    assert said and [line for line in said if line not in sources] == reported
    assert all(line.startswith("warning: 1 source run(s) never succeeded in any evaluation (") for line in sources)


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


def test_the_report_of_an_experiment_is_drawn_for_a_page(experiment, tmp_path, page_size):
    """``--figure one-column`` redraws a finished experiment's report as a one-column PDF; how it is drawn is
    no setting of the experiment (its experiment.yaml is the same)."""
    out, args = experiment
    mine = tmp_path / "paper"
    shutil.copytree(out, mine)
    saved = (mine / "experiment.yaml").read_text()
    assert main([a if a != str(out) else str(mine) for a in args] + ["--figure", "one-column"]) == 0
    assert page_size(mine / "report" / "transfer_plot.pdf")[0] == pytest.approx(3.3 * 72)
    assert (mine / "experiment.yaml").read_text() == saved


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
def test_seeds_auto_runs_the_plan_s_looks_and_continues_only_under_it(tmp_path, capsys):
    """A real (tiny) experiment capped at 2 pairs: one look, at the whole level, that 2 pairs cannot pass.
    Grown with a fixed count it reported an uncorrected p and dropped its plan's record; now it is refused."""
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
    # the folder continues only under its plan: a fixed count or another cap is refused, the same plan runs
    settings = (out / "experiment.yaml").read_bytes()
    fixed = [a if a != "auto" else "3" for a in args[:args.index("--max-seeds")]] + args[args.index("--frames"):]
    assert main(fixed) == 2
    assert (f"'{out}' holds a --seeds auto experiment, whose looks already spent its level; continue it with "
            "--seeds auto --max-seeds 2, or train --seeds 3 into another --out.") in capsys.readouterr().err
    assert main([a if a != "2" else "3" for a in args]) == 2
    assert "planned for --max-seeds 2, and another cap would change the share" in capsys.readouterr().err
    assert (out / "experiment.yaml").read_bytes() == settings and not (out / "baseline" / "seed-200").exists()
    assert main(args) == 0
    again = json.loads((out / "report" / "transfer_metrics.json").read_text())
    assert again["settings"]["sequential"] == seq and again["metrics"] == report["metrics"]


def test_an_option_given_twice_is_refused(tmp_path, capsys):
    """argparse keeps the last: `--seeds auto ... --seeds 14` trained 14 fixed seeds."""
    code = main(["experiment", "fourrooms-near", "--method", "model-reuse", "--seeds", "auto", "--frames", "256",
                 "--seeds", "14", "--out", str(tmp_path / "x")])
    assert code == 2
    assert capsys.readouterr().err.strip() == ("drltg experiment: error: argument --seeds is given twice ('auto', "
                                               "then 14); give it once")
    assert not (tmp_path / "x").exists()


def test_a_fixed_count_folder_is_not_continued_as_a_sequential_plan(tmp_path, capsys):
    from drltg.experiments.experiment import check_settings

    saved = tmp_path / "experiment.yaml"
    saved.write_text(yaml.safe_dump({"pair": "fourrooms-near", "seeds": 5}))
    check_settings(saved, {"pair": "fourrooms-near", "seeds": 8})  # more fixed seeds: allowed
    with pytest.raises(UsageError, match=r"holds an experiment of --seeds 5 already reported, and a sequential"):
        check_settings(saved, {"pair": "fourrooms-near", "seeds": "auto", "max_seeds": 20})


@pytest.mark.parametrize("p_values, stopped, pairs, verdict", [
    ([0.2, 0.004], "decided", 12, "higher"),        # look 2 of 4 passes its share 0.0125
    ([0.2, 0.02, 0.3, 0.04], "cap", 20, "undecided"),  # 0.04 < 0.05 alone, not below its share
])
def test_seeds_auto_stops_at_the_first_look_below_its_share(monkeypatch, tmp_path, p_values, stopped, pairs, verdict):
    from drltg.experiments import experiment as ex

    trained = []

    def fake_run(pair, method, frames, out, seeds, *rest, value_range=None, source_success=None, figure=None):
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
    code = main(["experiment", "fourrooms-near", "--method", "model-reuse", "--seeds", "3", "--max-seeds", "0",
                 "--frames", "256", "--out", str(tmp_path / "x")])
    assert code == 2 and "--max-seeds caps --seeds auto; with --seeds 3 it would do nothing, so leave it out." in \
        capsys.readouterr().err
    assert not (tmp_path / "x").exists()


def test_a_value_range_wider_than_a_float_is_refused_before_training(tmp_path, capsys):
    """-1e308,1e308 passed as finite, then its width overflowed to inf and the report's JSON writer failed."""
    code = main(["experiment", "fourrooms-near", "--method", "model-reuse", "--seeds", "2", "--frames", "256",
                 "--value-range=-1e308,1e308", "--out", str(tmp_path / "x")])
    assert code == 2 and "HIGH - LOW overflows" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


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


def test_an_experiment_yaml_runs_again_with_config_and_a_dry_run_lists_it(experiment, tmp_path, capsys):
    """`--config E/experiment.yaml` is the experiment's settings (the command line's win); `--dry-run` lists the
    runs and what each folder holds, and trains nothing."""
    out, args = experiment
    capsys.readouterr()
    assert main(["experiment", "--config", str(out / "experiment.yaml"), "--out", str(out), "--dry-run"]) == 0
    listed = capsys.readouterr().out.splitlines()
    assert sum(line.endswith("finished") for line in listed) == 6
    assert listed[-2] == "6 runs, 1 report; 0 units of work to train: 0 seed groups of 0 runs, 0 runs alone"
    assert listed[-1].startswith("left to train: about 0 of ")
    again = tmp_path / "again"
    assert main(["experiment", "--config", str(out / "experiment.yaml"), "--out", str(again), "--dry-run"]) == 0
    listed = capsys.readouterr().out.splitlines()
    assert sum(line.endswith("not started") for line in listed) == 6
    assert listed[-2] == ("6 runs, 1 report; 3 units of work to train: 3 seed groups of 6 runs (2 runs each), "
                          "0 runs alone")
    assert not again.exists()
    assert main(["experiment", "--config", str(out / "experiment.yaml"), "--out", str(again), "--threshold", "0",
                 "--no-progress"]) == 0
    for config in out.glob("*/seed-*/config.yaml"):
        mine, theirs = (yaml.safe_load(c.read_text()) for c in (config, again / config.relative_to(out)))
        mine["transfer"].pop("source"), theirs["transfer"].pop("source")
        assert mine == theirs
    assert yaml.safe_load((again / "experiment.yaml").read_text()) == yaml.safe_load((out / "experiment.yaml")
                                                                                      .read_text())


def test_config_settings_are_checked_and_the_command_line_wins(tmp_path, capsys):
    from drltg.experiments.experiment import settings_of

    path = tmp_path / "e.yaml"
    path.write_text(yaml.safe_dump({"pair": "fourrooms-near", "method": "model-reuse", "frames": 512, "seeds": 3,
                                    "overrides": ["optim.lr=0.01", "eval.every=64"]}))
    args = argparse.Namespace(config=path, pair=None, method="policy-reuse", algo=None, seeds=None, max_seeds=None,
                              seed=None, frames=None, source_frames=None, source_success=None,
                              overrides=["optim.lr=0.1"])
    settings = settings_of(args)
    assert (settings["pair"], settings["method"], settings["seeds"], settings["algo"]) == (
        "fourrooms-near", "policy-reuse", 3, "sac")
    assert settings["overrides"] == ["eval.every=64", "optim.lr=0.1"]
    path.write_text(yaml.safe_dump({"pair": "fourrooms-near", "budget": 5}))
    with pytest.raises(UsageError, match=r"holds 'budget', no experiment setting"):
        settings_of(args)
    assert main(["experiment", "--out", str(tmp_path / "x")]) == 2
    assert "name a pair, --method, --frames on the command line or in --config FILE." in capsys.readouterr().err
