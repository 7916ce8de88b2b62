"""Stage 4, metrics: each catalogue entry turns score columns into a value, its interval and
p-values (Holm over the report's family); the final trends."""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np
import pandas as pd

from drltg.analysis import metrics as M
from drltg.analysis import order_stats, stats
from drltg.analysis.planning import pairs_for_power
from drltg.analysis.stats import ASSUMES
from drltg.analysis.tables import number
from drltg.report.align import Window, eval_grid, on_grid
from drltg.report.catalogue import COMPARISONS, Metric, of_kind
from drltg.report.curves import Curve
from drltg.report.settings import MIN_SEEDS, MIN_TREND_POINTS, SIDES, ReportSettings


def metric_values(scores: pd.DataFrame, trends: dict, paired: bool, w: Window, s: ReportSettings,
                  warnings: list[str]) -> dict:
    """The ``metrics`` object, stage by stage (the JSON keeps this order): seed counts; comparisons of the
    sides with their intervals; each side's summaries; the trends of the mean curves."""
    sides = {side: scores[scores["side"] == side] for side in SIDES}
    m: dict = {}
    for metric in of_kind("count"):
        m.update({metric.key(side): len(sides[side]) for side in metric.sides})
    n_b, n_t = len(sides["baseline"]), len(sides["transfer"])
    enough = min(n_b, n_t) >= MIN_SEEDS
    if not enough:
        warnings.append(f"intervals need at least {MIN_SEEDS} seeds per side (got {n_b} baseline, "
                        f"{n_t} transfer); none are reported.")
    for metric in of_kind(*COMPARISONS):
        if metric.score in scores:
            b = sides["baseline"][metric.score].to_numpy(np.float64)
            t = sides["transfer"][metric.score].to_numpy(np.float64)
            m.update(_compare(metric, b, t, paired, w, s, enough, warnings))
    for side in SIDES:
        for metric in of_kind("mean", "time", "reached"):
            if side in metric.sides and metric.score in scores:
                m[metric.key(side)] = _summary(metric, sides[side][metric.score], w.threshold)
    for metric in of_kind("trend"):
        for side in metric.sides:
            m.update(_trend_values(metric, side, trends[side], s, warnings))
    return _with_holm(m)


def _with_holm(m: dict) -> dict:
    """``<name>_p_adjusted`` after each ``<name>_p_value``: Holm's adjustment over every p-value of the
    report, the family of intervals read together."""
    family = [k for k in m if k.endswith("_p_value")]
    adjusted = dict(zip(family, stats.holm([m[k] for k in family])))
    out = {}
    for key, value in m.items():
        out[key] = value
        if key in adjusted:
            out[key.removesuffix("_p_value") + "_p_adjusted"] = adjusted[key]
    return out


def family_of(metrics: dict) -> list[str]:
    """The metrics whose p-values are adjusted together (those with an interval and a test)."""
    return [k.removesuffix("_p_value") for k in metrics if k.endswith("_p_value")]


def _compare(metric: Metric, b: np.ndarray, t: np.ndarray, paired: bool, w: Window, s: ReportSettings,
             enough: bool, warnings: list[str]) -> dict:
    """``<name>``, and where an honest interval exists ``<name>_ci`` with its p-values; ``<name>_iqm``."""
    eps = float(s.ratio_eps)
    value = _estimate(metric, b, t, paired, M.mean, w.scale, eps)
    out = {metric.name: value}
    if metric.kind == "ratio" and value is None:
        why = ("every curve is 0 at every evaluation in the window" if w.scale == 0 else
               f"the baseline area ({b.mean():.4g}) is within {eps * 100:g}% of the largest possible area "
               f"({w.scale:.4g}) of zero")
        warnings.append(f"{why}, so transfer_ratio is undefined (null); compare mean_return_gain instead.")
    if enough:
        ci, why = _confidence_interval(metric, value, b, t, paired, w, s)
        if ci is not None:
            out[f"{metric.name}_ci"] = ci
            out[f"{metric.name}_ci_assumes"] = interval_assumes(metric.kind, paired, s.interval)
            out.update(_p_values(metric, b, t, paired, w, s, warnings))
        else:
            if why and why not in warnings:
                warnings.append(why)
            if metric.kind == "difference":
                out[f"{metric.name}_p_exact"] = stats.permutation_test(b, t, paired, seed=int(s.seed))
    if metric.iqm:
        out[f"{metric.name}_iqm"] = _estimate(metric, b, t, paired, M.interquartile_mean, w.scale, eps)
    out.update(_verdict(metric, value, b, t, paired, s, out))
    if enough and metric.kind == "difference":
        out.update(magnitudes(metric.name, b, t, paired, w, s))
    return out




