"""The networks of a run's best evaluation, ``checkpoints/best.safetensors`` (with ``checkpoint.keep_best``
also its whole checkpoint, ``checkpoints/best.pt``).

A run's last checkpoint is not always its best policy: a policy that reached success 1.0 can dip
later. After every evaluation whose score is higher than that of every earlier evaluation, the run saves
its checkpoint as ``last.pt`` and its networks alone as ``best.safetensors`` too (at frame 0, before
anything is trained, the networks only): they are what ``drltg evaluate --checkpoint best`` and
``transfer.source_checkpoint=best`` read, megabytes where a checkpoint with its replay buffer can be
gigabytes, so every run keeps them. ``checkpoint.keep_best=true`` also keeps the same content as
``last.pt`` as ``best.pt``. The score is the evaluation's
``checkpoint.best_metric``; ``auto`` is ``success_rate`` where the task reports success, else
``return_mean``. A tie keeps the earlier checkpoint: an equal score over the same episodes count is no
evidence that the later policy is better, so ``best.pt`` names the first frame at which the run
reached its best score and is not rewritten at every evaluation of a plateau.

The best of many noisy evaluations overstates the policy it picks (E[max_i X_i] >= max_i E[X_i]), so
the figure to report for the best networks is a fresh evaluation on other episodes:
``drltg evaluate RUN_DIR --checkpoint best`` (:mod:`drltg.training.reevaluate`).

Writing ``last.pt`` with the best means the best is never from a later frame than ``last.pt``: a resumed
run continues from a checkpoint whose evaluations (eval.csv) include the best's, and knows the best score
so far from them (:func:`check_resume`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from drltg.config import RunConfig
from drltg.errors import UsageError
from drltg.store import networks
from drltg.store.rundir import BEST, CHECKPOINT, EPISODE_FLAGS, load_checkpoint, write_tracked

__all__ = ["metric", "score", "best_row", "improves", "summary", "check_metric", "check_resume", "outcome", "Outcome"]

COLLAPSE = 0.5
"""A run collapsed when its last evaluations' mean score lies more than this share of its score range below
its best (its best earlier than those)."""


def metric(cfg: RunConfig, row: dict) -> str:
    """The eval.csv column ``best.pt`` maximises (``auto``: ``success_rate`` where ``row`` has it)."""
    chosen = cfg.checkpoint.best_metric
    if chosen != "auto":
        return chosen
    return "success_rate" if "success_rate" in row else "return_mean"


def score(cfg: RunConfig, row: dict, name: str | None = None) -> float:
    """``row``'s value of the metric (of ``name``; -inf for a row without it: an older row of a resumed
    run that lacks a rate column)."""
    return float(row.get(name or metric(cfg, row), -math.inf))


def best_row(cfg: RunConfig, rows: list[dict]) -> dict | None:
    """The first row with the highest score (ties keep the earlier), scored by the metric of the last row."""
    if not rows:
        return None
    name = metric(cfg, rows[-1])
    return max(rows, key=lambda r: score(cfg, r, name))  # max keeps the first of equal keys


def improves(cfg: RunConfig, rows: list[dict]) -> bool:
    """Whether the last evaluation of ``rows`` scores higher than every earlier one (the first always does)."""
    return best_row(cfg, rows) is rows[-1]


def summary(cfg: RunConfig, rows: list[dict], run_dir: Path) -> dict:
    """``{"best": {networks, [checkpoint,] frames, metric, score}}`` for summary.json; ``{}`` where the run holds
    no best networks (one resumed from a run of an earlier drltg that kept none and improved on nothing since)."""
    if not rows or not (Path(run_dir) / networks.NETWORKS["best"]).is_file():
        return {}
    row, name = best_row(cfg, rows), metric(cfg, rows[-1])
    kept = {"checkpoint": BEST.as_posix()} if cfg.checkpoint.keep_best else {}
    return {"best": {"networks": networks.NETWORKS["best"].as_posix(), **kept, "frames": row["frames"],
                     "metric": name, "score": score(cfg, row, name)}}


def check_metric(cfg: RunConfig, eval_env) -> None:
    """Refuse a ``checkpoint.best_metric`` rate the task does not report, before the run starts."""
    chosen = cfg.checkpoint.best_metric
    if chosen in ("auto", "return_mean"):
        return
    flag = chosen.removesuffix("_rate")
    if flag in EPISODE_FLAGS and flag not in eval_env.full_observation_spec.keys():
        raise UsageError(f"checkpoint.best_metric={chosen}, but task '{cfg.task}' reports no '{flag}'; "
                         "use auto or return_mean.")


def check_resume(cfg: RunConfig, run_dir: Path, ckpt: dict | None, rows: list[dict]) -> None:
    """Before a resumed run continues from ``ckpt`` with the evaluations ``rows``: make sure the best
    networks (with ``keep_best``, ``best.pt``) are those of the best of them. A kill between the writes of
    ``last.pt`` and the best leaves the best older than the best evaluation, which is then ``last.pt``'s: it
    is written from it. Any other mismatch (the best deleted or replaced) is one :class:`UsageError` sentence,
    but for a run of an earlier drltg that kept no best networks: it keeps them from its next best on."""
    if ckpt is None or not rows:
        return
    if not cfg.checkpoint.keep_best:
        _check_best_networks(cfg, run_dir, ckpt, rows)
        return
    best = best_row(cfg, rows)
    path = run_dir / BEST
    saved = load_checkpoint(run_dir, mmap=True, checkpoint="best").get("frames") if path.is_file() else None
    if saved == best["frames"]:
        return
    if best["frames"] == ckpt["frames"]:
        write_tracked(run_dir, BEST.as_posix(), (run_dir / CHECKPOINT).read_bytes())
        return
    held = "is missing" if saved is None else f"is the checkpoint at frame {saved}"
    raise _not_best(cfg, run_dir, f"{BEST.as_posix()} {held}, not that", best, rows)


def _check_best_networks(cfg: RunConfig, run_dir: Path, ckpt: dict, rows: list[dict]) -> None:
    """:func:`check_resume` for a run that keeps its best as networks alone."""
    best = best_row(cfg, rows)
    saved = networks.read_header(run_dir, "best")
    if saved is not None and saved["frames"] == best["frames"]:
        return
    if best["frames"] == ckpt["frames"]:
        write_tracked(run_dir, networks.NETWORKS["best"].as_posix(),
                      networks.encode(ckpt["loss"], ckpt["frames"], ckpt["updates"]))
        return
    if saved is None and not networks.listed(run_dir, "best"):
        return
    held = "is missing" if saved is None else f"holds the networks of frame {saved['frames']}"
    raise _not_best(cfg, run_dir, f"{networks.NETWORKS['best'].as_posix()} {held}, not those", best, rows)


def _not_best(cfg: RunConfig, run_dir: Path, held: str, best: dict, rows: list[dict]) -> UsageError:
    """The sentence refusing to resume a run whose kept best is not its best evaluation's."""
    name = metric(cfg, rows[-1])
    return UsageError(f"cannot resume '{run_dir}': its {held} of its best evaluation (frame {best['frames']}, {name} "
                      f"{score(cfg, best, name):g}); restore it, or start the run again in another --run-dir.")


