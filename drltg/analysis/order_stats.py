"""Distribution-free intervals of a median difference from order statistics: of paired differences (the sign
test inverted, exact binomial ranks) and, unpaired, of the Hodges-Lehmann shift (the Mann-Whitney test inverted,
its exact null distribution). They assume independent pairs (runs) and nothing of the scores' shape."""
from __future__ import annotations

import math

import numpy as np

from drltg.analysis.metrics import as_array
from drltg.analysis.stats import Array, check_confidence

__all__ = ["median_interval", "shift_interval"]


def median_interval(differences, confidence: float = 0.95) -> tuple[float, float, float, float]:
    r"""The median of paired differences and its distribution-free interval from their order statistics:
    ``(median, low, high, level)`` with :math:`[d_{(k)}, d_{(n+1-k)}]`, :math:`k` the largest rank with
    :math:`2 P(\mathrm{Bin}(n, 1/2) \le k - 1) \le \alpha` and ``level`` :math:`= 1 - 2 P(\mathrm{Bin}(n, 1/2) \le
    k - 1) \ge` ``confidence``, the coverage it holds.

    Each difference falls below the median with probability 1/2 whatever its distribution, so the count below is
    :math:`\mathrm{Bin}(n, 1/2)` (``scipy.stats.binom``): the interval assumes independent, identically distributed
    pairs and nothing of the differences' shape (the sign test inverted). It is ``nan`` where even
    :math:`[d_{(1)}, d_{(n)}]` holds less than ``confidence`` (:math:`1 - 2/2^n`: 5 pairs give 0.9375 < 0.95)."""
    from scipy import stats as sst

    alpha = 2 * check_confidence(confidence)
    d = np.sort(as_array(differences).ravel())
    n = d.size
    if n == 0:
        raise ValueError("a median interval needs at least one difference")
    tails = 2 * sst.binom.cdf(np.arange(n), n, 0.5)
    k = int((tails <= alpha * (1 + 1e-12)).sum())
    median = float(np.median(d))
    if k == 0:
        return median, math.nan, math.nan, math.nan
    return median, float(d[k - 1]), float(d[n - k]), float(1.0 - tails[k - 1])


def _u_counts(m: int, n: int) -> Array:
    """How many of the :math:`\\binom{m+n}{m}` orderings of two untied samples give each Mann-Whitney count
    :math:`U = 0, \\dots, mn`: :math:`f(u; m, n) = f(u - m; m, n - 1) + f(u; m - 1, n)` (the largest value is
    the second sample's, above all :math:`m` of the first, or the first's), in floats (the counts outgrow
    integers' speed, not their ratios)."""
    rows = [np.ones(1) for _ in range(n + 1)]  # m = 0: one ordering, U = 0
    for i in range(1, m + 1):
        current = [np.ones(1)]
        for j in range(1, n + 1):
            f = np.zeros(i * j + 1)
            f[: rows[j].size] += rows[j]
            f[i: i + current[j - 1].size] += current[j - 1]
            current.append(f)
        rows = current
    return rows[n]


def shift_interval(baseline, transfer, confidence: float = 0.95) -> tuple[float, float, float, float]:
    r"""Unpaired runs: the Hodges-Lehmann shift, the median of the :math:`mn` differences :math:`T_j - B_i`, and
    its distribution-free interval from their order statistics, ``(shift, low, high, level)``:
    :math:`[D_{(k)}, D_{(mn+1-k)}]` with :math:`k` the largest rank where :math:`2 P(U \le k - 1) \le lpha`
    under the exact Mann-Whitney null distribution (the Mann-Whitney test inverted), ``level`` the coverage it
    holds, at least ``confidence``. It assumes independent runs whose two distributions differ by a shift, and
    nothing of their shape; ``nan`` where even :math:`[D_{(1)}, D_{(mn)}]` holds less than ``confidence``
    (3 + 3 runs: 1 - 2/20)."""
    alpha = 2 * check_confidence(confidence)
    b, t = as_array(baseline).ravel(), as_array(transfer).ravel()
    if b.size == 0 or t.size == 0:
        raise ValueError("a shift interval needs runs on both sides")
    d = np.sort((t[:, None] - b[None, :]).ravel())
    counts = _u_counts(b.size, t.size)
    tails = 2 * np.cumsum(counts)[: d.size] / counts.sum()
    k = int((tails <= alpha * (1 + 1e-12)).sum())
    shift = float(np.median(d))
    if k == 0:
        return shift, math.nan, math.nan, math.nan
    return shift, float(d[k - 1]), float(d[d.size - k]), float(1.0 - tails[k - 1])