def interval_assumes(kind: str, paired: bool, interval: str) -> str:
    """The label of the ``<name>_ci`` of a comparison of ``kind`` under ``--interval interval``."""
    if kind == "poi":
        return ASSUMES["pairs" if paired else "runs"]
    if interval == "auto":
        return ASSUMES["range"]
    if kind == "ratio":
        return ASSUMES["normal areas"]
    if interval in ("t", "welch"):
        return ASSUMES["normal differences" if paired else "normal scores"]
    return ASSUMES["resampling"]


def magnitudes(name: str, b: np.ndarray, t: np.ndarray, paired: bool, w: Window, s: ReportSettings) -> dict:
    r"""The magnitudes beside a mean difference's verdict, each with what it assumes (``<key>_assumes``):
    ``<name>_t_interval``, the t interval (paired on :math:`d_i`, or Welch's standard error with Hsu's degrees of
    freedom), which assumes normal differences (scores); and ``<name>_median`` with ``<name>_median_interval``, an
    order-statistic interval at the coverage ``<name>_median_interval_level`` it holds, at least ``confidence``:
    paired, of the median of the :math:`d_i` (:func:`order_stats.median_interval`), assuming independent pairs only;
    unpaired, of the Hodges-Lehmann shift, the median of every :math:`T_j - B_i` (:func:`order_stats.shift_interval`),
    assuming independent runs whose sides differ by a shift. Each is left out where it does not exist (no spread;
    too few pairs for the order statistics)."""
    out: dict = {}
    lo, hi = (float(x) for x in stats.t_interval(b, t, paired=paired, confidence=float(s.confidence)))
    if math.isfinite(lo) and math.isfinite(hi):
        out[f"{name}_t_interval"] = _within(lo, hi, w.value_range)
        out[f"{name}_t_interval_assumes"] = ASSUMES["normal differences" if paired else "normal scores"]
    if paired:
        median, lo, hi, level = order_stats.median_interval(t - b, float(s.confidence))
    else:
        median, lo, hi, level = order_stats.shift_interval(b, t, float(s.confidence))
    out[f"{name}_median"] = median
    if math.isfinite(lo):
        out[f"{name}_median_interval"] = [lo, hi]
        out[f"{name}_median_interval_level"] = level
        out[f"{name}_median_interval_assumes"] = ASSUMES["pairs" if paired else "shift"]
    return out


VERDICT_TESTS = {("difference", True): "sign-flip", ("difference", False): "permutation",
                 ("ratio", True): "sign-flip", ("ratio", False): "permutation",
                 ("poi", True): "sign", ("poi", False): "permutation"}
"""The exact test that decides each kind of comparison, paired or not: sign-flip over the pairs' differences,
permutation of the runs between the sides, the sign test of P(T_i > B_i) = 1/2 over pairs."""


