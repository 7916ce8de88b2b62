"""A grown experiment writes its new runs, logs, progress files and report inside its own folder: a link or
an odd file planted where one of them goes is refused in one sentence before any work, and nothing outside
the folder changes."""
import os
import shutil
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from drltg.cli import main
from drltg.errors import UsageError
from drltg.regular import append_regular
from tests.test_fuzz import EXAMPLES, _plant

TINY = ["-o", "network.hidden=[16,16]", "-o", "collector.num_envs=4", "-o", "collector.frames_per_batch=16",
        "-o", "collector.init_random_frames=32", "-o", "optim.updates_per_batch=1", "-o", "buffer.batch_size=16",
        "-o", "eval.every=16", "-o", "eval.episodes=2", "-o", "log.tensorboard=false"]


def command(out, seeds):
    return ["experiment", "gridrooms/northeast", "--method", "reward-shaping", "--frames", "64", "--out", str(out),
            "--threshold", "0", "--no-progress", "--seeds", str(seeds), *TINY]


@pytest.fixture(scope="module")
def grown_once(tmp_path_factory):
    out = tmp_path_factory.mktemp("grown") / "E"
    assert main(command(out, 1)) == 0
    return out


@pytest.fixture
def experiment(grown_once, tmp_path):
    out = tmp_path / "E"
    shutil.copytree(grown_once, out, symlinks=True)
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "kept.log").write_text("a file of the user's\n")
    return out, outside


def error(capsys):
    """What the command said beyond the plan's warnings (printed once per process, so not every time)."""
    return "\n".join(line for line in capsys.readouterr().err.strip().splitlines() if not line.startswith("warning: "))


def snapshot(folder):
    return {p: (p.read_bytes() if p.is_file() else None) for p in folder.rglob("*")}


def plant_log_link(out, outside):
    (out / "logs" / "baseline" / "seed-100.log").symlink_to(outside / "kept.log")


def plant_logs_link(out, outside):
    shutil.move(out / "logs", outside / "logs")
    (out / "logs").symlink_to(outside / "logs")


def plant_report_link(out, outside):
    shutil.move(out / "report", outside / "report")
    (out / "report").symlink_to(outside / "report")


def plant_fifo(out, outside):
    os.mkfifo(out / "logs" / "baseline" / "seed-100.log")


def plant_dangling_run(out, outside):
    shutil.rmtree(out / "baseline" / "seed-0")
    (out / "baseline" / "seed-0").symlink_to(outside / "gone")


def plant_frames_folder(out, outside):
    (out / "logs" / "transfer" / "seed-100.log.frames").mkdir()


@pytest.mark.parametrize("plant, planted, words", [
    (plant_log_link, "logs/baseline/seed-100.log", "is a link"),
    (plant_logs_link, "logs", "is a link"),
    (plant_report_link, "report", "is a link"),
    (plant_fifo, "logs/baseline/seed-100.log", "is a FIFO where drltg keeps a file"),
    (plant_frames_folder, "logs/transfer/seed-100.log.frames", "is a folder where drltg keeps a file"),
    (plant_dangling_run, "baseline/seed-0", "is a link"),
], ids=["log link", "logs link", "report link", "fifo log", "frames folder", "dangling run link"])
def test_a_planted_link_or_odd_file_stops_the_grown_experiment_before_any_work(experiment, capsys, plant, planted,
                                                                               words):
    out, outside = experiment
    plant(out, outside)
    before_outside, before = snapshot(outside), snapshot(out)
    assert main(command(out, 2)) == 2
    err = error(capsys)
    assert err.startswith("drltg experiment: error: ") and "\n" not in err and f"'{out / planted}' {words}" in err, err
    assert snapshot(outside) == before_outside
    assert snapshot(out) == before  # nothing trained, no log line, no report


def test_the_same_experiment_grows_once_nothing_is_planted(experiment):
    out, outside = experiment
    assert main(command(out, 2)) == 0
    assert sorted(p.name for p in (out / "baseline").iterdir()) == ["seed-0", "seed-100"]
    assert (out / "logs" / "baseline" / "seed-100.log").is_file()


def test_append_regular_appends_to_a_file_and_refuses_a_link_and_a_fifo(tmp_path):
    path = tmp_path / "run.log"
    for line in ("one", "two"):
        with append_regular(path) as log:
            print(line, file=log)
    assert path.read_text() == "one\ntwo\n"
    (tmp_path / "link.log").symlink_to(path)
    with pytest.raises(UsageError, match=r"\(it is a link, and drltg appends to no file through one\); move it"):
        append_regular(tmp_path / "link.log")
    os.mkfifo(tmp_path / "fifo.log")
    with pytest.raises(UsageError, match=r"\(it is a FIFO or a socket; drltg appends to regular files only\)"):
        append_regular(tmp_path / "fifo.log")
    assert path.read_text() == "one\ntwo\n"


PLACES = ["logs", "logs/baseline", "logs/baseline/seed-100.log", "logs/transfer/seed-100.log.frames", "report",
          "baseline", "baseline/seed-100", "transfer/seed-100"]


@settings(max_examples=EXAMPLES or 16, derandomize=not EXAMPLES, database=None, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(shape=st.sampled_from(["link to a file outside", "link to a folder outside", "link to ..", "link to /",
                              "fifo", "socket"]), place=st.sampled_from(PLACES))
def test_any_link_or_special_file_where_a_grown_experiment_writes_is_one_sentence(grown_once, shape, place, capsys):
    """The property over the places a grown experiment writes and the shapes a hostile folder plants:
    always exit 2 with one sentence, before any work, inside or outside."""
    import tempfile

    root = Path(tempfile.mkdtemp(prefix="drltg-grown-"))
    try:
        out, outside = root / "E", root / "outside"
        shutil.copytree(grown_once, out, symlinks=True)
        outside.mkdir()
        (outside / "bystander.csv").write_text("frames,return_mean\n0,1.0\n")
        _plant(out / place, shape, outside)
        before_outside, before = snapshot(outside), snapshot(out)
        assert main(command(out, 2)) == 2
        err = error(capsys)
        assert "\n" not in err and "Traceback" not in err and str(out / place) in err, err
        assert snapshot(outside) == before_outside and snapshot(out) == before
    finally:
        shutil.rmtree(root, ignore_errors=True)
