"""A run directory is data: nothing its config names is imported.

A shared run whose ``config.yaml`` sets a Gymnasium task's id to ``"<run>.payload:Hostile-v0"`` would make
``gymnasium.make`` import the module ``payload.py`` shipped inside the run. Every command and API that opens
a run is given such a run, from a working directory where its folder is importable: each refuses it in one
sentence and the module never runs.
"""
import shutil
import sys

import pytest
import yaml

from drltg.cli import main
from drltg.errors import UsageError
from drltg.store import manifest, rundir
from tests.test_reliability import one_sentence, train_args

PAYLOAD = """\
import pathlib
pathlib.Path(__file__).with_name("marker").write_text("ran")
"""
HOSTILE_ID = "sharedrun.payload:Hostile-v0"
REFUSAL = ("gym_id", "part of the task", "not an option")  # said by the config check or by make_env


@pytest.fixture(scope="module")
def pendulum(tmp_path_factory):
    """A finished tiny SAC run on the Gymnasium task pendulum/g10."""
    run = tmp_path_factory.mktemp("pendulum") / "run"
    assert main(train_args(run, "-o", "eval.episodes=1", task="pendulum/g10", frames=64)) == 0
    return run


@pytest.fixture
def shared(pendulum, tmp_path, monkeypatch):
    """``tmp_path/sharedrun``: the run with the hostile id in its config (manifest updated to match, as an
    attacker would) and ``payload.py`` beside it; the working directory and ``sys.path`` see the folder."""
    run = tmp_path / "sharedrun"
    shutil.copytree(pendulum, run)
    (run / "payload.py").write_text(PAYLOAD)
    config = yaml.safe_load((run / "config.yaml").read_text())
    config["env"]["gym_id"] = HOSTILE_ID
    (run / "config.yaml").write_text(yaml.safe_dump(config, sort_keys=False))
    files = manifest.read(run)
    files["config.yaml"] = [manifest.digest(run / "config.yaml")]
    (run / manifest.MANIFEST).write_text(manifest.dumps(files))
    monkeypatch.chdir(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    yield run
    assert not (run / "marker").exists(), "a module named by the run's config was imported"
    sys.modules.pop("sharedrun.payload", None), sys.modules.pop("sharedrun", None)


def test_the_payload_is_real(shared):
    """What the tests guard: Gymnasium imports the module an id's prefix names."""
    import gymnasium

    with pytest.raises(gymnasium.error.Error):
        gymnasium.make(HOSTILE_ID)
    assert (shared / "marker").read_text() == "ran"
    (shared / "marker").unlink()


@pytest.mark.parametrize("args", [
    ["evaluate", "sharedrun", "--episodes", "1"],
    ["video", "sharedrun", "--out", "v", "--max-steps", "5"],
    ["train", "--resume", "--run-dir", "sharedrun", "--no-progress"],
], ids=["evaluate", "video", "resume"])
def test_a_command_that_opens_the_run_refuses_it(shared, args, capsys):
    one_sentence(capsys, main(args), 2, *REFUSAL)


@pytest.mark.parametrize("method", ["policy-reuse", "value-shaping"])
def test_a_method_that_rebuilds_the_run_s_policy_refuses_it(shared, method, tmp_path, capsys):
    args = train_args(tmp_path / "t", "-o", f"transfer.method={method}", "-o", "transfer.source=sharedrun",
                      task="pendulum/g15")
    one_sentence(capsys, main(args), 2, *REFUSAL)


def test_model_reuse_reads_only_the_run_s_weights(shared, tmp_path, capsys):
    """Model reuse copies the checkpoint's tensors into the target's own learner and never builds the
    source's env: it trains, and nothing the config names is imported (the fixture checks)."""
    args = train_args(tmp_path / "t", "-o", "transfer.method=model-reuse", "-o", "transfer.source=sharedrun",
                      task="pendulum/g15")
    assert main(args) == 0


@pytest.mark.parametrize("loader", ["load_actor", "load_critic", "load_agent"])
def test_the_python_loaders_refuse_it(shared, loader):
    import drltg.transfer

    with pytest.raises(UsageError) as err:
        getattr(drltg.transfer, loader)("sharedrun")
    assert all(fragment in str(err.value) for fragment in REFUSAL), err.value


def test_the_report_reads_it_without_importing_anything(shared, tmp_path, capsys):
    code = main(["report", "--baseline", "sharedrun", "--transfer", "sharedrun", "--out", str(tmp_path / "r")])
    assert "Traceback" not in capsys.readouterr().err and code in (0, 2)


def test_a_gym_name_with_a_module_prefix_is_no_task(shared, capsys):
    one_sentence(capsys, main(["train", f"gym/{HOSTILE_ID}", "--frames", "64", "--run-dir", "x"]), 2,
                 f"unknown task 'gym/{HOSTILE_ID}'")


def test_the_registration_is_no_override_either(tmp_path, capsys):
    """The same field from the command line: `-o env.gym_id=Acrobot-v1` would train Acrobot under Pendulum's
    name, and `env.info_keys` would read other flags."""
    for key, value in [("gym_id", "Acrobot-v1"), ("info_keys", "[success]")]:
        code = main(train_args(tmp_path / key, "-o", f"env.{key}={value}", task="pendulum/g10"))
        one_sentence(capsys, code, 2, f"config key 'env.{key}' cannot be set")


# ----------------------------------------------------------------------------- nothing out of the run
@pytest.fixture(scope="module")
def stopped(tmp_path_factory):
    """A run stopped at its checkpoint at frame 128 of a 256-frame budget, its manifest kept."""
    run = tmp_path_factory.mktemp("stopped") / "run"
    assert main(train_args(run, "-o", "checkpoint.every=128", "-o", "eval.every=64", frames=128)) == 0
    config = yaml.safe_load((run / "config.yaml").read_text())
    config["frames"] = 256
    (run / "config.yaml").write_text(yaml.safe_dump(config, sort_keys=False))
    (run / "summary.json").unlink()
    files = manifest.read(run)
    files["config.yaml"] = [manifest.digest(run / "config.yaml")]
    files.pop("summary.json", None)
    (run / manifest.MANIFEST).write_text(manifest.dumps(files))
    return run


@pytest.fixture
def copy(stopped, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(stopped, run)
    return run


def _resume(run):
    return main(["train", "--resume", "--run-dir", str(run), "--no-progress"])


def test_the_stopped_run_resumes(copy):
    """What the refusals below guard: the untouched copy resumes to its budget."""
    assert _resume(copy) == 0 and (copy / "summary.json").is_file()


def test_resume_rewrites_no_logs_a_link_points_at(copy, tmp_path, capsys):
    elsewhere = tmp_path / "my-data"
    shutil.move(copy / "logs", elsewhere)
    (copy / "logs").symlink_to(elsewhere)
    before = {p: p.read_bytes() for p in elsewhere.rglob("*") if p.is_file()}
    one_sentence(capsys, _resume(copy), 2, "holds a symbolic link, 'logs'")
    assert {p: p.read_bytes() for p in elsewhere.rglob("*") if p.is_file()} == before


@pytest.mark.parametrize("args", [["evaluate", "{run}", "--episodes", "1"], ["video", "{run}", "--max-steps", "2"]],
                         ids=["evaluate", "video"])
def test_a_linked_file_or_folder_in_a_run_is_refused(copy, tmp_path, args, capsys):
    outside = tmp_path / "outside"
    outside.mkdir()
    (copy / "videos").symlink_to(outside)
    one_sentence(capsys, main([a.format(run=copy) for a in args]), 2, "holds a symbolic link, 'videos'")
    assert not any(outside.iterdir())


def test_a_fifo_in_a_run_is_refused_before_anything_opens_it(copy, capsys):
    os = pytest.importorskip("os")
    os.mkfifo(copy / "logs" / "csv" / "pipe.csv")
    one_sentence(capsys, _resume(copy), 2, "holds a FIFO, 'logs/csv/pipe.csv'")


def test_a_linked_curve_is_refused_by_the_report(copy, tmp_path_factory, capsys):
    """The manifest was checked beside the file the link points at (or none), so a changed curve was reported."""
    elsewhere = tmp_path_factory.mktemp("elsewhere") / "eval.csv"
    shutil.move(copy / "eval.csv", elsewhere)
    (copy / "eval.csv").symlink_to(elsewhere)
    out = tmp_path_factory.mktemp("reports") / "r"
    code = main(["report", "--baseline", str(copy), "--transfer", str(copy), "--out", str(out)])
    one_sentence(capsys, code, 2, "is a symbolic link inside the run")


def test_the_report_does_not_follow_links_between_folders(copy, tmp_path, capsys):
    """Two links to ``..`` made the search for runs endless; a link is not searched."""
    (copy.parent / "up").symlink_to("..")
    (copy / "checkpoints" / "up").symlink_to("../..")
    from drltg.report.curves import find_runs

    assert find_runs(copy.parent) == [copy]


def test_resume_verifies_the_curve_it_carries_forward(copy, capsys):
    text = (copy / "eval.csv").read_text().splitlines(keepends=True)
    first = text[1].split(",")
    text[1] = ",".join([first[0], "0.999", *first[2:]])
    (copy / "eval.csv").write_text("".join(text))
    one_sentence(capsys, _resume(copy), 2, "eval.csv': it does not match its SHA-256")


@pytest.mark.parametrize("frames, shown", [(10**9, "1000000000"), ("abc", "'abc'"), (-5, "-5"), (True, "True")])
def test_a_checkpoint_counter_outside_the_run_s_budget_is_refused(copy, frames, shown, capsys):
    """A checkpoint beyond the budget made resume train forever (TorchRL reads a negative remainder as no end)."""
    import torch

    path = copy / "checkpoints" / "last.pt"
    torch.save({**torch.load(path, weights_only=True), "frames": frames}, path)
    files = manifest.read(copy)
    files["checkpoints/last.pt"] = [manifest.digest(path)]
    (copy / manifest.MANIFEST).write_text(manifest.dumps(files))
    one_sentence(capsys, _resume(copy), 2, f"its checkpoint's frames is {shown}, not a whole number from 0 to the "
                                           "budget of 256")


def test_a_manifest_digest_that_is_not_text_is_one_sentence(copy, capsys):
    files = manifest.read(copy)
    files["checkpoints/last.pt"] = 12345
    (copy / manifest.MANIFEST).write_text(manifest.dumps(files))
    one_sentence(capsys, main(["evaluate", str(copy), "--episodes", "1"]), 2,
                 "gives 'checkpoints/last.pt' digests 12345, not a list of SHA-256 strings")


def test_a_video_of_no_steps_is_refused(copy, capsys):
    one_sentence(capsys, main(["video", str(copy), "--max-steps", "-1"]), 2, "--max-steps must be at least 1")
    assert not (copy / "videos").exists()


# ----------------------------------------------------------------------------- no kill wedges a run
def _rewrite_manifest(run, change):
    files = manifest.read(run)
    change(files)
    (run / manifest.MANIFEST).write_text(manifest.dumps(files))


def test_a_kill_inside_the_first_checkpoint_write_counts_as_never_written(copy, capsys):
    """What a kill left: the manifest naming the checkpoint (written first, as before), the file itself only
    as drltg's half-written temporary. Resume starts over instead of refusing, and removes the temporary."""
    (copy / "checkpoints" / "last.pt").unlink()
    (copy / "checkpoints" / ".last.pt.k1ll3d.tmp").write_bytes(b"\x80\x02half a checkpoint")
    assert _resume(copy) == 0, capsys.readouterr().err
    assert (copy / "summary.json").is_file() and not list(copy.rglob("*.tmp"))
    assert [r["frames"] for r in rundir.read_eval_csv(copy / "eval.csv")][-1] == 256


def test_a_first_write_lands_the_file_before_the_manifest_names_it(tmp_path):
    rundir.write_tracked(tmp_path, "checkpoints/last.pt", b"one")
    assert manifest.read(tmp_path) == {"checkpoints/last.pt": [manifest.digest(b"one")]}
    rundir.write_tracked(tmp_path, "checkpoints/last.pt", b"two")
    assert manifest.read(tmp_path) == {"checkpoints/last.pt": [manifest.digest(b"two")]}


def test_a_temporary_file_of_a_killed_write_does_not_block_the_same_command(tmp_path, capsys):
    run = tmp_path / "run"
    run.mkdir()
    (run / ".config.yaml.k1ll3d.tmp").write_text("task: fourrooms/nor")  # killed inside the first config write
    assert main(train_args(run)) == 0, capsys.readouterr().err
    assert (run / "summary.json").is_file() and not list(run.glob(".*.tmp"))


def test_a_finished_run_killed_before_its_final_manifest_is_completed_on_resume(copy, capsys):
    assert _resume(copy) == 0
    _rewrite_manifest(copy, lambda files: [files.pop(k) for k in list(files) if k not in ("eval.csv", "config.yaml")])
    assert rundir.unlisted(copy)
    assert _resume(copy) == 0, capsys.readouterr().err
    assert not rundir.unlisted(copy) and manifest.read(copy)["checkpoints/last.pt"]
    assert not (copy / ".drltg.lock").exists()


def test_a_report_swap_killed_between_its_renames_loses_neither_version(tmp_path):
    """The old two-rename swap, killed after the first rename: the previous report lies aside as
    ``.report.*.old``. The next write puts it back first, then replaces it whole, and leaves nothing beside."""
    out = tmp_path / "report"
    rundir.write_directory(out, {"a.txt": "old"})
    out.rename(tmp_path / ".report.x1.old")
    (tmp_path / ".report.x1.tmp").mkdir()
    (tmp_path / ".report.x1.tmp" / "a.txt").write_text("half")
    rundir.write_directory(out, {"a.txt": "new"})
    assert (out / "a.txt").read_text() == "new" and sorted(p.name for p in tmp_path.iterdir()) == ["report"]
    rundir.write_directory(out, {"a.txt": "newer"})  # a swap in one step where the system has one
    assert (out / "a.txt").read_text() == "newer" and sorted(p.name for p in tmp_path.iterdir()) == ["report"]


# ----------------------------------------------------------------------------- bounded input, one sentence
def _report(baseline, transfer, tmp_path_factory):
    out = tmp_path_factory.mktemp("reports") / "r"
    return main(["report", "--baseline", str(baseline), "--transfer", str(transfer), "--out", str(out)])


def test_a_config_that_is_not_utf8_is_one_sentence_to_evaluate_and_report(copy, tmp_path_factory, capsys):
    (copy / "config.yaml").write_bytes(b"task: fourrooms/northeast\nalgo: \xff\n")
    _rewrite_manifest(copy, lambda files: files.update({"config.yaml": [manifest.digest(copy / "config.yaml")]}))
    one_sentence(capsys, main(["evaluate", str(copy), "--episodes", "1"]), 2, "config.yaml' is not UTF-8 text (byte")
    one_sentence(capsys, _report(copy, copy, tmp_path_factory), 2, "config.yaml' is not UTF-8 text (byte")


def test_a_cpu_index_this_machine_lacks_is_named_as_a_device(copy, capsys):
    one_sentence(capsys, main(["evaluate", str(copy), "--episodes", "1", "--device", "cpu:99"]), 2,
                 "--device is 'cpu:99', but the CPU is one device")


def test_a_log_naming_a_column_twice_is_refused(tmp_path, tmp_path_factory, capsys):
    log = tmp_path / "run" / "progress.csv"
    log.parent.mkdir()
    log.write_text("time/total_timesteps,eval/mean_reward,eval/mean_reward\n100,1.0,5.0\n200,2.0,6.0\n")
    one_sentence(capsys, _report(log, log, tmp_path_factory), 2, "names the column 'eval/mean_reward' twice")


def test_logs_too_large_to_be_learning_curves_are_refused_before_they_are_read(tmp_path, tmp_path_factory, capsys):
    import struct

    sparse = tmp_path / "big" / "eval.csv"
    sparse.parent.mkdir()
    with open(sparse, "wb") as f:  # 2 GB that take no disk: the size is what is refused
        f.write(b"frames,return_mean,return_std,episodes\n")
        f.truncate(2**31)
    one_sentence(capsys, _report(sparse, sparse, tmp_path_factory), 2, "holds 2,048 MB, more than the 256 MB")
    wide = tmp_path / "wide.csv"
    wide.write_text(",".join(f"c{i}" for i in range(20_000)) + "\n" + ",".join(["1"] * 20_000) + "\n")
    one_sentence(capsys, _report(wide, wide, tmp_path_factory), 2, "has more than 10,000 cells")
    events = tmp_path / "tb" / "events.out.tfevents.1.host"
    events.parent.mkdir()
    events.write_bytes(struct.pack("<Q", 2**40) + b"\0" * 12)
    one_sentence(capsys, _report(events.parent, events.parent, tmp_path_factory), 2,
                 "record 0 declares 1,099,511,627,776 bytes")


def test_a_fifo_among_a_user_s_logs_is_refused_not_read(tmp_path, tmp_path_factory, capsys):
    import os

    curve = tmp_path / "logs" / "scalars" / "eval" / "return_mean.csv"
    curve.parent.mkdir(parents=True)
    os.mkfifo(curve)  # a CSVLogger folder whose curve is a pipe: reading it would block
    one_sentence(capsys, _report(tmp_path / "logs", tmp_path / "logs", tmp_path_factory), 2, "is not a regular file")


def test_a_fifo_in_place_of_a_run_s_manifest_or_summary_is_refused_not_read(pendulum, tmp_path, tmp_path_factory,
                                                                          capsys):
    """Found by the hostile-directory property: reading a finished run's manifest.json as a FIFO blocked the
    report. Now the run is not counted, in one sentence."""
    import os
    import signal

    copy = tmp_path / "run"
    shutil.copytree(pendulum, copy)
    for name in ("manifest.json", "summary.json"):
        saved = (copy / name).read_bytes()
        (copy / name).unlink()
        os.mkfifo(copy / name)
        signal.alarm(30)  # a hang fails the test instead of the suite
        try:
            one_sentence(capsys, _report(pendulum, copy, tmp_path_factory), 2, "no transfer run can be counted")
        finally:
            signal.alarm(0)
        (copy / name).unlink()
        (copy / name).write_bytes(saved)
    from drltg.store import manifest as manifest_lib

    (copy / "eval.csv").unlink()
    os.mkfifo(copy / "eval.csv")
    with pytest.raises(UsageError, match="is not a regular file"):
        manifest_lib.verify(copy, "eval.csv")
