"""Where a plan's runs train: :class:`LocalBackend`, a pool of spawned worker processes on this machine,
or :class:`RayBackend`, Ray tasks on a local instance or a cluster. :func:`~drltg.experiments.executor.execute`
speaks to either through ``submit``, ``submit_group``, ``wait``, ``close`` and ``capacity``. A worker trains with
one torch thread, registers the driver's own tasks and methods first, and unwinds its run on SIGTERM (or a Ray
cancel) as ``drltg train`` does on Ctrl-C: lock released, checkpoint kept."""
from __future__ import annotations

import contextlib
import gc
import math
import os
import pickle
import signal
import sys
import threading
from typing import Any

from tqdm import tqdm

from drltg.errors import UsageError
from drltg.experiments.executor import Run, register, run_group, run_one

__all__ = ["LocalBackend", "RayBackend", "check_answers"]

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


def _worker_init(parent: int | None = None, registered: bytes = pickle.dumps(((), ()))) -> None:
    """One torch thread per run; SIGTERM unwinds the run as in ``drltg train`` (lock released, its
    checkpoint kept), so an interrupted experiment resumes where it stopped; the worker gets SIGTERM when
    its parent dies, and ignores Ctrl-C's SIGINT, which the parent answers by stopping its workers.
    ``registered``: the parent's own tasks and methods (:func:`registrations`), pickled."""
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    os.environ.setdefault("MKL_NUM_THREADS", "1")
    signal.signal(signal.SIGTERM, lambda signum, frame: sys.exit(128 + signum))
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C reaches the parent, which stops the workers
    tqdm.set_lock(threading.RLock())  # no semaphore of tqdm's own left behind when the worker ends
    if parent is not None:
        _die_with_parent(parent)
    global _START_ERROR
    try:
        register(registered)
    except Exception as err:  # kept for each run it is given: a raising initializer only breaks the pool, unsaid
        _START_ERROR = f"its worker process could not start: {_last_line(err) or type(err).__name__}"


_START_ERROR: str | None = None
"""Why this pool worker could not register the parent's tasks and plugins, if it could not."""


def _run_in_pool(call: bytes, runs: int | None = None):
    """``train(*args)`` (:func:`run_one`, or :func:`run_group` of ``runs`` runs; pickled in ``call`` by the
    parent and unpickled only here, after the plugins: a config names a plugin's task) in a pool worker. A
    SIGTERM (from the parent stopping the pool, or from the kernel when the parent died) unwinds the run,
    releasing its lock and keeping its checkpoint, and then ends the worker: the pool would catch the
    ``SystemExit`` and wait for work from a parent that may be gone."""
    failed = _START_ERROR
    if failed is None:
        try:
            train, args = pickle.loads(call)  # bytes from the parent's memory, never from a file
        except Exception as err:
            failed = f"its worker process could not read the run: {_last_line(err) or type(err).__name__}"
    if failed is not None:
        return ("failed", failed) if runs is None else [("failed", failed)] * runs
    try:
        return train(*args)
    except SystemExit as stop:
        code = stop.code if isinstance(stop.code, int) else 1
    gc.collect()  # the unwound run's objects go, and with them the semaphores of their replay buffers
    sys.stdout.flush(), sys.stderr.flush()
    os._exit(code)


class LocalBackend:
    """A pool of ``workers`` spawned processes, one run at a time in each (torch single-threaded)."""

    def __init__(self, workers: int):
        self.workers = workers
        self.pool = None
        self.pool_of = {}  # future -> the pool that runs it
        self.log_of = {}  # future -> the log its worker writes to
        self.registered: tuple = ((), ())  # the user's own tasks and methods, for the workers (registrations)

    @property
    def capacity(self) -> int:
        return self.workers

    def _pool(self):
        import concurrent.futures as cf
        import multiprocessing as mp

        if self.pool is None:
            self.pool = cf.ProcessPoolExecutor(self.workers, mp_context=mp.get_context("spawn"),
                                               initializer=_worker_init,
                                               initargs=(os.getpid(), pickle.dumps(self.registered)))
        return self.pool

    def submit(self, run: Run):
        pool = self._pool()
        future = pool.submit(_run_in_pool, pickle.dumps((run_one, (run.cfg, str(run.path), str(run.log)))))
        self.pool_of[future], self.log_of[future] = pool, run.log
        return future

    def submit_group(self, runs: list[Run]):
        pool = self._pool()
        call = (run_group, ([r.cfg for r in runs], [str(r.path) for r in runs], [str(r.log) for r in runs]))
        future = pool.submit(_run_in_pool, pickle.dumps(call), len(runs))
        self.pool_of[future], self.log_of[future] = pool, runs[0].log
        return future

    def wait(self, handles: list, timeout: float) -> list[tuple[Any, tuple[str, str]]]:
        import concurrent.futures as cf
        from concurrent.futures.process import BrokenProcessPool

        finished, _ = cf.wait(handles, timeout=timeout, return_when=cf.FIRST_COMPLETED)
        results = []
        for f in finished:
            pool, log = self.pool_of.pop(f), self.log_of.pop(f)
            try:
                results.append((f, f.result()))
            except BrokenProcessPool:  # a worker died (killed, out of memory): the next run gets a fresh pool
                last = _log_tail(log)
                results.append((f, ("failed", "its worker process died (killed or out of memory?)"
                                    + (f"; the last line of its log {str(log)!r}: {last}" if last else ""))))
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
        self.pool, self.pool_of, self.log_of = None, {}, {}


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


def _cancellable(registered: bytes, call: bytes):
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

    def ship(self, obj) -> bytes:
        """``obj`` pickled for a Ray worker: a Ray worker's ``__main__`` is not the driver's script, so a
        function the script defines travels by value (cloudpickle), where a local pool's spawned worker
        imports it by name."""
        return self.ray.cloudpickle.dumps(obj)

    def submit(self, run: Run):
        ref = self.task.remote(self.ship(self.registered), self.ship((run_one, (run.cfg, str(run.path), str(run.log)))))
        self.pending.add(ref)
        return ref

    def submit_group(self, runs: list[Run]):
        args = ([r.cfg for r in runs], [str(r.path) for r in runs], [str(r.log) for r in runs])
        ref = self.task.remote(self.ship(self.registered), self.ship((run_group, args)))
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


def _last_line(err: BaseException) -> str:
    """The last non-empty line of an error's text: the cause, under a remote traceback."""
    lines = [line.strip() for line in str(err).splitlines() if line.strip()]
    return lines[-1] if lines else ""


def _log_tail(log) -> str:
    """The last non-empty line of a run's log (what a worker that died printed last), or ``""``."""
    from drltg.regular import open_regular

    try:
        with open_regular(log) as f:
            f.seek(max(0, os.fstat(f.fileno()).st_size - 4096))
            lines = [line.strip() for line in f.read().decode(errors="replace").splitlines() if line.strip()]
    except (OSError, UsageError):
        return ""
    return lines[-1][:300] if lines else ""
