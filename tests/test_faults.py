"""Fault injection: damaged files and a full disk end in one sentence or in the undisturbed result.

Seeded damage (a truncation or one flipped bit) of every file a finished run's manifest lists is
refused, naming the file, by whatever reads it; a file size limit (``RLIMIT_FSIZE``, a full disk as
the kernel reports it) during training is one sentence and leaves nothing. kill -9 at seeded points
of an experiment and a sweep, then a resume compared with an undisturbed run, is
``benchmarks/faults.py`` (minutes; its last result is in ``benchmarks/faults_result.json``).
"""
import contextlib
import json
import os
import random
import resource
import shutil
import signal
from pathlib import Path

import pytest

from drltg.cli import main
from drltg.errors import UsageError
from drltg.store import manifest, rundir

TINY = ["network.hidden=[16,16]", "collector.num_envs=4", "collector.frames_per_batch=16",
        "collector.init_random_frames=32", "optim.updates_per_batch=1", "buffer.batch_size=16",
        "eval.every=32", "eval.episodes=2", "checkpoint.every=64", "log.every=32"]
OPTS = [a for o in TINY for a in ("-o", o)]


def train_args(run, frames=96):
    return ["train", "fourrooms/northeast", "--frames", str(frames), "--run-dir", str(run), "--no-progress", *OPTS]


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    run = tmp_path_factory.mktemp("finished") / "run"
    assert main(train_args(run)) == 0
    return run


def damage(path: Path, rng: random.Random) -> str:
    """Truncate ``path`` or flip one bit of it, chosen by ``rng``; the damage done, in words."""
    data = bytearray(path.read_bytes())
    if rng.random() < 0.5:
        cut = rng.randrange(1, len(data))
        path.write_bytes(bytes(data[:cut]))
        return f"cut to {cut} of {len(data)} bytes"
    at, bit = rng.randrange(len(data)), rng.randrange(8)
    data[at] ^= 1 << bit
    path.write_bytes(bytes(data))
    return f"bit {bit} of byte {at} flipped"


def read_everything(run: Path) -> None:
    """What drltg reads of a finished run: its curve and config (report), every logged scalar file, its
    checkpoint (resume), its networks file (reuse, evaluate, video) and its summary."""
    from drltg.report.curves import read_csvlogger, read_run, read_tensorboard

    read_run(run)
    for path in sorted((run / "logs" / "csv").rglob("*.csv")):
        read_csvlogger(path)
    for path in sorted((run / "logs" / "tensorboard").rglob("*tfevents*")):
        read_tensorboard(path)
    rundir.load_checkpoint(run)
    rundir.load_networks(run)
    status = rundir.summary_status(run)
    if status[0] != "complete":
        raise UsageError(status[1])


@pytest.mark.parametrize("seed", range(8))
def test_damage_to_any_file_of_a_finished_run_is_named(finished, seed, tmp_path):
    rng = random.Random(seed)
    run = tmp_path / "run"
    shutil.copytree(finished, run)
    read_everything(run)  # intact: nothing to say
    name = rng.choice(sorted(manifest.read(run)))
    what = damage(run / name, rng)
    with pytest.raises(UsageError) as refused:
        read_everything(run)
    message = str(refused.value)
    assert str(run / name) in message or name == "summary.json" and "summary.json" in message, (name, what, message)


def test_the_manifest_itself_damaged_is_named(finished, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(finished, run)
    (run / manifest.MANIFEST).write_text((run / manifest.MANIFEST).read_text()[:40])
    with pytest.raises(UsageError, match=f"'{run / manifest.MANIFEST}' is not readable JSON"):
        rundir.load_checkpoint(run)


@contextlib.contextmanager
def file_size_limit_applied():
    """Files this process writes may not grow past 4 KiB, as on a full disk (EFBIG instead of SIGXFSZ)."""
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    previous = signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (4096, hard))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
        signal.signal(signal.SIGXFSZ, previous)


def test_a_file_size_limit_during_train_is_one_sentence_and_leaves_nothing(tmp_path, capsys):
    with file_size_limit_applied():
        code = main(train_args(tmp_path / "run"))
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "cannot write" in err and "File too large" in err
    assert os.listdir(tmp_path) == []


def test_a_resumed_run_after_a_file_size_limit_completes(tmp_path, capsys):
    """A limit hit after the first checkpoint leaves a run that resumes to the undisturbed frames."""
    run = tmp_path / "run"
    real = rundir.atomic_torch_save
    calls = {"n": 0}

    def limited_second_checkpoint(obj, path):
        calls["n"] += 1
        if calls["n"] == 2:
            with file_size_limit_applied():
                return real(obj, path)
        return real(obj, path)

    rundir.atomic_torch_save = limited_second_checkpoint
    try:
        assert main(train_args(run, frames=160)) == 2
    finally:
        rundir.atomic_torch_save = real
    assert "File too large" in capsys.readouterr().err
    assert not rundir.is_complete(run) and not [p for p in run.rglob("*.tmp")]
    assert main(["train", "--resume", "--run-dir", str(run), "--no-progress"]) == 0
    assert [r["frames"] for r in rundir.read_eval_csv(run / "eval.csv")] == [0, 32, 64, 96, 128, 160]
    assert json.loads((run / "summary.json").read_text())["status"] == "complete"
    for name in manifest.read(run):
        manifest.verify(run, name)


def test_a_full_disk_first_met_by_the_training_logger_is_one_sentence(tmp_path, capsys, monkeypatch):
    """TorchRL's CSVLogger writes its own files: a full disk it meets first is said as every other writer's."""
    import errno

    from torchrl.record.loggers import CSVLogger

    def full(self, *args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(CSVLogger, "log_scalar", full)
    code = main(train_args(tmp_path / "run"))
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    assert "cannot write the training logs in" in err and "(No space left on device)" in err
