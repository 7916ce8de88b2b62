import csv
import json
import os
from pathlib import Path

import numpy as np
import pytest

from drltg.errors import UsageError
from drltg.report.curves import Curve, find_runs, read_curves, read_run

RUN_NAMES = [
    "lift_shaped_sac", "lift_soc4", "lift_sparse_sac", "liftplace_sac", "liftplace_sac_policyreuse",
    "liftplace_soc4", "liftplacebarrier_sac", "liftplacebarrier_sac_policyreuse",
]



def write_eval_csv(run_dir: Path, frames, values, task=None, success=None) -> Path:
    run_dir.mkdir(parents=True, exist_ok=True)
    lines = ["frames,return_mean,return_std,episodes,success_rate"]
    for i, (f, v) in enumerate(zip(frames, values)):
        s = "" if success is None else success[i]
        lines.append(f"{f},{v},0.0,16,{s}")
    (run_dir / "eval.csv").write_text("\n".join(lines) + "\n")
    if task is not None:
        (run_dir / "config.yaml").write_text(f"task: {task}\nseed: 0\n")
    return run_dir


def _independent_read(path: Path):
    """The evaluation rows of an SB3 progress.csv, read with the csv module."""
    with open(path, newline="") as f:
        rows = [r for r in csv.DictReader(f) if r["eval/mean_reward"] != ""]
    return (np.array([float(r["time/total_timesteps"]) for r in rows]),
            np.array([float(r["eval/mean_reward"]) for r in rows]))


@pytest.mark.parametrize("name", RUN_NAMES)
def test_every_sb3_progress_csv_is_read_as_it_is(sb3_runs, name):
    (curve,) = read_curves(sb3_runs / name)
    frames, values = _independent_read(sb3_runs / name / "progress.csv")
    assert curve.label == name and curve.task is None
    assert curve.source == sb3_runs / name / "progress.csv"
    assert len(curve) == len(frames) > 900  # training rows (empty eval cells) are skipped
    np.testing.assert_array_equal(curve.frames, frames)
    np.testing.assert_array_equal(curve.values, values)
    assert (np.diff(curve.frames) > 0).all() and np.isfinite(curve.values).all()


@pytest.mark.parametrize("name", ["liftplace_sac", "liftplace_sac_policyreuse"])
def test_tensorboard_event_files_match_progress_csv(sb3_runs, name):
    (events,) = read_curves(sb3_runs / name, format="tensorboard")
    (single,) = read_curves(next((sb3_runs / name).glob("events.out.tfevents.*")))
    (progress,) = read_curves(sb3_runs / name)
    assert events.label == single.label == name
    np.testing.assert_array_equal(events.frames, progress.frames)
    np.testing.assert_allclose(events.values, progress.values, rtol=1e-6)  # float32 in the event file
    np.testing.assert_array_equal(single.values, events.values)


def test_a_directory_of_runs_and_a_glob(sb3_runs):
    curves = read_curves(sb3_runs)
    assert [c.label for c in curves] == RUN_NAMES
    globbed = read_curves(str(sb3_runs / "liftplace*_sac"))
    assert [c.label for c in globbed] == ["liftplace_sac", "liftplacebarrier_sac"]
    both = read_curves([sb3_runs / "lift_soc4", sb3_runs / "liftplace_soc4"])
    assert [c.frames[0] for c in both] == [1999, 1999]  # the SOC logs' own three-column format


def test_drltg_run_dir_reads_eval_csv_and_task(tmp_path):
    run = write_eval_csv(tmp_path / "run", [0, 100, 250], [1.0, 2.0, 3.5], task="fourrooms/near",
                         success=[0.0, 0.5, 1.0])
    (c,) = read_curves(run)
    assert isinstance(c, Curve) and c.task == "fourrooms/near" and c.label == "run"
    np.testing.assert_array_equal(c.frames, [0, 100, 250])
    np.testing.assert_array_equal(c.values, [1.0, 2.0, 3.5])
    (s,) = read_curves(run, tag="success_rate")
    np.testing.assert_array_equal(s.values, [0.0, 0.5, 1.0])
    (f,) = read_curves(run / "eval.csv")
    assert f.task == "fourrooms/near"


