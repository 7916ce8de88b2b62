"""Training many runs: each in its own process, after the run it needs, on a local pool or Ray.

``drltg experiment`` and ``drltg sweep`` both plan a list of :class:`Run` and hand it to
:func:`execute` with a backend of :mod:`drltg.experiments.backends`: ``LocalBackend`` (``workers`` spawned
processes) or ``RayBackend`` (Ray tasks on a local instance or a cluster). A run's output goes to its own log;
a broken run is reported with its log and the others go on; a complete run (``summary.json``) is
skipped and an interrupted one resumes from its checkpoint, so running the same plan again finishes
what is missing. Runs that share everything but the seed (and the source run each reads) train as one
seed group in one task (:mod:`drltg.training.seeds`) where the learner and transfer method support it,
unless ``group_seeds`` is off.
"""
from __future__ import annotations

import contextlib
import os
import pickle
import sys
import time
import traceback
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from drltg.config import RunConfig
from drltg.errors import UsageError
from drltg.regular import append_regular, read_bytes
from drltg.store import rundir

__all__ = ["Run", "run_one", "run_group", "execute", "seed_groups", "registrations", "register"]


@dataclass
class Run:
    """One training run: its resolved config, its directory, its log and the run it needs first."""

    role: str  # source | baseline | transfer
    cfg: RunConfig
    path: Path
    log: Path
    needs: Path | None = None

    @property
    def frames(self) -> int:
        return self.cfg.frames


# --------------------------------------------------------------------------------------- one run
@contextlib.contextmanager
def _output_to(log):
    """Send this process's stdout and stderr (Python and C level) to ``log``."""
    sys.stdout.flush(), sys.stderr.flush()
    saved = os.dup(1), os.dup(2)
    os.dup2(log.fileno(), 1), os.dup2(log.fileno(), 2)
    try:
        yield
    finally:
        sys.stdout.flush(), sys.stderr.flush()
        os.dup2(saved[0], 1), os.dup2(saved[1], 2)
        os.close(saved[0]), os.close(saved[1])


def run_one(cfg: RunConfig, run_dir: str, log_path: str) -> tuple[str, str]:
    """Train (or resume) one run with its output in ``log_path``; ``("done" | "failed" | "diverged", detail)``.

    Never raises for a broken run: the traceback goes to the log, the sweep goes on.
    """
    return run_group([cfg], [run_dir], [log_path])[0]


def run_group(cfgs: list[RunConfig], run_dirs: list[str], log_paths: list[str]) -> list[tuple[str, str]]:
    """:func:`run_one` for a seed group: the runs train (or resume) together, their output in the first
    run's log (each other log says where); one ``(status, detail)`` per run. One config trains alone."""
    from drltg import plugins
    from drltg.store.rundir import DIVERGED
    from drltg.training.health import Diverged
    from drltg.training.loop import train
    from drltg.training.seeds import train_group

    plugins.load()  # a worker process registers the user's tasks too
    dirs, logs = [Path(d) for d in run_dirs], [Path(p) for p in log_paths]
    for log_path in logs:
        log_path.parent.mkdir(parents=True, exist_ok=True)
    for log_path in logs[1:]:
        with append_regular(log_path) as log:
            print(f"[{time.strftime('%Y-%m-%d %H:%M:%S')}] trains in a seed group; output in {logs[0]}", file=log)
    resume = all((d / rundir.CONFIG).is_file() for d in dirs)
    what = str(dirs[0]) if len(dirs) == 1 else f"seed group {', '.join(str(d) for d in dirs)}"
    report = FramesReport(logs)
    with append_regular(logs[0]) as log, _output_to(log):
        print(f"[{time.strftime('%Y-%m-%d %H:%M:%S')}] {'resume' if resume else 'start'} {what} "
              f"(pid {os.getpid()})", flush=True)
        try:
            if len(cfgs) == 1:
                train(cfgs[0], dirs[0], resume=resume, progress=False, on_frames=report)
            else:
                train_group(cfgs, dirs, resume=resume, progress=False, on_frames=report)
        except UsageError as err:
            print(f"error: {err}", flush=True)
            return [("failed", str(err))] * len(dirs)
        except Diverged as err:
            print(f"{err}.", flush=True)
            which = range(len(dirs)) if err.seeds is None else err.seeds
            stopped = ("failed", f"stopped with its seed group ({err}); a rerun resumes it")
            return [(DIVERGED, str(err)) if k in which else stopped for k in range(len(dirs))]
        except (KeyboardInterrupt, SystemExit):  # stopped by its parent (Ctrl-C there), or a cancelled Ray task
            print(f"[{time.strftime('%Y-%m-%d %H:%M:%S')}] interrupted; a rerun continues it", flush=True)
            raise
        except Exception as err:
            traceback.print_exc()
            return [("failed", f"{type(err).__name__}: {err}")] * len(dirs)
        print(f"[{time.strftime('%Y-%m-%d %H:%M:%S')}] complete", flush=True)
    return [("done", "")] * len(dirs)


