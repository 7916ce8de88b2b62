"""`drltg experiment`: source, baseline and transfer runs over seeds, then the report."""
import json
import shutil

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


def test_other_settings_in_same_dir_refused(experiment, capsys):
    out, args = experiment
    changed = [a if a != "512" else "1024" for a in args]
    assert main(changed) == 2
    assert "other settings" in capsys.readouterr().err


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
