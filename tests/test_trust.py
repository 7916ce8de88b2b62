"""A run directory from someone else is data: opening it never runs code from it.

Every command and API that reads a checkpoint is given one whose pickle would write a marker file
when unpickled (its manifest updated to match, as an attacker would): each refuses it in one sentence
and the marker never appears.
"""
import shutil

import pytest
import torch

from drltg.cli import main
from drltg.errors import UsageError
from drltg.store import manifest, networks, rundir
from tests.test_reliability import (
    one_sentence,
    source,  # noqa: F401  (fixture: a finished tiny SAC run)
    train_args,
)


class Payload:
    """Unpickling this calls ``exec`` on a line that writes ``marker``."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return exec, (f"open({self.marker!r}, 'w').write('ran')",)


def poison(run, marker, name="last"):
    """Replace ``run``'s checkpoint with one carrying the payload (its real weights kept beside it) and
    record the new file's digest in the manifest."""
    path = run / rundir.checkpoint_path(name)
    ckpt = torch.load(path, weights_only=True)
    ckpt["payload"] = Payload(marker)
    torch.save(ckpt, path)
    files = manifest.read(run)
    if files:
        files[rundir.checkpoint_path(name).as_posix()] = [manifest.digest(path)]
        (run / manifest.MANIFEST).write_text(manifest.dumps(files))


def as_old_run(run):
    """``run`` as drltg wrote runs before networks files: reusing it reads the networks from the checkpoint."""
    files = manifest.read(run)
    for name in networks.NETWORKS.values():
        (run / name).unlink(missing_ok=True)
        files.pop(name.as_posix(), None)
    if files:
        (run / manifest.MANIFEST).write_text(manifest.dumps(files))
    return run


@pytest.fixture(scope="module")
def unfinished(tmp_path_factory):
    """A run whose checkpoint is at frame 128 of a 256-frame budget (summary.json removed)."""
    run = tmp_path_factory.mktemp("unfinished") / "sac"
    assert main(train_args(run, "-o", "checkpoint.every=128", frames=128)) == 0
    (run / rundir.SUMMARY).unlink()
    (run / manifest.MANIFEST).unlink()
    return run


@pytest.fixture
def marker(tmp_path):
    path = tmp_path / "marker"
    yield path
    assert not path.exists(), "the checkpoint's payload ran"


@pytest.fixture
def evil(source, tmp_path, marker):  # noqa: F811
    run = as_old_run(shutil.copytree(source, tmp_path / "evil"))
    poison(run, marker)
    return run


@pytest.fixture
def evil_beside_networks(source, tmp_path, marker):  # noqa: F811
    """The poisoned checkpoint in a run that has its networks file."""
    run = shutil.copytree(source, tmp_path / "evil-with-networks")
    poison(run, marker)
    return run


def test_the_payload_is_real(evil, tmp_path):
    """The crafted file does run its payload when unpickled without restriction (what the tests guard)."""
    torch.load(evil / "checkpoints" / "last.pt", weights_only=False)
    assert (tmp_path / "marker").read_text() == "ran"
    (tmp_path / "marker").unlink()


def test_load_checkpoint_refuses_it(evil):
    with pytest.raises(UsageError, match="never allowed to run code"):
        rundir.load_checkpoint(evil)


def test_a_changed_checkpoint_is_refused_by_its_digest_before_it_is_read(source, tmp_path, marker):  # noqa: F811
    run = tmp_path / "changed"
    shutil.copytree(source, run)
    ckpt = torch.load(run / "checkpoints" / "last.pt", weights_only=True)
    torch.save({**ckpt, "payload": Payload(marker)}, run / "checkpoints" / "last.pt")  # manifest left as it was
    with pytest.raises(UsageError, match="does not match its SHA-256"):
        rundir.load_checkpoint(run)


def test_evaluate_refuses_it(evil, capsys):
    one_sentence(capsys, main(["evaluate", str(evil), "--episodes", "2"]), 2, "never allowed to run code")


