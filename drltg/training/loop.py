"""The training loop: env -> transforms -> Collector -> ReplayBuffer -> loss -> optimizer -> SoftUpdate.

Evaluation runs at frame 0 (before any update) and every ``eval.every`` frames, with the deterministic
actor on a separate evaluation env that measures the task's own reward (never a shaped one) and
success. What a run directory holds is described in :mod:`drltg.training.rundir`; :func:`train` owns it (its
lock) while it runs, checks everything it can before creating it, and removes what a failed start
wrote before its first checkpoint, so a retry is never blocked.
"""
from __future__ import annotations

import contextlib
import json
import math
import shutil
import signal
import threading
import time
from collections import defaultdict
from pathlib import Path
from typing import Callable

import torch
import yaml
from tensordict import TensorDictBase
from torchrl.collectors import Collector
from torchrl.data import LazyTensorStorage, ReplayBuffer
from torchrl.envs import EnvBase, ExplorationType, RewardSum, TransformedEnv, set_exploration_type
from torchrl.record.loggers import CSVLogger, TensorboardLogger
from tqdm.auto import tqdm

from drltg.config import config_changes
from drltg.envs import make_env
from drltg.errors import UsageError
from drltg.learners import UpdateStep, make_agent, sample_batches
from drltg.training import health, manifest, preflight, rundir
from drltg.training.rundir import CHECKPOINT, CONFIG, EPISODE_FLAGS, EVAL, SUMMARY, is_complete, read_eval_csv
from drltg.transfer import Transfer, get_method
from drltg.transfer.source import check as check_source

__all__ = ["train", "evaluate", "make_envs", "build_env", "check_config", "is_complete", "read_eval_csv"]


# ----------------------------------------------------------------------------- envs
def build_env(cfg: dict, **kwargs) -> EnvBase:
    """``make_env`` of the config's task with its ``env`` settings; a setting the task cannot take
    (``env.horizon=abc``) is one :class:`UsageError` sentence."""
    try:
        return make_env(cfg["task"], device=cfg["device"], **{**cfg["env"], **kwargs})
    except UsageError:
        raise
    except (TypeError, ValueError) as err:
        raise UsageError(f"task '{cfg['task']}' cannot be built with env settings {cfg['env']} ({err}).") from None


def make_envs(cfg: dict, agent_transforms=()) -> tuple[EnvBase, EnvBase]:
    """Training env (``num_envs`` batched, episode-return tracking) and a separate evaluation env
    (``eval.episodes`` batched, seeded apart from the training env)."""
    seed = cfg["seed"]
    train_env = TransformedEnv(build_env(cfg, batch_size=(cfg["collector"]["num_envs"],), seed=seed))
    eval_env = TransformedEnv(build_env(cfg, batch_size=(cfg["eval"]["episodes"],), seed=seed + 10_000))
    preflight.check_batch(cfg, train_env, eval_env)
    for t in agent_transforms:
        train_env.append_transform(t.clone())
        eval_env.append_transform(t.clone())
    train_env.append_transform(RewardSum())
    return train_env, eval_env


def check_config(cfg: dict):
    """Build the task's env and the learner of ``cfg`` (writing nothing): the checks a config can
    fail before any run directory is created. Returns the env and the agent."""
    probe = build_env(cfg, seed=cfg["seed"])
    preflight.check_network(cfg, probe)
    agent = make_agent(probe, cfg)
    preflight.check_buffer(cfg, probe, agent.loss.in_keys)
    return probe, agent


@torch.no_grad()
def evaluate(env: EnvBase, actor: Callable, max_steps: int = 100_000) -> dict:
    """Run one episode in every batch element of ``env`` with the deterministic actor.

    Returns the mean/std of the undiscounted episode return and, for each ``rundir.EPISODE_FLAGS``
    entry the env reports (``success``; ``lifted`` on the manipulation tasks), the fraction of episodes
    in which it was ever true (``success_rate``, ``lifted_rate``), counting each element's first
    episode only.
    """
    td = env.reset()
    shape = env.batch_size
    alive = torch.ones(*shape, 1, dtype=torch.bool, device=env.device)
    ret = torch.zeros(*shape, 1, device=env.device)
    flags = [key for key in EPISODE_FLAGS if key in env.full_observation_spec.keys()]
    ever = {key: torch.zeros_like(alive) for key in flags}
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        for _ in range(max_steps):
            td = env.step(actor(td))
            nxt = td["next"]
            ret += nxt["reward"] * alive
            for key in flags:
                ever[key] |= nxt[key].bool() & alive
            alive &= ~nxt["done"].bool()
            if not alive.any():
                break
            td = td["next"].clone()
    ret = ret.flatten().double()
    row = {
        "return_mean": ret.mean().item(),
        "return_std": ret.std(unbiased=False).item(),
        "episodes": ret.numel(),
    }
    for key in flags:
        row[f"{key}_rate"] = ever[key].float().mean().item()
    return row


