"""Stage 5, describe: the settings and rules a report states, and the plot's data."""
from __future__ import annotations

import math
from pathlib import Path
from typing import Sequence

import numpy as np
import pandas as pd

from drltg.analysis import metrics as M
from drltg.analysis import stats
from drltg.report.align import Window, eval_grid, on_grid
from drltg.report.checks import Sides, tuned_on
from drltg.report.curves import Curve
from drltg.report.inference import UNBOUNDED, family_of, is_missing, num
from drltg.report.settings import MIN_SEEDS, PLOT_POINTS, ReportSettings


def describe(s: ReportSettings, sides: Sides, w: Window, trends: dict, warnings: list[str],
             metrics: dict | None = None) -> dict:
    """The report's ``settings``: every choice made, with the reasons and warnings."""
    family = family_of(metrics or {})
    lo, hi = M.final_window(w.start, w.budget, float(s.asymptote_window))
    return {
        "baseline": [str(c.source) for c in sides.baseline],
        "transfer": [str(c.source) for c in sides.transfer],
        "baseline_label": s.baseline_label or _side_label(sides.baseline, "baseline"),
        "transfer_label": s.transfer_label or _side_label(sides.transfer, "transfer"),
        "task": sides.task,
        "format": s.format,
        "tag": s.tag,
        "start": num(w.start),
        "budget": num(w.budget),
        "budget_source": w.budget_source,
        "paired": sides.paired,
        "pairing": sides.pairing,
        "tuned_on": {side: tuned_on(runs) for side, runs in (("baseline", sides.baseline),
                                                             ("transfer", sides.transfer))},
        "jumpstart_window": int(s.jumpstart_window),
        "asymptote_window": float(s.asymptote_window),
        "asymptote_frames": [num(lo), num(hi)],
        "trend_window": float(s.trend_window),
        "convergence": {side: tr["verdict"] for side, tr in trends.items()},
        "convergence_rule": (f"converged only where two one-sided tests (TOST, level {1 - float(s.confidence):g}) "
                             "show that the mean curve's change over the trend window lies within +-"
                             f"{float(s.convergence_margin):g} x its range over the budget (margin: "
                             + ", ".join(f"{side} {tr['margin']:.4g}" for side, tr in trends.items()) + ")"),
        "convergence_margin": float(s.convergence_margin),
        "threshold": w.threshold,
        "threshold_given": s.threshold,
        "threshold_basis": w.threshold_basis,
        "crossing": s.crossing,
        "sustain": s.sustain,
        "sustain_after": None if s.crossing == "first" or s.sustain else M.SUSTAIN_AFTER,
        "time_to_threshold_rule": _crossing_rule(s),
        "median_rule": ("upper median over seeds: the earliest of the runs' own crossing frames by which a "
                        "strict majority of seeds has crossed; null when no strict majority does"),
        "source_frames": None if w.source_frames is None else [num(f) for f in w.source_frames],
        "source_frames_basis": w.source_basis,
        "smooth": int(s.smooth) if s.smooth else None,
        "ratio_eps": float(s.ratio_eps),
        "ratio_scale": w.scale,
        "interval": _interval_rule(s, sides.paired, w),
        "interval_method": s.interval,
        "allow_mixed": bool(s.allow_mixed),
        "allow_mismatch": bool(s.allow_mismatch),
        "include_unfinished": bool(s.include_unfinished),
        "value_range": None if w.value_range is None else list(w.value_range),
        "value_range_given": None if s.value_range is None else list(s.value_range),
        "p_values": _p_value_rule(sides.paired, s.interval),
        "family": {"size": len(family), "metrics": family, "adjustment": (
            f"Holm over these {len(family)} p-values: the chance of any false finding among them stays "
            f"below the level at which they are read")},
        "confidence": float(s.confidence),
        "bootstrap": int(s.bootstrap),
        "seed": int(s.seed),
        "location": ("mean of each side's seeds (for pairs, the mean of their differences); *_iqm: the "
                     "interquartile mean of each side"),
        "warnings": warnings,
        "plot_smooth": _plot_smooth(sides.runs, w, s),
    }


def _side_label(curves: Sequence[Curve], default: str) -> str:
    """The side's name: the transfer method its drltg runs share (``no transfer`` for none), else the one
    run's label, else the folder that holds its runs, else ``default``."""
    methods = {((c.config or {}).get("transfer") or {}).get("method") if c.config else None for c in curves}
    if len(methods) == 1 and None not in methods:
        method = str(methods.pop())
        return "no transfer" if method == "none" else method
    if len(curves) == 1:
        return curves[0].label
    parents = {Path(c.source).resolve().parent.parent if Path(c.source).is_file()
               else Path(c.source).resolve().parent for c in curves}
    name = parents.pop().name if len(parents) == 1 else ""
    return name or default


def _crossing_rule(s: ReportSettings) -> str:
    if s.crossing == "first":
        return "first evaluation at or above the threshold (--crossing first)"
    if s.sustain:
        return (f"first evaluation from which the run stays at or above the threshold for {s.sustain} "
                "evaluations, the crossing included")
    return ("first evaluation from which the run stays at or above the threshold until the budget, over at "
            f"least {M.SUSTAIN_AFTER} evaluations after it (a crossing at either of the last {M.SUSTAIN_AFTER} "
            "evaluations is not yet sustained)")


