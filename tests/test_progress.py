"""Progress counted in frames: a plain line every half minute where no bar is drawn, fed by the workers'
frame reports, not by evaluations."""
import io

import pytest

from drltg import config as config_lib
from drltg.experiments import executor
from drltg.experiments.executor import Run, execute, frames_done, frames_file
from drltg.training import progress as progress_lib
from drltg.training.progress import Progress, duration
from tests.test_faults import TINY


class Clock:
    def __init__(self):
        self.now = 1000.0

    def __call__(self):
        return self.now


def test_a_plain_line_every_half_minute_with_rate_and_time_left(monkeypatch):
    clock = Clock()
    monkeypatch.setattr(progress_lib.time, "monotonic", clock)
    out = io.StringIO()  # no terminal: no bar, plain lines
    bar = Progress(1000, desc="experiment", file=out)
    bar.set_note("runs 0/3 done")
    clock.now += 300  # start-up: builds, a transfer's pretraining; no frame yet
    bar.refresh()
    assert out.getvalue() == "experiment: 0 of 1,000 frames (0%); runs 0/3 done\n"  # no rate: no time left
    clock.now += 10
    bar.update(100)  # the first count: the clock of the rate starts here
    clock.now += 30
    bar.update(150)  # 150 frames in the 30 s since: 5 frames/s, 750 left take 150 s
    assert out.getvalue().splitlines()[1] == ("experiment: 250 of 1,000 frames (25%), 5 frames/s, about 2 min left; "
                                              "runs 0/3 done")
    clock.now += 29
    bar.refresh()
    assert out.getvalue().count("\n") == 2
    clock.now += 1
    bar.refresh()
    assert out.getvalue().count("\n") == 3
    bar.close()


def test_durations_read_as_a_person_says_them():
    assert [duration(s) for s in (42, 420, 9000)] == ["42 s", "7 min", "2.5 h"]


def test_no_lines_and_no_bar_when_progress_is_off(monkeypatch):
    clock = Clock()
    monkeypatch.setattr(progress_lib.time, "monotonic", clock)
    out = io.StringIO()
    bar = Progress(100, file=out, enabled=False)
    clock.now += 100
    bar.update(50)
    bar.close()
    assert out.getvalue() == ""


def test_a_worker_reports_the_frames_its_runs_reached_before_any_evaluation(tmp_path):
    """``run_group`` in this process, as a worker runs it: the report beside each log holds the last
    frames reached, which :func:`frames_done` reads although eval.csv has only frame 0 and the end."""
    cfg = config_lib.resolve(None, [*TINY, "eval.every=100000", "log.every=100000"], task="fourrooms/northeast",
                             frames=96)
    logs = [tmp_path / "logs" / "seed-0.log"]
    assert executor.run_group([cfg], [str(tmp_path / "run")], [str(logs[0])]) == [("done", "")]
    assert 0 < int(frames_file(logs[0]).read_text()) <= 96  # the first batch's frames at least
    run = Run("baseline", config_lib.updated(cfg, {"frames": 200}), tmp_path / "run", logs[0])
    frames_file(logs[0]).write_text("150\n")  # a run still training, past its last evaluation (frame 96)
    assert frames_done(run) == 150
    frames_file(logs[0]).write_text("half")  # torn or foreign: the evaluations count
    assert frames_done(run) == 96


class SimulatedBackend:
    """A backend whose one run reports 25 frames per poll, then finishes: what a worker does."""

    capacity = 1

    def __init__(self, clock):
        self.clock, self.polls = clock, 0

    def submit(self, run):
        self.run = run
        return "handle"

    def wait(self, handles, poll):
        self.polls += 1
        self.clock.now += 31  # half a minute per poll: each poll prints a line
        if self.polls < 4:
            frames_file(self.run.log).write_text(f"{25 * self.polls}\n")
            return []
        return [("handle", ("done", ""))]


def test_an_experiment_s_progress_moves_with_the_reported_frames(tmp_path, monkeypatch):
    clock = Clock()
    monkeypatch.setattr(progress_lib.time, "monotonic", clock)
    cfg = config_lib.resolve(None, list(TINY), task="fourrooms/northeast", frames=100)
    log = tmp_path / "logs" / "seed-0.log"
    log.parent.mkdir()
    frames_file(log).write_text("90\n")  # left by an earlier command: stale, not counted
    out = io.StringIO()
    monkeypatch.setattr("sys.stderr", out)
    status = execute([Run("baseline", cfg, tmp_path / "run", log)], SimulatedBackend(clock), desc="experiment")
    assert status == {tmp_path / "run": ("done", "")}
    counts = [line.split(": ", 1)[1].split(" of ")[0] for line in out.getvalue().splitlines()
              if line.startswith("experiment: ")]
    assert counts[:3] == ["25", "50", "75"], out.getvalue()
    assert not frames_file(log).exists()  # the report of a finished run is removed


def test_an_experiment_says_before_training_that_its_budget_gives_the_report_too_few_evaluations(tmp_path, capsys):
    """--frames 10k with eval.every 5000: 2 evaluations in the last quarter, where the report's convergence check
    needs 4; said once for the target runs, before any frame, with the eval.every to use. The default, auto,
    evaluates every 500 frames there: 6 in the last quarter, nothing to say."""
    from drltg.experiments.checks import plan_warnings

    def runs(*overrides, frames=10_000):
        cfg = config_lib.resolve(None, list(overrides), task="fourrooms/southeast", frames=frames)
        source = config_lib.resolve(None, list(overrides), task="fourrooms/northeast", frames=frames)
        return [Run("source", source, tmp_path / "s", tmp_path / "s.log"),
                *(Run(role, cfg, tmp_path / role, tmp_path / f"{role}.log") for role in ("baseline", "transfer"))]

    assert plan_warnings(runs("eval.every=5000")) == [
        "baseline and transfer runs: 10,016 frames with eval.every=5,000 give 2 evaluations in the last 25% of the "
        "budget, where the report's convergence check needs 4; use -o eval.every=834 or less."]
    short = config_lib.updated(runs("eval.every=5000")[1].cfg, {"frames": 6_016})
    assert plan_warnings([Run("baseline", short, tmp_path / "b", tmp_path / "b.log")]) == [
        "baseline runs: 6,016 frames with eval.every=5,000 give evaluations at frame 0 and 6,016 only: no learning "
        "curve to speak of; lower eval.every."]
    default = runs()
    assert default[1].cfg.eval.every == "auto" and default[1].cfg.eval.interval(default[1].cfg.frames) == 500
    assert plan_warnings(default) == []


def test_the_warning_comes_before_the_first_frame(tmp_path, monkeypatch, capsys):
    class Stop(Exception):
        pass

    class NoBackend:
        capacity = 1

        def submit(self, run):
            assert "warning: baseline runs:" in capsys.readouterr().err  # said already
            raise Stop

    cfg = config_lib.resolve(None, list(TINY), task="fourrooms/northeast", frames=64)  # eval.every=32
    with pytest.raises(Stop):
        execute([Run("baseline", cfg, tmp_path / "run", tmp_path / "run.log")], NoBackend(), progress=False)