def _verdict(metric: Metric, value, b, t, paired: bool, s: ReportSettings, out: dict) -> dict:
    r"""``<name>_verdict``: ``higher`` / ``lower`` where the exact randomization test rejects "no effect" at
    :math:`\alpha` = 1 - ``confidence``, by the sign of the metric (of P(T > B) - 1/2); for a mean difference
    it leaves undecided, ``equivalent`` where ``equivalence_margin`` is given and TOST (:func:`stats.tost`,
    which assumes normal differences) puts it within the margin; else ``undecided``;
    ``<name>_verdict_test`` names the test and ``<name>_verdict_p`` its two-sided p-value. The test's
    false-claim rate is at most :math:`\alpha` for any scores at any seed count (learn-or-not included), so
    a verdict needs no range, no normality and no interval; read alone (the report's headline metric,
    named in advance), not Holm-adjusted. Exact below 14 pairs (or 9999 arrangements), seeded Monte Carlo
    above."""
    test = VERDICT_TESTS[metric.kind, paired]
    if min(len(b), len(t)) == 0:
        return {}
    if metric.kind == "poi":
        p = stats.sign_test(b, t) if paired else stats.permutation_test(b, t, statistic="poi", seed=int(s.seed))
        effect = None if value is None else value - 0.5
    else:
        p = out.get(f"{metric.name}_p_exact")
        if p is None:
            p = stats.permutation_test(b, t, paired, seed=int(s.seed))
        effect = value
    alpha = 1.0 - float(s.confidence)
    decided = effect is not None and effect != 0 and p < alpha
    word = ("higher" if effect > 0 else "lower") if decided else "undecided"
    if (word == "undecided" and metric.kind == "difference" and s.equivalence_margin is not None
            and min(len(b), len(t)) >= 2):
        p_equivalent = stats.tost(b, t, paired, float(s.equivalence_margin))
        if p_equivalent < alpha:
            word, p = "equivalent", p_equivalent
            test = f"TOST within +-{float(s.equivalence_margin):g}, {'paired t' if paired else 'Welch t'}"
    out = {f"{metric.name}_verdict": word, f"{metric.name}_verdict_test": test, f"{metric.name}_verdict_p": float(p)}
    if word == "undecided" and metric.name == "mean_return_gain" and paired and len(b) >= 3:
        out["mean_return_gain_pairs_for_80_power"] = pairs_for_power(np.asarray(t) - np.asarray(b))
    return out


def _estimate(metric: Metric, b: np.ndarray, t: np.ndarray, paired: bool, location, scale, eps):
    """The metric with ``location`` taken of each side: one definition per name, paired or not (for
    the mean, the mean of the pairs' differences; P(T > B) alone counts pairs when paired)."""
    if metric.kind == "difference":
        return float(location(t) - location(b))
    if metric.kind == "ratio":
        return M.transfer_ratio(b, t, location=location, scale=scale, eps=eps)
    return stats.paired_probability_of_improvement(b, t) if paired else M.probability_of_improvement(b, t)


def _confidence_interval(metric: Metric, value, b, t, paired: bool, w: Window,
                         s: ReportSettings) -> tuple[list | None, str | None]:
    """``([low, high], None)``, or ``(None, reason)`` where no honest interval exists."""
    conf = float(s.confidence)
    if metric.kind == "poi":
        return list(stats.poi_interval(value, len(b), len(t), paired, conf)), None
    if metric.kind == "ratio":
        return _ratio_interval(metric, value, b, t, paired, w, s)
    if s.interval == "auto":
        if w.value_range is None:
            return None, f"no mean difference has an interval: {UNBOUNDED}."
        try:
            lo, hi, _ = stats.betting_interval(b, t, w.value_range, paired, conf)
        except ValueError as e:  # a score derived from the curves (with the source's frames) left the range
            return None, f"{metric.name} has no interval: {e}."
        return [float(lo), float(hi)], None
    kw = {} if s.interval in ("t", "welch") else dict(n_resamples=int(s.bootstrap), seed=int(s.seed))
    lo, hi = (float(x) for x in stats.INTERVALS[s.interval](b, t, paired=paired, confidence=conf, **kw))
    if math.isfinite(lo) and math.isfinite(hi) and hi > lo:
        return _within(lo, hi, w.value_range), None
    if paired and np.ptp(t - b) <= stats.roundoff(b, t):
        why = f"every pair gives the same difference ({float(t[0] - b[0]):.4g}), so there is no spread to scale"
    elif not paired and max(np.ptp(b), np.ptp(t)) <= stats.roundoff(b, t):
        why = "each side's seeds give identical values, so there is no spread to scale"
    else:
        why = f"the {s.interval} interval is undefined for these scores"
    return None, f"{metric.name} has no interval: {why}."


UNBOUNDED = ("the curves' range is unknown, and no interval built from the seeds alone held its coverage in "
             "simulation on skewed or learn-or-not scores at 3 to 30 seeds (results/coverage); give the range "
             "(--value-range LOW,HIGH) for one that holds for any scores, or choose --interval t")
"""Why a difference of unbounded scores has no interval under ``--interval auto``."""


