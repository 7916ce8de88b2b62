"""The best evaluated checkpoint of a run, ``checkpoints/best.pt`` (``checkpoint.keep_best``).

A run's last checkpoint is not always its best policy: a policy that reached success 1.0 can dip
later. With ``checkpoint.keep_best=true``, after every evaluation whose score is higher than that of
every earlier evaluation, the run saves its checkpoint as ``last.pt`` and the same content as
``best.pt`` (at frame 0, before anything is trained, ``best.pt`` only). The score is the evaluation's
``checkpoint.best_metric``; ``auto`` is ``success_rate`` where the task reports success, else
``return_mean``. A tie keeps the earlier checkpoint: an equal score over the same episodes count is no
evidence that the later policy is better, so ``best.pt`` names the first frame at which the run
reached its best score and is not rewritten at every evaluation of a plateau.

The best of many noisy evaluations overstates the policy it picks (E[max_i X_i] >= max_i E[X_i]), so
the figure to report for ``best.pt`` is a fresh evaluation on other episodes:
``drltg evaluate RUN_DIR --checkpoint best`` (:mod:`drltg.training.reevaluate`).

Writing ``last.pt`` with ``best.pt`` means ``best.pt`` is never from a later frame than ``last.pt``:
a resumed run continues from a checkpoint whose evaluations (eval.csv) include ``best.pt``'s, and
knows the best score so far from them (:func:`check_resume`).
"""
from __future__ import annotations

import math
from pathlib import Path

from drltg.config import RunConfig
from drltg.errors import UsageError
from drltg.store.rundir import BEST, CHECKPOINT, EPISODE_FLAGS, load_checkpoint, write_tracked

__all__ = ["metric", "score", "best_row", "improves", "summary", "check_metric", "check_resume", "outcome"]

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


def summary(cfg: RunConfig, rows: list[dict]) -> dict:
    """``{"best": {checkpoint, frames, metric, score}}`` for summary.json (``{}`` without keep_best)."""
    if not cfg.checkpoint.keep_best or not rows:
        return {}
    row, name = best_row(cfg, rows), metric(cfg, rows[-1])
    return {"best": {"checkpoint": BEST.as_posix(), "frames": row["frames"], "metric": name,
                     "score": score(cfg, row, name)}}


def check_metric(cfg: RunConfig, eval_env) -> None:
    """Refuse a ``checkpoint.best_metric`` rate the task does not report, before the run starts."""
    chosen = cfg.checkpoint.best_metric
    if not cfg.checkpoint.keep_best or chosen in ("auto", "return_mean"):
        return
    flag = chosen.removesuffix("_rate")
    if flag in EPISODE_FLAGS and flag not in eval_env.full_observation_spec.keys():
        raise UsageError(f"checkpoint.best_metric={chosen}, but task '{cfg.task}' reports no '{flag}'; "
                         "use auto or return_mean.")


def check_resume(cfg: RunConfig, run_dir: Path, ckpt: dict | None, rows: list[dict]) -> None:
    """Before a resumed run continues from ``ckpt`` with the evaluations ``rows``: make sure ``best.pt`` is
    the checkpoint of the best of them. A kill between the writes of ``last.pt`` and ``best.pt`` leaves
    ``best.pt`` older than the best evaluation, which is then ``last.pt``'s: it is copied. Any other
    mismatch (``best.pt`` deleted or replaced) is one :class:`UsageError` sentence."""
    if not cfg.checkpoint.keep_best or ckpt is None or not rows:
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
    name = metric(cfg, rows[-1])
    raise UsageError(
        f"cannot resume '{run_dir}': its {BEST.as_posix()} {held}, not that of its best evaluation (frame "
        f"{best['frames']}, {name} {score(cfg, best, name):g}); restore it, or start the run again in another "
        "--run-dir."
    )


def outcome(cfg: RunConfig, rows: list[dict]) -> list[str]:
    """How a run went, for its closing lines: its final and best evaluation, and a warning where the last
    evaluations (the last quarter of them, at least one) fall more than :data:`COLLAPSE` of the run's score
    range below its best: a collapse, which the last checkpoint carries."""
    if not rows:
        return []
    name = metric(cfg, rows[-1])
    label = name.removesuffix("_mean").replace("_", " ")
    best, last = best_row(cfg, rows), rows[-1]
    lines = [f"final evaluation: {label} {score(cfg, last, name):.3g} at frame {last['frames']:,}; best: "
             f"{score(cfg, best, name):.3g} at frame {best['frames']:,}"]
    tail = rows[-max(1, len(rows) // 4):]
    scores = [score(cfg, r, name) for r in rows]
    spread = max(scores) - min(scores)
    drop = score(cfg, best, name) - sum(score(cfg, r, name) for r in tail) / len(tail)
    if best not in tail and spread > 0 and drop > COLLAPSE * spread:
        span = f"frame {tail[0]['frames']:,}" if len(tail) == 1 else f"frames {tail[0]['frames']:,}-{last['frames']:,}"
        keep = ("checkpoints/best.pt keeps the best policy (drltg evaluate RUN --checkpoint best)"
                if cfg.checkpoint.keep_best else
                "train with -o checkpoint.keep_best=true to keep the best policy as checkpoints/best.pt")
        lines.append(f"warning: the run collapsed: its {label} fell from {score(cfg, best, name):.3g} at frame "
                     f"{best['frames']:,} to {score(cfg, last, name):.3g} ({span} average "
                     f"{score(cfg, best, name) - drop:.3g}); the last checkpoint holds the collapsed policy, {keep}.")
    return lines
