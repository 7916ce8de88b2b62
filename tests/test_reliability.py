"""Runs own their directories, nothing is lost or mixed, and every mistake is one sentence (exit 2)."""
import contextlib
import errno
import json
import os
import shutil
import signal
import subprocess
import sys
import time
import types
from pathlib import Path

import pytest
import torch
import yaml

import drltg.training.loop as train_mod
from drltg import config as config_lib
from drltg.cli import main
from drltg.errors import UsageError
from drltg.report.curves import read_csvlogger, read_tensorboard
from drltg.store import atomic, rundir
from drltg.store import lock as lock_mod

TINY = ["network.hidden=[16,16]", "collector.num_envs=4", "collector.frames_per_batch=16",
        "collector.init_random_frames=32", "optim.updates_per_batch=1", "buffer.batch_size=16",
        "eval.every=128", "eval.episodes=2", "checkpoint.every=256", "log.every=64"]
OPTS = [a for o in TINY for a in ("-o", o)]


def train_args(run_dir, *extra, task="fourrooms/northeast", frames=64):
    """``drltg train`` of a tiny run; a key ``extra`` sets is left out of the tiny settings (-o takes a key once)."""
    given = {a.split("=", 1)[0] for a in extra if "=" in a}
    opts = [a for o in TINY if o.split("=", 1)[0] not in given for a in ("-o", o)]
    return ["train", task, "--frames", str(frames), "--run-dir", str(run_dir), "--no-progress", *opts, *extra]


def one_sentence(capsys, code, expected, *fragments):
    err = capsys.readouterr().err
    assert code == expected
    if expected == 2:
        assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    for fragment in fragments:
        assert fragment in err, err
    return err


