"""The training loop: env -> transforms -> Collector -> ReplayBuffer -> loss -> optimizer -> SoftUpdate.

Evaluation runs at frame 0 (before any update) and every ``eval.every`` frames (``auto``: at least 20 times a
run, :meth:`~drltg.config.sections.EvalConfig.interval`), with the deterministic
actor on a separate evaluation env that measures the task's own reward (never a shaped one) and
success. A transfer that asks for it (``Transfer.on_eval``: jumpstart's curriculum) is told, after each, the
return of the collector's own policy evaluated deterministically on an env of its own
(:data:`GUIDED_EVAL_SEED_OFFSET`), logged as ``eval/guided_return_mean``.

:func:`run_loop` is the loop over parts (a collector, a learner, one :class:`~drltg.store.rundir.RunWriter` per
seed) and writes no file itself; what a run directory holds
and how it is written is :mod:`drltg.store.rundir`. :func:`train` builds the parts of one run; its
directory's lifecycle (checks, lock, resume, cleanup of a failed start) is
:class:`~drltg.training.session.RunSession`'s, as for a seed group's runs (:mod:`drltg.training.seeds`).
"""
from __future__ import annotations

import contextlib
import logging
import math
import signal
import sys
import threading
import time
from collections import defaultdict
from pathlib import Path
from typing import Callable

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictSequential
from torchrl.collectors import Collector
from torchrl.data import ReplayBuffer
from torchrl.envs import EnvBase, ExplorationType, RewardSum, TensorDictPrimer, TransformedEnv, set_exploration_type

from drltg import config
from drltg.config import EVAL_SEED_OFFSET, RunConfig
from drltg.envs import get_task, make_env
from drltg.envs.limits import MAX_HORIZON
from drltg.errors import UsageError
from drltg.learners import Agent, UpdateStep, make_agent, sample_batches
from drltg.store import rundir
from drltg.store.rundir import EPISODE_FLAGS, RunWriter, is_complete, read_eval_csv
from drltg.training import best, console, health, preflight
from drltg.training.pretraining import pretrain
from drltg.training.progress import Progress
from drltg.training.replay import buffer_state, replay_buffer
from drltg.training.session import RunSession
from drltg.transfer import Transfer, get_method
from drltg.transfer.source import check as check_source
from drltg.transfer.source import start_record

__all__ = ["train", "run_loop", "AgentLearner", "make_collector", "evaluate", "evaluate_seeds", "make_envs",
           "make_eval_env", "build_env", "check_config", "is_complete", "read_eval_csv", "primers", "transfer_state",
           "GUIDED_EVAL_SEED_OFFSET"]

log = logging.getLogger(__name__)

GUIDED_EVAL_SEED_OFFSET = 40_000
"""The env on which a transfer's combined policy is evaluated (``Transfer.on_eval``) is seeded ``seed +
GUIDED_EVAL_SEED_OFFSET``, apart from the learner's evaluation env, whose episodes stay those of a run without it."""


# ----------------------------------------------------------------------------- envs
def build_env(cfg: RunConfig, **kwargs) -> EnvBase:
    """``make_env`` of the config's task with its ``env`` settings; a setting the task cannot take
    (``env.horizon=abc``) is one :class:`UsageError` sentence."""
    try:
        return make_env(cfg.task, device=cfg.device, **{**cfg.env, **kwargs})
    except UsageError:
        raise
    except (TypeError, ValueError) as err:
        raise UsageError(f"task '{cfg.task}' cannot be built with env settings {cfg.env} ({err}).") from None


def make_envs(cfg: RunConfig, agent_transforms=()) -> tuple[EnvBase, EnvBase]:
    """Training env (``num_envs`` batched, episode-return tracking) and a separate evaluation env
    (``eval.episodes`` batched, seeded apart from the training env)."""
    train_env = TransformedEnv(build_env(cfg, batch_size=(cfg.collector.num_envs,), seed=cfg.seed))
    eval_env = make_eval_env(cfg, cfg.eval.episodes, cfg.seed + EVAL_SEED_OFFSET)
    preflight.check_batch(cfg, train_env, eval_env)
    best.check_metric(cfg, eval_env)
    for t in agent_transforms:
        train_env.append_transform(t.clone())
        eval_env.append_transform(t.clone())
    train_env.append_transform(RewardSum())
    return train_env, eval_env


