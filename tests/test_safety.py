"""Outputs are regular files, every count a user gives is bounded, a stop is prompt, and an evaluation
that cuts an episode says so."""
import os
import signal
import socket

import pytest
import torch

import drltg.training.loop as train_mod
from drltg.cli import main
from drltg.envs import make_env
from drltg.envs.fourrooms import FourRoomsEnv
from drltg.store import rundir
from tests.test_reliability import one_sentence, train_args


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    run = tmp_path_factory.mktemp("finished") / "sac"
    assert main(train_args(run, frames=64)) == 0
    return run


# ------------------------------------------------------------------------ outputs are regular files
def test_evaluate_refuses_a_device_as_out(finished, capsys):
    one_sentence(capsys, main(["evaluate", str(finished), "--episodes", "2", "--out", os.devnull]), 2, "is a device")
    assert os.path.exists(os.devnull) and not os.path.isfile(os.devnull)


def test_evaluate_refuses_a_fifo_as_out(finished, tmp_path, capsys):
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    one_sentence(capsys, main(["evaluate", str(finished), "--episodes", "2", "--out", str(fifo)]), 2, "is a FIFO")
    assert fifo.is_fifo()


def test_a_socket_is_neither_a_run_dir_nor_an_out_folder(tmp_path, capsys):
    path = tmp_path / "sock"
    with socket.socket(socket.AF_UNIX) as s:
        s.bind(str(path))
        one_sentence(capsys, main(train_args(path)), 2, "is a socket")
        one_sentence(capsys, main(["report", "--baseline", str(tmp_path), "--transfer", str(tmp_path),
                                   "--out", str(path)]), 2, "is a socket")
    assert not path.exists() or path.is_socket()


def test_a_report_is_never_written_into_a_run(finished, capsys):
    before = sorted(p.name for p in finished.iterdir())
    for out in (finished, finished / "report"):
        one_sentence(capsys, main(["report", "--baseline", str(finished), "--transfer", str(finished),
                                   "--out", str(out)]), 2, "the run directory", "a folder of its own")
    assert sorted(p.name for p in finished.iterdir()) == before


def test_atomic_writes_refuse_special_files(tmp_path):
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    with pytest.raises(Exception, match="is a FIFO"):
        rundir.atomic_write(fifo, "data")
    assert fifo.is_fifo() and [p.name for p in tmp_path.iterdir()] == ["fifo"]


# ------------------------------------------------------------------------------------------- bounds
@pytest.mark.parametrize("args, message", [
    (["-o", "threads=100000"], "'threads' must be an integer in [1, 512], got 100000"),
    (["-o", "eval.episodes=1000000000"], "'eval.episodes' must be an integer in [1, 10000], got 1000000000"),
    (["--algo", "soc", "--options", "100000000"], "'soc.num_options' must be an integer in [1, 256], got 100000000"),
    (["-o", f"buffer.batch_size={2**70}"], f"'buffer.batch_size' must be an integer in [1, 1048576], got {2**70}"),
    (["-o", f"collector.frames_per_batch={2**70}"], "'collector.frames_per_batch' must be an integer in [1, 1048576]"),
    (["-o", f"collector.num_envs={2**70}"], "'collector.num_envs' must be an integer in [1, 1048576]"),
    (["-o", f"optim.updates_per_batch={2**70}"], "'optim.updates_per_batch' must be an integer in [1, 100000]"),
    (["-o", f"eval.every={2**70}"], "'eval.every' must be 'auto' or an integer in [1, 1000000000000]"),
    (["--frames", "1e400"], "'1e400' is not a whole number of frames"),
])
def test_counts_in_the_config_are_bounded(args, message, tmp_path, capsys):
    one_sentence(capsys, main(train_args(tmp_path / "r", *args)), 2, message)
    assert not (tmp_path / "r").exists()


def test_seeds_and_episodes_on_the_command_line_are_bounded(finished, tmp_path, capsys):
    one_sentence(capsys, main(train_args(tmp_path / "r", "--seeds", "100000")), 2, "--seeds must be between 1 and")
    one_sentence(capsys, main(["evaluate", str(finished), "--episodes", "1000000000"]), 2,
                 "--episodes must be between 1 and")
    one_sentence(capsys, main(["evaluate", str(finished), "--episodes", "0"]), 2, "--episodes must be between 1 and")
    assert not (tmp_path / "r").exists()


