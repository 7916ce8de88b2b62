"""Aggregates over task pairs, as rliable defines them (Agarwal et al. 2021, "Deep RL at the edge of the
statistical precipice"), computed by the ``rliable`` package itself.

A score matrix holds one run a row and one task pair a column (``runs x pairs``); its scores are normalised
per pair to [0, 1] by the pair's return range where it is known, :math:`(x - lo) / (hi - lo)`, so pairs of
other scales weigh alike. Each side gets the interquartile mean (the mean of the middle 50% of all its
scores), the median and the mean of the pairs' mean scores, and the optimality gap (how far the scores,
capped at 1, fall short of 1 on average); the transfer side against the baseline gets each aggregate's
difference and the probability of improvement, P(T > B) averaged over pairs (Mann-Whitney per pair). Every
interval is rliable's stratified percentile bootstrap: runs resampled within each pair, the two sides
independently, seeded. A performance profile is the share of runs whose score exceeds each threshold tau.
"""
from __future__ import annotations

import contextlib
import warnings
from typing import Mapping, Sequence

import numpy as np

AGGREGATES = ("iqm", "median", "mean", "optimality_gap")
TAUS = np.linspace(0.0, 1.0, 21)
"""The thresholds a performance profile is drawn at (normalised scores)."""


def _functions():
    from rliable import metrics

    return {"iqm": metrics.aggregate_iqm, "median": metrics.aggregate_median, "mean": metrics.aggregate_mean,
            "optimality_gap": metrics.aggregate_optimality_gap}


def normalised(scores: Sequence[float], value_range: Sequence[float] | None) -> np.ndarray:
    x = np.asarray(scores, dtype=np.float64)
    if value_range is None:
        return x
    lo, hi = (float(v) for v in value_range)
    return (x - lo) / (hi - lo)


def score_matrix(columns: Sequence[Sequence[float]]) -> np.ndarray:
    """``runs x pairs`` from one column of run scores a pair; every pair needs as many runs."""
    counts = {len(c) for c in columns}
    if len(counts) != 1 or 0 in counts:
        raise ValueError(f"every pair needs the same number of runs for a score matrix, got {sorted(counts)}")
    return np.column_stack([np.asarray(c, dtype=np.float64) for c in columns])


def probability_of_improvement(x: np.ndarray, y: np.ndarray) -> float:
    """rliable's P(X > Y) over pairs (``rliable.metrics.probability_of_improvement``: each pair's Mann-Whitney
    U over its runs, P(X > Y) + P(X = Y) / 2, averaged over pairs), vectorised so the bootstrap stays fast."""
    x, y = np.asarray(x)[:, None, :], np.asarray(y)[None, :, :]
    return float(((x > y) + 0.5 * (x == y)).mean(axis=(0, 1)).mean())


def profile(scores: np.ndarray) -> np.ndarray:
    """rliable's score distribution at every :data:`TAUS`: the share of all runs' scores above tau
    (``rliable.library.score_distributions``, vectorised)."""
    return (np.asarray(scores)[..., None] > TAUS).mean(axis=tuple(range(np.ndim(scores))))


def _estimate(data, func, reps: int, confidence: float):
    """rliable's stratified-bootstrap point estimate and percentile interval of ``func`` over ``data``."""
    from rliable import library as rly

    with warnings.catch_warnings():  # arch's notice that its RandomState default is deprecated
        warnings.simplefilter("ignore", FutureWarning)
        point, ci = rly.get_interval_estimates({"x": data}, func, reps=reps, confidence_interval_size=confidence)
    return point["x"], ci["x"]


@contextlib.contextmanager
def _seeded(seed: int):
    """rliable's stratified bootstrap draws its indices from numpy's global generator (np.random.choice),
    whatever random_state it is given: seed that generator for these draws and give its state back after."""
    saved = np.random.get_state()
    np.random.seed(seed)
    try:
        yield
    finally:
        np.random.set_state(saved)


def interval_estimate(scores: np.ndarray, func, *, reps: int = 2000, confidence: float = 0.95, seed: int = 0) -> list:
    """``[value, [low, high]]`` of an aggregate ``func`` (e.g. ``rliable.metrics.aggregate_iqm``) of a ``runs x
    pairs`` score matrix, by rliable's stratified bootstrap, seeded."""
    with _seeded(seed):
        value, ci = _estimate(scores, lambda x: np.array([func(x)]), reps, confidence)
    return [float(value[0]), [float(ci[0][0]), float(ci[1][0])]]


def aggregates(baseline: np.ndarray, transfer: np.ndarray, *, reps: int = 2000, confidence: float = 0.95,
               seed: int = 0) -> dict:
    """Each side's aggregates, their differences (transfer - baseline) and P(T > B), each ``[value, [low,
    high]]``; and both sides' performance profiles at :data:`TAUS` with their bands."""
    with _seeded(seed):
        return _estimates(baseline, transfer, _functions(),
                          lambda data, func: _estimate(data, func, reps, confidence))


