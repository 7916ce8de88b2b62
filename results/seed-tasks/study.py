"""The seed's tasks as one queue: the Lift sources, then the rows' runs, one run per core at a time.

    python results/seed-tasks/study.py --cores 0 1          # re-running resumes; --dry-run lists the jobs
    python results/seed-tasks/study.py --only JOB ...       # just these jobs (those that fit a time slot)
    python results/seed-tasks/study.py --restore            # a new clone: the kept finished runs into RUNS
    kill PID                                                # (or Ctrl-C) stops it: each running run saves a
                                                            # checkpoint at the frame it reached first

A job is a source run (``drltg train lift-dense``, seed 60, 61 or 62) or one run of a row (``row.py ROW --seeds S
--sides SIDE``: the baseline or the transfer run of seed S), so the two sides of a seed can train side by side
and no core idles while another finishes a seed's second run. Each core takes the first job, in the order
below, that is neither finished nor running and whose source is finished, and runs it pinned to that core
(``taskset``), its output in ``RUNS/logs/JOB.log``. A finished source's curves are kept in
``results/seed-tasks/sources/``; the process that finishes a row's last run reports the row.

The sources: SAC, or the soft option-critic with 4 options, on ``lift-dense`` (robosuite's dense Lift reward, as
the earlier implementation trained its source) with the scripted demonstrator's 50 episodes (the recipe that
learned Lift in drltg's manipulation study: half of every batch demonstrated and LayerNorm critics for SAC, a
quarter for SOC-4), 60k frames, evaluated every 5k frames on 10 episodes, checkpoints every 5k and at the best
evaluation (the rows reuse ``best.pt``, which ``drltg evaluate`` then scores on 50 fresh episodes). Target seed s
reuses source seed s + 50.
"""
from __future__ import annotations

import argparse
import contextlib
import functools
import importlib.util
import json
import os
import shlex
import shutil
import signal
import statistics
import subprocess
import sys
import time
from pathlib import Path

from drltg.store.rundir import atomic_torch_save, checkpoint_path, frames_evaluated, load_checkpoint

HERE = Path(__file__).resolve().parent
_spec = importlib.util.spec_from_file_location("seed_rows", HERE / "row.py")
row = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(row)

SOURCE_SEEDS = tuple(s + row.SOURCE_OFFSET for s in row.SEEDS)
SOURCE_FRAMES = 60_000
DEMONSTRATIONS = ["transfer.method=demonstrations", "transfer.source=demonstrator:lift"]
SOURCES = {  # folder: learner flags
    "lift-dense-sac": ["-o", "network.layer_norm=critics", "-o", "transfer.demo_ratio=0.5"],
    "lift-dense-soc4": ["--algo", "soc", "-o", "soc.num_options=4"],
}
BEST_EPISODES = 50
"""Fresh episodes on which a finished source's best.pt, the checkpoint the rows reuse, is evaluated."""
SOURCE_WEIGHTS = ("loss", "frames", "evaluations")
"""What a kept source's ``best.pt`` holds: the learner's networks, its frame and the evaluations so far, not
the replay buffer and optimizer state that a run needs to resume."""
SOURCE_SETTINGS = ["eval.every=5000", "eval.episodes=10", "checkpoint.every=5000", "checkpoint.keep_best=true",
                   *DEMONSTRATIONS]
ORDER = [("source", "lift-dense-sac"), ("row", "pi-reuse-place-seed"), ("source", "lift-dense-soc4"),
         ("row", "model-reuse-place-seed"), ("row", "pi-reuse-barrier-seed"), ("row", "shaping-lift-seed"),
         ("row", "soc-model-reuse-place-seed")]


class Job:
    def __init__(self, name: str, argv: list[str], outputs: list[Path], needs: list[Path], frames: int, keep=None,
                 files=()):
        self.name, self.argv, self.outputs, self.needs, self.keep = name, argv, outputs, needs, keep
        self.frames = frames  # each output's budget
        self.files = files  # globs every output must also hold once the job is finished

    def finished(self) -> bool:
        return all((d / "summary.json").is_file() and all(any(d.glob(f)) for f in self.files) for d in self.outputs)

    def ready(self) -> bool:
        return all((d / "summary.json").is_file() for d in self.needs)


