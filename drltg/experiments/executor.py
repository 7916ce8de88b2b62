"""Training many runs: each in its own process, after the run it needs, on a local pool or Ray.

``drltg experiment`` and ``drltg sweep`` both plan a list of :class:`Run` and hand it to
:func:`execute` with a backend: :class:`LocalBackend` (``workers`` spawned processes) or
:class:`RayBackend` (Ray tasks on a local instance or a cluster). A run's output goes to its own log;
a broken run is reported with its log and the others go on; a complete run (``summary.json``) is
skipped and an interrupted one resumes from its checkpoint, so running the same plan again finishes
what is missing. Runs that share everything but the seed (and the source run each reads) train as one
seed group in one task (:mod:`drltg.training.seeds`) where the learner and transfer method support it,
unless ``group_seeds`` is off.
"""
from __future__ import annotations

import contextlib
import math
import os
import pickle
import signal
import sys
import time
import traceback
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import drltg.transfer  # noqa: F401  (the methods' transfer.* keys: a worker unpickles configs with them)
from drltg.config import RunConfig
from drltg.errors import UsageError
from drltg.store import rundir

__all__ = ["Run", "run_one", "run_group", "LocalBackend", "RayBackend", "execute", "seed_groups"]


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
    from drltg.training.health import DIVERGED, Diverged
    from drltg.training.loop import train
    from drltg.training.seeds import train_group

    plugins.load()  # a worker process registers the user's tasks too
    dirs, logs = [Path(d) for d in run_dirs], [Path(p) for p in log_paths]
    for log_path in logs:
        log_path.parent.mkdir(parents=True, exist_ok=True)
    for log_path in logs[1:]:
        with open(log_path, "a") as log:
            print(f"[{time.strftime('%Y-%m-%d %H:%M:%S')}] trains in a seed group; output in {logs[0]}", file=log)
    resume = all((d / rundir.CONFIG).is_file() for d in dirs)
    what = str(dirs[0]) if len(dirs) == 1 else f"seed group {', '.join(str(d) for d in dirs)}"
    with open(logs[0], "a", buffering=1) as log, _output_to(log):
        print(f"[{time.strftime('%Y-%m-%d %H:%M:%S')}] {'resume' if resume else 'start'} {what} "
              f"(pid {os.getpid()})", flush=True)
        try:
            if len(cfgs) == 1:
                train(cfgs[0], dirs[0], resume=resume, progress=False)
            else:
                train_group(cfgs, dirs, resume=resume, progress=False)
        except UsageError as err:
            print(f"error: {err}", flush=True)
            return [("failed", str(err))] * len(dirs)
        except Diverged as err:
            print(f"{err}.", flush=True)
            which = range(len(dirs)) if err.seeds is None else err.seeds
            stopped = ("failed", f"stopped with its seed group ({err}); a rerun resumes it")
            return [(DIVERGED, str(err)) if k in which else stopped for k in range(len(dirs))]
        except KeyboardInterrupt:  # Ctrl-C, or a cancelled Ray task
            print(f"[{time.strftime('%Y-%m-%d %H:%M:%S')}] interrupted; a rerun continues it", flush=True)
            raise
        except Exception as err:
            traceback.print_exc()
            return [("failed", f"{type(err).__name__}: {err}")] * len(dirs)
        print(f"[{time.strftime('%Y-%m-%d %H:%M:%S')}] complete", flush=True)
    return [("done", "")] * len(dirs)


def seed_groups(runs: list[Run]) -> list[list[Run]]:
    """``runs`` in units of work, in order: runs whose configs differ only in the seed (and in
    ``transfer.source``: a transfer run of seed s reads its own seed's source run), whose learner and
    transfer method train as a seed group in this process (:func:`~drltg.training.seeds.group_support`,
    :func:`~drltg.training.seeds.in_process`), and that are all new or all resumable, form one unit, which
    starts once every run its runs need is done (runs that need none are not held back by runs that do);
    every other run is a unit of one. A group of worker-process envs (robosuite) holds N runs' envs at
    once, and units run side by side here, so such tasks group only when asked (``drltg train --seeds N``)."""
    from drltg.training.seeds import group_support, in_process, same_but_seed

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


def _frames_done(run: Run) -> int:
    """Frames a run has reached so far (its last evaluation; 0 before the first)."""
    try:
        rows = rundir.read_eval_csv(run.path / rundir.EVAL)
    except (OSError, UsageError):
        return 0
    return min(rows[-1]["frames"], run.frames) if rows else 0


# --------------------------------------------------------------------------------------- backends
PR_SET_PDEATHSIG = 1