# ----------------------------------------------------------------------------- run directory
def _refuse_existing(run_dir: Path) -> None:
    if rundir.entries(run_dir):
        raise UsageError(
            f"run directory '{run_dir}' already exists; pass --resume to continue it or choose another --run-dir."
        )


def _check_saved_config(cfg: dict, run_dir: Path) -> None:
    try:
        saved = rundir.read_config(run_dir)
    except yaml.YAMLError:
        raise UsageError(f"cannot resume: '{run_dir / CONFIG}' is not valid YAML.") from None
    changed = config_changes(saved if isinstance(saved, dict) else {}, rundir.absolute_source(cfg, Path.cwd()))
    if changed:
        raise UsageError(f"cannot resume '{run_dir}': the config differs from the saved one in {', '.join(changed)}.")


def _resume_state(cfg: dict, run_dir: Path) -> tuple[dict | None, list[dict]]:
    """The checkpoint to continue from (``None``: start over) and the evaluations up to it."""
    if not (run_dir / CHECKPOINT).is_file():
        return None, []
    ckpt = rundir.load_checkpoint(run_dir, map_location=cfg["device"])
    if not {"frames", "updates", "optimizer", "buffer", "rng"} <= set(ckpt):
        raise UsageError(f"cannot resume '{run_dir}': its checkpoint is not a training checkpoint of drltg train.")
    frames = ckpt["frames"]
    if not (run_dir / EVAL).is_file():
        raise UsageError(
            f"cannot resume '{run_dir}': its {EVAL} is missing, so the curve up to the checkpoint at frame "
            f"{frames} is lost; start the run again in another --run-dir."
        )
    rows = [r for r in read_eval_csv(run_dir / EVAL) if r["frames"] <= frames]
    found, expected = [r["frames"] for r in rows], ckpt.get("evaluations", [0])
    missing = sorted(set(expected) - set(found))
    if missing:
        raise UsageError(
            f"cannot resume '{run_dir}': {EVAL} lacks the evaluations at frames {missing} before the checkpoint "
            f"at frame {frames}; restore it or start the run again in another --run-dir."
        )
    if len(found) != len(set(found)):
        raise UsageError(
            f"cannot resume '{run_dir}': {EVAL} repeats frames before the checkpoint at frame {frames}; restore "
            "it or start the run again in another --run-dir."
        )
    return ckpt, rows


def _remove_start(run_dir: Path, created: bool) -> None:
    """Remove what a failed start wrote, so that the same command can be run again."""
    if created:
        shutil.rmtree(run_dir, ignore_errors=True)
        return
    for path in rundir.entries(run_dir):
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path, ignore_errors=True)
        else:
            path.unlink(missing_ok=True)


