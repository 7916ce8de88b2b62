r"""Transfer metrics (Taylor & Stone 2009) and multi-seed statistics (Agarwal et al. 2021).

Pure functions on arrays (numpy arrays, lists or CPU torch tensors); usable without the report.

A learning curve is a pair ``(frames, values)`` with strictly increasing frames: ``values[i]`` is the
evaluation return after ``frames[i]`` environment frames. Curves are compared over a common interval
``[start, budget]`` on the real frame axis; nothing is extrapolated past a run's last evaluation.

Per-run scores
    ``area_under_curve``      :math:`A = \int_{start}^{budget} y\,df`, trapezoid rule on the real
                              (possibly uneven) frame grid; ``y(budget)`` is linearly interpolated
                              between the two evaluations around it.
    ``initial_performance``   mean of the first ``k`` evaluations.
    ``final_performance``     mean of the evaluations with
                              ``budget - w (budget - start) <= f <= budget``.
    ``time_to_threshold``     the first evaluation frame ``f <= budget`` with ``y(f) >= threshold``,
                              or ``None`` when it is never reached (a censored run, never a number).
    ``sustained_time_to_threshold``  the first evaluation frame from which ``y >= threshold`` holds
                              until the budget over at least ``SUSTAIN_AFTER`` later evaluations (or
                              for ``K >= 2`` consecutive evaluations): a run that touches the threshold
                              and collapses, or touches it at the end, has not shown it holds there.
    ``moving_average``        trailing mean over the last ``W`` evaluations (fewer at the start).

Transfer metrics over sets of per-seed scores (a single run is a set of one), with a location
statistic ``L`` of each side (the mean by default; ``interquartile_mean`` for a robust version). One
definition per name, paired or not: the difference of the two sides' locations (for the mean, the same
number as the mean of the pairs' differences; for the IQM, not).
    ``jumpstart``               :math:`L(\text{initial}_T) - L(\text{initial}_B)`
    ``asymptotic_performance``  :math:`L(\text{final}_T) - L(\text{final}_B)`
    ``transfer_ratio``          :math:`r = (L(A_T) - L(A_B)) / |L(A_B)|`.
        For a positive baseline area this is the plain ratio minus one, :math:`A_T/A_B - 1`: 0 means no
        gain, 0.25 means 25 % more area. Dividing by :math:`|A_B|` keeps the sign meaning "transfer is
        better" when the baseline area is negative (e.g. a per-step penalty), where the plain ratio
        :math:`A_T/A_B` falls *below* 1 for a better transfer curve. When :math:`|A_B|` is tiny compared
        with the largest possible area, the ratio explodes and says nothing: ``transfer_ratio`` returns
        ``None`` once :math:`|A_B| \le \epsilon\cdot` ``scale`` (``scale`` = span x largest
        :math:`|y|`). The ratio also changes if a constant is added to every reward, so it is only
        meaningful between curves measured with the same reward.

Multi-seed statistics
    ``interquartile_mean``          mean of the middle 50 %: drop ``floor(n/4)`` scores at each end.
    ``probability_of_improvement``  :math:`P(X_T > X_B) = \frac{1}{nm}\sum_{i,j}\big(1[t_j > b_i] +
                                    \tfrac12 1[t_j = b_i]\big)` (the Mann-Whitney U statistic / nm).
    ``bootstrap_ci``                percentile bootstrap: each side's seeds are resampled with
                                    replacement, independently, from a seeded generator.
    ``censored_median``             median time to threshold, a run that never reaches it counting as
                                    infinitely late; ``None`` when that median is infinite (``upper``:
                                    the upper median, a frame one of the runs had).

Intervals (vectorised over leading axes, so a coverage simulation is one call; ``tests/test_coverage.py``
measures them and chose ``t_interval`` as the default)
    ``t_interval``            paired: :math:`\bar d \pm t_{n-1} s_d/\sqrt n`; unpaired: Welch's standard
                              error with Hsu's :math:`\min(n_B, n_T) - 1` degrees of freedom.
    ``welch_interval``, ``studentized_interval``, ``bca_interval``, ``percentile_interval``: the
                              other candidates (they under-cover with 3 to 10 seeds).
    ``ratio_interval``        Fieller's interval of a ratio of means, mapped to ``transfer_ratio``; NaN
                              when the baseline mean's own interval contains 0 (unbounded).
    ``poi_interval``          interval of a probability of improvement inside [0, 1] (Clopper-Pearson
                              for pairs, Newcombe's method 5 for the Mann-Whitney estimate); never
                              ``[1, 1]``.
    ``trend``                 least-squares slope and its standard error (is a curve still changing?).

Tests (two-sided p-values)
    ``t_test``                the test dual to ``t_interval``; ``sign_test`` exact, over pairs;
    ``permutation_test``      exact (or seeded Monte Carlo) relabelling test of no effect, valid at any
                              number of seeds; ``equivalence_test`` two one-sided tests (TOST);
    ``holm``                  Holm's adjustment of a family of p-values; ``shape_of`` flags skewed or
                              bimodal per-seed scores.
"""
from __future__ import annotations