def _die_with_parent(parent: int) -> None:
    """Have the kernel send SIGTERM to this worker when the process that started it dies, even by
    ``kill -9`` (Linux ``prctl(PR_SET_PDEATHSIG)``); a worker whose parent is already gone exits now.
    Without it an orphaned worker trains on for hours, holding its run's lock."""
    if sys.platform.startswith("linux"):
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0)
    if os.getppid() != parent:
        os.kill(os.getpid(), signal.SIGTERM)


def _worker_init(parent: int | None = None, registered: tuple = ((), ())) -> None:
    """One torch thread per run; SIGTERM unwinds the run as in ``drltg train`` (lock released, its
    checkpoint kept), so an interrupted experiment resumes where it stopped; the worker gets SIGTERM when
    its parent dies. ``registered``: the parent's own tasks and methods (:func:`registrations`)."""
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    os.environ.setdefault("MKL_NUM_THREADS", "1")
    signal.signal(signal.SIGTERM, lambda signum, frame: sys.exit(128 + signum))
    if parent is not None:
        _die_with_parent(parent)
    register(registered)


def register(registered: tuple) -> None:
    """Register in this worker the tasks and methods the parent shipped (:func:`registrations`)."""
    from drltg.envs import register_task
    from drltg.transfer import register_method

    tasks, methods = registered
    for spec in tasks:
        register_task(spec.name, spec.entry, spec.description, train=spec.train, potential=spec.potential,
                      replace=True, **spec.defaults)
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


def _run_in_pool(train, *args):
    """``train(*args)`` (:func:`run_one`, :func:`run_group`) in a pool worker. A SIGTERM (from the parent
    stopping the pool, or from the kernel when the parent died) unwinds the run, releasing its lock and
    keeping its checkpoint, and then ends the worker: the pool would catch the ``SystemExit`` and wait for
    work from a parent that may be gone."""
    try:
        return train(*args)
    except SystemExit as stop:
        sys.stdout.flush(), sys.stderr.flush()
        os._exit(stop.code if isinstance(stop.code, int) else 1)


class LocalBackend:
    """A pool of ``workers`` spawned processes, one run at a time in each (torch single-threaded)."""

    def __init__(self, workers: int):
        self.workers = workers
        self.pool = None
        self.pool_of = {}  # future -> the pool that runs it
        self.registered: tuple = ((), ())  # the user's own tasks and methods, for the workers (registrations)

    @property
    def capacity(self) -> int:
        return self.workers

    def _pool(self):
        import concurrent.futures as cf
        import multiprocessing as mp

        if self.pool is None:
            self.pool = cf.ProcessPoolExecutor(self.workers, mp_context=mp.get_context("spawn"),
                                               initializer=_worker_init, initargs=(os.getpid(), self.registered))
        return self.pool

    def submit(self, run: Run):
        pool = self._pool()
        future = pool.submit(_run_in_pool, run_one, run.cfg, str(run.path), str(run.log))
        self.pool_of[future] = pool
        return future

    def submit_group(self, runs: list[Run]):
        pool = self._pool()
        future = pool.submit(_run_in_pool, run_group, [r.cfg for r in runs], [str(r.path) for r in runs],
                             [str(r.log) for r in runs])
        self.pool_of[future] = pool
        return future

    def wait(self, handles: list, timeout: float) -> list[tuple[Any, tuple[str, str]]]:
        import concurrent.futures as cf
        from concurrent.futures.process import BrokenProcessPool

        finished, _ = cf.wait(handles, timeout=timeout, return_when=cf.FIRST_COMPLETED)
        results = []
        for f in finished:
            pool = self.pool_of.pop(f)
            try:
                results.append((f, f.result()))
            except BrokenProcessPool:  # a worker died (killed, out of memory): the next run gets a fresh pool
                results.append((f, ("failed", "its worker process died (killed or out of memory?)")))
                if pool is self.pool:
                    pool.shutdown(wait=False, cancel_futures=True)
                    self.pool = None
            except Exception as err:  # raised in the worker before the run started (e.g. reading its config)
                results.append((f, ("failed", f"{type(err).__name__}: {err}")))
        return results

    def close(self) -> None:
        """Shut the pool down; runs still training (the caller was interrupted) are stopped with SIGTERM
        rather than awaited, which for a long run would take hours."""
        if self.pool is None:
            return
        workers = list((getattr(self.pool, "_processes", None) or {}).values())
        self.pool.shutdown(wait=not self.pool_of, cancel_futures=True)
        if self.pool_of:
            for process in workers:
                process.terminate()
            for process in workers:
                process.join(timeout=60)
                if process.is_alive():
                    process.kill()
        self.pool, self.pool_of = None, {}