class FramesReport:
    """What a worker tells its parent of a unit's progress: the frames its runs reached, in ``<log>.frames``
    beside each run's log, rewritten at most every ``every`` seconds (the parent reads it, :func:`frames_done`)."""

    def __init__(self, logs: list[Path], every: float = 2.0):
        self.paths, self.every, self.last = [frames_file(log) for log in logs], every, 0.0

    def __call__(self, frames: int) -> None:
        if time.monotonic() - self.last >= self.every:
            self.last = time.monotonic()
            for path in self.paths:
                with contextlib.suppress(UsageError):  # a full disk costs the parent's bar, not the run
                    rundir.atomic_write(path, f"{frames}\n")


def frames_file(log: Path) -> Path:
    return log.with_name(log.name + ".frames")


def seed_groups(runs: list[Run]) -> list[list[Run]]:
    """``runs`` in units of work, in order: runs whose configs differ only in the seed (and in
    ``transfer.source``: a transfer run of seed s reads its own seed's source run), whose learner and
    transfer method train as a seed group in this process (:func:`~drltg.training.grouping.group_support`,
    :func:`~drltg.training.grouping.in_process`), and that are all new or all resumable, form one unit, which
    starts once every run its runs need is done (runs that need none are not held back by runs that do);
    every other run is a unit of one. A group of worker-process envs (robosuite) holds N runs' envs at
    once, and units run side by side here, so such tasks group only when asked (``drltg train --seeds N``)."""
    from drltg.training.grouping import group_support, in_process, same_but_seed

    units: list[list[Run]] = []
    for run in runs:
        for unit in units:
            first = unit[0]
            if (same_but_seed(first.cfg, run.cfg) and (run.needs is None) == (first.needs is None)
                    and run.needs not in {r.path for r in unit}
                    and run.path not in {r.needs for r in unit}
                    and (run.path / rundir.CONFIG).is_file() == (first.path / rundir.CONFIG).is_file()
                    and group_support(run.cfg) is None and in_process(run.cfg)):
                unit.append(run)
                break
        else:
            units.append([run])
    return units


def frames_done(run: Run) -> int:
    """Frames a run has reached so far: what its worker last reported, else its last evaluation (0 before)."""
    try:
        reported = int(read_bytes(frames_file(run.log), 64, "a frames count"))
    except (OSError, ValueError, UsageError):
        reported = 0
    return min(max(reported, rundir.frames_evaluated(run.path)), run.frames)


def register(shipped: bytes) -> None:
    """Register in this worker the user's plugins (``--import``, ``DRLTG_IMPORT``, entry points), then the
    tasks and methods the parent shipped (:func:`registrations`, pickled there) over them. The plugins come
    first: a plugin registers its tasks without ``replace=True``, as a user writes it, and unpickling a
    plugin's method imports the plugin, so it is unpickled only here, after them."""
    from drltg import plugins
    from drltg.envs import register_task
    from drltg.transfer import register_method

    plugins.load()
    tasks, methods = pickle.loads(shipped)
    for spec in tasks:
        register_task(spec.name, spec.entry, spec.description, train=spec.train, potential=spec.potential,
                      returns=spec.returns, fixed=spec.fixed, options=spec.options, replace=True, **spec.defaults)
    for method in methods:
        register_method(method, replace=True)