def make_eval_env(cfg: RunConfig, episodes: int, seed: int, agent_transforms=()) -> EnvBase:
    """The evaluation env of :func:`evaluate`: ``episodes`` envs in one batch, seeded ``seed``, carrying
    the transforms the policy needs (``agent_transforms``), and no shaping."""
    env = TransformedEnv(build_env(cfg, batch_size=(episodes,), seed=seed))
    for t in agent_transforms:
        env.append_transform(t.clone())
    return env


def check_config(cfg: RunConfig):
    """Build the task's env and the learner of ``cfg`` (writing nothing): the checks a config can
    fail before any run directory is created. Returns the env and the agent."""
    probe = build_env(cfg, seed=cfg.seed)
    own = str(get_task(cfg.task).entry).startswith("drltg.")  # drltg's tasks: stepped by the suite, not here
    preflight.check_task(cfg, probe, None if own else lambda: build_env(cfg, seed=cfg.seed))
    preflight.check_network(cfg, probe)
    if cfg.eval.stop_at_success is not None and "success" not in probe.full_observation_spec.keys():
        raise UsageError(f"eval.stop_at_success={cfg.eval.stop_at_success:g}, but task '{cfg.task}' reports no "
                         "success; leave it null.")
    method = get_method(cfg.transfer.method)
    if method.check_env is not None:
        method.check_env(cfg, probe)
    agent = make_agent(probe, cfg)
    preflight.check_buffer(cfg, probe, agent.loss.in_keys)
    return probe, agent


def evaluate(env: EnvBase, actor: Callable, max_steps: int = MAX_HORIZON,
             check: Callable[[], None] = lambda: None) -> dict:
    """Run one episode in every batch element of ``env`` with the deterministic actor.

    Returns the mean/std of the undiscounted episode return and, for each ``rundir.EPISODE_FLAGS``
    entry the env reports (``success``; ``lifted`` on the manipulation tasks), the fraction of episodes
    in which it was ever true (``success_rate``, ``lifted_rate``), counting each element's first
    episode only. An episode still running after ``max_steps`` steps is counted with its partial return,
    said on stderr and in the row's ``unfinished`` entry. ``check`` is called at every step (a deferred
    Ctrl-C or SIGTERM stops an evaluation there).
    """
    return evaluate_seeds(env, actor, 1, max_steps, check)[0]


@torch.no_grad()
def evaluate_seeds(env: EnvBase, actor: Callable, seeds: int, max_steps: int = MAX_HORIZON,
                   check: Callable[[], None] = lambda: None) -> list[dict]:
    """:func:`evaluate` of a seed group's env: one row per block of ``batch / seeds`` elements (seed k's
    episodes), each computed as its seed's own evaluation would be."""
    td = env.reset()
    shape = env.batch_size
    alive = torch.ones(*shape, 1, dtype=torch.bool, device=env.device)
    ret = torch.zeros(*shape, 1, device=env.device)
    flags = [key for key in EPISODE_FLAGS if key in env.full_observation_spec.keys()]
    ever = {key: torch.zeros_like(alive) for key in flags}
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        for _ in range(max_steps):
            check()
            td = env.step(actor(td))
            nxt = td["next"]
            ret += nxt["reward"] * alive
            for key in flags:
                ever[key] |= nxt[key].bool() & alive
            alive &= ~nxt["done"].bool()
            if not alive.any():
                break
            td = td["next"].clone()
    rows = []
    for k, block in enumerate(ret.flatten().double().chunk(seeds)):
        row = {
            "return_mean": block.mean().item(),
            "return_std": block.std(unbiased=False).item(),
            "episodes": block.numel(),
        }
        for key in flags:
            row[f"{key}_rate"] = ever[key].flatten().chunk(seeds)[k].float().mean().item()
        unfinished = int(alive.flatten().chunk(seeds)[k].sum())
        if unfinished:
            row["unfinished"] = unfinished
            print(f"warning: {unfinished} of {row['episodes']} evaluation episodes did not end within {max_steps} "
                  "steps; their partial returns are counted (eval.csv's unfinished column).", file=sys.stderr)
        rows.append(row)
    return rows


