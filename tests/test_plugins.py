"""Users' tasks on every command: plugins from --import, DRLTG_IMPORT and the drltg.plugins entry points."""
import importlib.metadata
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from drltg import plugins
from drltg.cli import main
from drltg.envs import registry

PLUGIN_DIR = Path(__file__).resolve().parents[1] / "examples" / "plugin"
TINY = ["eval.every=256", "eval.episodes=4", "collector.num_envs=4", "collector.frames_per_batch=16",
        "collector.init_random_frames=128", "optim.updates_per_batch=1", "log.tensorboard=false"]


def _drltg(*args, env_extra=None):
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(PLUGIN_DIR), os.environ.get("PYTHONPATH", "")])}
    env.pop("DRLTG_IMPORT", None)
    env.update(env_extra or {})
    return subprocess.run([sys.executable, "-m", "drltg.cli", *args], capture_output=True, text=True, env=env,
                          timeout=300)


def test_experiment_runs_a_plugin_method_on_a_plugin_pair_in_worker_processes(tmp_path):
    out = tmp_path / "exp"
    args = ["experiment", "line-shift", "--method", "critic-reuse", "--seeds", "2", "--frames", "512",
            "--workers", "2", "--out", str(out), "--import", "drltg_example_plugin"]
    for o in TINY:
        args += ["-o", o]
    done = _drltg(*args)
    assert done.returncode == 0, done.stderr[-2000:]
    configs = {p.parent: yaml.safe_load(p.read_text()) for p in sorted(out.glob("*/seed-*/config.yaml"))}
    assert sorted(c["task"] for c in configs.values()) == ["line/middle"] * 4 + ["line/right"] * 2
    for run in out.glob("transfer/seed-*"):
        assert configs[run]["transfer"]["method"] == "critic-reuse"
        first, *entries = (run / "model_reuse.txt").read_text().splitlines()
        assert first.startswith("model reuse: 16 loaded") and "6 skipped" in first  # critics, targets, alpha
        assert len(entries) == 6 and all(e.startswith("  skipped  actor_network_params.") for e in entries)
    report = json.loads((out / "report" / "transfer_metrics.json").read_text())
    assert report["metrics"]["n_seeds_transfer"] == 2


def test_drltg_import_variable_reaches_every_command():
    done = _drltg("tasks", env_extra={"DRLTG_IMPORT": "drltg_example_plugin"})
    assert done.returncode == 0 and "line-shift" in done.stdout and "line/right" in done.stdout
    assert "line-shift" not in _drltg("tasks").stdout


def test_a_missing_plugin_module_is_one_sentence(capsys, monkeypatch):
    monkeypatch.setenv("DRLTG_IMPORT", "")  # restored after the test: a successful load exports its modules
    assert main(["tasks", "--import", "no_such_plugin_module"]) == 2
    assert os.environ["DRLTG_IMPORT"] == ""
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "cannot import plugin module 'no_such_plugin_module'" in err


def test_entry_point_plugins_are_loaded(monkeypatch):
    monkeypatch.setattr(registry, "TASKS", dict(registry.TASKS))
    monkeypatch.setattr(registry, "PAIRS", dict(registry.PAIRS))
    monkeypatch.syspath_prepend(str(PLUGIN_DIR))
    monkeypatch.setenv("DRLTG_IMPORT", "")
    sys.modules.pop("drltg_example_plugin", None)
    ep = importlib.metadata.EntryPoint(name="line", value="drltg_example_plugin", group=plugins.GROUP)
    monkeypatch.setattr(plugins, "entry_points", lambda group: [ep] if group == plugins.GROUP else [])
    assert plugins.load() == ["drltg_example_plugin"]
    assert registry.get_pair("line-shift").target == "line/middle"
    sys.modules.pop("drltg_example_plugin", None)


def test_a_broken_entry_point_is_one_sentence(monkeypatch):
    monkeypatch.setenv("DRLTG_IMPORT", "")
    ep = importlib.metadata.EntryPoint(name="broken", value="no_such_module_xyz", group=plugins.GROUP)
    monkeypatch.setattr(plugins, "entry_points", lambda group: [ep])
    with pytest.raises(plugins.UsageError, match="the drltg plugin 'broken' .* failed to load"):
        plugins.load()


def test_plugins_are_loaded_on_the_gymnasium_path(tmp_path):
    """gymnasium.make("drltg:drltg/<task>-v0") finds a DRLTG_IMPORT plugin's task, as every command does."""
    code = ("import gymnasium\nenv = gymnasium.make('drltg:drltg/line-right-v0')\nobs, _ = env.reset(seed=0)\n"
            "print(env.unwrapped.task, obs.shape)")
    root = Path(__file__).resolve().parents[1]
    env = {**os.environ, "DRLTG_IMPORT": "drltg_example_plugin",
           "PYTHONPATH": os.pathsep.join([str(root / "examples" / "plugin"), str(root)])}
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path, env=env)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.split()[0] == "line/right"