def _interval_rule(s: ReportSettings, paired: bool, w: Window) -> str:
    level = f"{100 * float(s.confidence):g}%"
    poi = "Clopper-Pearson's exact interval over pairs" if paired else "Newcombe's score interval (method 5)"
    tail = (f"{poi} for the probabilities of improvement, inside [0, 1]; none with fewer than {MIN_SEEDS} seeds on "
            "a side")
    if s.interval == "auto":
        if w.value_range is None:
            return (f"{level}: none for the mean differences and transfer_ratio ({UNBOUNDED}); {tail}. "
                    f"{BETTING_CLAIM}")
        diff = ("the betting interval (hedged capital, Waudby-Smith & Ramdas 2024) of the per-pair differences"
                if paired else "the two sides' betting intervals (hedged capital, Waudby-Smith & Ramdas 2024) at "
                "half the error level each, their ends subtracted")
        return (f"{level}: {diff} for the mean differences, from the values' range [{w.value_range[0]:g}, "
                f"{w.value_range[1]:g}] alone; the ratio of the sides' intervals for transfer_ratio; {tail}. "
                f"{BETTING_CLAIM}")
    diff = {"t": "paired t-interval on the per-pair differences" if paired else
            "t-interval with Welch's standard error and Hsu's min(n_B, n_T) - 1 degrees of freedom",
            "welch": "paired t-interval" if paired else "Welch t-interval",
            "studentized": "studentized (bootstrap-t) interval", "bca": "BCa bootstrap interval",
            "percentile": "percentile bootstrap interval"}[s.interval]
    bounded = ("" if w.value_range is None else
               f"; the values lie in [{w.value_range[0]:g}, {w.value_range[1]:g}], so every difference's interval "
               f"is cut to +-{w.value_range[1] - w.value_range[0]:g} (the truth lies inside, coverage is kept)")
    return f"{level}: {diff} for the mean differences; Fieller's interval for transfer_ratio; {tail}{bounded}. " \
           f"{COVERAGE_CLAIM}"


BETTING_CLAIM = ("A betting interval holds its level for any scores within the range, learn-or-not seeds "
                 "included (Ville's inequality; in simulation, results/coverage, at least 95% on every shape at 3, "
                 "5 and 10 seeds); it is wide with few seeds and cannot exclude 0 with 6 pairs or fewer.")
COVERAGE_CLAIM = ("In simulation (results/coverage) the t intervals cover at least 93% of the time with 3 to 10 "
                  "seeds on normal, bimodal and success-rate scores, except for paired scores with a strong "
                  "multiplicative seed effect (right-skewed differences) and paired bimodal scores at 3 seeds "
                  "(and at 5 for transfer_ratio), and on learn-or-not scores (0.68 to 0.76 at 3 and 5 seeds); no "
                  "bootstrap interval measured did better there.")
COVERAGE_EXCEPTIONS = (("lognormal", "paired", None), ("bimodal", "paired", 3), ("bimodal", "paired", 5))
"""(scores, design, seeds or None for any) of results/coverage where the claim above does not hold; a test
checks the committed table against it."""


def _p_value_rule(paired: bool, interval: str = "auto") -> str:
    poi = "the exact sign test over pairs (ties dropped)" if paired else \
        "the exact permutation test of the Mann-Whitney estimate"
    exact = "sign-flip test over pairs" if paired else "permutation test of the runs"
    if interval == "auto":
        return (f"two-sided, of no effect: the betting test dual to each mean difference's interval (to "
                f"transfer_ratio's, the sides compared), where there is one; the exact {exact} in *_p_exact for "
                f"every mean difference; {poi} for P(T > B); the slope's t test for final_trend_*")
    test = "the paired t test" if paired else "the t test with Welch's standard error and Hsu's degrees of freedom"
    return (f"two-sided, of no effect: {test} behind each mean difference's interval (transfer_ratio's too, "
            f"whose Fieller interval excludes 0 exactly where it rejects), unless the per-seed scores look skewed "
            f"or bimodal (from {stats.SHAPE_MIN_SEEDS} seeds: D'Agostino's skewness test at 0.05, Sarle's "
            f"bimodality coefficient above 5/9), where the exact {exact}'s p-value is used (given in "
            f"*_p_exact for every mean difference); {poi} for P(T > B); the slope's t test for final_trend_*")


def _plot_smooth(runs: Sequence[Curve], w: Window, s: ReportSettings) -> int:
    """The plotted lines' moving-average width: ``--plot-smooth``, else ``--smooth``, else about
    ``PLOT_POINTS`` windows per curve."""
    n_evals = int(np.median([int((c.frames <= w.budget).sum()) for c in runs]))
    return int(s.plot_smooth or (int(s.smooth) if s.smooth else None) or max(1, n_evals // PLOT_POINTS))


def plot_curves(sides: Sides, w: Window, scores: pd.DataFrame, described: dict) -> dict:
    """Per side, what the plot draws: the (smoothed) mean on a common grid, a t-interval band over seeds
    where there are enough, the raw runs and each run's crossing frame."""
    width, confidence = described["plot_smooth"], described["confidence"]
    curves = {}
    for side, runs in sides.items():
        grid = eval_grid(runs, w.start, w.budget)
        ys = on_grid(runs, grid, width)
        band = None
        if len(runs) >= MIN_SEEDS:
            half = stats.t_quantile(0.5 + confidence / 2, len(runs) - 1) * ys.std(0, ddof=1) / math.sqrt(len(runs))
            band = (ys.mean(0) - half, ys.mean(0) + half)
            if w.value_range is not None:  # a rate's mean lies in its range
                band = tuple(np.clip(x, *w.value_range) for x in band)
        times = [None if is_missing(x) else x for x in scores.loc[scores["side"] == side, "time_to_threshold"]]
        curves[side] = dict(grid=grid, mean=ys.mean(axis=0), band=band, smooth=width,
                            runs=[(c.frames, c.values) for c in runs], times=times)
    return curves