def source_job(name: str, seed: int, runs: Path) -> Job:
    run = runs / "sources" / name / f"seed-{seed}"
    drltg = str(Path(sys.executable).with_name("drltg"))
    argv = [drltg, "train", "lift-dense", *SOURCES[name], "--seed", str(seed), "--frames", str(SOURCE_FRAMES),
            "--run-dir", str(run), "--no-progress", *[x for o in SOURCE_SETTINGS for x in ("-o", o)]]
    if (run / "config.yaml").is_file():
        argv.append("--resume")
    evaluate = [drltg, "evaluate", str(run), "--checkpoint", "best", "--episodes", str(BEST_EPISODES)]
    trained = shlex.quote(str(run / "summary.json"))
    argv = ["sh", "-c", f"{{ [ -f {trained} ] || {shlex.join(argv)}; }} && {shlex.join(evaluate)}"]
    return Job(f"{name}-seed-{seed}", argv, [run], [], SOURCE_FRAMES, keep=run,
               files=(f"evaluate-best-*-{BEST_EPISODES}ep.json",))


@functools.cache
def _sides(name: str, runs: Path) -> dict:
    """``row.sides``, resolved once: the queue asks for its jobs every 30 s, and the rows' configs never change."""
    return row.sides(name, runs)


def row_job(name: str, seed: int, side: str, runs: Path) -> Job:
    """The ``side`` run of seed ``seed`` of row ``name``; a transfer run waits for its source."""
    run = _sides(name, runs)[side][1][row.SEEDS.index(seed)]
    source = row.ROWS[name][3]
    needs = [runs / "sources" / source / f"seed-{seed + row.SOURCE_OFFSET}"] if source and side == "transfer" else []
    argv = [sys.executable, str(HERE / "row.py"), name, "--seeds", str(seed), "--sides", side, "--runs", str(runs)]
    return Job(f"{name}-seed-{seed}-{side}", argv, [run], needs, row.FRAMES)


def jobs(runs: Path, only=None) -> list[Job]:
    """The study's jobs in queue order; with ``only``, just the jobs of those names."""
    out = []
    for kind, name in ORDER:
        if kind == "source":
            out += [source_job(name, s, runs) for s in SOURCE_SEEDS]
        else:
            out += [row_job(name, s, side, runs) for s in row.SEEDS for side in ("baseline", "transfer")]
    return [job for job in out if only is None or job.name in only]


def keep(job: Job) -> None:
    """A finished source's curves and configs in ``results/seed-tasks/sources/`` (:func:`row.kept_source`),
    and its ``best.pt`` as the rows reuse it: the networks alone (``SOURCE_WEIGHTS``), without the replay
    buffer and optimizer, so that a clone's queue reuses this very source instead of training it again."""
    if job.keep is None or not job.finished():
        return
    run = job.keep
    kept = row.kept_source(run)
    kept.mkdir(parents=True, exist_ok=True)
    for path in [run / name for name in row.KEPT] + sorted(run.glob(f"evaluate-best-*-{BEST_EPISODES}ep.json")):
        shutil.copyfile(path, kept / path.name)
    best = load_checkpoint(run, checkpoint="best")
    atomic_torch_save({k: best[k] for k in SOURCE_WEIGHTS}, kept / checkpoint_path("best"))