def _loopback_only() -> None:
    """Make a local Ray node listen on 127.0.0.1 only.

    On Linux Ray replaces a loopback node address by the machine's reachable one and its servers
    listen on every interface; the switch Ray reads for single-machine nodes (the environment
    variable below, read when Ray is imported) keeps them on loopback.
    """
    os.environ["RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"] = "0"
    if "ray" in sys.modules:  # imported already: set the constant Ray derived from it
        from ray._private import ray_constants

        ray_constants.ENABLE_RAY_CLUSTER = False


RAY_RETRIES = 3
"""Times Ray starts a task again after its worker process or node died; a run's own error is not retried
(:func:`run_one` returns it). The rerun resumes the run from its checkpoint, or starts it over before the first."""
CANCEL_GRACE = 60.0
"""Seconds a cancelled Ray task has to unwind its run (lock released, checkpoint kept) before it is killed."""
CONNECT_TIMEOUT = 15.0
"""Seconds a Ray cluster's address has to answer before ``drltg sweep`` gives up (Ray itself waits minutes)."""


def check_answers(address: str, timeout: float = CONNECT_TIMEOUT) -> None:
    """Refuse, in one sentence, a ``HOST:PORT`` Ray address whose gRPC server does not answer within
    ``timeout`` seconds: nothing listening, or a socket that accepts and stays silent. ``auto`` is left to Ray."""
    target = address.removeprefix("ray://")
    if target == "auto" or ":" not in target:
        return
    import grpc

    channel = grpc.insecure_channel(target)
    try:
        grpc.channel_ready_future(channel).result(timeout=timeout)
    except grpc.FutureTimeoutError:
        raise UsageError(f"the Ray cluster at '{address}' did not answer within {timeout:g} s; check the address "
                         "and that `ray start --head` runs there.") from None
    finally:
        channel.close()


def _cancellable(registered, call: bytes):
    """``train(*args)`` (:func:`run_one`, :func:`run_group`, pickled in ``call`` by the driver) as a Ray task,
    after the driver's own tasks and methods are registered: a config names its task, so it is unpickled
    only then. Ray cancels a running task by calling its SIGINT handler, which Ray's workers ignore; with
    Python's, the run unwinds at its next batch as after Ctrl-C (lock released, checkpoint kept) and the
    task ends cancelled."""
    with contextlib.suppress(ValueError):  # not in the main thread: a cancelled task is killed after the grace
        signal.signal(signal.SIGINT, signal.default_int_handler)
    register(registered)
    train, args = pickle.loads(call)  # bytes from the driver's memory, never from a file
    return train(*args)


