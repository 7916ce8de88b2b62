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


MY_TASKS = '''
from drltg.envs import register_pair, register_task
from drltg.envs.fourrooms import FourRoomsEnv
from neighbour import GOAL  # a module beside this file, imported as a script would


def rooms(**options):
    return FourRoomsEnv(**options)


register_task("mine/a", rooms, "a source beside the script", goal=GOAL, horizon=40)
register_task("mine/b", rooms, "a target beside the script", goal=(8.0, 7.0), horizon=40)
register_pair("mine-near", "mine/a", "mine/b", "a pair in a file, not an installed module")
'''


def _console(*args, cwd):
    """The installed ``drltg`` script, as a user runs it: the working directory is not on its path."""
    env = {k: v for k, v in os.environ.items() if k not in ("DRLTG_IMPORT", "PYTHONPATH")}
    return subprocess.run([str(Path(sys.executable).with_name("drltg")), *args], capture_output=True, text=True,
                          env=env, cwd=cwd, timeout=300)


@pytest.fixture
def my_tasks(tmp_path):
    folder = tmp_path / "mine"
    folder.mkdir()
    (folder / "my_tasks.py").write_text(MY_TASKS)
    (folder / "neighbour.py").write_text("GOAL = (8.0, 8.0)\n")
    return folder


def test_import_takes_a_file_path_and_a_module_of_the_working_directory(my_tasks, tmp_path):
    by_path = _console("tasks", "--import", "mine/my_tasks.py", cwd=tmp_path)
    assert by_path.returncode == 0 and "mine-near" in by_path.stdout, by_path.stderr[-2000:]
    by_name = _console("tasks", "--import", "my_tasks", cwd=my_tasks)
    assert by_name.returncode == 0 and "mine-near" in by_name.stdout, by_name.stderr[-2000:]
    missing = _console("tasks", "--import", "mine/nothing.py", cwd=tmp_path)
    assert missing.returncode == 2
    assert missing.stderr.strip() == ("drltg tasks: error: cannot import plugin 'mine/nothing.py': no such Python "
                                      "file or package folder.")


def test_a_plugin_file_reaches_the_worker_processes(my_tasks, tmp_path):
    args = ["experiment", "mine-near", "--method", "model-reuse", "--seeds", "1", "--frames", "256", "--workers", "2",
            "--out", "exp", "--import", "mine/my_tasks.py", "--no-progress"]
    done = _console(*args, *(a for o in TINY for a in ("-o", o)), cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    tasks = sorted(yaml.safe_load(p.read_text())["task"] for p in (tmp_path / "exp").glob("*/seed-*/config.yaml"))
    assert tasks == ["mine/a", "mine/b", "mine/b"]


def test_version_names_the_installed_distribution(tmp_path):
    done = _console("--version", cwd=tmp_path)
    assert done.returncode == 0 and done.stdout.strip() == f"drltg {importlib.metadata.version('drltg')}"