@dataclass(frozen=True)
class Outcome:
    """How a run went: the final and best evaluation, and the collapse warning where there is one."""

    final: str
    collapse: str | None = None


def outcome(cfg: RunConfig, rows: list[dict]) -> Outcome | None:
    """How a run went, for its closing lines: its final and best evaluation, and a warning where the last
    evaluations (the last quarter of them, at least one) fall more than :data:`COLLAPSE` of the run's score
    range below its best: a collapse, which the last checkpoint carries. ``None`` for a run never evaluated."""
    if not rows:
        return None
    name = metric(cfg, rows[-1])
    label = name.removesuffix("_mean").replace("_", " ")
    best, last = best_row(cfg, rows), rows[-1]
    final = (f"final evaluation: {label} {score(cfg, last, name):.3g} at frame {last['frames']:,}; best: "
             f"{score(cfg, best, name):.3g} at frame {best['frames']:,}")
    tail = rows[-max(1, len(rows) // 4):]
    scores = [score(cfg, r, name) for r in rows]
    spread = max(scores) - min(scores)
    drop = score(cfg, best, name) - sum(score(cfg, r, name) for r in tail) / len(tail)
    if best not in tail and spread > 0 and drop > COLLAPSE * spread:
        span = f"frame {tail[0]['frames']:,}" if len(tail) == 1 else f"frames {tail[0]['frames']:,}-{last['frames']:,}"
        keep = (f"{networks.NETWORKS['best'].as_posix()} keeps the best policy's networks (drltg evaluate RUN "
                "--checkpoint best)")
        return Outcome(final, f"the run collapsed: its {label} fell from {score(cfg, best, name):.3g} at frame "
                              f"{best['frames']:,} to {score(cfg, last, name):.3g} ({span} average "
                              f"{score(cfg, best, name) - drop:.3g}); the last checkpoint holds the collapsed "
                              f"policy, {keep}.")
    return Outcome(final)