# ----------------------------------------------------------------------------- loop
def train(
    cfg: dict,
    run_dir: str | Path,
    *,
    resume: bool = False,
    progress: bool = True,
) -> Path:
    """Train ``cfg["algo"]`` on ``cfg["task"]`` for ``cfg["frames"]`` frames, with the transfer method
    of ``cfg["transfer"]``; return the run directory.

    The directory is locked while the run writes it (a second process is refused). Everything the
    config can fail on is built before a new directory is created; if a new run fails before its first
    checkpoint, what it wrote is removed, and after it the directory can be resumed.
    """
    run_dir = rundir.check_directory(run_dir, "--run-dir")
    with contextlib.ExitStack() as owned:
        if resume:
            if not (run_dir / CONFIG).is_file():
                raise UsageError(f"cannot resume: '{run_dir}' holds no {CONFIG} (is it a drltg run directory?).")
            _check_saved_config(cfg, run_dir)
            if is_complete(run_dir):  # nothing to write: a finished run may sit in a read-only archive
                return run_dir
            owned.enter_context(rundir.lock(run_dir))
            if is_complete(run_dir):  # finished by its previous owner meanwhile
                return run_dir
            ckpt, rows = _resume_state(cfg, run_dir)
        else:
            _refuse_existing(run_dir)
            ckpt, rows = None, []

        torch.set_num_threads(cfg["threads"])
        torch.manual_seed(cfg["seed"])
        # Build everything before writing anything: a bad config fails with nothing on disk.
        check_source(cfg)
        probe, agent = check_config(cfg)
        train_env, eval_env = make_envs(cfg, agent.env_transforms)
        transfer = get_method(cfg["transfer"]["method"]).build(cfg, agent, probe, resuming=ckpt is not None)
        for t in transfer.train_transforms:  # after RewardSum: train/episode_return stays the task's return
            train_env.append_transform(t)
        buffer = ReplayBuffer(
            storage=LazyTensorStorage(cfg["buffer"]["size"], device=cfg["device"]),
            batch_size=cfg["buffer"]["batch_size"],
        )
        if ckpt is not None:
            try:
                agent.loss.load_state_dict(ckpt["loss"])
                agent.optimizer.load_state_dict(ckpt["optimizer"])
                buffer.load_state_dict(ckpt["buffer"])
            except (KeyError, RuntimeError, ValueError) as err:
                raise UsageError(
                    f"checkpoint '{run_dir / CHECKPOINT}' does not fit the run's config ({type(err).__name__})."
                ) from None

        created = False
        if resume:
            rundir.truncate_logs(run_dir, ckpt["frames"] if ckpt is not None else -1)
        else:
            created = not run_dir.exists()
            try:
                run_dir.mkdir(parents=True, exist_ok=True)
            except OSError as err:
                raise UsageError(f"cannot create --run-dir '{run_dir}' ({err.strerror}).") from None
            owned.enter_context(rundir.lock(run_dir))
            _refuse_existing(run_dir)  # another process started it first
        try:
            for name, text in transfer.files.items():
                rundir.atomic_write(run_dir / name, text)
            with deferred_signals() as stop_if_signalled, health.on_divergence(run_dir, cfg):
                _loop(cfg, run_dir, agent, train_env, eval_env, transfer, buffer, ckpt, rows, progress,
                      stop_if_signalled)
        except BaseException as err:
            if not resume and not (run_dir / CHECKPOINT).is_file() and not isinstance(err, health.Diverged):
                _remove_start(run_dir, created)
            raise
    return run_dir


@contextlib.contextmanager
def deferred_signals(signums=(signal.SIGINT, signal.SIGTERM)):
    """Hold SIGINT and SIGTERM while training and hand them to the handlers that were in place (Ctrl-C's
    KeyboardInterrupt, the CLI's SIGTERM unwinding) when the loop calls the yielded check, once per
    batch, or at the end. Raised in the middle of a TorchRL loss, the exception does not always unwind:
    tensordict's context managers can turn it into another error, and a stopped run would end in a
    traceback instead of releasing its directory."""
    if threading.current_thread() is not threading.main_thread():  # handlers can only be set there
        yield lambda: None
        return
    received: list[int] = []
    previous = {s: signal.signal(s, lambda signum, frame: received.append(signum)) for s in signums}

    def deliver() -> None:
        if received:
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