def test_seed_runs_are_found_recursively_but_not_inside_a_run(tmp_path):
    for seed in (2, 0, 1):
        run = write_eval_csv(tmp_path / "exp" / "baseline" / f"seed_{seed}", [0, 10], [seed, seed + 1])
        (run / "checkpoints").mkdir()
        write_eval_csv(run / "checkpoints" / "not_a_seed", [0, 10], [9, 9])
    runs = find_runs(tmp_path / "exp")
    assert [p.name for p in runs] == ["seed_0", "seed_1", "seed_2"]
    assert [c.values[0] for c in read_curves(tmp_path / "exp" / "baseline")] == [0, 1, 2]


def _log_with_torchrl(run_dir: Path):
    from torchrl.record.loggers import CSVLogger, TensorboardLogger

    loggers = [CSVLogger("csv", log_dir=str(run_dir / "logs")),
               TensorboardLogger("tensorboard", log_dir=str(run_dir / "logs"))]
    for logger in loggers:
        for step, value in [(0, -1.0), (100, 0.5), (300, 2.0)]:
            logger.log_scalar("eval/return_mean", value, step=step)
            logger.log_scalar("train/loss", value * 2, step=step)
    loggers[1].experiment.flush()


def test_torchrl_csvlogger_and_tensorboard_logs(tmp_path):
    run = tmp_path / "run"
    _log_with_torchrl(run)
    (run / "config.yaml").write_text("task: gridrooms/far\n")
    for fmt in ("csvlogger", "tensorboard"):
        (c,) = read_curves(run, format=fmt)
        np.testing.assert_array_equal(c.frames, [0, 100, 300])
        np.testing.assert_array_equal(c.values, [-1.0, 0.5, 2.0])
        assert c.label == "run" and c.task == "gridrooms/far"  # the run owning logs/<logger>/
        (loss,) = read_curves(run, format=fmt, tag="train/loss")
        np.testing.assert_array_equal(loss.values, [-2.0, 1.0, 4.0])
    (f,) = read_curves(run / "logs" / "csv" / "scalars" / "eval" / "return_mean.csv")
    np.testing.assert_array_equal(f.values, [-1.0, 0.5, 2.0])
    (d,) = read_curves(run / "logs" / "csv")  # auto-detected by its scalars/ folder
    np.testing.assert_array_equal(d.frames, [0, 100, 300])


def test_sb3_monitor_files_merge_by_wall_time(tmp_path):
    run = tmp_path / "mon"
    run.mkdir()
    head = '#{"t_start": 1.0, "env_id": "Lift"}\nr,l,t\n'
    (run / "0.monitor.csv").write_text(head + "1.0,100,0.5\n3.0,100,2.5\n")
    (run / "1.monitor.csv").write_text(head + "2.0,50,1.5\n")
    (c,) = read_curves(run)
    np.testing.assert_array_equal(c.frames, [100, 150, 250])
    np.testing.assert_array_equal(c.values, [1.0, 2.0, 3.0])
    (one,) = read_curves(run / "1.monitor.csv")
    np.testing.assert_array_equal(one.frames, [50])


def test_monitor_files_of_several_runs_in_one_folder_are_refused_or_read_as_runs(tmp_path):
    """Three seeds' monitor files in one folder were merged into one run, silently: now the folder is one
    sentence, and its files given as a pattern are three runs."""
    side = tmp_path / "baseline"
    side.mkdir()
    head = '#{"t_start": 1.0, "env_id": "Lift"}\nr,l,t\n'
    for seed in range(3):
        (side / f"seed{seed}.monitor.csv").write_text(head + f"{seed}.0,100,0.5\n")
    with pytest.raises(UsageError) as err:
        read_curves(side)
    assert str(err.value).startswith(f"'{side}' holds 3 monitor files (seed0.monitor.csv, seed1.monitor.csv, "
                                     "seed2.monitor.csv) not named as one run's environments")
    curves = read_curves(str(side / "*monitor.csv"))
    assert [c.values.tolist() for c in curves] == [[0.0], [1.0], [2.0]]


# ------------------------------------------------------------------------------------- bad inputs
def _bad(tmp_path, text: str, name: str = "eval.csv") -> Path:
    run = tmp_path / "bad"
    run.mkdir(exist_ok=True)
    (run / name).write_text(text)
    return run