# ----------------------------------------------------------------------------- loop
def train(
    cfg: RunConfig | dict,
    run_dir: str | Path,
    *,
    resume: bool = False,
    progress: bool = True,
    on_frames: Callable[[int], None] | None = None,
) -> Path:
    """Train ``cfg.algo`` on ``cfg.task`` for ``cfg.frames`` frames, with the transfer method
    of ``cfg.transfer``; return the run directory. ``cfg`` is a :class:`~drltg.config.RunConfig`, or a mapping
    of config keys resolved as a ``--config`` file is.

    ``progress`` draws a bar (a plain line every 30 s where stderr is no terminal); ``on_frames`` is called
    with the frames reached after every collected batch (an experiment's worker reports them to its parent).
    The directory is locked while the run writes it (a second process is refused). Everything the
    config can fail on is built before a new directory is created; if a new run fails before its first
    checkpoint, what it wrote is removed, and after it the directory can be resumed.
    """
    cfg = config.as_config(cfg)
    run_dir = rundir.check_directory(run_dir, "--run-dir")
    with RunSession([cfg], [run_dir], resume=resume) as session:
        if session.finished:
            return run_dir
        console.plain_unless_terminal()  # TorchRL's colour codes reach a terminal, never a log file
        torch.set_num_threads(cfg.threads)
        torch.manual_seed(cfg.seed)
        # Build everything before writing anything: a bad config fails with nothing on disk.
        check_source(cfg)
        probe, agent = check_config(cfg)
        train_env, eval_env = make_envs(cfg, agent.env_transforms)
        resuming = session.checkpoints[0] is not None
        transfer = get_method(cfg.transfer.method).build(cfg, agent, probe, resuming=resuming)
        if transfer.pretraining is not None:
            transfer.summary.update(pretrain(transfer.pretraining))
        source = start_record(cfg, run_dir, resuming, transfer.files)  # the source by content, as it was loaded
        summary = {**transfer.summary, **source}
        for t in transfer.train_transforms:  # after RewardSum: train/episode_return stays the task's return
            train_env.append_transform(t)
        guided_env = None
        if transfer.on_eval is not None:
            guided_env = make_eval_env(cfg, cfg.eval.episodes, cfg.seed + GUIDED_EVAL_SEED_OFFSET,
                                       [*agent.env_transforms, *primers(transfer)])
        buffer = replay_buffer(cfg)
        session.restore([agent], [buffer], [transfer])
        session.claim()
        preflight.warn_budget(cfg)  # every check passed and the directory is ours: training starts now
        writers = session.writers([transfer])
        frames, updates = session.position()
        learner = AgentLearner(agent, buffer, eval_env, transfer, cudagraphs=cfg.optim.cudagraphs,
                               guided_env=guided_env)
        collector = make_collector(cfg, train_env, learner.policy, frames)
        with deferred_signals() as stop_if_signalled, health.on_divergence(run_dir, cfg):
            run_loop(cfg, collector, learner, writers, frames=frames, updates=updates, progress=progress,
                     stop_if_signalled=stop_if_signalled, extra_summary=summary, on_frames=on_frames)
    return run_dir


def primers(transfer: Transfer) -> list:
    """The transfer's training transforms that declare per-env state its policy reads (policy reuse's episode
    choice): what an env on which the collector's policy is evaluated needs, without the transfer's shaping."""
    return [t for t in transfer.train_transforms if isinstance(t, TensorDictPrimer)]


def make_collector(cfg: RunConfig, env: EnvBase, policy, frames: int = 0, seeds: int = 1) -> Collector:
    """TorchRL's single-process collector for the frames left after ``frames`` (per seed), random
    actions until ``collector.init_random_frames``; ``seeds`` runs in step share one batched env."""
    fpb = cfg.collector.frames_per_batch
    init_random = cfg.collector.warm_up_frames
    return Collector(
        env,
        policy,
        frames_per_batch=fpb * seeds,
        total_frames=(cfg.frames - frames) * seeds,
        init_random_frames=max(init_random - frames, 0) * seeds,
        device=cfg.device,
        auto_register_policy_transforms=False,
    )