def _ratio_interval(metric: Metric, value, b, t, paired: bool, w: Window,
                    s: ReportSettings) -> tuple[list | None, str | None]:
    """Fieller's interval (``--interval`` other than auto); under auto, the ratio of the two sides' betting
    intervals (each at ``1 - alpha/2``) of the mean value, where the range is known."""
    if value is None:
        return None, None
    unbounded = (f"{metric.name} has no interval: the interval of the baseline's mean area contains 0, so the "
                 "ratio's would be unbounded.")
    if s.interval != "auto":
        lo, hi = stats.ratio_interval(b, t, paired, float(s.confidence))
        return (None, unbounded) if math.isnan(lo) else ([lo, hi], None)
    if w.value_range is None:
        return None, f"no mean difference has an interval: {UNBOUNDED}."
    span = w.budget - w.start
    try:
        (lb, ub), (lt, ut) = stats.betting_sides(b / span, t / span, w.value_range, float(s.confidence))
    except ValueError as e:
        return None, f"{metric.name} has no interval: {e}."
    if lb <= 0 <= ub:
        return None, unbounded
    rho = [x / y for x in (lt, ut) for y in (lb, ub)]
    sign = 1.0 if b.mean() > 0 else -1.0
    return sorted((sign * (min(rho) - 1), sign * (max(rho) - 1))), None


def _within(lo: float, hi: float, value_range) -> list[float]:
    """A difference of two means of values in ``[a, b]`` lies in ``[-(b - a), b - a]``: the interval is cut
    there (the truth lies inside, so the cut never lowers coverage)."""
    if value_range is None:
        return [lo, hi]
    span = float(value_range[1]) - float(value_range[0])
    return [max(lo, -span), min(hi, span)]


def _p_values(metric: Metric, b, t, paired: bool, w: Window, s: ReportSettings, warnings: list[str]) -> dict:
    """``<name>_p_value`` (and ``<name>_p_exact`` for a mean difference): see ``settings.p_values``."""
    name = f"{metric.name}_p_value"
    if metric.kind == "poi":
        p = stats.sign_test(b, t) if paired else stats.permutation_test(b, t, statistic="poi", seed=int(s.seed))
        return {name: p}
    if s.interval == "auto":  # the betting test dual to the interval (sides compared, for the ratio)
        if metric.kind == "ratio":
            span = w.budget - w.start
            return {name: float(stats.betting_interval(b / span, t / span, w.value_range, False,
                                                       float(s.confidence))[2])}
        p = float(stats.betting_interval(b, t, w.value_range, paired, float(s.confidence))[2])
        return {name: p, f"{metric.name}_p_exact": stats.permutation_test(b, t, paired, seed=int(s.seed))}
    t_p = float(stats.t_test(b, t, paired))
    if metric.kind == "ratio":  # Fieller's interval contains 0 exactly where this test accepts
        if math.isnan(t_p):  # the pairs' differences have no spread: no test to give
            warnings.append(f"{metric.name}: no p-value, the differences of the paired areas have no spread.")
            return {}
        return {name: t_p}
    exact = stats.permutation_test(b, t, paired, seed=int(s.seed))
    shapes = [x for x in ([stats.shape_of(t - b)] if paired else [stats.shape_of(b), stats.shape_of(t)]) if x]
    if shapes:
        scores = "per-pair differences" if paired else "per-seed scores"
        warnings.append(f"{metric.name}: the {scores} look {shapes[0]}, so its p_value is the exact permutation "
                        f"test's ({exact:.3g}, not the t test's {t_p:.3g}); the t interval may cover less than "
                        "promised for such scores.")
        return {name: exact, f"{metric.name}_p_exact": exact}
    return {name: t_p, f"{metric.name}_p_exact": exact}


def _summary(metric: Metric, column: pd.Series, threshold: float | None):
    """A side's mean over seeds; or its upper-median crossing frame (a frame a run had, by which a strict
    majority has crossed) and the share of runs that cross, both null without a threshold."""
    if metric.kind == "mean":
        return float(column.mean())
    if threshold is None:
        return None
    times = [None if is_missing(x) else x for x in column]
    if metric.kind == "time":
        return num(M.censored_median(times, upper=True))
    return sum(x is not None for x in times) / len(times)