def restore(runs: Path) -> list[Path]:
    """Copy what is kept here of finished runs to their folders in ``runs``, unless a folder already holds a
    run, so that a fresh clone's queue trains only what is left: each source whose networks are kept (its
    last training, :func:`keep`), then each row run (``row.KEPT``), its ``transfer.source`` the kept source
    training it reused, as an absolute path (a source trained again in ``runs/sources/`` is another one)."""
    restored = []
    for job in jobs(runs):
        if job.keep is not None:
            trainings = [k for k in sorted(HERE.glob(f"sources/{job.keep.parent.name}/{job.keep.name}*"))
                         if (k / checkpoint_path("best")).is_file()]
            if trainings and not (job.keep / "config.yaml").exists():
                shutil.copytree(trainings[-1], job.keep)
                restored.append(job.keep)
    for kind, name in ORDER:
        if kind != "row":
            continue
        for side, (_, dirs) in _sides(name, runs).items():
            for run in dirs:
                kept = [k for k in (HERE / name / side / run.name, HERE / run.relative_to(runs))
                        if (k / "summary.json").is_file()]
                if not kept or (run / "config.yaml").exists():
                    continue
                run.mkdir(parents=True)
                for file in row.KEPT:
                    shutil.copyfile(kept[0] / file, run / file)
                config = run / "config.yaml"
                config.write_text(row.SOURCE_LINE.sub(functools.partial(_absolute, kept[0]),
                                                      config.read_text()))
                restored.append(run)
    return restored


def _absolute(kept: Path, m) -> str:
    """A kept run's source, the training it reused kept here, as an absolute path (anything else as it is)."""
    source = Path(os.path.normpath(kept.resolve() / m[2]))
    return m[1] + str(source) if source.is_relative_to(HERE / "sources") else m[0]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cores", type=int, nargs="+", default=[1], help="the cores that take jobs, one each")
    parser.add_argument("--runs", type=Path, default=Path("runs/seed-tasks"))
    parser.add_argument("--only", nargs="+", metavar="JOB", help="take only these jobs (names as --dry-run lists)")
    parser.add_argument("--dry-run", action="store_true",
                        help="list the jobs, the frames each run has reached, the frames left and the time they "
                             "take on --cores at the frames/s of each row's finished runs (else the last logged)")
    parser.add_argument("--restore", action="store_true",
                        help="copy the finished runs kept in results/seed-tasks/ to RUNS first (a new clone)")
    args = parser.parse_args()
    unknown = set(args.only or ()) - {job.name for job in jobs(args.runs)}
    if unknown:
        parser.error(f"no such job: {', '.join(sorted(unknown))} (--dry-run lists them)")
    if args.restore:
        for run in restore(args.runs):
            print(f"restored {run}")
    if args.dry_run:
        dry_run(args.runs, len(args.cores))
        return
    (args.runs / "logs").mkdir(parents=True, exist_ok=True)
    running: dict[int, tuple[Job, subprocess.Popen]] = {}
    signal.signal(signal.SIGTERM, lambda signum, frame: sys.exit(128 + signum))
    try:
        queue(args, running)
    finally:
        stop(running)


def dry_run(runs: Path, cores: int = 1) -> None:
    """Each job's state, with the frames each of its runs has reached, and the frames left to train; with the
    time left at the frames/s of the finished runs of its row or source (whole runs, warm-up included), else at
    the rate the run itself, or before it starts the other runs of its family, last logged."""
    left, seconds, untimed = 0, 0.0, 0
    rates: dict[bool, dict[str, list[float]]] = {True: {}, False: {}}
    for job in jobs(runs):
        for d in job.outputs:
            if r := rate(d):
                rates[(d / "summary.json").is_file()].setdefault(_family(job), []).append(r)
    finished_rate, logged_rate = ({f: statistics.fmean(r) for f, r in rates[k].items()} for k in (True, False))
    for job in jobs(runs):
        if job.finished():
            print(f"{job.name:44} finished")
            continue
        done = {d: job.frames if (d / "summary.json").is_file() else frames_evaluated(d) for d in job.outputs}
        left += sum(job.frames - n for n in done.values())
        for d, n in done.items():
            fps = finished_rate.get(_family(job)) or rate(d) or logged_rate.get(_family(job))
            seconds += (job.frames - n) / fps if fps else 0.0
            untimed += fps is None and n < job.frames
        state = "ready" if job.ready() else "waits for its source"
        reached = ", ".join(f"{n:,}" for n in done.values())
        print(f"{job.name:44} {state}: {reached} of {job.frames:,} frames")
    timed = f" ({untimed} runs with nothing yet to time them by left out)" if untimed else ""
    print(f"left to train: about {left:,} frames; at the frames/s the runs trained at, about "
          f"{seconds / 3600:.1f} core-hours, {seconds / 3600 / cores:.1f} h on {cores} core{'s' * (cores > 1)}{timed}")