def _estimates(baseline, transfer, functions, estimate) -> dict:
    out: dict = {"baseline": {}, "transfer": {}, "difference": {}}
    for name, f in functions.items():
        for side, scores in (("baseline", baseline), ("transfer", transfer)):
            value, ci = estimate(scores, lambda x, f=f: np.array([f(x)]))
            out[side][name] = [float(value[0]), [float(ci[0][0]), float(ci[1][0])]]
        value, ci = estimate((transfer, baseline), lambda t, b, f=f: np.array([f(t) - f(b)]))
        out["difference"][name] = [float(value[0]), [float(ci[0][0]), float(ci[1][0])]]
    value, ci = estimate((transfer, baseline), lambda t, b: np.array([probability_of_improvement(t, b)]))
    out["probability_of_improvement"] = [float(value[0]), [float(ci[0][0]), float(ci[1][0])]]
    out["profile"] = {"tau": TAUS.tolist()}
    for side, scores in (("baseline", baseline), ("transfer", transfer)):
        value, ci = estimate(scores, profile)
        out["profile"][side] = {"share": value.tolist(), "low": ci[0].tolist(), "high": ci[1].tolist()}
    return out


def sweep_aggregates(rows: Sequence[Mapping], score: str = "mean_return", **kwargs) -> list[dict]:
    """One entry per (algo, variant, method) of a sweep's report rows: the pairs it covers, the runs a pair
    it uses (the fewest any of its pairs has, the first seeds of each) and :func:`aggregates`."""
    groups: dict[tuple, list[Mapping]] = {}
    for row in rows:
        if row.get("per_seed"):
            groups.setdefault((row["algo"], row["variant"], row["method"]), []).append(row)
    out = []
    for (algo, variant, method), members in sorted(groups.items()):
        columns = {side: [normalised([r[score] for r in m["per_seed"][side]], m.get("value_range")) for m in members]
                   for side in ("baseline", "transfer")}
        runs = min(len(c) for side in columns.values() for c in side)
        if runs < 1:
            continue
        b, t = (score_matrix([c[:runs] for c in columns[side]]) for side in ("baseline", "transfer"))
        out.append({"algo": algo, "variant": variant, "method": method, "pairs": [m["pair"] for m in members],
                    "runs_per_pair": runs, "score": score,
                    "normalised": all(m.get("value_range") is not None for m in members),
                    **aggregates(b, t, **kwargs)})
    return out


def aggregates_table(entries: Sequence[Mapping]) -> str:
    """A Markdown table: each method's aggregate differences and P(T > B) with their intervals."""
    from drltg.analysis import tables

    rows = [("algo", "method", "pairs x runs", *(f"{name} diff" for name in AGGREGATES), "P(T > B)")]
    for e in entries:
        cells = [tables.estimate(v, ci, ".2g") for v, ci in (e["difference"][n] for n in AGGREGATES)]
        value, ci = e["probability_of_improvement"]
        label = f"{e['method']} {e['variant']}".strip()
        rows.append((e["algo"], label, f"{len(e['pairs'])} x {e['runs_per_pair']}", *cells,
                     tables.estimate(value, ci, ".2g")))
    return tables.render(rows, "markdown")


def across_pairs(members: Sequence[tuple[str, Mapping]], score: str = "mean_return", seed: int = 0) -> dict | None:
    r"""One method against no transfer over several pairs at once: the stratified exact sign-flip test
    (:func:`drltg.analysis.stats.stratified_sign_flip`) of the sum of the pairs' mean differences.

    ``members``: ``(pair, per_seed)`` of each report (its ``per_seed`` JSON); a pair is a stratum of the
    differences :math:`T_i - B_i` of ``score`` over the seeds its two sides share, its signs flipped within it.
    Returns ``pairs`` (the strata, in order), ``seed_pairs`` (in all), ``mean_difference`` (the mean over pairs of
    their mean differences), ``test``, ``p`` and ``unpaired`` (reports whose sides share no seed, left out);
    ``None`` when none pairs."""
    from drltg.analysis.stats import STRATIFIED_EXACT_PAIRS, STRATIFIED_RESAMPLES, stratified_sign_flip

    strata, pairs, unpaired = [], [], []
    for pair, per_seed in members:
        b, t = ({x["seed"]: x[score] for x in per_seed[side] if x.get("seed") is not None and x.get(score) is not None}
                for side in ("baseline", "transfer"))
        shared = sorted(set(b) & set(t))
        if shared:
            strata.append([t[k] - b[k] for k in shared])
            pairs.append(pair)
        else:
            unpaired.append(pair)
    if not strata:
        return None
    statistic, p = stratified_sign_flip(strata, seed=seed)
    n = sum(map(len, strata))
    test = ("stratified sign-flip, exact" if n <= STRATIFIED_EXACT_PAIRS else
            f"stratified sign-flip, Monte Carlo ({STRATIFIED_RESAMPLES:,} sign patterns)")
    return {"score": score, "pairs": pairs, "seed_pairs": n, "mean_difference": statistic / len(strata),
            "test": test, "p": p, "unpaired": unpaired}