def tree(path: Path) -> dict:
    return {str(p.relative_to(path)): p.read_bytes() for p in sorted(path.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def source(tmp_path_factory):
    """A complete tiny SAC run on fourrooms/northeast."""
    run = tmp_path_factory.mktemp("source") / "sac"
    assert main(train_args(run, frames=128)) == 0
    return run


@pytest.fixture(scope="module")
def killed(tmp_path_factory):
    """A run killed at frame 448 of 512: checkpoint at 256, evaluations and logs up to 384."""
    run = tmp_path_factory.mktemp("killed") / "run"
    real, calls = train_mod._episode_stats, {"n": 0}

    def kill_at_frame_448(data, stats):
        calls["n"] += 1
        if calls["n"] == 28:
            raise KeyboardInterrupt
        return real(data, stats)

    train_mod._episode_stats = kill_at_frame_448
    try:
        assert main(train_args(run, "-o", "log.tensorboard=true", frames=512)) == 130
    finally:
        train_mod._episode_stats = real
    assert [r["frames"] for r in rundir.read_eval_csv(run / "eval.csv")] == [0, 128, 256, 384]
    assert torch.load(run / "checkpoints" / "last.pt", weights_only=True)["frames"] == 256
    return run


@pytest.fixture
def copy_of_killed(killed, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(killed, run)
    return run


@pytest.mark.parametrize("text, frames", [
    (None, 0),  # no eval.csv yet
    ("frames,return_mean\n", 0),  # before the first evaluation
    ("frames,return_mean\n0,1.0\n128,2.0\n", 128),
    ("frames,return_mean\n0,1.0\n128,2.", 0),  # torn: unreadable, so nothing is counted
])
def test_frames_evaluated_is_the_last_evaluation_or_zero(text, frames, tmp_path):
    if text is not None:
        (tmp_path / "eval.csv").write_text(text)
    assert rundir.frames_evaluated(tmp_path) == frames


def test_a_killed_run_has_reached_its_last_evaluation(killed):
    assert rundir.frames_evaluated(killed) == 384


# -------------------------------------------------------------------------------- 1: ownership
def test_two_processes_into_one_run_dir_one_is_refused(tmp_path):
    run = tmp_path / "run"
    procs = [subprocess.Popen([sys.executable, "-m", "drltg.cli", *train_args(run, "--seed", str(seed), frames=128)],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for seed in (1, 2)]
    results = [(p.communicate(timeout=300)[1], seed) for p, seed in zip(procs, (1, 2))]
    results = [(p.returncode, err, seed) for p, (err, seed) in zip(procs, results)]
    assert sorted(code for code, _, _ in results) == [0, 2]
    (_, _, winner), = [r for r in results if r[0] == 0]
    (_, refusal, _), = [r for r in results if r[0] == 2]
    assert len(refusal.strip().splitlines()) == 1
    assert "is in use by process" in refusal or "already exists" in refusal
    assert yaml.safe_load((run / "config.yaml").read_text())["seed"] == winner
    assert '"seed": %d' % winner in (run / "summary.json").read_text()
    assert not (run / rundir.LOCK).exists()


def test_a_terminated_start_releases_its_lock_and_removes_what_it_wrote(tmp_path):
    run = tmp_path / "run"
    args = train_args(run, "-o", "checkpoint.every=1000000", frames=10**6)
    proc = subprocess.Popen([sys.executable, "-m", "drltg.cli", *args], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    while not (run / "eval.csv").exists() and proc.poll() is None:
        time.sleep(0.1)
    proc.terminate()
    assert proc.wait(timeout=60) == 128 + signal.SIGTERM
    assert not run.exists()


def test_a_terminated_experiment_stops_its_running_run_which_resumes(tmp_path):
    """SIGTERM to `drltg experiment` alone (a scheduler's stop) ends the run its worker is training
    instead of waiting for it, leaving that run unlocked with its checkpoint."""
    out = tmp_path / "exp"
    args = ["experiment", "fourrooms-near", "--method", "model-reuse", "--seeds", "1", "--frames", "128",
            "--source-frames", str(10**6), "--out", str(out), *OPTS]
    proc = subprocess.Popen([sys.executable, "-m", "drltg.cli", *args], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    source = out / "source" / "seed-50"
    try:
        while not (source / "checkpoints" / "last.pt").exists() and proc.poll() is None:
            time.sleep(0.1)
        proc.terminate()
        assert proc.wait(timeout=60) == 128 + signal.SIGTERM
    finally:
        subprocess.run(["pkill", "-KILL", "-f", str(out)])  # nothing left behind if the assertion failed
    assert not (source / rundir.LOCK).exists() and not (out / rundir.LOCK).exists()
    assert torch.load(source / "checkpoints" / "last.pt", weights_only=True)["frames"] >= 128  # its first evaluation
    assert not rundir.is_complete(source)


def test_a_live_owner_is_refused_and_a_dead_one_taken_over(copy_of_killed, tmp_path, capsys):
    run = copy_of_killed
    before = tree(run)
    (run / rundir.LOCK).write_text(f"{os.getpid()} {os.uname().nodename} x\n")
    one_sentence(capsys, main(["train", "--resume", "--run-dir", str(run), "--no-progress"]), 2,
                 f"is in use by process {os.getpid()}")
    assert tree(run) == before | {rundir.LOCK: (run / rundir.LOCK).read_bytes()}
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    (run / rundir.LOCK).write_text(f"{dead.pid} {os.uname().nodename} x\n")
    one_sentence(capsys, main(["train", "--resume", "--run-dir", str(run), "--no-progress"]), 0)
    assert rundir.is_complete(run) and not (run / rundir.LOCK).exists()


def test_lock_file_is_exclusive_and_released(tmp_path):
    with rundir.lock(tmp_path):
        assert (tmp_path / rundir.LOCK).read_text().split()[0] == str(os.getpid())
        with pytest.raises(UsageError, match="is in use by process"):
            with rundir.lock(tmp_path):
                pass
    assert not (tmp_path / rundir.LOCK).exists()


@pytest.mark.parametrize("command", [
    ["experiment", "gridrooms/northeast", "--method", "reward-shaping", "--seeds", "1", "--frames", "64"],
    ["sweep", "SPEC"],
])
def test_experiment_and_sweep_folders_are_owned(command, tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / rundir.LOCK).write_text(f"{os.getpid()} {os.uname().nodename} x\n")
    spec = tmp_path / "spec.yaml"
    spec.write_text(yaml.safe_dump({"pairs": ["gridrooms-near"], "methods": ["reward-shaping"], "seeds": 1,
                                    "frames": 64}))
    command = [str(spec) if a == "SPEC" else a for a in command]
    one_sentence(capsys, main(command + ["--out", str(out)]), 2, "folder", "is in use by process")
    assert os.listdir(out) == [rundir.LOCK]


# ------------------------------------------------------------------------------- 2, 3: model reuse
@pytest.fixture(scope="module")
def soc_source(tmp_path_factory):
    run = tmp_path_factory.mktemp("soc") / "run"
    assert main(train_args(run, "--algo", "soc", "--options", "2", frames=64)) == 0
    return run


def test_model_reuse_across_learners_is_refused_unless_partial(soc_source, tmp_path, capsys):
    target = tmp_path / "target"
    reuse = ["-o", "transfer.method=model-reuse", "-o", f"transfer.source={soc_source}"]
    one_sentence(capsys, main(train_args(target, *reuse)), 2, "lacks trainable ones", "transfer.partial=true")
    assert not target.exists()
    assert main(train_args(target, *reuse, "-o", "transfer.partial=true")) == 0
    assert "model reuse: 2 loaded" in capsys.readouterr().out


def test_model_reuse_prints_its_load_summary(source, tmp_path, capsys):
    assert main(train_args(tmp_path / "t", "-o", "transfer.method=model-reuse", "-o", f"transfer.source={source}")) == 0
    assert "model reuse: 22 loaded, 0 widened, 0 narrowed, 0 skipped" in capsys.readouterr().out


def test_an_unfinished_source_is_refused_naming_its_frames(copy_of_killed, tmp_path, capsys):
    target = tmp_path / "target"
    reuse = ["-o", "transfer.method=policy-reuse", "-o", f"transfer.source={copy_of_killed}"]
    one_sentence(capsys, main(train_args(target, *reuse)), 2, "did not finish", "checkpoint is at frame 256",
                 "transfer.allow_incomplete=true")
    assert not target.exists()
    assert main(train_args(target, *reuse, "-o", "transfer.allow_incomplete=true")) == 0


# ------------------------------------------------------------------------------------ 4, 5: resume
def test_resume_rewrites_the_logs_to_the_checkpoint(copy_of_killed, capsys):
    run = copy_of_killed
    one_sentence(capsys, main(["train", "--resume", "--run-dir", str(run), "--no-progress"]), 0)
    assert [r["frames"] for r in rundir.read_eval_csv(run / "eval.csv")] == [0, 128, 256, 384, 512]
    for path in (run / "logs" / "csv" / "scalars").rglob("*.csv"):
        steps = [int(line.split(",")[0]) for line in path.read_text().splitlines()]
        assert steps == sorted(set(steps)), path
    csv_curve = read_csvlogger(run / "logs" / "csv" / "scalars", tag="eval/return_mean")
    tb_curve = read_tensorboard(run / "logs" / "tensorboard", tag="eval/return_mean")
    assert list(csv_curve.frames) == list(tb_curve.frames) == [0, 128, 256, 384, 512]
    assert list(read_tensorboard(run / "logs" / "tensorboard", tag="train/fps").frames) == list(range(64, 513, 64))


@pytest.mark.parametrize("damage, message", [
    (lambda run: ((run / "eval.csv").write_text(
        "".join(line for line in (run / "eval.csv").read_text().splitlines(True) if not line.startswith("128,"))),
        (run / "manifest.json").unlink()), "lacks the evaluations at frames [128]"),  # no manifest: read unchecked
    (lambda run: (run / "eval.csv").unlink(), "eval.csv is missing"),
    (lambda run: (run / "eval.csv").write_bytes((run / "eval.csv").read_bytes()[:-9]),
     "eval.csv': it does not match its SHA-256"),  # the curve resume carries forward is checked first
    (lambda run: ((run / "eval.csv").write_bytes((run / "eval.csv").read_bytes()[:-9]),
                  (run / "manifest.json").unlink()),
     "is truncated or malformed"),
    (lambda run: (run / "checkpoints" / "last.pt").write_bytes((run / "checkpoints" / "last.pt").read_bytes()[:5000]),
     "does not match its SHA-256"),  # checked against the manifest before a byte is unpickled
    (lambda run: ((run / "checkpoints" / "last.pt").write_bytes((run / "checkpoints" / "last.pt").read_bytes()[:5000]),
                  (run / "manifest.json").unlink()), "cannot read checkpoint"),  # no manifest: torch finds it torn
    (lambda run: (run / "checkpoints" / "last.pt").unlink(), "checkpoints/last.pt is missing though its manifest"),
    (lambda run: shutil.rmtree(run / "logs" / "csv"), "its logs/csv folder is missing"),
    (lambda run: shutil.rmtree(run / "logs" / "tensorboard"), "its logs/tensorboard folder is missing"),
])
def test_resume_of_a_damaged_run_is_one_sentence(copy_of_killed, damage, message, capsys):
    damage(copy_of_killed)
    before = tree(copy_of_killed)
    one_sentence(capsys, main(["train", "--resume", "--run-dir", str(copy_of_killed), "--no-progress"]), 2, message)
    assert tree(copy_of_killed) == before


def test_resume_in_a_read_only_run_dir_is_one_sentence(copy_of_killed, monkeypatch, capsys):
    real = os.open

    def read_only(path, flags, *args, **kwargs):
        if str(path).startswith(str(copy_of_killed)) and flags & (os.O_WRONLY | os.O_RDWR | os.O_CREAT):
            raise OSError(errno.EROFS, os.strerror(errno.EROFS), str(path))
        return real(path, flags, *args, **kwargs)

    before = tree(copy_of_killed)
    monkeypatch.setattr(os, "open", read_only)
    one_sentence(capsys, main(["train", "--resume", "--run-dir", str(copy_of_killed), "--no-progress"]), 2,
                 "cannot write to run directory", "Read-only file system")
    assert tree(copy_of_killed) == before


# ---------------------------------------------------------------------------------- 6, 7: files
def full_disk(monkeypatch):
    """Every write of drltg's run files fails as on a full disk."""
    def write(fd, data):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(atomic, "os", types.SimpleNamespace(**{**vars(os), "write": write}))


def test_a_full_disk_leaves_no_temporary_file_and_the_old_content(tmp_path, monkeypatch):
    path = tmp_path / "eval.csv"
    path.write_text("old\n")
    full_disk(monkeypatch)
    with pytest.raises(UsageError, match="No space left on device"):
        rundir.atomic_write(path, "new\n")
    assert os.listdir(tmp_path) == ["eval.csv"] and path.read_text() == "old\n"


def test_a_full_disk_during_train_is_one_sentence_and_leaves_nothing(tmp_path, monkeypatch, capsys):
    full_disk(monkeypatch)
    # eval.every=32: a budget with a learning curve, so no warning precedes the sentence
    one_sentence(capsys, main(train_args(tmp_path / "run", "-o", "eval.every=32")), 2, "cannot write",
                 "No space left on device")
    assert os.listdir(tmp_path) == []


def test_run_files_respect_the_umask(tmp_path):
    old = os.umask(0o002)
    try:
        assert main(train_args(tmp_path / "run")) == 0
    finally:
        os.umask(old)
    for name in ("config.yaml", "eval.csv", "summary.json", "checkpoints/last.pt"):
        assert (tmp_path / "run" / name).stat().st_mode & 0o777 == 0o664, name


# ---------------------------------------------------------------------------- 8, 9: checked early
@pytest.mark.parametrize("extra, message", [
    (["-o", "env.horizon=abc"], "horizon"),
    (["-o", "env.colour=red"], "colour"),
])
def test_env_settings_are_checked_before_the_run_dir_exists(extra, message, tmp_path, capsys):
    one_sentence(capsys, main(train_args(tmp_path / "run", *extra)), 2, message)
    assert not (tmp_path / "run").exists()


def test_an_env_the_task_cannot_build_is_one_sentence():
    cfg = config_lib.updated(config_lib.resolve(task="fourrooms/northeast"), {"env": {"goal": "x"}})
    with pytest.raises(UsageError, match=r"^keyword 'goal' must be a list of numbers \(task 'fourrooms/"):
        train_mod.build_env(cfg)


def test_a_run_dir_or_out_that_is_a_file(tmp_path, capsys):
    file = tmp_path / "file"
    file.write_text("mine\n")
    one_sentence(capsys, main(train_args(file)), 2, "is a file, not a directory")
    one_sentence(capsys, main(["train", "--resume", "--run-dir", str(file)]), 2, "is a file, not a directory")
    one_sentence(capsys, main(["experiment", "gridrooms/northeast", "--method", "reward-shaping", "--frames", "64",
                               "--out", str(file)]), 2, "is a file, not a directory")
    assert file.read_text() == "mine\n"


def test_video_on_a_task_with_another_observation_size(source, tmp_path, capsys):
    one_sentence(capsys, main(["video", str(source), "--task", "gridrooms/northeast", "--out", str(tmp_path / "v")]),
                 2, "reads 2 observation entries", "has 104 observation entries")
    assert not (tmp_path / "v").exists()


def test_policy_reuse_from_another_observation_space_is_checked_first(source, tmp_path, capsys):
    target = tmp_path / "target"
    reuse = ["-o", "transfer.method=policy-reuse", "-o", f"transfer.source={source}"]
    one_sentence(capsys, main(train_args(target, *reuse, task="gridrooms/northeast")), 2, "reads 2 observation entries")
    assert not target.exists()


def test_a_failed_start_removes_what_it_wrote(tmp_path, monkeypatch):
    def broken(data, stats):
        raise RuntimeError("broken")

    monkeypatch.setattr(train_mod, "_episode_stats", broken)
    with pytest.raises(RuntimeError):
        main(train_args(tmp_path / "run"))
    assert not (tmp_path / "run").exists()
    monkeypatch.undo()
    assert main(train_args(tmp_path / "run")) == 0  # the same command again


# -------------------------------------------------------------------- 10, 11, 12: experiment, sweep
EXPERIMENT = ["experiment", "gridrooms/northeast", "--method", "reward-shaping", "--seeds", "1",
              "--frames", "64"] + OPTS


@pytest.mark.parametrize("extra, message", [
    (["--threshold", "abc"], "--threshold 'abc' is neither a number"),
    (["--workers", "0"], "--workers must be at least 1"),
    (["--algo", "ppo"], "'ppo'"),
    (["-o", "env.horizon=abc"], "horizon"),
])
def test_experiment_checks_everything_before_writing(extra, message, tmp_path, capsys):
    one_sentence(capsys, main(EXPERIMENT + extra + ["--out", str(tmp_path / "exp")]), 2, message)
    assert not (tmp_path / "exp").exists()


def test_experiment_out_relative_or_absolute_is_the_same_experiment(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(EXPERIMENT + ["--out", "exp"]) == 0
    stamps = {p: p.stat().st_mtime_ns for p in (tmp_path / "exp").glob("*/seed-*/summary.json")}
    assert len(stamps) == 2
    capsys.readouterr()
    assert main(EXPERIMENT + ["--out", str(tmp_path / "exp")]) == 0
    assert stamps == {p: p.stat().st_mtime_ns for p in stamps}


@pytest.mark.parametrize("spec, extra, message", [
    ({"threshold": "abc"}, [], "threshold 'abc' is neither a number"),
    ({}, ["--workers", "0"], "--workers must be at least 1"),
])
def test_sweep_checks_its_settings_before_training(spec, extra, message, tmp_path, capsys):
    path = tmp_path / "spec.yaml"
    path.write_text(yaml.safe_dump({"pairs": ["gridrooms-near"], "methods": ["reward-shaping"], "seeds": 1,
                                    "frames": 64, **spec}))
    one_sentence(capsys, main(["sweep", str(path), "--out", str(tmp_path / "out")] + extra), 2, message)
    assert not (tmp_path / "out").exists()


def test_truncated_logs_drop_later_steps_and_torn_records(tmp_path):
    from torch.utils.tensorboard import SummaryWriter

    writer = SummaryWriter(str(tmp_path / "logs" / "tensorboard"))
    for step in range(5):
        writer.add_scalar("eval/return_mean", float(step), step)
    writer.close()
    (event,) = (tmp_path / "logs" / "tensorboard").glob("*tfevents*")
    with open(event, "ab") as f:
        f.write(b"\x20\x00\x00")  # a record torn by a kill
    scalars = tmp_path / "logs" / "csv" / "scalars" / "eval"
    scalars.mkdir(parents=True)
    (scalars / "return_mean.csv").write_text("0,0.0\n1,1.0\n2,2.0\n3,3.0\n4,4")
    rundir.truncate_logs(tmp_path, 2)
    assert list(read_tensorboard(tmp_path / "logs" / "tensorboard", tag="eval/return_mean").frames) == [0, 1, 2]
    assert (scalars / "return_mean.csv").read_text() == "0,0.0\n1,1.0\n2,2.0\n"


# ------------------------------------------------------------------- 13: per-run keys owned by the plan
PLAN_VALUES = {"task": "gridrooms/northeast", "algo": "td3", "seed": 3, "frames": 128,
               "transfer.method": "model-reuse", "eval.stop_at_success": 0.9}


def nested(key, value):
    """``a.b=v`` as the mapping ``{a: {b: v}}`` (a key without a dot as it is)."""
    head, _, rest = key.partition(".")
    return {head: {rest: value}} if rest else {key: value}


def test_every_per_run_key_has_a_test_value():
    from drltg.experiments.experiment import PLAN_KEYS
    from drltg.experiments.spec import SET_BY_SWEEP

    assert set(PLAN_VALUES) == set(PLAN_KEYS) == set(SET_BY_SWEEP)


@pytest.mark.parametrize("key", sorted(PLAN_VALUES))
@pytest.mark.parametrize("form", ["dotted", "nested"])
def test_experiment_refuses_an_override_of_a_per_run_key(key, form, tmp_path, capsys):
    from drltg.experiments.experiment import PLAN_KEYS

    value = PLAN_VALUES[key]
    text = f"{key}={value}" if form == "dotted" else "{}={}".format(*next(iter(
        {k: yaml.safe_dump(v, default_flow_style=True).strip() for k, v in nested(key, value).items()}.items())))
    one_sentence(capsys, main(EXPERIMENT + ["-o", text, "--out", str(tmp_path / "exp")]), 2,
                 f"may not set '{key}'", f"use {PLAN_KEYS[key]} instead")
    assert not (tmp_path / "exp").exists()


@pytest.mark.parametrize("key", sorted(PLAN_VALUES))
@pytest.mark.parametrize("where, form", [("overrides", "dotted"), ("overrides", "nested"), ("grid", "dotted"),
                                         ("grid", "nested")])
def test_sweep_refuses_an_override_of_a_per_run_key(key, where, form, tmp_path, capsys):
    from drltg.experiments.spec import SET_BY_SWEEP

    value = PLAN_VALUES[key]
    entry = {key: value} if form == "dotted" else nested(key, value)
    if where == "grid":
        entry = {k: [v] for k, v in entry.items()}
    path = tmp_path / "spec.yaml"
    path.write_text(yaml.safe_dump({"pairs": ["gridrooms-near"], "methods": ["reward-shaping"], "seeds": 1,
                                    "frames": 64, where: entry}))
    one_sentence(capsys, main(["sweep", str(path), "--out", str(tmp_path / "out")]), 2,
                 f"'{where}' may not set '{key}'", f"use {SET_BY_SWEEP[key]} instead")
    assert not (tmp_path / "out").exists()


def test_a_source_given_in_the_config_serves_the_transfer_runs_only(source, tmp_path):
    from drltg.experiments.experiment import plan_runs

    runs = plan_runs("fourrooms/northeast", "policy-reuse", frames=64, seeds=2, out=tmp_path,
                     overrides=[f"transfer.source={source}"])
    assert [(role, c.transfer.method, c.transfer.source) for role, c, _ in runs] == [
        ("baseline", "none", None), ("transfer", "policy-reuse", str(source))] * 2


# --------------------------------------------------------------------- 14: checked before the first frame
def write_spec(tmp_path, text: str | bytes) -> Path:
    path = tmp_path / "spec.yaml"
    (path.write_bytes if isinstance(text, bytes) else path.write_text)(text)
    return path


SPEC = "pairs: [gridrooms-near]\nmethods: [reward-shaping]\nseeds: 1\nframes: 64\n"


@pytest.mark.parametrize("extra, message", [
    (["--threshold", "nan"], "--threshold 'nan' must be a finite number"),
    (["--threshold", "inf%"], "--threshold 'inf%' must be a finite percentage"),
    (["--threshold", "1.7e308"], "--threshold '1.7e308' must be a finite number of magnitude at most 1e+15"),
    (["--source-frames", "0"], "argument --source-frames: '0' is not a whole number of frames >= 1"),
    (["--seeds", str(10**9)], "more than the 1000 runs a side"),
    (["--seed", "-1"], "--seed -1 with --seeds 1 gives run seeds outside [0, 2147483647]"),
])
def test_experiment_refuses_bad_numbers_before_training(extra, message, tmp_path, capsys):
    at = EXPERIMENT.index("--seeds")
    base = EXPERIMENT[:at] + EXPERIMENT[at + 2:] if extra[0] == "--seeds" else EXPERIMENT  # an option is given once
    one_sentence(capsys, main(base + extra + ["--out", str(tmp_path / "exp")]), 2, message)
    assert not (tmp_path / "exp").exists()


@pytest.mark.parametrize("spec, message", [
    (SPEC + "threshold: .nan\n", "threshold 'nan' must be a finite number"),
    (SPEC + "seeds: 2\n", "key 'seeds' appears twice (line 5)"),
    (SPEC.replace("[reward-shaping]", "[reward-shaping, reward-shaping]"), "'methods' lists 'reward-shaping' twice"),
    (SPEC + "grid: {optim.lr: [0.001, 0.001]}\n", "'grid: optim.lr' lists 0.001 twice"),
    (SPEC + "overrides: {eval.every: 64, eval.every: 128}\n", "key 'eval.every' appears twice"),
    (SPEC + "source_frames: 0\n", "'source_frames' must be positive"),
    (SPEC.encode() + b"# caf\xe9\n", f"is not UTF-8 text (byte {len(SPEC) + 5})"),
])
def test_sweep_refuses_a_bad_spec_before_training(spec, message, tmp_path, capsys):
    one_sentence(capsys, main(["sweep", str(write_spec(tmp_path, spec)), "--out", str(tmp_path / "out")]), 2, message)
    assert not (tmp_path / "out").exists()


def test_a_variant_name_the_file_system_cannot_hold_is_refused_by_dry_run(tmp_path, capsys):
    spec = write_spec(tmp_path, SPEC + f"grid: {{network.hidden: [[16], {[16] * 70}]}}\n")
    one_sentence(capsys, main(["sweep", str(spec), "--out", str(tmp_path / "out"), "--dry-run"]), 2,
                 "bytes, more than the 255 the file system allows")
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("extra, message", [
    (["-o", "buffer.size=100000000000"], "buffer.size=100000000000 needs"),
    (["-o", "network.hidden=[1000000,1000000]"], "network.hidden=[1000000, 1000000] needs at least"),
])
def test_sizes_beyond_the_machine_are_refused_before_the_run_dir_exists(extra, message, tmp_path, capsys):
    one_sentence(capsys, main(train_args(tmp_path / "run", *extra)), 2, message, "GiB of device 'cpu'")
    assert not (tmp_path / "run").exists()


def test_experiment_out_into_a_run_directory_is_refused(source, tmp_path, capsys):
    before = tree(source)
    one_sentence(capsys, main(EXPERIMENT + ["--out", str(source)]), 2, "is the run directory of one run")
    spec = write_spec(tmp_path, SPEC)
    one_sentence(capsys, main(["sweep", str(spec), "--out", str(source)]), 2, "is the run directory of one run")
    assert tree(source) == before


def test_experiment_over_a_stray_folder_names_it_without_suggesting_resume(tmp_path, capsys):
    stray = tmp_path / "exp" / "baseline" / "seed-0"
    stray.mkdir(parents=True)
    (stray / "notes.txt").write_text("mine\n")
    err = one_sentence(capsys, main(EXPERIMENT + ["--out", str(tmp_path / "exp")]), 2,
                       f"'{stray}' exists but holds no config.yaml")
    assert "--resume" not in err
    assert sorted(p.name for p in (tmp_path / "exp").rglob("*")) == ["baseline", "notes.txt", "seed-0"]


def test_a_task_that_ignores_the_batch_size_is_refused_before_the_run_dir_exists(tmp_path, capsys):
    from drltg.envs import TASKS, register_task
    from drltg.envs.fourrooms import FourRoomsEnv

    def one_env_only(batch_size=(), device=None, **options):  # a plugin factory that drops batch_size
        return FourRoomsEnv(device=device, **options)

    register_task("test/one-env-only", one_env_only, "FourRooms that ignores batch_size", goal=(8.0, 8.0))
    try:
        one_sentence(capsys, main(train_args(tmp_path / "run", task="test/one-env-only")), 2,
                     "built an env of batch size () when asked for (4,) (collector.num_envs=4)")
    finally:
        del TASKS["test/one-env-only"]
    assert not (tmp_path / "run").exists()


REPORT_FLAGS = [
    (["--seed", "-1"], "--seed must be an integer in [0, 2**32 - 1], got -1"),
    (["--threshold", "1.7e308"], "--threshold '1.7e308' must be a finite number"),
    (["--threshold", "nan"], "--threshold 'nan' must be a finite number"),
    (["--budget", "1.7e308"], "--budget '1.7e308' must be a finite number of frames"),
    (["--source-frames", "1.7e308"], "--source-frames '1.7e308' must be a finite number of frames"),
]


@pytest.mark.parametrize("extra, message", REPORT_FLAGS)
def test_report_refuses_out_of_range_numbers(extra, message, tmp_path, capsys):
    runs = {}
    for side in ("b", "t"):
        for seed in range(3):
            run = tmp_path / side / str(seed)
            run.mkdir(parents=True)
            (run / "eval.csv").write_text("frames,return_mean,return_std,episodes\n0,0.1,0,4\n100,0.5,0,4\n"
                                          "200,0.6,0,4\n300,0.7,0,4\n")
            runs.setdefault(side, []).append(str(run))
    one_sentence(capsys, main(["report", "--baseline", *runs["b"], "--transfer", *runs["t"],
                               "--out", str(tmp_path / "r"), *extra]), 2, message)
    assert not (tmp_path / "r").exists()


# ------------------------------------------------------------------------------------- 15: run health
@pytest.fixture
def nan_reward_task():
    """A task whose rewards are NaN: the critic's loss is NaN from its first update on."""
    from drltg.envs import TASKS, register_task
    from drltg.envs.fourrooms import FourRoomsEnv

    class NanReward(FourRoomsEnv):
        def _step(self, td):
            out = super()._step(td)
            out["reward"] = out["reward"] * float("nan")
            return out

    register_task("test/nan-reward", NanReward, "FourRooms with NaN rewards", goal=(8.0, 8.0))
    yield "test/nan-reward"
    del TASKS["test/nan-reward"]


def test_a_diverging_run_stops_non_zero_with_status_diverged(nan_reward_task, tmp_path, capsys):
    import json

    run = tmp_path / "run"
    err = one_sentence(capsys, main(train_args(run, "-o", "eval.every=64", task=nan_reward_task, frames=128)), 1,
                       "the run diverged: the loss term '", "' became nan at frame 32")
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    summary = json.loads((run / "summary.json").read_text())
    assert summary["status"] == "diverged" and summary["reason"] in err and summary["seed"] == 0
    assert [r["frames"] for r in rundir.read_eval_csv(run / "eval.csv")] == [0]  # nothing after the first update
    assert not (run / "checkpoints" / "last.pt").exists()
    assert rundir.summary_status(run) == ("diverged", summary["reason"])


def test_non_finite_parameters_are_named():
    from drltg.training import health

    net = torch.nn.Sequential(torch.nn.Linear(2, 2), torch.nn.Linear(2, 1))
    health.check_parameters(net, 10)
    with torch.no_grad():
        net[1].bias.fill_(float("inf"))
    with pytest.raises(health.Diverged, match=r"parameter '1.bias' holds non-finite values at frame 10"):
        health.check_parameters(net, 10)
    with pytest.raises(health.Diverged, match=r"loss term 'loss_actor' became -inf at frame 3"):
        health.check_losses({"loss_qvalue": torch.tensor(1.0), "loss_actor": torch.tensor(float("-inf"))}, 3)


def fake_run(path: Path, values, *, seed: int, status: str | None = "complete", config: bool = True,
             logs: bool = True) -> Path:
    """A drltg run directory on disk: eval.csv, config.yaml, logs/ and a summary.json with ``status``."""
    import json

    path.mkdir(parents=True)
    rows = "".join(f"{100 * i},{v},0,4\n" for i, v in enumerate(values))
    (path / "eval.csv").write_text("frames,return_mean,return_std,episodes\n" + rows)
    if config:
        (path / "config.yaml").write_text(yaml.safe_dump({"task": "fourrooms/northeast", "seed": seed,
                                                          "env": {"horizon": 100},
                                                          "eval": {"episodes": 4, "every": 100}}))
    if logs:
        (path / "logs").mkdir()
    if status is not None:
        (path / "summary.json").write_text(json.dumps({"status": status}))
    return path


def test_report_lists_unfinished_runs_apart_and_counts_them_only_when_asked(tmp_path, capsys):
    base = [fake_run(tmp_path / "b" / f"seed-{i}", [0.1, 0.2, 0.3, 0.4], seed=i) for i in range(3)]
    transfer = [fake_run(tmp_path / "t" / f"seed-{i}", [0.2, 0.4, 0.6, 0.8], seed=i) for i in range(3)]
    diverged = fake_run(tmp_path / "t" / "seed-3", [0.0, -1.0, -1.0, -1.0], seed=3, status="diverged")
    incomplete = fake_run(tmp_path / "t" / "seed-4", [0.0, -1.0, -1.0, -1.0], seed=4, status=None)
    args = ["report", "--baseline", *map(str, base), "--transfer", *map(str, transfer + [diverged, incomplete])]
    assert main(args + ["--out", str(tmp_path / "r1")]) == 0
    err = capsys.readouterr().err
    for state, run in (("diverged", diverged), ("incomplete", incomplete)):
        assert f"1 transfer run(s) {state}, left out of the metrics (--include-unfinished counts them): {run}" in err
    result = json.loads((tmp_path / "r1" / "transfer_metrics.json").read_text())
    assert (result["metrics"]["n_seeds_baseline"], result["metrics"]["n_seeds_transfer"]) == (3, 3)
    assert result["metrics"]["jumpstart"] == pytest.approx(0.1)  # 0.2 - 0.1: the unfinished runs' 0.0 left out
    assert main(args + ["--out", str(tmp_path / "r2"), "--include-unfinished"]) == 0
    result = json.loads((tmp_path / "r2" / "transfer_metrics.json").read_text())
    assert result["metrics"]["n_seeds_transfer"] == 5
    assert result["metrics"]["jumpstart"] == pytest.approx((0.2 * 3 + 0.0 * 2) / 5 - 0.1)


def test_report_leaves_a_config_less_run_out_and_says_why(tmp_path, capsys):
    base = [fake_run(tmp_path / "b" / f"seed-{i}", [0.1, 0.2, 0.3], seed=i) for i in range(3)]
    transfer = [fake_run(tmp_path / "t" / f"seed-{i}", [0.2, 0.3, 0.4], seed=i) for i in range(3)]
    torn = fake_run(tmp_path / "t" / "seed-3", [5.0, 5.0, 5.0], seed=3, config=False)  # eval.csv, no config.yaml
    args = ["report", "--baseline", *map(str, base), "--transfer", *map(str, transfer + [torn])]
    assert main(args + ["--out", str(tmp_path / "r1")]) == 0
    assert (f"1 transfer run(s) without config.yaml, left out of the metrics (nothing records the settings they "
            f"were trained with, so they cannot be checked against the other runs) (--include-unfinished counts "
            f"them): {torn}") in capsys.readouterr().err
    metrics = json.loads((tmp_path / "r1" / "transfer_metrics.json").read_text())["metrics"]
    assert metrics["n_seeds_transfer"] == 3 and metrics["jumpstart"] == pytest.approx(0.1)  # 0.2 - 0.1
    assert main(args + ["--out", str(tmp_path / "r2"), "--include-unfinished"]) == 0
    assert f"1 transfer run(s) without config.yaml, counted: {torn}" in capsys.readouterr().err
    metrics = json.loads((tmp_path / "r2" / "transfer_metrics.json").read_text())["metrics"]
    assert metrics["n_seeds_transfer"] == 4 and metrics["jumpstart"] == pytest.approx((0.2 * 3 + 5.0) / 4 - 0.1)


def test_report_refuses_when_no_run_of_a_side_can_be_counted(tmp_path, capsys):
    base = [fake_run(tmp_path / "b" / f"seed-{i}", [0.1, 0.2, 0.3], seed=i) for i in range(3)]
    torn = fake_run(tmp_path / "t" / "seed-0", [0.2, 0.3, 0.4], seed=0, config=False)
    stopped = fake_run(tmp_path / "t" / "seed-1", [0.2, 0.3, 0.4], seed=1, status=None)
    out = tmp_path / "r"
    assert main(["report", "--baseline", *map(str, base), "--transfer", str(torn), str(stopped),
                 "--out", str(out)]) == 2
    assert capsys.readouterr().err.endswith(
        f"error: no transfer run can be counted, each is without config.yaml or incomplete ({torn}, {stopped}); "
        "finish them, or pass --include-unfinished.\n")
    assert not out.exists()


# ----------------------------------------------------------------------------------- 16: integrity
def flip_a_tensor_byte(checkpoint: Path) -> None:
    """Flip one byte in the middle of the largest tensor of a torch zip checkpoint (it still loads)."""
    import zipfile

    with zipfile.ZipFile(checkpoint) as z:
        info = max(z.infolist(), key=lambda i: i.file_size)
    data = bytearray(checkpoint.read_bytes())
    name_len, extra_len = int.from_bytes(data[info.header_offset + 26:info.header_offset + 28], "little"), \
        int.from_bytes(data[info.header_offset + 28:info.header_offset + 30], "little")
    data[info.header_offset + 30 + name_len + extra_len + info.file_size // 2] ^= 0x01
    checkpoint.write_bytes(bytes(data))


def test_a_bit_flipped_checkpoint_is_refused(copy_of_killed, capsys):
    checkpoint = copy_of_killed / "checkpoints" / "last.pt"
    flip_a_tensor_byte(checkpoint)
    assert torch.load(checkpoint, weights_only=True)["frames"] == 256  # it still loads
    before = tree(copy_of_killed)
    one_sentence(capsys, main(["train", "--resume", "--run-dir", str(copy_of_killed), "--no-progress"]), 2,
                 f"cannot read '{checkpoint}': it does not match its SHA-256 in {copy_of_killed / 'manifest.json'}")
    assert tree(copy_of_killed) == before


def test_the_manifest_of_a_finished_run_covers_every_file(source):
    from drltg.store import manifest

    files = manifest.read(source)
    on_disk = {p.relative_to(source).as_posix() for p in source.rglob("*") if p.is_file()}
    assert set(files) == on_disk - {"manifest.json"}
    assert {"eval.csv", "checkpoints/last.pt", "summary.json", "config.yaml"} <= set(files)
    assert all(digests == [manifest.digest(source / name)] for name, digests in files.items())


def test_an_edited_curve_of_a_finished_run_is_refused_by_the_report(source, tmp_path, capsys):
    run = tmp_path / "run"
    shutil.copytree(source, run)
    lines = (run / "eval.csv").read_text().splitlines(True)
    frames, rest = lines[-1].split(",", 1)
    (run / "eval.csv").write_text("".join(lines[:-1]) + f"{frames},{9.0},{rest.split(',', 1)[1]}")
    one_sentence(capsys, main(["report", "--baseline", str(source), "--transfer", str(run), "--out",
                               str(tmp_path / "r")]), 2, f"cannot read '{run / 'eval.csv'}': it does not match")
    assert not (tmp_path / "r").exists()


@pytest.mark.parametrize("name, text, last", [
    ("eval.csv", "frames,return_mean,return_std,episodes\n0,0.5,0,4\n100,0.7,0,4\n200,0.8,0,4\n", 4),
    ("progress.csv", "time/total_timesteps,eval/mean_reward\n0,0.5\n100,0.7\n200,0.8\n", 4),
    ("scalars/eval/return_mean.csv", "0,0.5\n100,0.7\n200,0.8\n", 3),
])
def test_a_torn_last_line_is_refused_naming_file_and_line(name, text, last, tmp_path):
    from drltg.report.curves import read_curves

    path = tmp_path / "run" / name
    path.parent.mkdir(parents=True)
    path.write_text(text)
    assert list(read_curves(path)[0].values) == [0.5, 0.7, 0.8]
    path.write_text(text[:-3])  # cut inside the last value: "0.8" would be read as 0
    with pytest.raises(UsageError, match=rf"'{path}' line {last} is torn: the file ends without a newline"):
        read_curves(path)


def test_a_corrupt_tensorboard_event_file_is_named(tmp_path):
    from torch.utils.tensorboard import SummaryWriter

    writer = SummaryWriter(str(tmp_path / "tb"))
    for step in range(20):
        writer.add_scalar("eval/return_mean", float(step), step)
    writer.close()
    (event,) = (tmp_path / "tb").glob("*tfevents*")
    assert len(read_tensorboard(tmp_path / "tb").frames) == 20
    data = bytearray(event.read_bytes())
    data[len(data) // 2] ^= 0xFF
    event.write_bytes(bytes(data))
    with pytest.raises(UsageError, match=rf"'{event}' is a corrupt TensorBoard event file: record \d+ fails its CRC"):
        read_tensorboard(tmp_path / "tb")


def test_resume_without_logs_is_refused(copy_of_killed, capsys):
    shutil.rmtree(copy_of_killed / "logs")
    before = tree(copy_of_killed)
    one_sentence(capsys, main(["train", "--resume", "--run-dir", str(copy_of_killed), "--no-progress"]), 2,
                 "its logs/ folder is missing, so the training scalars up to the checkpoint at frame 256 are lost")
    assert tree(copy_of_killed) == before


# ------------------------------------------------------------------------ 17: comparable by construction
def sides_with(tmp_path, change: dict) -> list[str]:
    """Three baseline and three transfer runs; the transfer configs carry ``change``."""
    args = []
    for side, values in (("b", [0.1, 0.2, 0.3, 0.4]), ("t", [0.2, 0.4, 0.6, 0.8])):
        runs = [fake_run(tmp_path / side / f"seed-{i}", values, seed=i) for i in range(3)]
        if side == "t":
            for run in runs:
                cfg = yaml.safe_load((run / "config.yaml").read_text())
                for key, value in change.items():
                    section, _, leaf = key.partition(".")
                    cfg.setdefault(section, {})[leaf] = value
                cfg["transfer"] = {"method": "reward-shaping"}
                (run / "config.yaml").write_text(yaml.safe_dump(cfg))
        args += ["--baseline" if side == "b" else "--transfer", *map(str, runs)]
    return ["report", *args]


@pytest.mark.parametrize("change, shown", [
    ({"eval.episodes": 16}, "eval.episodes (4 vs 16)"),
    ({"eval.every": 200}, "eval.every (100 vs 200)"),
    ({"env.horizon": 50}, "env.horizon (100 vs 50)"),
    ({"network.hidden": [32]}, "network.hidden ((unset) vs [32])"),
])
def test_report_refuses_sides_whose_curves_mean_different_things(change, shown, tmp_path, capsys):
    args = sides_with(tmp_path, change)
    one_sentence(capsys, main(args + ["--out", str(tmp_path / "r")]), 2,
                 "runs differ in settings that change what a curve means: " + shown, "--allow-mismatch")
    assert not (tmp_path / "r").exists()
    assert main(args + ["--out", str(tmp_path / "r"), "--allow-mismatch"]) == 0
    warnings = json.loads((tmp_path / "r" / "transfer_metrics.json").read_text())["settings"]["warnings"]
    assert f"baseline and transfer settings differ (--allow-mismatch): {shown}" in warnings


def test_a_transfer_method_is_no_mismatch(tmp_path):
    assert main(sides_with(tmp_path, {}) + ["--out", str(tmp_path / "r")]) == 0


def test_a_report_that_fails_midway_leaves_the_old_report_whole(tmp_path, monkeypatch, capsys):
    args = sides_with(tmp_path, {}) + ["--out", str(tmp_path / "r")]
    assert main(args) == 0
    capsys.readouterr()
    before = tree(tmp_path / "r")
    real, calls = os.write, {"n": 0}

    def third_write_fails(fd, data):  # the disk fills up after two report files
        calls["n"] += 1
        if calls["n"] == 3:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return real(fd, data)

    monkeypatch.setattr(atomic, "os", types.SimpleNamespace(**{**vars(os), "write": third_write_fails}))
    one_sentence(capsys, main(args + ["--threshold", "0.3"]), 2,
                 f"cannot write '{tmp_path / 'r' / 'transfer_plot.png'}' (No space left on device)")
    assert tree(tmp_path / "r") == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b", "r", "t"]


# ------------------------------------------------------------------------------ 18: processes and locks
def test_a_lock_whose_pid_was_reused_is_taken_over(tmp_path):
    host = os.uname().nodename
    from drltg.store.lock import _started

    started = _started(os.getpid())
    (tmp_path / rundir.LOCK).write_text(f"{os.getpid()} {host} x {started}\n")  # this process: alive
    with pytest.raises(UsageError, match=f"is in use by process {os.getpid()}"):
        with rundir.lock(tmp_path):
            pass
    (tmp_path / rundir.LOCK).write_text(f"{os.getpid()} {host} x {int(started) - 1}\n")  # the pid, reused
    with rundir.lock(tmp_path):
        assert (tmp_path / rundir.LOCK).read_text().split()[3] == started
    assert not (tmp_path / rundir.LOCK).exists()


def children_of(pid: int) -> list[int]:
    found = []
    for proc in Path("/proc").iterdir():
        if proc.name.isdigit():
            with contextlib.suppress(OSError, IndexError, ValueError):
                if int((proc / "stat").read_text().rsplit(")", 1)[1].split()[1]) == pid:
                    found.append(int(proc.name))
    return found


def test_workers_die_with_a_killed_experiment(tmp_path):
    """kill -9 of `drltg experiment --workers 2` while one worker trains and the other waits: both end (the
    kernel sends them SIGTERM), the training one after releasing its run's lock."""
    out = tmp_path / "exp"
    args = ["experiment", "fourrooms-near", "--method", "model-reuse", "--seeds", "1", "--frames", "128",
            "--source-frames", str(10**6), "--workers", "2", "--out", str(out), *OPTS]
    proc = subprocess.Popen([sys.executable, "-m", "drltg.cli", *args], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    source = out / "source" / "seed-50"
    host, workers = os.uname().nodename, []
    try:
        while not (source / "checkpoints" / "last.pt").exists() and proc.poll() is None:
            time.sleep(0.1)
        workers = children_of(proc.pid)
        assert int((source / rundir.LOCK).read_text().split()[0]) in workers
        proc.kill()  # kill -9: no handler runs in the parent
        proc.wait(timeout=30)
        deadline = time.monotonic() + 60
        while any(lock_mod._alive(w, host) for w in workers) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert [w for w in workers if lock_mod._alive(w, host)] == []
    finally:
        for w in workers:
            if lock_mod._alive(w, host):
                os.kill(w, signal.SIGKILL)
    assert not (source / rundir.LOCK).exists()  # the worker unwound: its run is free to resume
    assert torch.load(source / "checkpoints" / "last.pt", weights_only=True)["frames"] >= 128  # its first evaluation


def test_a_ray_address_that_stays_silent_is_one_sentence(tmp_path):
    import socket
    import threading

    from drltg.experiments.backends import RayBackend

    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen()
    accepted = []
    threading.Thread(target=lambda: accepted.append(server.accept()), daemon=True).start()
    address = f"127.0.0.1:{server.getsockname()[1]}"
    try:
        with pytest.raises(UsageError, match=rf"the Ray cluster at '{address}' did not answer within 1 s"):
            RayBackend(address, {}, connect_timeout=1.0)
    finally:
        server.close()
    assert accepted  # the address took the connection and said nothing