@contextlib.contextmanager
def deferred_signals(signums=(signal.SIGINT, signal.SIGTERM)):
    """Hold SIGINT and SIGTERM while training and hand them to the handlers that were in place (Ctrl-C's
    KeyboardInterrupt, the CLI's SIGTERM unwinding) when the loop calls the yielded check, once per
    batch, or at the end; ``check(before=f)`` calls ``f`` first when a signal is pending (the loop saves
    a checkpoint there). Raised in the middle of a TorchRL loss, the exception does not always unwind:
    tensordict's context managers can turn it into another error, and a stopped run would end in a
    traceback instead of releasing its directory. A signal the process ignores (SIGINT in a job started
    in the background, ``nohup``) stays ignored."""
    if threading.current_thread() is not threading.main_thread():  # handlers can only be set there
        yield lambda before=None: None
        return
    received: list[int] = []
    previous = {s: signal.signal(s, lambda signum, frame: received.append(signum)) for s in signums
                if signal.getsignal(s) != signal.SIG_IGN}

    def deliver(before: Callable[[], None] | None = None) -> None:
        if received:
            if before is not None:
                before()
            signum = received[0]
            handler = previous[signum]
            restore()
            if callable(handler):
                handler(signum, None)
            elif handler == signal.SIG_DFL:
                signal.raise_signal(signum)

    def restore() -> None:
        for s, handler in previous.items():
            signal.signal(s, handler)

    try:
        yield deliver
    finally:
        restore()
    deliver()


class AgentLearner:
    """One agent as the loop's learner: its replay buffer, its update step and its evaluation env.

    The loop speaks to a learner in lists with one entry per seed (here, one): ``split`` the
    collected frames, ``store`` them, draw ``batches``, ``update`` (losses with a leading seed
    dimension), ``evaluate``, ``evaluate_guided`` (the transfer's ``on_eval``, on ``guided_env``) and
    ``state`` (what a checkpoint holds).
    """

    seeds = 1

    def __init__(self, agent: Agent, buffer: ReplayBuffer, eval_env: EnvBase, transfer: Transfer, *,
                 cudagraphs: bool = False, guided_env: EnvBase | None = None):
        self.agent, self.buffer, self.eval_env, self.transfer = agent, buffer, eval_env, transfer
        self.guided_env = guided_env
        self.actor_delay = agent.actor_delay
        self.policy = agent.policy if transfer.policy is None else transfer.policy
        if transfer.mixer is not None:
            self.policy = TensorDictSequential(self.policy, transfer.mixer)
        self.step = UpdateStep(agent, loss_terms=transfer.loss_terms, cudagraphs=cudagraphs,
                               threads=None)  # train() set torch to cfg.threads for the whole run

    def split(self, data: TensorDictBase) -> list[TensorDictBase]:
        return [data.reshape(-1)]

    def store(self, data: list[TensorDictBase], frames: int) -> None:
        if self.transfer.on_frames is not None:
            self.transfer.on_frames(frames)
        self.buffer.extend(data[0].select(*self.agent.loss.in_keys))  # only what the loss reads is stored

    def batches(self, count: int):
        return (self.transfer.batches or sample_batches)(self.buffer, count)

    def update(self, batch: TensorDictBase, update_actor: bool) -> TensorDictBase:
        return self.step(batch, update_actor=update_actor).unsqueeze(0)

    def evaluate(self, check: Callable[[], None] = lambda: None) -> list[dict]:
        return [evaluate(self.eval_env, self.agent.actor, check=check)]

    def evaluate_guided(self, check: Callable[[], None] = lambda: None) -> list[dict]:
        """The collector's policy evaluated deterministically on ``guided_env`` and its mean return told to the
        transfer's ``on_eval``: the scalars to log for the seed (none without ``on_eval``)."""
        if self.transfer.on_eval is None:
            return []
        value = evaluate(self.guided_env, self.policy, check=check)["return_mean"]
        return [{"eval/guided_return_mean": value, **self.transfer.on_eval(value)}]

    def state(self) -> list[dict]:
        return [{
            "loss": self.agent.loss.state_dict(),
            "optimizer": self.agent.optimizer.state_dict(),
            "buffer": buffer_state(self.buffer),
            "rng": torch.get_rng_state(),
            **transfer_state(self.transfer),
        }]