def registrations(runs: list[Run]) -> tuple[list, list]:
    """The tasks and transfer methods of ``runs`` as this process registered them, for the worker processes
    to register too: a spawned worker imports drltg and the plugins (``--import``, ``DRLTG_IMPORT``), not
    what a script registered, inside a function or not. A script's registration whose code a worker
    cannot import (a lambda, a function defined inside another) is refused here, before any work."""
    from drltg.envs import get_task
    from drltg.transfer import get_method

    tasks = {run.cfg.task: get_task(run.cfg.task) for run in runs}
    methods = {part: get_method(part) for run in runs for part in run.cfg.transfer.method.split("+")}
    shipped: tuple[list, list] = ([], [])
    for kind, (what, specs) in enumerate((("task", tasks), ("transfer method", methods))):
        for name, spec in specs.items():
            try:
                pickle.dumps(spec)
            except (pickle.PicklingError, AttributeError, TypeError) as err:
                code = (spec.entry, spec.potential) if kind == 0 else (spec.build, spec.check)
                if all(getattr(c, "__module__", None) != "__main__" for c in code):
                    continue  # registered by a module the workers import too (a plugin)
                raise UsageError(f"the {what} {name!r} cannot reach the worker processes ({err}); define its "
                                 "functions at the top level of the script or a module, or register it in a "
                                 "module given to --import (or DRLTG_IMPORT).") from None
            shipped[kind].append(spec)
    return shipped


# --------------------------------------------------------------------------------------- schedule
def check_order(runs: list[Run]) -> None:
    """Refuse a plan in which a run needs itself, directly or through other runs (its source would never
    finish): one sentence before anything runs, instead of a wait without end."""
    by_path = {r.path: r for r in runs}
    for run in runs:
        chain, current = [run.path], run
        while current.needs is not None and current.needs in by_path:
            if current.needs in chain:
                loop = " -> ".join(f"'{p}'" for p in [*chain[chain.index(current.needs):], current.needs])
                raise UsageError(f"run '{run.path}' needs its own output as transfer.source ({loop}); name a source "
                                 "that is not one of the runs it feeds.")
            chain.append(current.needs)
            current = by_path[current.needs]


def execute(runs: list[Run], backend, poll: float = 1.0, desc: str = "runs", progress: bool = True,
            group_seeds: bool = True) -> dict[Path, tuple[str, str]]:
    """Run every incomplete run (each after the run it needs) and return ``{path: (status, detail)}``
    with status ``skipped`` (complete before), ``done``, ``diverged`` or ``failed``. With ``group_seeds``,
    runs that differ only in their seed train as one seed group (:func:`seed_groups`)."""
    from drltg.experiments.checks import plan_warnings
    from drltg.training.progress import Progress

    check_order(runs)
    backend.registered = registrations(runs)
    status: dict[Path, tuple[str, str]] = {}
    for r in runs:
        finished = rundir.summary_status(r.path)
        if finished is not None:
            status[r.path] = ("skipped", "") if finished[0] == "complete" else finished
    todo = [r for r in runs if r.path not in status]
    for sentence in plan_warnings(todo):  # before any frame: the workers' own warnings go to their logs
        print(f"warning: {sentence}", file=sys.stderr)
    units = seed_groups(todo) if group_seeds else [[r] for r in todo]
    for r in todo:  # what an earlier command's workers reported is stale: they resume from a checkpoint
        with contextlib.suppress(FileNotFoundError):
            frames_file(r.log).unlink()
    reached = {r.path: frames_done(r) for r in todo}
    bar = Progress(sum(r.frames for r in todo), initial=sum(reached.values()), desc=desc, enabled=progress)
    running: dict[Any, list[Run]] = {}

    def postfix() -> None:
        counts = [s for s, _ in status.values()]
        busy = sum(len(unit) for unit in running.values())
        bar.set_note(f"runs {len(counts)}/{len(runs)} done ({counts.count('failed')} failed), {busy} running")

    try:
        while units or running:
            for unit in list(units):
                if any(run.needs and run.needs not in status for run in unit):
                    continue  # a source is not trained yet
                for run in list(unit):
                    state = status[run.needs][0] if run.needs else "done"
                    if state in ("failed", "diverged"):
                        status[run.path] = ("failed", f"not run: the run it needs {state} ({run.needs})")
                        unit.remove(run)
                if not unit:
                    units.remove(unit)
                elif len(running) < backend.capacity:
                    handle = backend.submit(unit[0]) if len(unit) == 1 else backend.submit_group(unit)
                    running[handle] = unit
                    units.remove(unit)
            if units and not running:  # nothing runs and nothing can start: never wait on that
                for run in (run for unit in units for run in unit):
                    status[run.path] = ("failed", f"not run: the run it needs ({run.needs}) cannot run before it")
                units.clear()
            postfix()
            for handle, result in backend.wait(list(running), poll) if running else ():
                unit = running.pop(handle)
                for run, one in zip(unit, result if isinstance(result, list) else [result] * len(unit)):
                    status[run.path] = one
                    with contextlib.suppress(FileNotFoundError):
                        frames_file(run.log).unlink()
                    bar.update(run.frames - reached[run.path])
                    reached[run.path] = run.frames
            for unit in running.values():
                for run in unit:
                    now = frames_done(run)
                    bar.update(max(now - reached[run.path], 0))
                    reached[run.path] = max(now, reached[run.path])
            postfix()
            bar.refresh()
    finally:
        bar.close()
    return status