def test_video_refuses_it(evil, tmp_path, capsys):
    one_sentence(capsys, main(["video", str(evil), "--out", str(tmp_path / "v")]), 2, "never allowed to run code")
    assert not (tmp_path / "v").exists()


def test_model_reuse_refuses_it_as_a_source(evil, tmp_path, capsys):
    reuse = ["-o", "transfer.method=model-reuse", "-o", f"transfer.source={evil}"]
    one_sentence(capsys, main(train_args(tmp_path / "t", *reuse)), 2, "never allowed to run code")


def test_policy_reuse_refuses_it_as_a_source(evil, tmp_path, capsys):
    reuse = ["-o", "transfer.method=policy-reuse", "-o", f"transfer.source={evil}"]
    one_sentence(capsys, main(train_args(tmp_path / "t", *reuse)), 2, "never allowed to run code")


def test_load_actor_refuses_it(evil):
    from drltg.transfer import load_actor

    with pytest.raises(UsageError, match="never allowed to run code"):
        load_actor(evil)


def test_the_preflight_of_an_unfinished_source_refuses_it(unfinished, tmp_path, marker, capsys):
    reused = as_old_run(shutil.copytree(unfinished, tmp_path / "source"))
    poison(reused, marker)
    reuse = ["-o", "transfer.method=policy-reuse", "-o", f"transfer.source={reused}"]
    one_sentence(capsys, main(train_args(tmp_path / "t", *reuse)), 2, "never allowed to run code")


def test_resume_refuses_it(unfinished, tmp_path, marker, capsys):
    run = tmp_path / "run"
    shutil.copytree(unfinished, run)
    poison(run, marker)
    one_sentence(capsys, main(["train", "--resume", "--run-dir", str(run), "--no-progress"]), 2,
                 "never allowed to run code")


def test_an_experiment_worker_refuses_it(evil, tmp_path, marker, capsys):
    code = main(["experiment", "fourrooms/northeast", "--method", "model-reuse", "--seeds", "1", "--frames", "64",
                 "--out", str(tmp_path / "x"), "-o", f"transfer.source={evil}",
                 *[a for o in ("network.hidden=[16,16]", "collector.num_envs=4", "collector.frames_per_batch=16",
                               "collector.init_random_frames=32", "eval.every=32") for a in ("-o", o)]])
    out = capsys.readouterr().out
    assert code != 0 and "failed runs:" in out and "never allowed to run code" in out, out
    assert "Traceback" not in out


@pytest.mark.parametrize("command", ["model-reuse", "policy-reuse", "value-shaping", "evaluate", "video", "load_actor"])
def test_what_reads_only_the_networks_never_opens_the_checkpoint(evil_beside_networks, tmp_path, command, capsys):
    """Reusing, evaluating or filming a run reads its networks file: the poisoned checkpoint beside it is
    not opened, so the run works and the payload never runs (the ``marker`` fixture checks)."""
    run = evil_beside_networks
    if command == "load_actor":
        from drltg.transfer import load_actor

        load_actor(run)
        return
    args = {"evaluate": ["evaluate", str(run), "--episodes", "2"],
            "video": ["video", str(run), "--out", str(tmp_path / "v"), "--max-steps", "5"]}.get(command) or \
        train_args(tmp_path / "t", "-o", f"transfer.method={command}", "-o", f"transfer.source={run}")
    assert main(args) == 0, capsys.readouterr().err


def test_committed_checkpoints_read_as_data():
    """Every checkpoint shipped under results/ loads with the restricted reader (they hold no objects)."""
    from pathlib import Path

    runs = sorted({p.parents[1] for p in (Path(__file__).parents[1] / "results").rglob("checkpoints/*.pt")})
    assert runs
    for run in runs:
        for name in ("last", "best"):
            if (run / rundir.checkpoint_path(name)).is_file():
                assert "loss" in rundir.load_checkpoint(run, mmap=True, checkpoint=name)