import math
from typing import Callable, Sequence

import numpy as np

Array = np.ndarray


def _as_array(x) -> Array:
    if hasattr(x, "detach"):
        x = x.detach().cpu().numpy()
    return np.asarray(x, dtype=np.float64)


def _curve(frames, values) -> tuple[Array, Array]:
    f, v = _as_array(frames), _as_array(values)
    if f.ndim != 1 or f.shape != v.shape or f.size == 0:
        raise ValueError("frames and values must be non-empty 1-D arrays of the same length")
    if (np.diff(f) <= 0).any():
        raise ValueError("frames must strictly increase")
    return f, v


def value_at(frames, values, frame: float) -> float:
    """The curve at ``frame``, linearly interpolated between evaluations (never extrapolated)."""
    f, v = _curve(frames, values)
    if not f[0] <= frame <= f[-1]:
        raise ValueError(f"frame {frame:g} lies outside the curve's range [{f[0]:g}, {f[-1]:g}]")
    return float(np.interp(frame, f, v))


def truncate(frames, values, start: float | None = None, stop: float | None = None) -> tuple[Array, Array]:
    """The curve on ``[start, stop]``, with interpolated end points where they fall between evaluations."""
    f, v = _curve(frames, values)
    start = f[0] if start is None else float(start)
    stop = f[-1] if stop is None else float(stop)
    if not f[0] <= start < stop <= f[-1]:
        raise ValueError(f"[{start:g}, {stop:g}] is not inside the curve's range [{f[0]:g}, {f[-1]:g}]")
    inner = (f > start) & (f < stop)
    fs = np.concatenate([[start], f[inner], [stop]])
    return fs, np.interp(fs, f, v)


def area_under_curve(frames, values, start: float | None = None, stop: float | None = None) -> float:
    """Trapezoid area under the curve on the real frame axis over ``[start, stop]``."""
    f, v = truncate(frames, values, start, stop)
    return float(np.sum(np.diff(f) * (v[1:] + v[:-1]) / 2.0))


def initial_performance(values, k: int = 1) -> float:
    """Mean of the first ``k`` evaluations."""
    v = _as_array(values)
    if not 1 <= k <= v.size:
        raise ValueError(f"k={k} needs between 1 and {v.size} evaluations")
    return float(v[:k].mean())


def final_window(start: float, stop: float, fraction: float) -> tuple[float, float]:
    """The last ``fraction`` of ``[start, stop]``."""
    if not 0.0 < fraction <= 1.0:
        raise ValueError(f"fraction must lie in (0, 1], got {fraction}")
    return stop - fraction * (stop - start), stop


def final_performance(frames, values, stop: float | None = None, fraction: float = 0.1,
                      start: float | None = None) -> float:
    """Mean of the evaluations in the last ``fraction`` of ``[start, stop]`` (defaults: the curve's range)."""
    f, v = _curve(frames, values)
    lo, hi = final_window(f[0] if start is None else start, f[-1] if stop is None else stop, fraction)
    inside = (f >= lo) & (f <= hi)
    if not inside.any():
        raise ValueError(f"no evaluation lies in the final window [{lo:g}, {hi:g}]")
    return float(v[inside].mean())


def time_to_threshold(frames, values, threshold: float, stop: float | None = None) -> float | None:
    """First evaluation frame (``<= stop``) whose value reaches ``threshold``; ``None`` if none does."""
    f, v = _curve(frames, values)
    reached = (v >= threshold) & (f <= (f[-1] if stop is None else stop))
    return float(f[np.argmax(reached)]) if reached.any() else None


SUSTAIN_AFTER = 2
"""Evaluations after the crossing that must confirm a sustained crossing run to the budget: a run that
first reaches the threshold at its last evaluation (or the one before) has not shown it holds there."""