def trend(curves: Sequence[Curve], w: Window, s: ReportSettings) -> dict:
    r"""Has the side's mean curve converged over the last ``trend_window`` of the budget?

    Least-squares line through the mean over seeds at every evaluation frame of that window; the
    change over the window, :math:`c = \hat\beta (f_1 - f_0)`, with its t-interval (n - 2 degrees of
    freedom) and the equivalence margin :math:`\delta` = ``convergence_margin`` x the mean curve's range
    over the budget. ``converged`` only where two one-sided tests show :math:`|c| < \delta`; ``still
    rising`` / ``still falling`` where the interval excludes 0; else undetermined, with the reason."""
    start, budget = w.start, w.budget
    lo = budget - float(s.trend_window) * (budget - start)
    frames = np.unique(np.concatenate([c.frames[(c.frames >= lo) & (c.frames <= budget)] for c in curves]))
    progress = float(np.ptp(on_grid(curves, eval_grid(curves, start, budget)).mean(axis=0)))
    margin = float(s.convergence_margin) * progress
    out = dict(window=[num(lo), num(budget)], n_points=int(frames.size), margin=margin)
    if frames.size < MIN_TREND_POINTS:
        return {**out, "change": None, "ci": None, "p_value": None, "p_equivalence": None,
                "verdict": f"undetermined (too few evaluations: {frames.size} in the window, "
                           f"{MIN_TREND_POINTS} needed)"}
    mean = on_grid(curves, frames).mean(axis=0)
    slope, se, df = stats.trend(frames, mean)
    span = budget - lo
    change, se_change = slope * span, se * span
    half = stats.t_quantile(0.5 + float(s.confidence) / 2, df) * se_change
    alpha = 1.0 - float(s.confidence)
    p_equivalence = stats.equivalence_test(change, se_change, df, margin)
    if progress == 0:  # a constant mean curve has nothing left to change
        p_equivalence = 0.0
    if se_change > 0:
        p_value = 2 * _t_sf(abs(change) / se_change, df)
    else:  # the mean lies on a line: its change is exact
        p_value = 1.0 if change == 0 else 0.0
    if p_equivalence < alpha:
        verdict = "converged"
    elif abs(change) > half:
        verdict = "still rising" if change > 0 else "still falling"
    else:
        verdict = (f"undetermined (the change is neither shown within +-{margin:.3g} nor shown to differ "
                   "from 0)")
    ci = _within(change - half, change + half, w.value_range)
    return {**out, "change": change, "ci": ci, "p_value": p_value, "p_equivalence": p_equivalence,
            "verdict": verdict}


def _t_sf(x: float, df: float) -> float:
    from scipy.stats import t as student_t

    return float(student_t.sf(x, df))


def _trend_values(metric: Metric, side: str, tr: dict, s: ReportSettings, warnings: list[str]) -> dict:
    """``final_trend_<side>`` with its interval and p-value, and a warning for a side whose curve still moves."""
    out = {metric.key(side): tr["change"]}
    if tr["ci"] is not None:
        out[f"{metric.key(side)}_ci"] = tr["ci"]
        out[f"{metric.key(side)}_ci_assumes"] = ASSUMES["line"]
        out[f"{metric.key(side)}_p_value"] = tr["p_value"]
    if tr["verdict"].startswith("still"):
        warnings.append(
            f"the {side} mean curve is {tr['verdict']} over the last {100 * float(s.trend_window):g}% of the "
            f"budget ({tr['change']:+.4g} [{tr['ci'][0]:+.4g}, {tr['ci'][1]:+.4g}] from frame "
            f"{number(tr['window'][0])} to {number(tr['window'][1])}): asymptotic_performance compares final "
            "performances, not asymptotes.")
    return out


def is_missing(x) -> bool:
    return x is None or (isinstance(x, float) and math.isnan(x))


def num(x):
    if x is None:
        return None
    x = float(x)
    return int(x) if x.is_integer() and abs(x) < 2**53 else x


def records_of(df: pd.DataFrame) -> list[dict]:
    """JSON-ready rows: NaN cells as None, numpy scalars as Python numbers."""
    return [{k: (None if is_missing(v) else v.item() if isinstance(v, np.generic) else v) for k, v in row.items()}
            for row in df.to_dict("records")]