def test_a_budget_that_cannot_learn_is_said_before_training(tmp_path, capsys):
    import json

    assert main(train_args(tmp_path / "r", "-o", "collector.init_random_frames=128", frames=64)) == 0
    err = capsys.readouterr().err
    assert "warning: 64 frames lie within the 128 random warm-up frames" in err, err
    summary = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert summary["updates"] == 0 and summary["note"].startswith("no update was made")
    assert main(train_args(tmp_path / "s", "-o", "eval.every=5000", frames=2000)) == 0
    assert "give evaluations at frame 0 and 2,000 only" in capsys.readouterr().err


def test_no_progress_bar_where_no_one_watches(tmp_path, capsys):
    """stderr here is not a terminal: no bar from train or experiment, with or without --no-progress."""
    tiny = [a for o in ("network.hidden=[16,16]", "collector.num_envs=4", "collector.frames_per_batch=16",
                        "collector.init_random_frames=32", "eval.every=32", "eval.episodes=2") for a in ("-o", o)]
    assert main(["train", "fourrooms/northeast", "--frames", "64", "--run-dir", str(tmp_path / "r"), *tiny]) == 0
    assert main(["experiment", "fourrooms/northeast", "--method", "reward-shaping", "--seeds", "1", "--frames", "64",
                 "--out", str(tmp_path / "x"), *tiny]) == 0
    assert main(["experiment", "fourrooms/northeast", "--method", "reward-shaping", "--seeds", "1", "--frames", "64",
                 "--out", str(tmp_path / "x"), "--no-progress", *tiny]) == 0  # the same experiment: all skipped
    err = capsys.readouterr().err
    assert "frame/s" not in err and "%|" not in err, err


def test_an_experiment_whose_transfer_run_is_its_own_source_is_refused(tmp_path, capsys):
    out = tmp_path / "x"
    code = main(["experiment", "fourrooms/northeast", "--method", "model-reuse", "--seeds", "1", "--frames", "64",
                 "--out", str(out), "-o", f"transfer.source={out / 'transfer' / 'seed-0'}"])
    one_sentence(capsys, code, 2, "needs its own output as transfer.source")
    assert not out.exists()


def test_the_executor_never_waits_on_runs_that_cannot_start(tmp_path):
    from drltg.experiments.executor import Run, execute

    class NoBackend:
        capacity = 1

    a, b = tmp_path / "a", tmp_path / "b"
    runs = [Run("transfer", None, a, tmp_path / "a.log", needs=b),
            Run("transfer", None, b, tmp_path / "b.log", needs=a)]
    with pytest.raises(Exception, match="needs its own output"):
        execute(runs, NoBackend())


@pytest.mark.parametrize("text, message", [
    ("a: &a [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
        f"{n}: &{n} [{', '.join(['*' + p] * 10)}]\n" for p, n in zip("abcdefg", "bcdefgh")) + "network: {hidden: *h}\n",
     "more than 100,000 values once its aliases are expanded"),
    ("network: " + "[" * 3000 + "]" * 3000 + "\n", "more than 64 levels deep"),
    ("network: " + "[" * 65 + "]" * 65 + "\n", "more than 64 levels deep"),
])
def test_a_config_file_that_expands_or_nests_without_bound_is_one_sentence(text, message, tmp_path, capsys):
    path = tmp_path / "config.yaml"
    path.write_text(text)
    one_sentence(capsys, main(train_args(tmp_path / "r", "--config", str(path))), 2, message)
    assert not (tmp_path / "r").exists()


def test_an_override_value_that_expands_without_bound_is_one_sentence(tmp_path, capsys):
    value = "[" + ", ".join(["&a [[1, 1, 1, 1, 1, 1, 1, 1, 1, 1]]"] + ["*a"] * 9) + "]"
    bomb = "[" + ", ".join([f"&b {value}"] + ["*b"] * 9) + "]"
    from drltg.safe_yaml import MAX_NODES, load

    assert len(str(load(bomb, "x"))) > 0  # 100 lists of 10: within the bound
    deeper = "[" + ", ".join([f"&c {bomb}"] + ["*c"] * 999) + "]"
    one_sentence(capsys, main(train_args(tmp_path / "r", "-o", f"network.hidden={deeper}")), 2,
                 f"more than {MAX_NODES:,} values")