def sustained_time_to_threshold(frames, values, threshold: float, stop: float | None = None,
                                sustain: int | None = None, after: int = SUSTAIN_AFTER) -> float | None:
    """First evaluation frame ``f_i <= stop`` from which the run stays at or above ``threshold``.

    ``sustain=None``: for every later evaluation up to ``stop`` (a run that dips below again has not
    reached it yet), and at least ``after`` of them; ``sustain=K`` (at least 2): for ``K`` consecutive
    evaluations ``y_i .. y_{i+K-1}``, all within ``stop``. A first crossing alone is never sustained.
    ``None`` when no evaluation qualifies (a censored run)."""
    f, v = _curve(frames, values)
    inside = f <= (f[-1] if stop is None else stop)
    f, ok = f[inside], v[inside] >= threshold
    if not ok.size:
        return None
    if sustain is None:
        if after < 1:
            raise ValueError(f"after must be >= 1 evaluations, got {after}")
        holds = np.flip(np.cumprod(np.flip(ok))).astype(bool)  # ok from i to the end
        holds &= np.arange(ok.size) < ok.size - after  # confirmed by `after` later evaluations
    else:
        if sustain < 2:
            raise ValueError(f"sustain must be >= 2 evaluations (the crossing and one after it), got {sustain}")
        run = np.convolve(ok.astype(int), np.ones(sustain, dtype=int), mode="full")[sustain - 1:]
        holds = run[:ok.size] >= sustain
    return float(f[np.argmax(holds)]) if holds.any() else None


def moving_average(values, window: int) -> Array:
    """Trailing moving average: ``s_i = mean(y_{max(0, i-W+1)} .. y_i)``; same length as ``values``."""
    v = _as_array(values)
    if window < 1:
        raise ValueError(f"window must be >= 1, got {window}")
    c = np.concatenate([[0.0], np.cumsum(v)])
    i = np.arange(1, v.size + 1)
    lo = np.maximum(i - window, 0)
    return (c[i] - c[lo]) / (i - lo)


def interquartile_mean(x, axis: int = -1) -> Array | float:
    """Mean of the middle 50 % of the scores along ``axis`` (``floor(n/4)`` dropped at each end)."""
    x = np.sort(_as_array(x), axis=axis)
    n = x.shape[axis]
    cut = n // 4
    out = np.take(x, np.arange(cut, n - cut), axis=axis).mean(axis=axis)
    return float(out) if np.ndim(out) == 0 else out


def mean(x, axis: int = -1) -> Array | float:
    out = _as_array(x).mean(axis=axis)
    return float(out) if np.ndim(out) == 0 else out


def _difference(baseline, transfer, location: Callable) -> float:
    return float(location(_as_array(transfer)) - location(_as_array(baseline)))


def jumpstart(initial_baseline, initial_transfer, location: Callable = mean) -> float:
    """``L(initial_T) - L(initial_B)`` over per-seed initial performances (or two scalars)."""
    return _difference(np.atleast_1d(initial_baseline), np.atleast_1d(initial_transfer), location)


def asymptotic_performance(final_baseline, final_transfer, location: Callable = mean) -> float:
    """``L(final_T) - L(final_B)`` over per-seed final performances (or two scalars)."""
    return _difference(np.atleast_1d(final_baseline), np.atleast_1d(final_transfer), location)


def transfer_ratio(area_baseline, area_transfer, location: Callable = mean,
                   scale: float | None = None, eps: float = 0.01) -> float | None:
    """``(L(A_T) - L(A_B)) / |L(A_B)|``; ``None`` when ``|L(A_B)| <= eps * scale``.

    ``scale`` is the largest area the curves could have (span x largest ``|value|``); without it only
    an exactly zero baseline area gives ``None``.
    """
    b = location(np.atleast_1d(_as_array(area_baseline)))
    t = location(np.atleast_1d(_as_array(area_transfer)))
    if abs(b) <= (eps * scale if scale is not None else 0.0):
        return None
    return float((t - b) / abs(b))


def probability_of_improvement(baseline, transfer) -> float:
    """``P(T > B)`` for a random transfer seed against a random baseline seed; ties count one half."""
    b, t = np.atleast_1d(_as_array(baseline)), np.atleast_1d(_as_array(transfer))
    return float(_poi(b[None], t[None])[0])


def _poi(b: Array, t: Array) -> Array:
    """Vectorised over a leading resample axis: ``b`` [R, n], ``t`` [R, m] -> [R]."""
    diff = t[:, None, :] - b[:, :, None]
    return ((diff > 0) + 0.5 * (diff == 0)).mean(axis=(1, 2))


