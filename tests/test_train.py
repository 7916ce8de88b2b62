"""The training loop and `drltg train`: run directory contract, determinism, resume, CLI errors."""
import csv
import json
import os
import signal

import pytest
import torch
import yaml

import drltg.training.loop as train_mod
from drltg import config as config_lib
from drltg.cli import main
from drltg.training.loop import read_eval_csv, train

TINY = [
    "network.hidden=[16,16]",
    "collector.num_envs=4",
    "collector.frames_per_batch=16",
    "collector.init_random_frames=256",
    "optim.updates_per_batch=1",
    "buffer.batch_size=32",
    "eval.every=512",
    "eval.episodes=4",
    "checkpoint.every=512",
    "log.every=256",
    "log.tensorboard=false",
]


def tiny_cfg(**kw):
    return config_lib.resolve({}, TINY, task="fourrooms/northeast", frames=1024, seed=3, **kw)


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    return train(tiny_cfg(), tmp_path_factory.mktemp("runs") / "a", progress=False)


def test_run_directory_contract(tiny_run):
    cfg = yaml.safe_load((tiny_run / "config.yaml").read_text())
    assert cfg == tiny_cfg().model_dump()
    with open(tiny_run / "eval.csv") as f:
        header = next(csv.reader(f))
    assert header == ["frames", "return_mean", "return_std", "episodes", "success_rate"]
    rows = read_eval_csv(tiny_run / "eval.csv")
    assert [r["frames"] for r in rows] == [0, 512, 1024]  # frame 0 is evaluated before any update
    assert all(r["episodes"] == 4 and 0.0 <= r["success_rate"] <= 1.0 for r in rows)
    assert (tiny_run / "checkpoints" / "last.pt").is_file()
    assert (tiny_run / "summary.json").is_file()
    assert (tiny_run / "logs" / "csv" / "scalars").is_dir()


def test_the_summary_splits_the_wall_time_by_phase(tmp_path, monkeypatch):
    """A known delay in each evaluation and one in each batch's handling land in their own phases: the two
    evaluations after frame 0 (at 512 and 1024) take 0.2 s more each, the 64 batches 0.02 s more each."""
    import time

    evaluate, stats = train_mod.AgentLearner.evaluate, train_mod._episode_stats
    calls = {"evaluate": 0, "stats": 0}

    def slow_evaluate(self, *args, **kwargs):
        calls["evaluate"] += 1
        time.sleep(0.2)
        return evaluate(self, *args, **kwargs)

    def slow_stats(data, seed_stats):
        calls["stats"] += 1
        time.sleep(0.02)
        return stats(data, seed_stats)

    monkeypatch.setattr(train_mod.AgentLearner, "evaluate", slow_evaluate)
    monkeypatch.setattr(train_mod, "_episode_stats", slow_stats)
    summary = json.loads((train(tiny_cfg(), tmp_path / "r", progress=False) / "summary.json").read_text())
    split = summary["wall_time_split_s"]
    assert set(split) == {"update", "evaluate", "checkpoint", "collect_and_rest"}
    assert calls == {"evaluate": 3, "stats": 64}  # frame 0's evaluation comes before the timed window
    assert split["evaluate"] >= 2 * 0.2 - 0.01 and split["collect_and_rest"] >= 64 * 0.02 - 0.01
    assert split["update"] > 0 and split["checkpoint"] > 0  # 2 saves
    assert summary["timed_frames"] == summary["frames"]  # one start: the wall time covers every frame