def test_a_source_the_method_would_ignore_is_refused(finished, tmp_path, capsys):
    for method in ("none", "reward-shaping"):
        one_sentence(capsys, main(train_args(tmp_path / "r", "-o", f"transfer.method={method}",
                                             "-o", f"transfer.source={finished}")), 2, "reads no source")
    assert not (tmp_path / "r").exists()


def test_a_plugin_that_exits_at_import_is_one_sentence(tmp_path, monkeypatch, capsys):
    (tmp_path / "exits_at_import.py").write_text("import sys\nsys.exit(0)\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    code = main(["train", "--import", "exits_at_import", "fourrooms/northeast", "--run-dir", str(tmp_path / "r")])
    one_sentence(capsys, code, 2, "plugin module 'exits_at_import' called sys.exit(0)")
    assert not (tmp_path / "r").exists()


def test_a_lock_that_is_a_folder_is_one_sentence(finished, tmp_path, capsys):
    import shutil

    run = tmp_path / "run"
    shutil.copytree(finished, run)
    (run / rundir.SUMMARY).unlink()  # an unfinished run, so that the resume takes its lock
    (run / rundir.LOCK).mkdir()
    one_sentence(capsys, main(["train", "--resume", "--run-dir", str(run), "--no-progress"]), 2,
                 "is not drltg's lock file")


def test_evaluate_on_a_device_this_machine_lacks_is_one_sentence(finished, capsys):
    if torch.cuda.is_available():
        pytest.skip("this machine has a CUDA device")
    one_sentence(capsys, main(["evaluate", str(finished), "--episodes", "2", "--device", "cuda"]), 2,
                 "--device is 'cuda' but no CUDA device is available")


@pytest.mark.parametrize("task", ["fourrooms/northeast", "gridrooms/northeast"])
def test_a_horizon_longer_than_an_evaluation_runs_is_one_sentence(task, tmp_path, capsys):
    one_sentence(capsys, main(train_args(tmp_path / "r", "-o", "env.horizon=1000000", task=task)), 2,
                 "horizon 1000000 is more than the 100,000 steps an evaluation runs an episode")


def test_a_render_size_that_cannot_be_drawn_is_one_sentence(tmp_path, capsys):
    one_sentence(capsys, main(train_args(tmp_path / "r", "-o", "env.render_size=0")), 2,
                 "render_size is the side of a rendered frame in pixels, from 16 to 4096; got 0")
    assert not (tmp_path / "r").exists()


class Float64Rooms(FourRoomsEnv):
    def _make_spec(self):
        super()._make_spec()
        self.observation_spec["observation"] = self.observation_spec["observation"].to(torch.float64)


class NoTerminatedRooms(FourRoomsEnv):
    def _step(self, td):
        out = super()._step(td)
        del out["terminated"]
        return out


@pytest.mark.parametrize("factory, message", [
    (NoTerminatedRooms, "cannot take a step (RuntimeError: Cannot infer the value of terminated"),
    (lambda **kw: None, "its factory returned NoneType, not a TorchRL EnvBase"),
    (lambda **kw: __import__("gymnasium").make("Pendulum-v1"), "not a TorchRL EnvBase; for a Gymnasium environment"),
    (Float64Rooms, "reports its observation as torch.float64; drltg's networks take torch.float32"),
])
def test_a_task_drltg_cannot_train_is_one_sentence(factory, message, tmp_path, capsys):
    from drltg.envs import TASKS, register_task

    register_task("test/broken", factory, "a task drltg cannot train", goal=(8.0, 8.0))
    try:
        one_sentence(capsys, main(train_args(tmp_path / "r", task="test/broken")), 2, message)
    finally:
        del TASKS["test/broken"]
    assert not (tmp_path / "r").exists()


def test_gymnasium_ids_check_options_and_actions():
    import gymnasium as gym
    import numpy as np

    import drltg  # noqa: F401  (registers the ids)

    with pytest.raises(ValueError, match="keyword 'horizon' must be an integer"):
        gym.make("drltg/fourrooms-northeast-v0", horizon="abc")
    with pytest.raises(ValueError, match="num_envs must be a positive integer"):
        gym.make_vec("drltg/fourrooms-northeast-v0", num_envs=0)
    grid = gym.make("drltg/gridrooms-northeast-v0")
    grid.reset(seed=0)
    for action in (7, 1.7, np.array([1, 2])):  # out of range, not an integer (was taken as 1), two actions
        with pytest.raises(ValueError, match="is not in the action space Discrete"):
            grid.step(action)
    grid.step(1)
    rooms = gym.make("drltg/fourrooms-northeast-v0")
    rooms.reset(seed=0)
    for action in (np.array([np.nan, 0.0], dtype=np.float32), np.zeros(3, dtype=np.float32)):
        with pytest.raises(ValueError, match="is not in the action space Box"):
            rooms.step(action)
    obs, *_ = rooms.step([0.1, 0.2])
    assert np.isfinite(obs).all()


def sweep_spec(tmp_path, **extra):
    import yaml

    path = tmp_path / "spec.yaml"
    path.write_text(yaml.safe_dump({"pairs": ["fourrooms-near"], "methods": ["model-reuse"], "seeds": 1,
                                    "frames": 64, **extra}))
    return str(path)


def test_a_sweep_grid_of_a_million_points_is_refused_before_it_is_planned(tmp_path, capsys):
    grid = {"optim.lr": [1e-4 * (i + 1) for i in range(100)], "optim.updates_per_batch": list(range(1, 101)),
            "buffer.batch_size": list(range(16, 116))}
    code = main(["sweep", sweep_spec(tmp_path, grid=grid), "--out", str(tmp_path / "s"), "--dry-run"])
    one_sentence(capsys, code, 2, "expands to 1,000,000 transfer runs", "more than the 10,000")


def test_a_grid_value_with_a_nul_byte_is_one_sentence(tmp_path, capsys):
    spec = sweep_spec(tmp_path, grid={"env.start_room": ["northeast\x00x", "southwest"]})
    one_sentence(capsys, main(["sweep", spec, "--out", str(tmp_path / "s"), "--dry-run"]), 2,
                 "holds a control character; grid values name the runs' folders")


@pytest.mark.parametrize("args, message", [
    (["--num-cpus", "-1"], "--num-cpus must be a finite number >= 0, got -1"),
    (["--num-cpus", "nan"], "--num-cpus must be a finite number >= 0, got nan"),
    (["--num-gpus", "1"], "asks for 1 GPU(s) but this machine has 0"),
])
def test_ray_resources_that_cannot_be_met_are_refused_before_ray_starts(args, message, tmp_path, capsys):
    if args[0] == "--num-gpus" and torch.cuda.is_available():
        pytest.skip("this machine has a CUDA device")
    code = main(["sweep", sweep_spec(tmp_path), "--out", str(tmp_path / "s"), "--backend", "ray", *args])
    one_sentence(capsys, code, 2, message)
    assert not (tmp_path / "s").exists()


# ------------------------------------------------------------------------------------ report inputs
def test_a_copied_run_is_not_another_seed(tmp_path, capsys):
    import shutil

    from tests.test_reliability import fake_run

    base = [fake_run(tmp_path / "b" / f"seed-{s}", [0, 1, 2], seed=s) for s in (0, 1)]
    shutil.copytree(base[0], tmp_path / "b" / "copy")
    trans = [fake_run(tmp_path / "t" / f"seed-{s}", [1, 2, 3], seed=s) for s in (0, 1)]
    code = main(["report", "--baseline", str(tmp_path / "b"), "--transfer", *map(str, trans),
                 "--out", str(tmp_path / "r")])
    one_sentence(capsys, code, 2, "are the same run (same config, seed 0, same curve)")
    assert main(["report", "--baseline", *map(str, base), "--transfer", *map(str, trans),
                 "--out", str(tmp_path / "r")]) == 0


def test_drltg_runs_and_config_less_logs_are_not_pooled_on_one_side(tmp_path, capsys):
    from tests.test_reliability import fake_run

    base = [fake_run(tmp_path / "b" / f"seed-{s}", [0, 1, 2], seed=s) for s in (0, 1)]
    sb3 = tmp_path / "sb3" / "progress.csv"
    sb3.parent.mkdir()
    sb3.write_text("time/total_timesteps,eval/mean_reward\n0,0.5\n100,1.5\n200,2.5\n")
    trans = [fake_run(tmp_path / "t" / f"seed-{s}", [1, 2, 3], seed=s) for s in (0, 1)]
    code = main(["report", "--baseline", *map(str, base), str(sb3), "--transfer", *map(str, trans),
                 "--out", str(tmp_path / "r")])
    one_sentence(capsys, code, 2, "pool drltg runs", "carry no config", "--allow-mixed")


def test_a_run_that_skips_evaluations_is_named(tmp_path):
    from pathlib import Path

    from drltg.report import compute
    from drltg.report.curves import Curve

    grid = list(range(0, 1100, 100))
    full = [Curve(grid, [i / 10 for i in range(11)], Path(f"/b/seed-{s}"), f"b/seed-{s}") for s in range(3)]
    skipping = Curve([0, 100, 900, 1000], [0, 0.1, 0.9, 1.0], Path("/t/seed-0"), "t/seed-0")  # 7 of 11 missing
    transfer = [skipping] + [Curve(grid, [i / 10 for i in range(11)], Path(f"/t/seed-{s}"), f"t/seed-{s}")
                             for s in (1, 2)]
    warnings = compute(full, transfer)["settings"]["warnings"]
    assert any("1 run(s) skip evaluations: 't/seed-0' (/t/seed-0) has a gap of 800 frames where it is evaluated "
               "every 100" in w for w in warnings), warnings
    assert not any("skip evaluations" in w for w in compute(full, full[:2])["settings"]["warnings"])


def test_negative_frame_counts_are_refused(tmp_path, capsys):
    sb3 = tmp_path / "sb3" / "progress.csv"
    sb3.parent.mkdir()
    sb3.write_text("time/total_timesteps,eval/mean_reward\n-100,0.5\n100,1.5\n200,2.5\n")
    code = main(["report", "--baseline", str(sb3), "--transfer", str(sb3), "--out", str(tmp_path / "r")])
    one_sentence(capsys, code, 2, "counts a negative number of frames")


# ------------------------------------------------------------------------------- a prompt stop
def test_ctrl_c_during_an_evaluation_stops_it_at_the_next_step(tmp_path, monkeypatch):
    """SIGINT arriving in the middle of the third evaluation (frame 256) ends the run there (exit 130), with
    a checkpoint saved at that frame and the lock released; a resume makes that evaluation, then finishes."""
    real, steps = train_mod.evaluate, {"evaluations": 0, "after_signal": 0}

    def evaluate(env, actor, max_steps=100_000, check=lambda: None):
        steps["evaluations"] += 1
        calls = {"n": 0}

        def act(td):
            calls["n"] += 1
            if steps["evaluations"] == 3 and calls["n"] == 3:
                os.kill(os.getpid(), signal.SIGINT)
            elif steps["evaluations"] == 3 and calls["n"] > 3:
                steps["after_signal"] += 1
            return actor(td)

        return real(env, act, max_steps, check)

    monkeypatch.setattr(train_mod, "evaluate", evaluate)
    run = tmp_path / "run"
    # Ctrl-C as Python sets it up (a library imported by an earlier test in this process may have changed it)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        assert main(train_args(run, "-o", "checkpoint.every=128", frames=512)) == 130
    finally:
        signal.signal(signal.SIGINT, previous)
    assert steps["after_signal"] == 0
    assert not (run / rundir.LOCK).exists()
    assert [r["frames"] for r in rundir.read_eval_csv(run / "eval.csv")] == [0, 128]
    assert rundir.load_checkpoint(run)["frames"] == 256
    monkeypatch.setattr(train_mod, "evaluate", real)
    assert main(["train", "--resume", "--run-dir", str(run), "--no-progress"]) == 0
    assert [r["frames"] for r in rundir.read_eval_csv(run / "eval.csv")] == [0, 128, 256, 384, 512]


# ------------------------------------------------------------------------- a cut episode is said
def test_an_evaluation_cut_at_its_step_limit_says_so(capsys, tmp_path):
    env = make_env("fourrooms/northeast", batch_size=(4,), seed=0)
    still = lambda td: td.set("action", torch.zeros(4, 2))  # noqa: E731  (never reaches the goal)
    row = train_mod.evaluate(env, still, max_steps=5)
    assert row["unfinished"] == 4 and row["episodes"] == 4
    assert "4 of 4 evaluation episodes did not end within 5 steps" in capsys.readouterr().err
    finished = train_mod.evaluate(env, still)  # the horizon (100) ends every episode
    assert "unfinished" not in finished
    rows = [{"frames": 0, **finished}, {"frames": 10, **row}]
    rundir.write_eval_csv(tmp_path / "eval.csv", rows)
    assert rundir.read_eval_csv(tmp_path / "eval.csv") == rows