def transfer_state(transfer: Transfer) -> dict:
    """A checkpoint's ``transfer`` entry: the ``state_dict`` of the transfer's ``state`` (none without one)."""
    return {} if transfer.state is None else {"transfer": transfer.state.state_dict()}


class _Session:
    """What one :func:`run_loop` call shares between its steps: the frames and updates reached, the frame of
    the latest ``last.pt``, the seeds already ended by ``eval.stop_at_success``, the clock and the bar."""

    def __init__(self, cfg, learner, writers, frames, updates, stop_if_signalled, extra_summary, bar):
        self.cfg, self.learner, self.writers, self.bar = cfg, learner, writers, bar
        self.frames, self.updates, self.saved = frames, updates, frames  # saved: the latest last.pt's frame
        self.stop_if_signalled, self.extra_summary = stop_if_signalled, extra_summary
        self.stopped: set[int] = set()
        self.clock = PhaseClock()
        self.restart()

    def restart(self) -> None:
        self.start, self.start_frames = self.clock.start(), self.frames

    def active(self) -> list[int]:
        return [k for k in range(len(self.writers)) if k not in self.stopped]

    def evaluate(self) -> None:
        with self.clock("evaluate"):
            rows = self.learner.evaluate(lambda: self.stop_if_signalled(before=self.save_on_stop))
            for k in self.active():
                self.writers[k].evaluation({"frames": self.frames, **rows[k]})
            # a signal waits for the next batch here: a resumed run does not evaluate this frame again, so a stop
            # inside would lose the combined policy's return at it
            guided = self.learner.evaluate_guided()
            for k in self.active() if guided else ():
                self.writers[k].log(guided[k], self.frames)
            self.bar.set_note(f"eval return {self.writers[self.active()[0]].rows[-1]['return_mean']:.3f}")
            improved = [k not in self.stopped and best.improves(self.cfg, w.rows) for k, w in enumerate(self.writers)]
            if any(improved):  # last.pt too, so that the best is never later than the checkpoint a resume reads
                self.checkpoint(improved, last=self.frames > 0)
            self.stop_reached()

    def checkpoint(self, improved=(), last: bool = True, only: list[int] | None = None) -> None:
        with self.clock("checkpoint"):
            for k, state in enumerate(self.learner.state()):
                if k in (self.active() if only is None else only):
                    health.check_state(state["loss"], self.frames, k if self.learner.seeds > 1 else None)
                    self.writers[k].checkpoint(state, self.frames, self.updates, last=last,
                                               best=bool(improved and improved[k]))
            self.saved = self.frames if last and only is None else self.saved

    def stop_reached(self) -> None:
        """End each run whose evaluation at this frame meets ``eval.stop_at_success``: its checkpoint here
        is its last, its summary.json says why it stopped; the group's other seeds train on."""
        done = [k for k in self.active() if stop_met(self.cfg, self.writers[k].rows, self.frames)]
        if done:
            self.checkpoint(only=done)
            for k in done:
                self.writers[k].close()
            self.finish(done)
            self.stopped.update(done)

    def finish(self, which: list[int]) -> None:
        _finish(self.cfg, self.writers, self.extra_summary, self.frames, self.updates,
                self.frames - self.start_frames, self.clock, self.start, which)

    def save_on_stop(self) -> None:  # before its first checkpoint a stopped run is a failed start (RunSession)
        if 0 < self.saved < self.frames:  # inside an evaluation too: the resumed run evaluates first
            self.checkpoint()
            log.info("stopped at frame %d with a checkpoint there: --resume continues from it", self.frames)