def _loop(cfg, run_dir, agent, train_env, eval_env, transfer: Transfer, buffer, ckpt, rows, progress,
          stop_if_signalled) -> None:
    col, opt = cfg["collector"], cfg["optim"]
    fpb = col["frames_per_batch"]
    init_random = math.ceil(col["init_random_frames"] / fpb) * fpb
    frames = updates = 0
    if ckpt is not None:
        torch.set_rng_state(ckpt["rng"])
        frames, updates = ckpt["frames"], ckpt["updates"]

    rundir.write_config(run_dir, cfg)
    loggers = [CSVLogger("csv", log_dir=str(run_dir / rundir.LOGS))]
    if cfg["log"]["tensorboard"]:
        loggers.append(TensorboardLogger("tensorboard", log_dir=str(run_dir / rundir.LOGS)))

    def log(metrics: dict, step: int) -> None:
        for logger in loggers:
            for k, v in metrics.items():
                logger.log_scalar(k, float(v), step=step)

    def run_eval() -> None:
        row = {"frames": frames, **evaluate(eval_env, agent.actor)}
        rows.append(row)
        rundir.write_eval_csv(run_dir / EVAL, rows)
        log({f"eval/{k}": v for k, v in row.items() if k != "frames"}, frames)
        bar.set_postfix(eval_return=f"{row['return_mean']:.3f}", refresh=False)

    def save_checkpoint() -> None:
        health.check_parameters(agent.loss, frames)
        rundir.atomic_torch_save(
            {
                "loss": agent.loss.state_dict(),
                "optimizer": agent.optimizer.state_dict(),
                "buffer": buffer.state_dict(),
                "rng": torch.get_rng_state(),
                "frames": frames,
                "updates": updates,
                "evaluations": [r["frames"] for r in rows],
            },
            run_dir / CHECKPOINT,
        )

    collector = Collector(
        train_env,
        agent.policy if transfer.policy is None else transfer.policy,
        frames_per_batch=fpb,
        total_frames=cfg["frames"] - frames,
        init_random_frames=max(init_random - frames, 0),
        device=cfg["device"],
        auto_register_policy_transforms=False,
    )
    bar = tqdm(total=cfg["frames"], initial=frames, unit="frame", disable=not progress, dynamic_ncols=True)
    try:
        if not rows:
            run_eval()
        next_eval = (frames // cfg["eval"]["every"] + 1) * cfg["eval"]["every"]
        next_ckpt = (frames // cfg["checkpoint"]["every"] + 1) * cfg["checkpoint"]["every"]
        next_log = frames + cfg["log"]["every"]
        stats: dict[str, list[float]] = defaultdict(list)
        update = UpdateStep(agent, loss_terms=transfer.loss_terms)
        start, start_frames = time.perf_counter(), frames

        for data in collector:
            stop_if_signalled()
            data = data.reshape(-1)
            frames += data.numel()
            if transfer.on_frames is not None:
                transfer.on_frames(frames)
            buffer.extend(data.select(*agent.loss.in_keys))  # only what the loss reads is stored
            _episode_stats(data, stats)
            if frames >= init_random:
                for batch in (transfer.batches or sample_batches)(buffer, opt["updates_per_batch"]):
                    losses = update(batch, update_actor=updates % agent.actor_delay == 0)
                    health.check_losses(losses, frames)
                    updates += 1
                    for k, v in losses.items():
                        if v.numel() == 1:
                            stats[f"train/{k}"].append(v.item())
            bar.update(data.numel())
            if frames >= next_log:
                fps = (frames - start_frames) / (time.perf_counter() - start)
                log({k: sum(v) / len(v) for k, v in stats.items() if v} | {"train/fps": fps}, frames)
                stats.clear()
                next_log = frames + cfg["log"]["every"]
            if frames >= next_eval or frames >= cfg["frames"]:
                run_eval()
                next_eval = (frames // cfg["eval"]["every"] + 1) * cfg["eval"]["every"]
            if frames >= next_ckpt or frames >= cfg["frames"]:
                save_checkpoint()
                next_ckpt = (frames // cfg["checkpoint"]["every"] + 1) * cfg["checkpoint"]["every"]
    finally:
        collector.shutdown()
        bar.close()
        for logger in loggers:
            if isinstance(logger, TensorboardLogger):
                logger.experiment.close()
    if rows[-1]["frames"] != frames:
        run_eval()
    save_checkpoint()
    wall = time.perf_counter() - start
    summary = {
        "status": health.COMPLETE,
        "task": cfg["task"],
        "algo": cfg["algo"],
        "seed": cfg["seed"],
        "frames": frames,
        "updates": updates,
        "wall_time_s": round(wall, 2),
        "frames_per_s": round((frames - start_frames) / max(wall, 1e-9), 1),
        "final_eval": rows[-1],
        **transfer.summary,
    }
    rundir.atomic_write(run_dir / SUMMARY, json.dumps(summary, indent=2) + "\n")
    manifest.finalize(run_dir)


def _episode_stats(data: TensorDictBase, stats: dict) -> None:
    done = data["next", "done"].squeeze(-1)
    if done.any():
        stats["train/episode_return"].extend(data["next", "episode_reward"][done].flatten().tolist())
        if ("next", "success") in data.keys(True):
            stats["train/success_rate"].extend(data["next", "success"][done].float().flatten().tolist())
    if "reused" in data.keys():
        stats["train/reused_fraction"].append(data["reused"].float().mean().item())
