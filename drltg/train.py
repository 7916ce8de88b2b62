"""The training loop: env -> transforms -> Collector -> ReplayBuffer -> loss -> optimizer -> SoftUpdate.

Evaluation runs at frame 0 (before any update) and every ``eval.every`` frames, with the deterministic
actor on a separate evaluation env that measures the task's own reward (never a shaped one) and
success. A run directory holds:

    config.yaml          the resolved config; `drltg train --config config.yaml` reproduces the run
    eval.csv             frames,return_mean,return_std,episodes[,success_rate]  (one row per evaluation)
    logs/csv/, logs/tensorboard/   training scalars (TorchRL CSVLogger + TensorboardLogger)
    checkpoints/last.pt  weights, optimizer, replay buffer and RNG state (for --resume and model reuse)
    summary.json         written last: the run is complete when it exists
"""
from __future__ import annotations

import csv
import io
import json
import math
import os
import shutil
import tempfile
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

from drltg import transfer
from drltg.agents import make_agent
from drltg.config import dump
from drltg.envs import make_env
from drltg.errors import UsageError
from drltg.fast import UpdateStep, sample_batches

EVAL_COLUMNS = ["frames", "return_mean", "return_std", "episodes", "success_rate"]


# ----------------------------------------------------------------------------- files
def atomic_write(path: Path, data: str | bytes) -> None:
    """Write to a temporary file in the same folder, then rename: readers never see half a file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
    with os.fdopen(fd, "wb") as f:
        f.write(data.encode() if isinstance(data, str) else data)
    os.replace(tmp, path)


def atomic_torch_save(obj, path: Path) -> None:
    buf = io.BytesIO()
    torch.save(obj, buf)
    atomic_write(path, buf.getvalue())


def write_eval_csv(path: Path, rows: list[dict]) -> None:
    columns = [c for c in EVAL_COLUMNS if any(c in r for r in rows)]
    out = io.StringIO()
    writer = csv.DictWriter(out, fieldnames=columns, lineterminator="\n")
    writer.writeheader()
    for r in rows:
        writer.writerow({c: r[c] for c in columns})
    atomic_write(path, out.getvalue())


def read_eval_csv(path: Path) -> list[dict]:
    with open(path) as f:
        return [
            {k: (int(v) if k in ("frames", "episodes") else float(v)) for k, v in row.items()}
            for row in csv.DictReader(f)
        ]


def is_complete(run_dir: str | Path) -> bool:
    return (Path(run_dir) / "summary.json").is_file()


# ----------------------------------------------------------------------------- envs
def make_envs(cfg: dict, agent_transforms=()) -> tuple[EnvBase, EnvBase]:
    """Training env (``num_envs`` batched, episode-return tracking) and a separate evaluation env
    (``eval.episodes`` batched, seeded apart from the training env)."""
    seed, device = cfg["seed"], cfg["device"]
    train_env = make_env(
        cfg["task"], batch_size=(cfg["collector"]["num_envs"],), device=device, seed=seed, **cfg["env"]
    )
    eval_env = make_env(
        cfg["task"], batch_size=(cfg["eval"]["episodes"],), device=device, seed=seed + 10_000, **cfg["env"]
    )
    train_env = TransformedEnv(train_env)
    eval_env = TransformedEnv(eval_env)
    for t in agent_transforms:
        train_env.append_transform(t.clone())
        eval_env.append_transform(t.clone())
    train_env.append_transform(RewardSum())
    return train_env, eval_env


@torch.no_grad()
def evaluate(env: EnvBase, actor: Callable, max_steps: int = 100_000) -> dict:
    """Run one episode in every batch element of ``env`` with the deterministic actor.

    Returns the mean/std of the undiscounted episode return and the success rate (fraction of
    episodes in which ``success`` was ever true), counting each element's first episode only.
    """
    td = env.reset()
    shape = env.batch_size
    alive = torch.ones(*shape, 1, dtype=torch.bool, device=env.device)
    ret = torch.zeros(*shape, 1, device=env.device)
    success = torch.zeros_like(alive)
    has_success = "success" in env.full_observation_spec.keys()
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        for _ in range(max_steps):
            td = env.step(actor(td))
            nxt = td["next"]
            ret += nxt["reward"] * alive
            if has_success:
                success |= nxt["success"].bool() & alive
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
    if has_success:
        row["success_rate"] = success.float().mean().item()
    return row


# ----------------------------------------------------------------------------- loop
def _prepare_run_dir(cfg: dict, run_dir: Path, resume: bool) -> dict | None:
    """Validate the run directory; return the checkpoint to resume from (or None)."""
    config_path = run_dir / "config.yaml"
    if not resume:
        if run_dir.exists() and any(run_dir.iterdir()):
            raise UsageError(f"run directory '{run_dir}' already exists; pass --resume to continue it or choose another --run-dir.")
        return None
    if not config_path.is_file():
        raise UsageError(f"cannot resume: '{run_dir}' holds no config.yaml (is it a drltg run directory?).")
    saved = yaml.safe_load(config_path.read_text())
    if saved != cfg:
        changed = sorted(_diff_keys(saved, cfg))
        raise UsageError(
            f"cannot resume '{run_dir}': the config differs from the saved one in {', '.join(changed)}."
        )
    ckpt = run_dir / "checkpoints" / "last.pt"
    return torch.load(ckpt, weights_only=False) if ckpt.is_file() else None


def _diff_keys(a, b, prefix=""):
    if isinstance(a, dict) and isinstance(b, dict):
        for k in set(a) | set(b):
            yield from _diff_keys(a.get(k), b.get(k), f"{prefix}{k}.")
    elif a != b:
        yield prefix.rstrip(".")


def train(
    cfg: dict,
    run_dir: str | Path,
    *,
    resume: bool = False,
    progress: bool = True,
) -> Path:
    """Train ``cfg["algo"]`` on ``cfg["task"]`` for ``cfg["frames"]`` frames, with the transfer method
    of ``cfg["transfer"]``; return the run directory."""
    run_dir = Path(run_dir).expanduser().resolve()
    ckpt = _prepare_run_dir(cfg, run_dir, resume)
    if resume and is_complete(run_dir):
        return run_dir

    torch.set_num_threads(cfg["threads"])
    torch.manual_seed(cfg["seed"])
    # Build everything before writing anything: a bad config fails with nothing on disk.
    transfer.check(cfg)
    probe = make_env(cfg["task"], seed=cfg["seed"], device=cfg["device"], **cfg["env"])
    agent = make_agent(probe, cfg)
    train_env, eval_env = make_envs(cfg, agent.env_transforms)
    method = cfg["transfer"]["method"]
    policy, mixer, reuse_report = agent.policy, None, None
    if method == "reward-shaping":  # after RewardSum: train/episode_return stays the task's return
        train_env.append_transform(transfer.shaping(cfg))
    elif method == "policy-reuse":
        policy, mixer = transfer.reuse_policy(cfg, agent)
    elif method == "model-reuse" and ckpt is None:
        reuse_report = transfer.reuse_weights(cfg, agent)

    col, opt = cfg["collector"], cfg["optim"]
    fpb = col["frames_per_batch"]
    init_random = math.ceil(col["init_random_frames"] / fpb) * fpb
    buffer = ReplayBuffer(
        storage=LazyTensorStorage(cfg["buffer"]["size"], device=cfg["device"]),
        batch_size=cfg["buffer"]["batch_size"],
    )
    frames = updates = 0
    rows: list[dict] = []
    if ckpt is not None:
        agent.loss.load_state_dict(ckpt["loss"])
        agent.optimizer.load_state_dict(ckpt["optimizer"])
        buffer.load_state_dict(ckpt["buffer"])
        torch.set_rng_state(ckpt["rng"])
        frames, updates = ckpt["frames"], ckpt["updates"]
        rows = [r for r in read_eval_csv(run_dir / "eval.csv") if r["frames"] <= frames]

    run_dir.mkdir(parents=True, exist_ok=True)
    atomic_write(run_dir / "config.yaml", dump(cfg))
    if reuse_report is not None:
        atomic_write(run_dir / "model_reuse.txt", f"{reuse_report}\n")
    loggers = [CSVLogger("csv", log_dir=str(run_dir / "logs"))]
    if cfg["log"]["tensorboard"]:
        loggers.append(TensorboardLogger("tensorboard", log_dir=str(run_dir / "logs")))

    def log(metrics: dict, step: int) -> None:
        for logger in loggers:
            for k, v in metrics.items():
                logger.log_scalar(k, float(v), step=step)

    def run_eval() -> None:
        row = {"frames": frames, **evaluate(eval_env, agent.actor)}
        rows.append(row)
        write_eval_csv(run_dir / "eval.csv", rows)
        log({f"eval/{k}": v for k, v in row.items() if k != "frames"}, frames)
        bar.set_postfix(eval_return=f"{row['return_mean']:.3f}", refresh=False)

    def save_checkpoint() -> None:
        atomic_torch_save(
            {
                "loss": agent.loss.state_dict(),
                "optimizer": agent.optimizer.state_dict(),
                "buffer": buffer.state_dict(),
                "rng": torch.get_rng_state(),
                "frames": frames,
                "updates": updates,
            },
            run_dir / "checkpoints" / "last.pt",
        )

    collector = Collector(
        train_env,
        policy,
        frames_per_batch=fpb,
        total_frames=cfg["frames"] - frames,
        init_random_frames=max(init_random - frames, 0),
        device=cfg["device"],
        auto_register_policy_transforms=False,
    )
    bar = tqdm(total=cfg["frames"], initial=frames, unit="frame", disable=not progress, dynamic_ncols=True)
    if not rows:
        run_eval()
    next_eval = (frames // cfg["eval"]["every"] + 1) * cfg["eval"]["every"]
    next_ckpt = (frames // cfg["checkpoint"]["every"] + 1) * cfg["checkpoint"]["every"]
    next_log = frames + cfg["log"]["every"]
    stats: dict[str, list[float]] = defaultdict(list)
    update = UpdateStep(agent)
    start, start_frames = time.perf_counter(), frames

    for data in collector:
        data = data.reshape(-1)
        frames += data.numel()
        if mixer is not None:
            mixer.set_progress(frames)
        buffer.extend(data.select(*agent.loss.in_keys))  # only what the loss reads is stored
        _episode_stats(data, stats)
        if frames >= init_random:
            for batch in sample_batches(buffer, opt["updates_per_batch"]):
                losses = update(batch, update_actor=updates % agent.actor_delay == 0)
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
    collector.shutdown()
    bar.close()
    if rows[-1]["frames"] != frames:
        run_eval()
    save_checkpoint()
    wall = time.perf_counter() - start
    summary = {
        "task": cfg["task"],
        "algo": cfg["algo"],
        "seed": cfg["seed"],
        "frames": frames,
        "updates": updates,
        "wall_time_s": round(wall, 2),
        "frames_per_s": round((frames - start_frames) / max(wall, 1e-9), 1),
        "final_eval": rows[-1],
    }
    atomic_write(run_dir / "summary.json", json.dumps(summary, indent=2) + "\n")
    return run_dir


def _episode_stats(data: TensorDictBase, stats: dict) -> None:
    done = data["next", "done"].squeeze(-1)
    if done.any():
        stats["train/episode_return"].extend(data["next", "episode_reward"][done].flatten().tolist())
        if ("next", "success") in data.keys(True):
            stats["train/success_rate"].extend(data["next", "success"][done].float().flatten().tolist())
    if "reused" in data.keys():
        stats["train/reused_fraction"].append(data["reused"].float().mean().item())


def remove_run(run_dir: Path) -> None:
    shutil.rmtree(run_dir, ignore_errors=True)