@pytest.mark.parametrize("text, message", [
    ("", "is empty"),
    ("\n\n", "is empty"),
    ("frames,return_mean\n", "header but no rows"),
    ("frames,return_mean\n0,1.0\n10,nan\n", "non-finite value nan"),
    ("frames,return_mean\n0,1.0\n10,inf\n", "non-finite value inf"),
    ("frames,return_mean\n0,1.0\n10,\n", "line 3: column 'return_mean' is empty"),
    ("frames,return_mean\n0,1.0\n10,abc\n", "holds 'abc', not a number"),
    ("frames,return_mean\n0,1.0\n20,2.0\n10,3.0\n", "frame 10 at line 4 comes after frame 20"),
    ("frames,return_mean\n0,1.0\n10,2.0\n10,3.0\n", "frame 10 at line 4 appears twice"),
    ("frames,reward\n0,1.0\n", "has no column 'return_mean'"),
    ("frames,return_mean\n0,1.0,5\n", "line 2 has 3 cells"),
    ("frames,return_mean\n0,1.0\n10\n", "line 3 has 1 cells, but the header has 2"),
    ("frames,return_mean\n\n0,1.0\n   \n10,abc\n", "line 5: column 'return_mean' holds 'abc'"),  # blank lines count
    ("frames,return_mean\n0,1.0\n20,2.0\n30,2.0,1\n", "line 4 has 3 cells, but the header has 2"),
])
def test_bad_eval_csv(tmp_path, text, message):
    run = _bad(tmp_path, text)
    with pytest.raises(UsageError, match=message) as err:
        read_curves(run)
    assert str(run / "eval.csv") in str(err.value)


@pytest.mark.parametrize("text, message", [
    ("time/total_timesteps,eval/mean_reward\n500,\n1000,\n", "no values in column 'eval/mean_reward'"),
    ("time/total_timesteps,eval/mean_reward\n500,1.0\n1000,nan\n", "non-finite"),
    ("time/total_timesteps,eval/mean_reward\n500,1.0\n,2.0\n", "column 'time/total_timesteps' is empty"),
    ("time/total_timesteps,rollout/ep_rew_mean\n500,1.0\n", "no column 'eval/mean_reward'"),
])
def test_bad_progress_csv(tmp_path, text, message):
    run = _bad(tmp_path, text, "progress.csv")
    with pytest.raises(UsageError, match=message):
        read_curves(run)


def test_missing_tag_column_and_tensorboard_tag(sb3_runs, tmp_path):
    with pytest.raises(UsageError, match="has no column 'eval/success'"):
        read_curves(sb3_runs / "lift_soc4", tag="eval/success")
    with pytest.raises(UsageError, match="has no scalar tag 'eval/success'.*eval/mean_reward"):
        read_curves(sb3_runs / "liftplace_sac", format="tensorboard", tag="eval/success")
    run = tmp_path / "run"
    _log_with_torchrl(run)
    with pytest.raises(UsageError, match="has no scalar 'eval/success'"):
        read_curves(run, format="csvlogger", tag="eval/success")


def test_no_runs_missing_paths_and_unknown_formats(tmp_path):
    (tmp_path / "empty" / "sub").mkdir(parents=True)
    with pytest.raises(UsageError, match="holds no runs"):
        read_curves(tmp_path / "empty")
    with pytest.raises(UsageError, match="does not exist"):
        read_curves(tmp_path / "nowhere")
    os.mkfifo(tmp_path / "pipe")  # exists, but is no file to read whole and no folder to search
    with pytest.raises(UsageError, match="'.*pipe' is neither a log file nor a directory of runs"):
        read_curves(tmp_path / "pipe")
    with pytest.raises(UsageError, match="matches no file"):
        read_curves(str(tmp_path / "run_*"))
    with pytest.raises(UsageError, match="unknown log format"):
        read_curves(tmp_path, format="wandb")
    (tmp_path / "notes.txt").write_text("hello")
    with pytest.raises(UsageError, match="cannot tell the log format"):
        read_curves(tmp_path / "notes.txt")
    with pytest.raises(UsageError, match="holds no run"):
        read_run(tmp_path / "empty")


