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
    ``censored_median``             median time to threshold, a run that never reaches it counting as
                                    infinitely late; ``None`` when that median is infinite (``upper``:
                                    the upper median, a frame one of the runs had).

Intervals and tests over the per-seed scores: :mod:`drltg.analysis.stats`.
"""
from __future__ import annotations

from typing import Callable, Sequence

import numpy as np

Array = np.ndarray


def as_array(x) -> Array:
    if hasattr(x, "detach"):
        x = x.detach().cpu().numpy()
    return np.asarray(x, dtype=np.float64)


def checked_curve(frames, values) -> tuple[Array, Array]:
    f, v = as_array(frames), as_array(values)
    if f.ndim != 1 or f.shape != v.shape or f.size == 0:
        raise ValueError("frames and values must be non-empty 1-D arrays of the same length")
    if (np.diff(f) <= 0).any():
        raise ValueError("frames must strictly increase")
    return f, v


def truncate(frames, values, start: float | None = None, stop: float | None = None) -> tuple[Array, Array]:
    """The curve on ``[start, stop]``, with interpolated end points where they fall between evaluations."""
    f, v = checked_curve(frames, values)
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
    v = as_array(values)
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
    f, v = checked_curve(frames, values)
    lo, hi = final_window(f[0] if start is None else start, f[-1] if stop is None else stop, fraction)
    inside = (f >= lo) & (f <= hi)
    if not inside.any():
        raise ValueError(f"no evaluation lies in the final window [{lo:g}, {hi:g}]")
    return float(v[inside].mean())


def time_to_threshold(frames, values, threshold: float, stop: float | None = None) -> float | None:
    """First evaluation frame (``<= stop``) whose value reaches ``threshold``; ``None`` if none does."""
    f, v = checked_curve(frames, values)
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
    f, v = checked_curve(frames, values)
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
    v = as_array(values)
    if window < 1:
        raise ValueError(f"window must be >= 1, got {window}")
    c = np.concatenate([[0.0], np.cumsum(v)])
    i = np.arange(1, v.size + 1)
    lo = np.maximum(i - window, 0)
    return (c[i] - c[lo]) / (i - lo)


def interquartile_mean(x, axis: int = -1) -> Array | float:
    """Mean of the middle 50 % of the scores along ``axis`` (``floor(n/4)`` dropped at each end)."""
    x = np.sort(as_array(x), axis=axis)
    n = x.shape[axis]
    cut = n // 4
    out = np.take(x, np.arange(cut, n - cut), axis=axis).mean(axis=axis)
    return float(out) if np.ndim(out) == 0 else out


def mean(x, axis: int = -1) -> Array | float:
    out = as_array(x).mean(axis=axis)
    return float(out) if np.ndim(out) == 0 else out


def _difference(baseline, transfer, location: Callable) -> float:
    return float(location(as_array(transfer)) - location(as_array(baseline)))


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
    b = location(np.atleast_1d(as_array(area_baseline)))
    t = location(np.atleast_1d(as_array(area_transfer)))
    if abs(b) <= (eps * scale if scale is not None else 0.0):
        return None
    return float((t - b) / abs(b))


def probability_of_improvement(baseline, transfer) -> float:
    """``P(T > B)`` for a random transfer seed against a random baseline seed; ties count one half."""
    b, t = np.atleast_1d(as_array(baseline)), np.atleast_1d(as_array(transfer))
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
