"""A plan checked before its first frame: what the runs' budgets cannot give, said once per kind of run.

An experiment's runs train in worker processes whose warnings land in their logs, and its report comes
at the end: a budget whose evaluations the report cannot read (too few in the window its convergence
check fits) would be found only then. :func:`plan_warnings` says it before anything trains."""
from __future__ import annotations

from drltg.report.settings import MIN_TREND_POINTS, ReportSettings
from drltg.training.preflight import budget_warnings, every_text


def evaluation_frames(frames: int, every: int) -> list[int]:
    """The frames a run evaluates at: 0, every multiple of ``every`` below ``frames``, and ``frames``."""
    return [*range(0, frames, every), frames]


def plan_warnings(runs) -> list[str]:
    """One sentence per (role, problem) of ``runs`` (:class:`~drltg.experiments.executor.Run`): the budget
    checks of :func:`~drltg.training.preflight.budget_warnings`, and for the target runs the evaluations
    the report's trend check (its last ``trend_window`` of the budget) will have."""
    window = float(ReportSettings().trend_window)
    found: dict[str, list[str]] = {}
    for run in runs:
        cfg = run.cfg
        sentences = budget_warnings(cfg)
        if run.role != "source" and not sentences:
            last = [f for f in evaluation_frames(cfg.frames, cfg.eval.interval(cfg.frames))
                    if f >= (1 - window) * cfg.frames]
            if len(last) < MIN_TREND_POINTS:
                every = int(window * cfg.frames / (MIN_TREND_POINTS - 1))
                sentences = [f"{cfg.frames:,} frames with {every_text(cfg)} give {len(last)} evaluations "
                             f"in the last {100 * window:g}% of the budget, where the report's convergence check "
                             f"needs {MIN_TREND_POINTS}; use -o eval.every={max(every, 1):,} or less."]
        for sentence in sentences:
            found.setdefault(sentence, []).append(run.role)
    return [f"{' and '.join(dict.fromkeys(roles))} runs: {sentence}" for sentence, roles in found.items()]