class RayBackend:
    """Ray tasks declaring ``num_cpus``/``num_gpus`` each; Ray places them on the cluster's nodes.

    ``address=None`` starts a private local instance (``num_cpus`` CPUs, loopback only);
    ``address="auto"`` or ``"ip:port"`` joins a running cluster (`ray start --head`). A task whose
    worker or node dies runs again (:data:`RAY_RETRIES`); :meth:`close` cancels the tasks still running.
    """

    def __init__(self, address: str | None, resources: dict, num_cpus: int | None = None,
                 connect_timeout: float = CONNECT_TIMEOUT):
        if address is None or address.removeprefix("ray://").rsplit(":", 1)[0] in ("127.0.0.1", "localhost"):
            _loopback_only()  # a cluster on this machine's loopback address: the driver stays there too
        try:
            import ray
        except ImportError:
            raise UsageError("--backend ray needs Ray: pip install 'drltg[ray]'.") from None
        self.ray = ray
        self.pending: set = set()
        self.registered: tuple = ((), ())  # the user's own tasks and methods, for the workers (registrations)
        sigterm = signal.getsignal(signal.SIGTERM)  # ray.init sets its own; the caller's unwinds the sweep
        if address is None:
            ray.init(address="local", num_cpus=num_cpus, include_dashboard=False,
                     _node_ip_address="127.0.0.1", configure_logging=False, log_to_driver=False)
            cpus = num_cpus if num_cpus is not None else ray.cluster_resources().get("CPU", 0)
            print(f"ray: a local instance on {ray.util.get_node_ip_address()} with {cpus:g} CPUs",
                  file=sys.stderr)
        else:
            check_answers(address, connect_timeout)
            try:
                ray.init(address=address, configure_logging=False, log_to_driver=False)
            except (ConnectionError, ValueError, RuntimeError, ray.exceptions.RayError) as err:
                token = "" if os.environ.get("RAY_AUTH_MODE") == "token" else (
                    "; if the cluster requires a token, set RAY_AUTH_MODE=token and RAY_AUTH_TOKEN to its token")
                raise UsageError(f"cannot join the Ray cluster at '{address}' ({err}){token}.") from None
        if signal.getsignal(signal.SIGTERM) is not sigterm and sigterm is not None:
            signal.signal(signal.SIGTERM, sigterm)
        imports = os.environ.get("DRLTG_IMPORT")  # workers on other nodes import the same plugins
        options = dict(max_retries=RAY_RETRIES, retry_exceptions=False, **resources)
        if imports:
            options["runtime_env"] = {"env_vars": {"DRLTG_IMPORT": imports}}
        self.task = ray.remote(_cancellable).options(**options)

    capacity = math.inf  # Ray queues the tasks and runs as many as the cluster's resources allow

    def submit(self, run: Run):
        ref = self.task.remote(self.registered, pickle.dumps((run_one, (run.cfg, str(run.path), str(run.log)))))
        self.pending.add(ref)
        return ref

    def submit_group(self, runs: list[Run]):
        args = ([r.cfg for r in runs], [str(r.path) for r in runs], [str(r.log) for r in runs])
        ref = self.task.remote(self.registered, pickle.dumps((run_group, args)))
        self.pending.add(ref)
        return ref

    def wait(self, handles: list, timeout: float) -> list[tuple[Any, tuple[str, str]]]:
        ready, _ = self.ray.wait(handles, num_returns=1, timeout=timeout)
        if ready:
            ready, _ = self.ray.wait(handles, num_returns=len(handles), timeout=0)
        results = []
        for ref in ready:
            self.pending.discard(ref)
            try:
                results.append((ref, self.ray.get(ref)))
            except Exception as err:  # its worker or node died more often than it is retried
                results.append((ref, ("failed", f"Ray task failed: {type(err).__name__}: {_last_line(err)}")))
        return results

    def close(self, grace: float = CANCEL_GRACE) -> None:
        """Cancel the tasks still running (the sweep was stopped) and leave the cluster. A cancelled task gets
        a KeyboardInterrupt, which ends its run at the next batch as Ctrl-C ends ``drltg train`` (lock
        released, checkpoint kept); one still running after ``grace`` seconds is killed with its worker."""
        try:
            if self.pending:
                pending = list(self.pending)
                for ref in pending:
                    self.ray.cancel(ref)
                _, left = self.ray.wait(pending, num_returns=len(pending), timeout=grace)
                for ref in left:
                    self.ray.cancel(ref, force=True)
                print(f"ray: cancelled {len(pending)} task(s) of this sweep"
                      + (f", {len(left)} of them killed after {grace:g} s" if left else ""), file=sys.stderr)
                self.pending.clear()
        finally:
            self.ray.shutdown()


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
    from tqdm.auto import tqdm

    check_order(runs)
    backend.registered = registrations(runs)
    status: dict[Path, tuple[str, str]] = {}
    for r in runs:
        finished = rundir.summary_status(r.path)
        if finished is not None:
            status[r.path] = ("skipped", "") if finished[0] == "complete" else finished
    todo = [r for r in runs if r.path not in status]
    reached = {r.path: _frames_done(r) for r in todo}
    units = seed_groups(todo) if group_seeds else [[r] for r in todo]
    bar = tqdm(total=sum(r.frames for r in todo), initial=sum(reached.values()), unit="frame",
               desc=desc, dynamic_ncols=True, smoothing=0.05, disable=None if progress else True)
    running: dict[Any, list[Run]] = {}

    def postfix() -> None:
        counts = [s for s, _ in status.values()]
        busy = sum(len(unit) for unit in running.values())
        bar.set_postfix_str(f"runs {len(counts)}/{len(runs)} ({counts.count('failed')} failed), "
                            f"{busy} running", refresh=False)

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
                    bar.update(run.frames - reached[run.path])
                    reached[run.path] = run.frames
            for unit in running.values():
                for run in unit:
                    now = _frames_done(run)
                    bar.update(max(now - reached[run.path], 0))
                    reached[run.path] = max(now, reached[run.path])
            postfix()
            bar.refresh()
    finally:
        bar.close()
    return status


def _last_line(err: BaseException) -> str:
    """The last non-empty line of an error's text: the cause, under a remote traceback."""
    lines = [line.strip() for line in str(err).splitlines() if line.strip()]
    return lines[-1] if lines else ""
