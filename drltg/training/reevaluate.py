"""A run's saved policy evaluated afresh: ``drltg evaluate RUN_DIR [--checkpoint best]``.

The training evaluations that chose the best networks cannot also measure them: the best of many noisy
evaluations overstates the policy it picks. :func:`evaluate_run` runs the checkpoint's deterministic
actor through the training loop's own :func:`~drltg.training.loop.evaluate` on ``episodes`` new
episodes, from an env seeded apart from every env of training: the training env is seeded ``seed``,
its evaluations ``seed + EVAL_SEED_OFFSET``, demonstrations ``seed + DEMO_SEED_OFFSET``, and this
evaluation by default ``seed + FRESH_SEED_OFFSET`` (``seed``: the run's; the offsets are in
:mod:`drltg.config.values`). Each rate comes with its exact (Clopper-Pearson) 95% interval,
[B(0.025; k, n - k + 1), B(0.975; k + 1, n - k)] for k of n episodes, whose coverage is at least 95% whatever
the rate: the conservative choice for a claim that a policy succeeds reliably.
"""
from __future__ import annotations

from pathlib import Path

from drltg.config.values import FRESH_SEED_OFFSET
from drltg.errors import UsageError

__all__ = ["evaluate_run", "rate_interval", "FRESH_SEED_OFFSET"]

def rate_interval(successes: int, episodes: int, confidence: float = 0.95) -> tuple[float, float]:
    """The exact (Clopper-Pearson) interval of a rate observed as ``successes`` of ``episodes``."""
    from scipy import stats

    ci = stats.binomtest(successes, episodes).proportion_ci(confidence_level=confidence, method="exact")
    return float(ci.low), float(ci.high)


def pooled(rows: list[dict]) -> dict:
    """One evaluation row from the rows of several batches: rates and the mean weighted by episodes, the
    standard deviation of all episodes together, sqrt(sum_i n_i (s_i^2 + m_i^2) / N - m^2)."""
    n = [r["episodes"] for r in rows]
    total = sum(n)
    mean = sum(k * r["return_mean"] for k, r in zip(n, rows)) / total
    square = sum(k * (r["return_std"] ** 2 + r["return_mean"] ** 2) for k, r in zip(n, rows)) / total
    out = {"return_mean": mean, "return_std": max(square - mean**2, 0.0) ** 0.5, "episodes": total}
    for key in [k for k in rows[0] if k.endswith("_rate")]:
        out[key] = sum(k * r[key] for k, r in zip(n, rows)) / total
    return out


def evaluate_run(run_dir: str | Path, *, checkpoint: str = "last", episodes: int = 100, seed: int | None = None,
                 device: str = "cpu") -> dict:
    """Evaluate the deterministic actor of ``run_dir``'s ``checkpoints/<checkpoint>.pt`` on ``episodes``
    episodes, in batched envs of at most the run's ``eval.episodes`` envs (what its training evaluations
    held at once: 10 robosuite envs, not 100), batch i seeded ``seed + i`` (default ``seed``: the run's
    seed + ``FRESH_SEED_OFFSET``), the rows :func:`pooled`. Returns the evaluation's numbers with the
    checkpoint, its frame, the seed and a 95% interval ``<flag>_rate_ci95`` for every rate."""
    from drltg.config import MAX_EPISODES, check_device
    from drltg.training.loop import evaluate, make_eval_env
    from drltg.transfer.source import rebuild

    if not 1 <= episodes <= MAX_EPISODES:
        raise UsageError(f"--episodes must be between 1 and {MAX_EPISODES}, got {episodes}.")
    if seed is not None and not 0 <= seed <= 2**31 - 1:
        raise UsageError(f"--seed must be an integer in [0, 2147483647], got {seed}.")
    check_device("--device", device)
    agent, _, cfg, frames = rebuild(run_dir, device, checkpoint)
    cfg = cfg.model_copy(update={"device": device})
    seed = cfg.seed + FRESH_SEED_OFFSET if seed is None else seed
    batch = cfg.eval.episodes
    rows = []
    for i, start in enumerate(range(0, episodes, batch)):
        env = make_eval_env(cfg, min(batch, episodes - start), seed + i, agent.env_transforms)
        try:
            rows.append(evaluate(env, agent.actor))
        finally:
            env.close()
    row = pooled(rows)
    result = {"run": Path(run_dir).as_posix(), "checkpoint": checkpoint, "frames": frames,
              "episodes": episodes, "seed": seed, **{k: v for k, v in row.items() if k != "episodes"}}
    for key in [k for k in row if k.endswith("_rate")]:
        result[f"{key}_ci95"] = list(rate_interval(round(row[key] * episodes), episodes))
    return result