def _family(job: Job) -> str:
    """The row or source a job belongs to: its runs train at about one rate."""
    return job.name.rsplit("-seed-", 1)[0]


def rate(run: Path) -> float | None:
    """A run's frames/s: its summary's once finished, else the last it logged (``train/fps``, frames over seconds
    since the process started, so early on the fast random warm-up inflates it)."""
    if (run / "summary.json").is_file():
        return json.loads((run / "summary.json").read_text()).get("frames_per_s")
    log = run / "logs" / "csv" / "scalars" / "train" / "fps.csv"
    values = [float(line.split(",")[1]) for line in log.read_text().split()] if log.is_file() else []
    return values[-1] if values else None


def queue(args: argparse.Namespace, running: dict[int, tuple[Job, subprocess.Popen]]) -> None:
    failed: set[str] = set()  # not tried again by this process: its log says why
    while True:
        for core, (job, proc) in list(running.items()):
            if proc.poll() is not None:
                keep(job)
                if proc.returncode != 0:
                    failed.add(job.name)
                print(f"{time.strftime('%H:%M')} {job.name}: exit {proc.returncode}", flush=True)
                del running[core]
        skip = failed | {job.name for job, _ in running.values()}
        todo = [j for j in jobs(args.runs, args.only) if not j.finished() and j.name not in skip]
        for core in [c for c in args.cores if c not in running]:
            ready = [j for j in todo if j.ready()]
            if not ready:
                break
            job = ready[0]
            todo.remove(job)
            running[core] = (job, start(job, core, args.runs / "logs"))
            print(f"{time.strftime('%H:%M')} {job.name} on core {core}", flush=True)
        if not running:
            left = [j.name for j in jobs(args.runs, args.only) if not j.finished()]
            print("every job is finished" if not left else f"not finished (failed, or waiting for a source that "
                  f"failed): {', '.join(left)}", flush=True)
            return
        time.sleep(30)


def start(job: Job, core: int, logs: Path) -> subprocess.Popen:
    """``job`` pinned to ``core``, its output appended to ``logs/JOB.log``, in a process group of its own (a
    source job is ``sh -c``, whose ``drltg`` commands are its children), so that :func:`stop` reaches them all."""
    with open(logs / f"{job.name}.log", "a") as log:
        return subprocess.Popen(["taskset", "-c", str(core), *job.argv], stdout=log, stderr=subprocess.STDOUT,
                                start_new_session=True)


def stop(running: dict[int, tuple[Job, subprocess.Popen]], timeout: float = 300.0) -> None:
    """SIGTERM to every running job's process group: each run saves a checkpoint at the frame it reached and
    unwinds. Waits until every process of the groups has ended; a group still alive after ``timeout`` seconds
    gets SIGKILL (its run resumes from its last checkpoint, as after ``kill -9``)."""
    for _, proc in running.values():
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGTERM)
    deadline = time.monotonic() + timeout
    for job, proc in running.values():
        while time.monotonic() < deadline and _running(proc):
            time.sleep(0.2)
        how = "stopped"
        if _running(proc):
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGKILL)
            how = f"killed, still running {timeout:g} s after SIGTERM"
        code = proc.wait()
        print(f"{time.strftime('%H:%M')} {job.name}: {how} (exit {code}); a rerun resumes it", flush=True)


def _running(proc: subprocess.Popen) -> bool:
    """Whether a process of ``proc``'s group is still running (``poll`` reaps the leader once it has ended)."""
    if proc.poll() is None:
        return True
    try:
        os.killpg(proc.pid, 0)
    except ProcessLookupError:
        return False
    return True


if __name__ == "__main__":
    main()