def test_a_run_of_the_default_evaluation_schedule_gives_the_report_20_evaluations(tmp_path):
    """eval.every's default, auto, evaluates a 2,000-frame run every 100 frames (at the first batch of 16 at or
    past each multiple): 21 evaluations with frame 0, 6 of them in the budget's last quarter."""
    cfg = config_lib.resolve({}, [o for o in TINY if not o.startswith("eval.every")], task="fourrooms/northeast",
                             frames=2000, seed=3)
    run = train(cfg, tmp_path / "run", progress=False)
    frames = [r["frames"] for r in read_eval_csv(run / "eval.csv")]
    assert frames == [0, *(-(-f // 16) * 16 for f in range(100, 2000, 100)), 2000]
    assert len(frames) == 21 and sum(f >= 1500 for f in frames) == 6
    assert yaml.safe_load((run / "config.yaml").read_text())["eval"]["every"] == "auto"


def test_same_seed_same_curve(tiny_run, tmp_path):
    again = train(tiny_cfg(), tmp_path / "b", progress=False)
    assert (again / "eval.csv").read_text() == (tiny_run / "eval.csv").read_text()


def test_resume_after_interruption(tiny_run, tmp_path, monkeypatch):
    real = train_mod._episode_stats
    calls = {"n": 0}

    def crash_after_first_checkpoint(data, stats):
        calls["n"] += 1
        if (tmp_path / "c" / "checkpoints" / "last.pt").exists() and calls["n"] > 40:
            raise KeyboardInterrupt
        return real(data, stats)

    monkeypatch.setattr(train_mod, "_episode_stats", crash_after_first_checkpoint)
    with pytest.raises(KeyboardInterrupt):
        train(tiny_cfg(), tmp_path / "c", progress=False)
    assert not (tmp_path / "c" / "summary.json").exists()
    monkeypatch.setattr(train_mod, "_episode_stats", real)
    run = train(tiny_cfg(), tmp_path / "c", resume=True, progress=False)
    rows = read_eval_csv(run / "eval.csv")
    ref = read_eval_csv(tiny_run / "eval.csv")
    assert [r["frames"] for r in rows] == [r["frames"] for r in ref]
    assert rows[:2] == ref[:2]  # identical up to the checkpoint at 512 frames
    assert (run / "summary.json").is_file()


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_a_stopped_run_saves_a_checkpoint_at_the_frame_it_reached(signum, tiny_run, tmp_path, monkeypatch):
    """Ctrl-C or SIGTERM at frame 640 (checkpoints every 512): the run saves one at 640 before it stops, so
    the resumed run trains the 384 frames left; its curve is the uninterrupted one up to the signal."""
    real, calls = train_mod._episode_stats, {"n": 0}

    def signal_at_frame_640(data, stats):
        calls["n"] += 1
        if calls["n"] == 640 // 16:
            os.kill(os.getpid(), signum)  # held by the loop until this batch is stored and learned from
        return real(data, stats)

    monkeypatch.setattr(train_mod, "_episode_stats", signal_at_frame_640)
    previous = signal.signal(signal.SIGTERM, _exit_like_the_cli)
    try:
        with pytest.raises((KeyboardInterrupt, SystemExit)):
            train(tiny_cfg(), tmp_path / "c", progress=False)
    finally:
        signal.signal(signal.SIGTERM, previous)
    checkpoint = torch.load(tmp_path / "c" / "checkpoints" / "last.pt", weights_only=True)
    assert checkpoint["frames"] == 640
    frames_trained = []
    monkeypatch.setattr(train_mod, "_episode_stats", lambda data, stats: (frames_trained.append(data.numel()),
                                                                          real(data, stats)))
    run = train(tiny_cfg(), tmp_path / "c", resume=True, progress=False)
    assert sum(frames_trained) == 1024 - 640
    summary = json.loads((run / "summary.json").read_text())
    assert summary["frames"] == 1024 and summary["timed_frames"] == 1024 - 640  # the wall time is this start's
    # wall_time_s is rounded to 0.01 s (a short start's rate moves by more than 2% within that) and the
    # rate to 0.1: the rate lies between the timed frames over the two ends of the wall time's rounding
    wall, rate = summary["wall_time_s"], summary["frames_per_s"]
    assert summary["timed_frames"] / (wall + 0.005) - 0.05 <= rate <= summary["timed_frames"] / (wall - 0.005) + 0.05
    rows = read_eval_csv(run / "eval.csv")
    assert [r["frames"] for r in rows] == [0, 512, 1024]
    assert rows[:2] == read_eval_csv(tiny_run / "eval.csv")[:2]


@pytest.mark.parametrize("stop_in_evaluation", [2, 3])
def test_a_run_stopped_inside_an_evaluation_saves_a_checkpoint_and_evaluates_first_on_resume(
        stop_in_evaluation, tiny_run, tmp_path, monkeypatch):
    """Ctrl-C inside the evaluation at frame 512 or the final one at 1024 (checkpoints every 256): the run
    saves a checkpoint at that frame; the resume makes that evaluation, then trains only the frames left."""
    real_evaluate, real_stats, calls = train_mod.evaluate, train_mod._episode_stats, {"n": 0}

    def interrupt_evaluation(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] == stop_in_evaluation:
            os.kill(os.getpid(), signal.SIGINT)  # held until the evaluation's first step checks for it
        return real_evaluate(*args, **kwargs)

    monkeypatch.setattr(train_mod, "evaluate", interrupt_evaluation)
    cfg = config_lib.resolve({}, TINY + ["checkpoint.every=256"], task="fourrooms/northeast", frames=1024, seed=3)
    with pytest.raises(KeyboardInterrupt):
        train(cfg, tmp_path / "c", progress=False)
    stopped_at = 512 * (stop_in_evaluation - 1)
    checkpoint = torch.load(tmp_path / "c" / "checkpoints" / "last.pt", weights_only=True)
    assert checkpoint["frames"] == stopped_at
    assert [r["frames"] for r in read_eval_csv(tmp_path / "c" / "eval.csv")] == [0, 512][:stop_in_evaluation - 1]
    frames_trained = []
    monkeypatch.setattr(train_mod, "_episode_stats", lambda data, stats: (frames_trained.append(data.numel()),
                                                                          real_stats(data, stats)))
    run = train(cfg, tmp_path / "c", resume=True, progress=False)
    assert sum(frames_trained) == 1024 - stopped_at
    rows = read_eval_csv(run / "eval.csv")
    assert [r["frames"] for r in rows] == [0, 512, 1024]
    assert rows[0] == read_eval_csv(tiny_run / "eval.csv")[0]
    assert (run / "summary.json").is_file()


def _exit_like_the_cli(signum, frame):
    raise SystemExit(128 + signum)


def _sigint_at_frame(frame, monkeypatch):
    """SIGINT to this process once the run has collected ``frame`` frames (16 a batch); the batch count."""
    real, calls = train_mod._episode_stats, {"n": 0}

    def interrupt(data, stats):
        calls["n"] += 1
        if calls["n"] == frame // 16:
            os.kill(os.getpid(), signal.SIGINT)
        return real(data, stats)

    monkeypatch.setattr(train_mod, "_episode_stats", interrupt)
    return calls


def test_a_run_stopped_before_its_first_checkpoint_is_removed(tmp_path, monkeypatch):
    _sigint_at_frame(320, monkeypatch)
    with pytest.raises(KeyboardInterrupt):
        train(tiny_cfg(), tmp_path / "c", progress=False)
    assert not (tmp_path / "c").exists()  # a failed start: the same command can run again


def test_a_run_started_with_sigint_ignored_keeps_ignoring_it(tmp_path, monkeypatch):
    """A run started in the background (``nohup``, ``&`` in a script) inherits SIGINT ignored: a SIGINT at
    frame 640 then neither stops it nor makes it save a checkpoint there (checkpoints every 512), and the
    disposition is the same after the run."""
    from drltg.store.rundir import RunWriter

    calls = _sigint_at_frame(640, monkeypatch)
    saves, real_checkpoint = [], RunWriter.checkpoint

    def checkpoint(self, state, frames, *args, last=True, **kwargs):
        if last:  # frame 0's call writes the first best networks alone
            saves.append(frames)
        return real_checkpoint(self, state, frames, *args, last=last, **kwargs)

    monkeypatch.setattr(RunWriter, "checkpoint", checkpoint)
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        run = train(tiny_cfg(), tmp_path / "c", progress=False)
        assert signal.getsignal(signal.SIGINT) == signal.SIG_IGN
    finally:
        signal.signal(signal.SIGINT, previous)
    assert (run / "summary.json").is_file() and calls["n"] > 640 // 16
    assert sorted(set(saves)) == [512, 1024]


def _cli(args, capsys):
    code = main(args)
    return code, capsys.readouterr().err


@pytest.mark.parametrize(
    "args, message",
    [
        (["train", "fourrooms/nowhere"], "unknown task 'fourrooms/nowhere'"),
        (["train", "fourrooms/northeast", "--algo", "ppo"], "unknown algorithm 'ppo'"),
        (["train", "fourrooms/northeast", "-o", "optim.lrr=1"], "did you mean 'optim.lr'"),
        (["train", "fourrooms/northeast", "-o", "optim.lr"], "must look like KEY=VALUE"),
        (["train", "fourrooms/northeast", "-o", "eval.episodes=many"], "must be an integer"),
        (["train", "fourrooms/northeast", "--config", "missing.yaml"], "does not exist"),
    ],
)
def test_cli_bad_input_is_one_sentence_and_exit_2(args, message, capsys, tmp_path):
    run_dir = tmp_path / "run"
    code, err = _cli(args + ["--run-dir", str(run_dir)], capsys)
    assert code == 2
    assert message in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1
    assert not run_dir.exists()  # nothing written


def test_cli_refuses_existing_run_dir_and_changed_resume(tiny_run, capsys):
    before = (tiny_run / "eval.csv").read_text()
    code, err = _cli(["train", "fourrooms/northeast", "--run-dir", str(tiny_run)], capsys)
    assert code == 2 and "already exists; pass --resume" in err
    code, err = _cli(["train", "--resume", "--run-dir", str(tiny_run), "--seed", "99"], capsys)
    assert code == 2 and "differs from the saved one in seed" in err
    assert (tiny_run / "eval.csv").read_text() == before


def test_cli_unknown_subcommand_option(capsys):
    assert main(["train", "fourrooms/northeast", "--no-such-option"]) == 2  # returned, as every refusal is
    err = capsys.readouterr().err
    assert err == "drltg: error: unrecognized arguments: --no-such-option\n", err


@pytest.mark.parametrize("argv, err", [
    (["train", "fourrooms/northeast", "--frames", "-5"], "drltg train: error: argument --frames: '-5' is not a whole"),
    (["experiment", "fourrooms-near"], "drltg experiment: error: the following arguments are required: --out"),
    (["experiment", "fourrooms-near", "--out", "never-written"],  # --method may come from --config FILE
     "drltg experiment: error: name --method, --frames on the command line or in --config FILE."),
])
def test_cli_a_refused_option_names_the_command_that_refused_it(capsys, argv, err):
    assert main(argv) == 2
    printed = capsys.readouterr().err
    assert printed.startswith(err) and printed.count("\n") == 1, printed


def _buffer(capacity):
    from torchrl.data import LazyTensorStorage, ReplayBuffer

    return ReplayBuffer(storage=LazyTensorStorage(capacity), batch_size=2)


def _rows(start, n):
    import torch
    from tensordict import TensorDict

    count = torch.arange(start, start + n, dtype=torch.float32)
    return TensorDict({"observation": count[:, None].expand(n, 3), "next": {"reward": -count[:, None]}}, [n])


@pytest.mark.parametrize("written", [7, 10, 13])  # part filled, exactly full, wrapped around
def test_a_saved_buffer_holds_its_written_rows_and_resumes_row_for_row(written, tmp_path):
    """The checkpoint's buffer keeps len(buffer) rows, not the capacity; loaded back, it is the same buffer:
    the same rows, the same capacity and cursor, so the next writes land where they would have."""
    import torch

    from drltg.training.replay import buffer_state, load_buffer_state

    saved = _buffer(10)
    saved.extend(_rows(0, written))
    torch.save(buffer_state(saved), tmp_path / "buffer.pt")
    state = torch.load(tmp_path / "buffer.pt", weights_only=True)
    assert state["_storage"]["_storage"]["observation"].shape[0] == min(written, 10)
    resumed = _buffer(10)
    load_buffer_state(resumed, state)
    for buffer in (saved, resumed):
        buffer.extend(_rows(100, 5))
    assert len(resumed) == len(saved) == min(written + 5, 10)
    assert torch.equal(resumed.storage[:10]["observation"], saved.storage[:10]["observation"])
    assert resumed.writer.state_dict() == saved.writer.state_dict()


def test_a_checkpoint_that_holds_the_whole_storage_still_loads(tmp_path):
    import torch

    from drltg.training.replay import load_buffer_state

    saved = _buffer(10)
    saved.extend(_rows(0, 4))
    resumed = _buffer(10)
    load_buffer_state(resumed, saved.state_dict())  # TorchRL's own form: all 10 rows, 4 of them written
    assert len(resumed) == 4
    assert torch.equal(resumed.storage[:4]["observation"], saved.storage[:4]["observation"])


def test_a_runs_checkpoint_keeps_the_frames_it_stored_of_a_larger_buffer(tiny_run):
    import torch

    from drltg.store.rundir import load_checkpoint

    buffer = load_checkpoint(tiny_run)["buffer"]
    assert tiny_cfg().buffer.size > 1024
    assert buffer["_storage"]["_len"] == 1024
    tensors = [v for v in buffer["_storage"]["_storage"].values() if isinstance(v, torch.Tensor)]
    assert tensors and all(v.shape[0] == 1024 for v in tensors)