def test_bad_csvlogger_and_monitor_files(tmp_path):
    d = tmp_path / "scalars"
    d.mkdir()
    (d / "r.csv").write_text("0,1.0\n10,2.0,3\n")
    with pytest.raises(UsageError, match="line 2 is not a 'step,value' pair"):
        read_curves(tmp_path, format="csvlogger", tag="r")
    (d / "r.csv").write_text("0,1.0\n0,2.0\n")
    with pytest.raises(UsageError, match="appears twice"):
        read_curves(tmp_path, tag="r")
    m = tmp_path / "m"
    m.mkdir()
    (m / "monitor.csv").write_text('#{"t_start": 1}\nr,l,t\n')
    with pytest.raises(UsageError, match="header but no rows"):
        read_curves(m)


def test_config_without_task_and_broken_yaml(tmp_path):
    run = write_eval_csv(tmp_path / "run", [0, 1], [0, 1])
    (run / "config.yaml").write_text(json.dumps({"seed": 1}))
    assert read_curves(run)[0].task is None
    (run / "config.yaml").write_text("task: [unclosed\n")
    with pytest.raises(UsageError, match="config.yaml' is not valid YAML"):
        read_curves(run)


def test_byte_order_mark_and_quoted_headers_are_read(tmp_path):
    run = tmp_path / "bom"
    run.mkdir()
    (run / "eval.csv").write_bytes('\ufeff"frames","return_mean"\n0,"1.5"\n10,2.5\n'.encode("utf-8"))
    (c,) = read_curves(run)
    np.testing.assert_array_equal(c.frames, [0, 10])
    np.testing.assert_array_equal(c.values, [1.5, 2.5])
    sb3 = tmp_path / "sb3"
    sb3.mkdir()
    (sb3 / "progress.csv").write_bytes(
        '\ufeff"time/total_timesteps","eval/mean_reward"\n500,\n1000,"-3.0"\n'.encode("utf-8"))
    (p,) = read_curves(sb3)
    np.testing.assert_array_equal(p.frames, [1000])
    np.testing.assert_array_equal(p.values, [-3.0])


def test_drltg_runs_carry_their_config(tmp_path):
    run = write_eval_csv(tmp_path / "run", [0, 1], [0, 1], task="fourrooms/near")
    (c,) = read_curves(run)
    assert c.config == {"task": "fourrooms/near", "seed": 0}
    (f,) = read_curves(run / "eval.csv")
    assert f.config == c.config


def test_quoted_cells_and_duplicate_columns(tmp_path):
    run = tmp_path / "q"
    run.mkdir()
    (run / "eval.csv").write_text('frames,note,return_mean\n0,"a, b",1.25\n10," x ",2.5\n')
    (c,) = read_curves(run)
    np.testing.assert_array_equal(c.values, [1.25, 2.5])  # a quoted comma is one cell
    (run / "eval.csv").write_text('frames,note,return_mean,return_mean\n0,"a, b",1.25,9\n10," x ",2.5,9\n')
    with pytest.raises(UsageError, match="names the column 'return_mean' twice in its header"):
        read_curves(run)  # which of the two was meant is a guess
    (run / "eval.csv").write_text("frames,return_mean\n0,0.1\n10,1e-7\n20,-3.000000000000001\n")
    np.testing.assert_array_equal(read_curves(run)[0].values, [0.1, 1e-7, -3.000000000000001])  # exact digits


def test_a_rate_column_added_on_resume_is_empty_in_earlier_rows(tmp_path):
    from drltg.store import rundir

    run = tmp_path / "run"
    run.mkdir()
    rows = [
        {"frames": 0, "return_mean": 0.0, "return_std": 0.0, "episodes": 2, "success_rate": 0.0},
        {"frames": 10, "return_mean": 2.0, "return_std": 0.0, "episodes": 2, "success_rate": 0.5, "lifted_rate": 1.0},
    ]
    rundir.write_eval_csv(run / "eval.csv", rows)
    assert (run / "eval.csv").read_text().splitlines() == [
        "frames,return_mean,return_std,episodes,success_rate,lifted_rate", "0,0.0,0.0,2,0.0,", "10,2.0,0.0,2,0.5,1.0",
    ]
    assert rundir.read_eval_csv(run / "eval.csv") == rows
    assert read_run(run).values.tolist() == [0.0, 2.0]
    with pytest.raises(UsageError, match="lifted_rate"):
        read_run(run, tag="lifted_rate")