def _next(frames: int, every: int) -> int:
    return (frames // every + 1) * every


def run_loop(cfg: RunConfig, collector, learner, writers: list[RunWriter], *, frames: int = 0, updates: int = 0,
             progress: bool = True, stop_if_signalled: Callable[..., None] = lambda before=None: None,
             extra_summary: dict | list[dict] | None = None,
             on_frames: Callable[[int], None] | None = None) -> None:
    """Collect, store, update, evaluate and checkpoint until ``cfg.frames`` frames per seed.

    ``learner`` trains one or several seeds in step (see :class:`AgentLearner`); ``writers`` gets one
    :class:`~drltg.store.rundir.RunWriter` per seed and receives every evaluation, logged scalar,
    checkpoint and the summary (with ``extra_summary``, one for every writer or a list of one per writer):
    the loop itself writes no file. ``frames`` counts one seed's frames.
    """
    bar = Progress(cfg.frames, initial=frames, desc="train", enabled=progress, on_update=on_frames)
    s = _Session(cfg, learner, writers, frames, updates, stop_if_signalled, extra_summary, bar)
    try:
        if _evaluation_due(cfg, writers[0].rows, s.frames):
            s.evaluate()
        else:
            s.stop_reached()  # a resumed run stopped by its last evaluation but killed before its summary.json
        every = cfg.eval.interval(cfg.frames)
        next_eval, next_ckpt = _next(s.frames, every), _next(s.frames, cfg.checkpoint.every)
        next_log = s.frames + cfg.log.every
        stats: list[dict[str, list[float]]] = [defaultdict(list) for _ in range(learner.seeds)]
        s.restart()
        for data in collector:
            if not s.active():
                break
            stop_if_signalled(before=s.save_on_stop)
            pieces = learner.split(data)
            s.frames += pieces[0].numel()
            learner.store(pieces, s.frames)
            for piece, seed_stats in zip(pieces, stats):
                _episode_stats(piece, seed_stats)
            if s.frames >= cfg.collector.warm_up_frames:
                with s.clock("update"):
                    s.updates = _update(learner, cfg.optim.updates_per_batch, s.updates, s.frames, stats)
            bar.update(pieces[0].numel())
            if s.frames >= next_log:
                fps = (s.frames - s.start_frames) / (time.perf_counter() - s.start)
                _log([writers[k] for k in s.active()], [stats[k] for k in s.active()], s.frames, fps=fps)
                next_log = s.frames + cfg.log.every
            if s.frames >= next_eval or s.frames >= cfg.frames:
                s.evaluate()
                next_eval = _next(s.frames, every)
            if s.frames >= next_ckpt or s.frames >= cfg.frames:
                if s.saved != s.frames:  # not saved already with the best at this frame
                    s.checkpoint()
                next_ckpt = _next(s.frames, cfg.checkpoint.every)
    finally:
        collector.shutdown()
        bar.close()
        for k in s.active():
            writers[k].close()
    if s.active() and writers[s.active()[0]].rows[-1]["frames"] != s.frames:
        s.evaluate()
    if s.active():
        s.checkpoint()
        s.finish(s.active())


def _evaluation_due(cfg: RunConfig, rows: list[dict], frames: int) -> bool:
    """Whether the loop owes an evaluation at ``frames`` before collecting: at frame 0, and on resuming a
    checkpoint saved by a stop inside the evaluation at its frame (eval.csv stops before the last
    multiple of ``eval.every`` the checkpoint reached, or before the final frame)."""
    if not rows:
        return True
    last, every = rows[-1]["frames"], cfg.eval.interval(cfg.frames)
    return last < frames and (frames >= cfg.frames or last < frames // every * every)


def stop_met(cfg: RunConfig, rows: list[dict], frames: int) -> bool:
    """Whether the evaluation at ``frames`` (the last of ``rows``) reaches ``eval.stop_at_success``."""
    target = cfg.eval.stop_at_success
    return (target is not None and bool(rows) and rows[-1]["frames"] == frames
            and rows[-1].get("success_rate", -math.inf) >= target)


def stop_summary(cfg: RunConfig, rows: list[dict], frames: int) -> dict:
    """summary.json's ``stop_at_success`` entry: whether the run met the criterion, and why it ended where it did
    (``{}`` without one)."""
    target = cfg.eval.stop_at_success
    if target is None:
        return {}
    if stop_met(cfg, rows, frames):
        rate = rows[-1]["success_rate"]
        return {"stop_at_success": {"target": target, "met": True, "frames": frames, "success_rate": rate,
                                    "reason": f"success rate {rate:g} reached eval.stop_at_success={target:g} "
                                              f"at frame {frames:,}"}}
    top = max(r.get("success_rate", -math.inf) for r in rows)
    return {"stop_at_success": {"target": target, "met": False, "frames": frames, "best_success_rate": top,
                                "reason": f"success rate never reached eval.stop_at_success={target:g} (best "
                                          f"{top:g}): trained the whole budget of {frames:,} frames"}}


def _finish(cfg: RunConfig, writers: list[RunWriter], extra_summary, frames: int, updates: int, trained: int,
            clock: PhaseClock, start: float, which: list[int]) -> None:
    """The ``summary.json`` of the writers ``which``: ``trained`` frames (this session's) in the wall time since
    ``start``."""
    wall = time.perf_counter() - start
    extras = extra_summary if isinstance(extra_summary, list) else [extra_summary] * len(writers)
    for k in which:
        writer = writers[k]
        writer.finish(frames, updates, wall, trained,
                      {**(extras[k] or {}), **best.summary(cfg, writer.rows, writer.run_dir),
                       **stop_summary(cfg, writer.rows, frames),
                       "wall_time_split_s": clock.split(wall)})


class PhaseClock:
    """Where a loop's wall time went: ``with clock("update"):`` adds its body's time to a phase; :meth:`split`
    gives the phases and, as ``collect_and_rest``, what is left of the window."""

    PHASES = ("update", "evaluate", "checkpoint")

    def __init__(self):
        self.seconds: dict[str, float] = defaultdict(float)

    def start(self) -> float:
        """Forget what was timed so far (a window starts); returns ``time.perf_counter()``."""
        self.seconds.clear()
        return time.perf_counter()

    @contextlib.contextmanager
    def __call__(self, phase: str):
        begin = time.perf_counter()
        try:
            yield
        finally:
            self.seconds[phase] += time.perf_counter() - begin

    def split(self, wall: float) -> dict[str, float]:
        """Seconds per phase over a window of ``wall`` seconds, rounded to 10 ms."""
        out = {k: round(self.seconds[k], 2) for k in self.PHASES}
        return out | {"collect_and_rest": round(max(wall - sum(self.seconds.values()), 0.0), 2)}


def _log(writers: list[RunWriter], stats: list[dict[str, list[float]]], frames: int, fps: float) -> None:
    """Each seed's training scalars since the last log, averaged, with the loop's frames/s; then forgotten."""
    for writer, seed_stats in zip(writers, stats):
        writer.log({k: sum(v) / len(v) for k, v in seed_stats.items() if v} | {"train/fps": fps}, frames)
        seed_stats.clear()


def _update(learner, count: int, updates: int, frames: int, stats: list[dict[str, list[float]]]) -> int:
    """``count`` gradient steps (the actor's every ``actor_delay``-th), each seed's losses kept in its
    stats; returns the number of updates so far."""
    for batch in learner.batches(count):
        losses = learner.update(batch, update_actor=updates % learner.actor_delay == 0)
        health.check_losses(losses, frames, learner.seeds)
        updates += 1
        for k, v in losses.items():
            if v.numel() == learner.seeds:
                for seed_stats, x in zip(stats, v.reshape(-1).tolist()):
                    seed_stats[f"train/{k}"].append(x)
    return updates


def _episode_stats(data: TensorDictBase, stats: dict) -> None:
    done = data["next", "done"].squeeze(-1)
    if done.any():
        stats["train/episode_return"].extend(data["next", "episode_reward"][done].flatten().tolist())
        if ("next", "success") in data.keys(True):
            stats["train/success_rate"].extend(data["next", "success"][done].float().flatten().tolist())
    if "reused" in data.keys():
        stats["train/reused_fraction"].append(data["reused"].float().mean().item())
