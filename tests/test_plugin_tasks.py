"""A plugin's own tasks, pair and method, registered as a user writes them (no ``replace=True``), run through
every command that trains in spawned workers: ``experiment``, ``sweep`` and ``bench run``. A worker registers
the plugins first and the parent's shipped tasks over them; a worker that cannot start says why."""
import json
import os
import subprocess
import sys
from pathlib import Path

import yaml

from drltg.cli import main

PLUGIN_DIR = Path(__file__).resolve().parent / "data" / "plugins"
TINY = {"eval.every": 256, "eval.episodes": 2, "collector.num_envs": 2, "collector.frames_per_batch": 16,
        "collector.init_random_frames": 128, "optim.updates_per_batch": 1, "log.tensorboard": False}


def _drltg(*args, cwd, env_extra=None):
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(PLUGIN_DIR), os.environ.get("PYTHONPATH", "")])}
    env.pop("DRLTG_IMPORT", None)
    env.update(env_extra or {})
    return subprocess.run([sys.executable, "-m", "drltg.cli", *args], capture_output=True, text=True, env=env,
                          cwd=cwd, timeout=300)


def _overrides():
    return [a for k, v in TINY.items() for a in ("-o", f"{k}={str(v).lower() if isinstance(v, bool) else v}")]


def _tasks(out: Path) -> dict[str, str]:
    return {str(p.parent.relative_to(out)): yaml.safe_load(p.read_text())["task"]
            for p in sorted(out.rglob("seed-*/config.yaml"))}


def test_experiment_runs_a_plugins_own_pair_in_spawned_workers(tmp_path):
    out = tmp_path / "E"
    done = _drltg("experiment", "pend-lh", "--method", "pend-reuse", "--import", "pendplug", "--seeds", "2",
                  "--frames", "512", "--workers", "2", "--out", str(out), *_overrides(), cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    tasks = _tasks(out)
    assert sorted(tasks) == ["baseline/seed-0", "baseline/seed-100", "source/seed-150", "source/seed-50",
                             "transfer/seed-0", "transfer/seed-100"]
    assert {tasks[k] for k in tasks if k.startswith("source")} == {"pend/light"}
    assert {tasks[k] for k in tasks if not k.startswith("source")} == {"pend/heavy"}
    report = json.loads((out / "report" / "transfer_metrics.json").read_text())
    assert report["metrics"]["n_seeds_transfer"] == 2


def test_sweep_runs_a_plugins_own_pair_in_spawned_workers(tmp_path):
    spec = {"pairs": ["pend-lh"], "methods": ["pend-reuse"], "algos": ["sac"], "seeds": 2, "seed": 0,
            "frames": 512, "source_frames": 512, "threshold": -1000.0, "overrides": TINY}
    (tmp_path / "spec.yaml").write_text(yaml.safe_dump(spec))
    out = tmp_path / "S"
    done = _drltg("sweep", "spec.yaml", "--import", "pendplug", "--workers", "2", "--out", str(out), cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    tasks = _tasks(out)
    assert len(tasks) == 6 and set(tasks.values()) == {"pend/light", "pend/heavy"}
    assert list(out.rglob("transfer_metrics.json"))


def test_bench_run_trains_a_plugins_own_pair_in_spawned_workers(tmp_path, monkeypatch, request):
    from drltg.bench import suite
    from drltg.config.registry import METHODS
    from drltg.envs import registry

    tier = suite.Tier("pend", "the plugin's pair", (suite.Group("pend", {
        "pairs": ["pend-lh"], "algos": ["sac"], "seeds": 2, "seed": 0, "frames": 512, "source_frames": 512,
        "threshold": -1000.0, "overrides": TINY}),))
    monkeypatch.setitem(suite.SUITES, "plug", {"pend": tier})
    sys.modules.pop("pendplug", None)

    def undo():  # what the plugin registered in this process
        registry.TASKS.pop("pend/light", None), registry.TASKS.pop("pend/heavy", None)
        registry.PAIRS.pop("pend-lh", None), METHODS.pop("pend-reuse", None), sys.modules.pop("pendplug", None)

    request.addfinalizer(undo)
    monkeypatch.syspath_prepend(str(PLUGIN_DIR))
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(PLUGIN_DIR), os.environ.get("PYTHONPATH", "")]))
    monkeypatch.setenv("DRLTG_IMPORT", "")
    out = tmp_path / "B"
    assert main(["bench", "run", "--method", "pend-reuse", "--import", "pendplug", "--suite", "plug", "--tier",
                 "pend", "--reference", "none", "--no-progress", "--workers", "2", "--out", str(out)]) == 0
    tasks = _tasks(out)
    assert sum(t == "pend/heavy" for t in tasks.values()) == 4 and sum(t == "pend/light" for t in tasks.values()) == 2


def test_a_worker_that_cannot_load_a_plugin_says_why(tmp_path):
    done = _drltg("experiment", "pend-lh", "--method", "pend-reuse", "--import", "pendplug", "--seeds", "1",
                  "--frames", "512", "--workers", "2", "--out", str(tmp_path / "E"), *_overrides(), cwd=tmp_path,
                  env_extra={"PENDPLUG_FAIL_IN_WORKER": "1"})
    said = done.stdout + done.stderr
    assert done.returncode != 0
    assert "its worker process could not start: plugin module 'pendplug' failed to import: RuntimeError: pendplug " \
           "refuses to load in a worker" in said
    assert "killed or out of memory" not in said