def censored_median(times: Sequence[float | None], upper: bool = False) -> float | None:
    """Median over seeds with ``None`` (never reached) as +inf; ``None`` when the median is infinite.

    ``upper=False``: the mean of the two middle values for an even count (a frame no run may have
    had); ``upper=True``: the upper median ``x_(floor(n/2)+1)``, the earliest of the runs' own frames
    by which a strict majority of the seeds has reached the threshold."""
    if len(times) == 0:
        raise ValueError("no times given")
    x = np.sort([np.inf if t is None else float(t) for t in times])
    n = len(x)
    med = x[n // 2] if n % 2 or upper else (x[n // 2 - 1] + x[n // 2]) / 2.0
    return float(med) if np.isfinite(med) else None


def bootstrap_ci(
    statistic: Callable[..., Array],
    *samples,
    n_resamples: int = 10_000,
    confidence: float = 0.95,
    seed: int = 0,
) -> tuple[float, float] | tuple[Array, Array]:
    """Percentile bootstrap confidence interval of ``statistic(*samples)``.

    Each sample (seeds along axis 0, anything after) is resampled with replacement independently;
    ``statistic`` receives arrays with a leading resample axis, ``[R, n_seeds, ...]``, and returns
    ``[R, ...]``. If any resample's statistic is NaN (undefined), the interval is NaN: dropping
    those resamples would condition the interval on the data it cannot describe. The generator is
    ``numpy.random.default_rng(seed)``: the same call gives the same interval.
    """
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must lie in (0, 1), got {confidence}")
    rng = np.random.default_rng(seed)
    arrays = [_as_array(s) for s in samples]
    resampled = [a[rng.integers(0, len(a), size=(n_resamples, len(a)))] for a in arrays]
    stats = _as_array(statistic(*resampled))
    alpha = (1.0 - confidence) / 2.0
    lo, hi = np.quantile(stats, [alpha, 1.0 - alpha], axis=0)
    if np.ndim(lo) == 0:
        return float(lo), float(hi)
    return lo, hi


def difference_statistic(location: Callable = mean) -> Callable[[Array, Array], Array]:
    """``(b [R, n], t [R, m]) -> L(t) - L(b)`` per resample, for :func:`bootstrap_ci`."""
    return lambda b, t: location(t, axis=-1) - location(b, axis=-1)


def ratio_statistic(location: Callable = mean, scale: float | None = None,
                    eps: float = 0.01) -> Callable[[Array, Array], Array]:
    """Vectorised :func:`transfer_ratio` (NaN where the baseline area is near zero)."""
    def stat(b, t):
        lb, lt = location(b, axis=-1), location(t, axis=-1)
        tol = eps * scale if scale is not None else 0.0
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(np.abs(lb) > tol, (lt - lb) / np.abs(lb), np.nan)
    return stat


def poi_statistic(b: Array, t: Array) -> Array:
    """Vectorised :func:`probability_of_improvement` for :func:`bootstrap_ci`."""
    return _poi(b, t)


# --------------------------------------------------------------------------------------- intervals
# Interval functions work along the last axis (seeds), so one call can hold thousands of simulated
# experiments ``[..., n]``; they return ``(low, high)`` of the leading shape, NaN where undefined.
def t_quantile(p: float, df) -> Array | float:
    """Quantile ``p`` in (0.5, 1) of Student's t with real ``df`` > 0 (``scipy.stats.t.ppf``)."""
    from scipy import stats

    if not 0.5 < p < 1.0:
        raise ValueError(f"p must lie in (0.5, 1), got {p}")
    q = stats.t.ppf(p, df)
    return float(q) if np.ndim(q) == 0 else q


def _normal_ppf(p: Array) -> Array:
    from scipy import stats

    return stats.norm.ppf(p)


def _check_confidence(confidence: float) -> float:
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must lie in (0, 1), got {confidence}")
    return (1.0 - confidence) / 2.0


def roundoff(*scores: Array) -> Array:
    """The largest spread that is only round-off of these scores: 16 float32 ulps of their magnitude.
    Curves are logged in float32 (0.9 reads back as 0.8999999761581421), so pairs with the same
    difference, summed from different evaluations, differ by ~1e-9: no spread to scale an interval or
    a test by (a t-test would give p ~ 1e-18)."""
    return 16 * np.finfo(np.float32).eps * np.max([np.abs(x).max(-1) for x in scores], axis=0)


def _difference_and_se(b: Array, t: Array, paired: bool, df: str = "hsu") -> tuple[Array, Array, Array]:
    r"""Mean difference, its standard error and the t degrees of freedom.

    Paired: :math:`\bar d`, :math:`s_d/\sqrt n`, :math:`n-1` with :math:`d_i = t_i - b_i`.
    Unpaired: :math:`\bar t - \bar b`, :math:`\sqrt{s_b^2/n_b + s_t^2/n_t}` and either Hsu's
    :math:`\min(n_b, n_t) - 1` degrees of freedom (``df="hsu"``: at least the promised coverage for
    normal scores whatever the two spreads) or Welch-Satterthwaite's (``df="welch"``). A spread within
    :func:`roundoff` of the scores counts as none."""
    tol = roundoff(b, t)
    if paired:
        d = t - b
        n = d.shape[-1]
        se = d.std(-1, ddof=1) / np.sqrt(n)
        return d.mean(-1), np.where(se > tol, se, 0.0), np.full(d.shape[:-1], n - 1.0)
    nb, nt = b.shape[-1], t.shape[-1]
    vb = np.where(np.ptp(b, -1) > tol, b.var(-1, ddof=1) / nb, 0.0)
    vt = np.where(np.ptp(t, -1) > tol, t.var(-1, ddof=1) / nt, 0.0)
    if df == "hsu":
        dof = np.full(vb.shape, min(nb, nt) - 1.0)
    else:
        with np.errstate(divide="ignore", invalid="ignore"):
            dof = (vb + vt) ** 2 / (vb ** 2 / (nb - 1) + vt ** 2 / (nt - 1))
    return t.mean(-1) - b.mean(-1), np.sqrt(vb + vt), dof


def _pairs(b, t, paired: bool) -> tuple[Array, Array]:
    b, t = _as_array(b), _as_array(t)
    if paired and b.shape != t.shape:
        raise ValueError(f"paired samples need the same shape, got {b.shape} and {t.shape}")
    if min(b.shape[-1], t.shape[-1]) < 2:
        raise ValueError("an interval needs at least 2 seeds per side")
    return b, t


def t_interval(b, t, paired: bool = False, confidence: float = 0.95, df: str = "hsu") -> tuple[Array, Array]:
    """``mean(t) - mean(b)`` +- ``t_{1-a/2, df} x se``: the paired t-interval (on :math:`d_i`), or
    the unpaired one with Welch's standard error (``df`` as in :func:`_difference_and_se`). Exact for
    normal pairs; NaN where the standard error is 0 (no spread to scale)."""
    alpha = _check_confidence(confidence)
    b, t = _pairs(b, t, paired)
    est, se, df = _difference_and_se(b, t, paired, df)
    half = t_quantile(1.0 - alpha, np.where(se > 0, df, 1.0)) * se
    bad = ~(se > 0)
    return np.where(bad, np.nan, est - half), np.where(bad, np.nan, est + half)


def _resample(b: Array, t: Array, paired: bool, n_resamples: int, rng) -> tuple[Array, Array]:
    """``[..., R, n]`` resamples: pairs kept together when paired, each side on its own otherwise."""
    def draw(x, idx):
        return np.take_along_axis(x[..., None, :], idx, axis=-1)

    ib = rng.integers(0, b.shape[-1], size=(*b.shape[:-1], n_resamples, b.shape[-1]))
    it = ib if paired else rng.integers(0, t.shape[-1], size=(*t.shape[:-1], n_resamples, t.shape[-1]))
    return draw(b, ib), draw(t, it)


def percentile_interval(b, t, paired: bool = False, confidence: float = 0.95, n_resamples: int = 2000,
                        seed: int = 0) -> tuple[Array, Array]:
    """Percentile bootstrap of the mean difference: the ``a/2`` and ``1-a/2`` quantiles of the
    resampled differences. Too narrow with few seeds (it ignores the t-correction)."""
    alpha = _check_confidence(confidence)
    b, t = _pairs(b, t, paired)
    rb, rt = _resample(b, t, paired, n_resamples, np.random.default_rng(seed))
    diff = rt.mean(-1) - rb.mean(-1)
    lo, hi = np.quantile(diff, [alpha, 1 - alpha], axis=-1)
    return lo, hi


def bca_interval(b, t, paired: bool = False, confidence: float = 0.95, n_resamples: int = 2000,
                 seed: int = 0) -> tuple[Array, Array]:
    """Bias-corrected and accelerated bootstrap (Efron 1987) of the mean difference, by
    ``scipy.stats.bootstrap`` (the pairs' differences resampled, or each side on its own). NaN where
    the resamples are degenerate (no spread)."""
    import warnings

    from scipy import stats

    _check_confidence(confidence)
    b, t = _pairs(b, t, paired)
    if paired:
        data, statistic = (t - b,), lambda d, axis: d.mean(axis)
    else:
        data, statistic = (b, t), lambda b, t, axis: t.mean(axis) - b.mean(axis)
    with warnings.catch_warnings(), np.errstate(divide="ignore", invalid="ignore"):
        warnings.simplefilter("ignore")
        ci = stats.bootstrap(data, statistic, n_resamples=n_resamples, confidence_level=confidence, method="BCa",
                             rng=np.random.default_rng(seed), axis=-1, vectorized=True, batch=100).confidence_interval
    return ci.low, ci.high


def studentized_interval(b, t, paired: bool = False, confidence: float = 0.95, n_resamples: int = 2000,
                         seed: int = 0) -> tuple[Array, Array]:
    r"""Bootstrap-t: :math:`\hat\theta - q^*_{1-a/2}\,se,\ \hat\theta - q^*_{a/2}\,se` with
    :math:`q^*` the quantiles of :math:`(\theta^* - \hat\theta)/se^*`. A resample without spread
    has :math:`se^* = 0` and counts as an infinite ratio (kept, not dropped), so the interval is
    NaN (unbounded) when such resamples reach a tail."""
    alpha = _check_confidence(confidence)
    b, t = _pairs(b, t, paired)
    est, se, _ = _difference_and_se(b, t, paired)
    rb, rt = _resample(b, t, paired, n_resamples, np.random.default_rng(seed))
    est_r, se_r, _ = _difference_and_se(rb, rt, paired)
    dev = est_r - est[..., None]
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(se_r > 0, dev / se_r, np.sign(dev) * np.inf)
    q_lo, q_hi = np.quantile(ratio, [alpha, 1 - alpha], axis=-1, method="inverted_cdf")
    lo, hi = est - q_hi * se, est - q_lo * se
    ok = np.isfinite(lo) & np.isfinite(hi) & (se > 0)
    return np.where(ok, lo, np.nan), np.where(ok, hi, np.nan)


def welch_interval(b, t, paired: bool = False, confidence: float = 0.95) -> tuple[Array, Array]:
    """:func:`t_interval` with Welch-Satterthwaite degrees of freedom when unpaired."""
    return t_interval(b, t, paired, confidence, df="welch")


INTERVALS = {"t": t_interval, "welch": welch_interval, "studentized": studentized_interval,
             "bca": bca_interval, "percentile": percentile_interval}
"""Candidate intervals of a mean difference; ``t`` is the report's, chosen by the coverage measured in
``tests/test_coverage.py`` (the only candidate at or near the promised level with 3 to 10 seeds)."""


def fieller_interval(b, t, paired: bool = False, confidence: float = 0.95) -> tuple[float, float]:
    r"""Fieller's interval for the ratio of means :math:`\rho = \mu_T / \mu_B`.

    The set of :math:`\rho` with :math:`(\bar t - \rho \bar b)^2 \le q^2 (v_t - 2\rho c + \rho^2 v_b)`
    (:math:`v` = squared standard errors, :math:`c` their covariance when paired, :math:`q` the t
    quantile). It is a bounded interval only when the denominator's own interval excludes 0
    (:math:`\bar b^2 > q^2 v_b`); otherwise ``(nan, nan)``: no honest bounded interval exists."""
    alpha = _check_confidence(confidence)
    b, t = _pairs(b, t, paired)
    size = max(float(np.abs(b).max()), float(np.abs(t).max()))
    if size > 0:  # the ratio is scale-free; squares of large areas would overflow
        b, t = b / size, t / size
    nb, nt = b.shape[-1], t.shape[-1]
    mb, mt = b.mean(), t.mean()
    vb, vt = b.var(ddof=1) / nb, t.var(ddof=1) / nt
    c = float(np.cov(b, t, ddof=1)[0, 1]) / nb if paired else 0.0
    df = (nb if paired else min(nb, nt)) - 1
    if vb + vt <= 0:
        return math.nan, math.nan
    q2 = float(t_quantile(1.0 - alpha, df)) ** 2
    qa, qb, qc = mb * mb - q2 * vb, -2.0 * (mt * mb - q2 * c), mt * mt - q2 * vt
    disc = qb * qb - 4 * qa * qc
    if qa <= 0 or disc < 0:
        return math.nan, math.nan
    r = math.sqrt(disc)
    return (-qb - r) / (2 * qa), (-qb + r) / (2 * qa)


def ratio_interval(area_baseline, area_transfer, paired: bool = False,
                   confidence: float = 0.95) -> tuple[float, float]:
    r"""Interval of :func:`transfer_ratio` :math:`r = \mathrm{sign}(\mu_B)(\rho - 1)` from
    :func:`fieller_interval`; ``(nan, nan)`` when the baseline area's interval contains 0."""
    lo, hi = fieller_interval(area_baseline, area_transfer, paired, confidence)
    if math.isnan(lo):
        return lo, hi
    sign = 1.0 if _as_array(area_baseline).mean() > 0 else -1.0
    ends = sorted((sign * (lo - 1), sign * (hi - 1)))
    return ends[0], ends[1]


def paired_probability_of_improvement(baseline, transfer) -> float:
    r""":math:`\frac1n\sum_i 1[t_i > b_i] + \tfrac12 1[t_i = b_i]` over pairs ``(b_i, t_i)``."""
    d = _as_array(transfer) - _as_array(baseline)
    return float(((d > 0) + 0.5 * (d == 0)).mean())


def poi_interval(p_hat: float, n_baseline: int, n_transfer: int, paired: bool = False,
                 confidence: float = 0.95) -> tuple[float, float]:
    r"""Interval of a probability of improvement, inside [0, 1] and never degenerate at 0 or 1.

    Paired (a share of ``n`` pairs, ``k = n p`` with ties counting one half): Clopper-Pearson's exact
    interval :math:`[B_{a/2}(k, n-k+1),\ B_{1-a/2}(k+1, n-k)]` (Beta quantiles), the inversion of the
    exact binomial test, so it excludes 1/2 only where :func:`sign_test` rejects (5 of 5 pairs do not).
    Unpaired (the Mann-Whitney estimate): Newcombe's (2006) method 5, all :math:`p` with
    :math:`(\hat p - p)^2 \le z^2 V(p)`, :math:`V = \frac{p(1-p)}{nm}\big[1 + (N-1)\frac{1-p}{2-p}
    + (N-1)\frac{p}{1+p}\big]`, :math:`N = (n+m)/2`."""
    from scipy import optimize, stats

    alpha = _check_confidence(confidence)
    if not 0.0 <= p_hat <= 1.0:
        raise ValueError(f"a probability of improvement lies in [0, 1], got {p_hat}")
    if paired:
        n = n_baseline
        k = p_hat * n
        lo = 0.0 if k <= 0 else float(stats.beta.ppf(alpha, k, n - k + 1))
        hi = 1.0 if k >= n else float(stats.beta.ppf(1 - alpha, k + 1, n - k))
        return lo, hi
    z2 = float(_normal_ppf(1 - alpha)) ** 2
    big = (n_baseline + n_transfer) / 2.0

    def excess(p):
        v = p * (1 - p) / (n_baseline * n_transfer) * (1 + (big - 1) * (1 - p) / (2 - p) + (big - 1) * p / (1 + p))
        return (p_hat - p) ** 2 - z2 * v

    inner = min(max(p_hat, 1e-12), 1 - 1e-12)  # the score set's inside, also when p_hat is 0 or 1
    lo = 0.0 if p_hat <= 0 else optimize.brentq(excess, 0.0, inner, xtol=1e-12)
    hi = 1.0 if p_hat >= 1 else optimize.brentq(excess, inner, 1.0, xtol=1e-12)
    return float(lo), float(hi)


# ------------------------------------------------------------------------------------------ tests
# Two-sided p-values, each the test behind one interval (or distribution-free beside it).
def t_test(b, t, paired: bool = False, df: str = "hsu") -> Array | float:
    """Two-sided p-value of :math:`\bar d / se` on the degrees of freedom of :func:`t_interval`: that
    interval excludes 0 exactly when ``p < 1 - confidence``. NaN without spread."""
    from scipy import stats

    b, t = _pairs(b, t, paired)
    est, se, dof = _difference_and_se(b, t, paired, df)
    with np.errstate(divide="ignore", invalid="ignore"):
        p = np.where(se > 0, 2 * stats.t.sf(np.abs(est / se), np.where(se > 0, dof, 1.0)), np.nan)
    return float(p) if np.ndim(p) == 0 else p


def sign_test(baseline, transfer) -> float:
    """Exact two-sided sign test of :math:`P(T_i > B_i) = 1/2` over pairs, tied pairs dropped
    (``scipy.stats.binomtest``); 1 when every pair ties."""
    from scipy import stats

    d = _as_array(transfer) - _as_array(baseline)
    wins, losses = int((d > 0).sum()), int((d < 0).sum())
    return 1.0 if wins + losses == 0 else float(stats.binomtest(wins, wins + losses, 0.5).pvalue)


def permutation_test(baseline, transfer, paired: bool = False, statistic: str = "mean", seed: int = 0,
                     n_resamples: int = 9999) -> float:
    """Two-sided permutation test that transfer changes nothing (``scipy.stats.permutation_test``):
    paired, the two runs of each pair swapped (the differences' signs flipped); unpaired, the runs
    relabelled. ``statistic``: ``"mean"`` (the mean difference) or ``"poi"`` (the Mann-Whitney
    estimate). Exact while the arrangements number at most ``n_resamples`` (up to 13 pairs; 5 + 5 runs
    have 252), else a seeded Monte Carlo p-value; its false-positive rate is at most the level at any
    number of seeds."""
    from scipy import stats

    b, t = _as_array(baseline), _as_array(transfer)
    if statistic == "mean":
        def stat(x, y, axis=-1):
            return y.mean(axis) - x.mean(axis)
    elif statistic == "poi":
        def stat(x, y, axis=-1):
            diff = np.moveaxis(y, axis, -1)[..., None, :] - np.moveaxis(x, axis, -1)[..., :, None]
            return ((diff > 0) + 0.5 * (diff == 0)).mean(axis=(-2, -1)) - 0.5
    else:
        raise ValueError(f"unknown statistic '{statistic}'")
    if np.ptp(np.concatenate([b, t])) == 0:
        return 1.0
    res = stats.permutation_test((b, t), stat, permutation_type="samples" if paired else "independent",
                                 vectorized=True, n_resamples=n_resamples, alternative="two-sided",
                                 rng=np.random.default_rng(seed))
    return float(min(1.0, res.pvalue))


def holm(p_values: Sequence[float | None]) -> list[float | None]:
    r"""Holm's step-down adjustment: the :math:`i`-th smallest of :math:`k` p-values becomes
    :math:`\max_{j \le i} \min(1, (k - j + 1) p_{(j)})`; rejecting where it is below :math:`\alpha` keeps
    the chance of any false finding in the family at most :math:`\alpha`. ``None`` stays ``None`` and
    does not count in :math:`k`."""
    given = [(i, float(p)) for i, p in enumerate(p_values) if p is not None and not math.isnan(p)]
    out: list[float | None] = [None] * len(p_values)
    running = 0.0
    for rank, (i, p) in enumerate(sorted(given, key=lambda x: x[1])):
        running = max(running, min(1.0, (len(given) - rank) * p))
        out[i] = running
    return out


def shape_of(x) -> str | None:
    r"""``"skewed"`` or ``"bimodal"`` when per-seed scores visibly are, else ``None``; only from
    ``SHAPE_MIN_SEEDS`` scores up (fewer cannot show a shape).

    Skewed: D'Agostino's skewness test (``scipy.stats.skewtest``) at 0.05. Bimodal: Sarle's coefficient
    :math:`(g_1^2 + 1) / (g_2 + 3(n-1)^2/((n-2)(n-3))) > 5/9` (the value of a uniform distribution),
    :math:`g_1, g_2` the bias-corrected skewness and excess kurtosis."""
    from scipy import stats

    x = _as_array(x)
    n = x.size
    if n < SHAPE_MIN_SEEDS or np.ptp(x) == 0:
        return None
    if stats.skewtest(x).pvalue < 0.05:
        return "skewed"
    g1, g2 = stats.skew(x, bias=False), stats.kurtosis(x, bias=False)
    coefficient = (g1 ** 2 + 1) / (g2 + 3 * (n - 1) ** 2 / ((n - 2) * (n - 3)))
    return "bimodal" if coefficient > 5 / 9 else None


SHAPE_MIN_SEEDS = 8
"""``scipy.stats.skewtest`` needs 8 scores; below that no shape is tested and the t-based rule holds."""


def equivalence_test(estimate: float, se: float, df: float, margin: float) -> float:
    r"""Two one-sided tests (TOST) that :math:`|\theta| < \delta`: the larger of the p-values of
    :math:`\theta \le -\delta` and :math:`\theta \ge \delta` on Student's t; below :math:`\alpha` it shows
    equivalence (the :math:`1 - 2\alpha` interval lies inside :math:`(-\delta, \delta)`). With
    ``se == 0`` it is 0 inside the margin and 1 outside."""
    from scipy import stats

    if margin <= 0:
        return 1.0
    if se == 0:
        return 0.0 if abs(estimate) < margin else 1.0
    below = stats.t.sf((estimate + margin) / se, df)
    above = stats.t.cdf((estimate - margin) / se, df)
    return float(max(below, above))


def trend(frames, values) -> tuple[float, float, int]:
    """Least-squares slope of ``values`` on ``frames``, its standard error and ``n - 2`` degrees of
    freedom: the test of whether a curve still changes over its final evaluations."""
    f, v = _curve(frames, values)
    if f.size < 3:
        raise ValueError("a trend needs at least 3 evaluations")
    fc = f - f.mean()
    sxx = float((fc * fc).sum())
    slope = float((fc * (v - v.mean())).sum() / sxx)
    resid = v - v.mean() - slope * fc
    se = math.sqrt(float((resid * resid).sum()) / (f.size - 2) / sxx)
    return slope, se, f.size - 2