@dataclass(frozen=True)
class Plan:
    """What a set of planned runs holds and would train: each run's state in words and frames left, and the
    units of work the runs left to train train in (:func:`seed_groups`)."""

    states: dict
    units: list

    @property
    def left(self) -> int:
        return sum(left for _, left in self.states.values())

    def summary(self, runs: list[Run], reports: int) -> list[str]:
        """Two lines: the units of work, and the frames left with the runs counted by state."""
        groups = [u for u in self.units if len(u) > 1]
        sizes = sorted({len(u) for u in groups})
        kinds = [words.split(":")[0] for words, _ in self.states.values()]
        counts = ", ".join(f"{kinds.count(k)} {k}" for k in ("finished", "copied from the reference", "started",
                                                               "not started", "diverged", "unreadable") if k in kinds)
        return [f"{_count(len(runs), 'run')}, {_count(reports, 'report')}; {_count(len(self.units), 'unit')} of work "
                f"to train: {_count(len(groups), 'seed group')} of {_count(sum(map(len, groups)), 'run')}"
                + (f" ({' or '.join(map(str, sizes))} runs each)" if sizes else "")
                + f", {_count(len(self.units) - len(groups), 'run')} alone" + _why_alone(self.units),
                f"left to train: about {self.left:,} of {sum(r.frames for r in runs):,} frames ({counts})"]


def _why_alone(units: list[list[Run]]) -> str:
    """Why runs that could share a group train one at a time, where a part says so (``" (why)"``)."""
    from drltg.training.grouping import group_support

    reasons = sorted({why for u in units if len(u) == 1 and (why := group_support(u[0].cfg))})
    return f" ({'; '.join(reasons)})" if reasons else ""


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}{'s' * (n != 1)}"


def plan_of(runs: list[Run], group_seeds: bool = True, copied: frozenset = frozenset()) -> Plan:
    """The :class:`Plan` of ``runs``; a run in ``copied`` (paths) is taken from a reference, nothing to train."""
    states = {r.path: ("copied from the reference", 0) if r.path in copied else _state(r) for r in runs}
    todo = [r for r in runs if states[r.path][1] > 0]
    return Plan(states, seed_groups(todo) if group_seeds else [[r] for r in todo])


def plan_lines(runs: list[Run], out: Path, reports: int, group_seeds: bool = True) -> list[str]:
    """A dry run's listing: each run with its frames, folder and what the folder holds already, the units of
    work they train in and the frames left."""
    planned = plan_of(runs, group_seeds)
    width = max(len(str(r.path.relative_to(out))) for r in runs)
    return [*(f"{r.role:<9} {r.frames:>9} frames  {str(r.path.relative_to(out)):<{width}}  "
              f"{planned.states[r.path][0]}" for r in runs), *planned.summary(runs, reports)]


def _state(run: Run) -> tuple[str, int]:
    """What a run's folder holds, in words, and about how many frames a sweep would still train in it: none
    once it ended (``summary.json``: finished, diverged, or unreadable and so failed), else from its last
    checkpoint, which is at or before its last evaluation (:func:`frames_done`)."""
    ended = rundir.summary_status(run.path)
    if ended is not None:
        return ("finished" if ended[0] == "complete" else ended[0]), 0
    if not (run.path / rundir.CONFIG).is_file():
        return "not started", run.frames
    done = frames_done(run)
    return f"started: last evaluated at {done:,} frames", run.frames - done
