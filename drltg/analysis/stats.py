r"""Intervals and tests over per-seed scores: how sure a report may be of a difference.

Intervals (vectorised over leading axes, so a coverage simulation is one call; ``tests/test_coverage.py``
measures them and chose ``t_interval`` as the default)
    ``t_interval``            paired: :math:`\bar d \pm t_{n-1} s_d/\sqrt n`; unpaired: Welch's standard
                              error with Hsu's :math:`\min(n_B, n_T) - 1` degrees of freedom.
    ``welch_interval``, ``studentized_interval``, ``bca_interval``, ``percentile_interval``: the
                              other candidates (they under-cover with 3 to 10 seeds).
    ``betting_interval``      from the scores' known range alone (hedged capital betting, Waudby-Smith &
                              Ramdas 2024): valid for any distribution on it, learn-or-not included; the
                              report's default. ``betting_p``: its p-values.
    ``ratio_interval``        Fieller's interval of a ratio of means, mapped to ``transfer_ratio``; NaN
                              when the baseline mean's own interval contains 0 (unbounded).
    ``poi_interval``          interval of a probability of improvement inside [0, 1] (Clopper-Pearson
                              for pairs, Newcombe's method 5 for the Mann-Whitney estimate); never
                              ``[1, 1]``.
    (distribution-free intervals of a median difference from order statistics: :mod:`drltg.analysis.order_stats`)
    ``trend``                 least-squares slope and its standard error (is a curve still changing?).

Tests (two-sided p-values)
    ``t_test``                the test dual to ``t_interval``; ``sign_test`` exact, over pairs;
    ``permutation_test``      exact (or seeded Monte Carlo) relabelling test of no effect, valid at any
                              number of seeds; ``stratified_sign_flip`` the same over pairs in several
                              strata (the targets of a family); ``equivalence_test`` two one-sided tests (TOST);
    ``holm``                  Holm's adjustment of a family of p-values; ``shape_of`` flags skewed or
                              bimodal per-seed scores.
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from drltg.analysis.metrics import as_array, checked_curve

Array = np.ndarray

ASSUMES = {
    "range": "only the declared range (worst case over it)",
    "normal differences": "normal differences",
    "normal scores": "normal scores on each side",
    "normal areas": "normal areas (Fieller)",
    "resampling": "that the seeds stand for their distribution (bootstrap)",
    "pairs": "independent pairs, any shape",
    "shift": "independent runs, the sides differing by a shift, any shape",
    "runs": "independent runs, a normal approximation of the score (Newcombe)",
    "line": "normal scatter about a straight line",
}
"""What each interval assumes, as ``<key>_assumes`` gives it beside every ``<key>`` interval in the metrics: the
test that decides a verdict assumes none of these (exchangeable runs under no effect only)."""


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


def check_confidence(confidence: float) -> float:
    """The tail probability (1 - confidence) / 2 of a two-sided interval, refusing a confidence outside (0, 1)."""
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
    b, t = as_array(b), as_array(t)
    if paired and b.shape != t.shape:
        raise ValueError(f"paired samples need the same shape, got {b.shape} and {t.shape}")
    if min(b.shape[-1], t.shape[-1]) < 2:
        raise ValueError("an interval needs at least 2 seeds per side")
    return b, t


def t_interval(b, t, paired: bool = False, confidence: float = 0.95, df: str = "hsu") -> tuple[Array, Array]:
    """``mean(t) - mean(b)`` +- ``t_{1-a/2, df} x se``: the paired t-interval (on :math:`d_i`), or
    the unpaired one with Welch's standard error (``df`` as in :func:`_difference_and_se`). Exact for
    normal pairs; NaN where the standard error is 0 (no spread to scale)."""
    alpha = check_confidence(confidence)
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
    alpha = check_confidence(confidence)
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

    check_confidence(confidence)
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
    alpha = check_confidence(confidence)
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


def _bets(x: Array, alpha: float) -> Array:
    r"""Predictable plug-in bets :math:`\lambda_i = \sqrt{2\log(2/\alpha) / (n\,\hat\sigma^2_{i-1})}` with
    :math:`\hat\mu_i = (\tfrac12 + \sum_{j\le i} x_j)/(i+1)` and
    :math:`\hat\sigma^2_i = (\tfrac14 + \sum_{j\le i}(x_j - \hat\mu_j)^2)/(i+1)` (:math:`\hat\sigma^2_0 = 1/4`)."""
    n = x.shape[-1]
    i = np.arange(1, n + 1)
    mu = (0.5 + np.cumsum(x, -1)) / (i + 1)
    var = (0.25 + np.cumsum((x - mu) ** 2, -1)) / (i + 1)
    before = np.concatenate([np.full((*x.shape[:-1], 1), 0.25), var[..., :-1]], -1)
    return np.sqrt(2 * np.log(2 / alpha) / (n * before))


def betting_p(x, means, alpha: float = 0.05, c: float = 0.75) -> Array:
    r"""p-values of "the mean of ``x`` is m" for each m of ``means``, ``x`` in [0, 1] along its last axis:
    ``[..., len(means)]``.

    Waudby-Smith & Ramdas (2024)'s hedged capital: a gambler who bets that the mean is above m and one who
    bets it is below each start with 1/2, :math:`K^\pm_i(m) = \prod_{j \le i}(1 \pm \lambda^\pm_j (x_j - m))` with
    the bets of :func:`_bets` capped at :math:`c/m` and :math:`c/(1-m)`. Under the mean m their wealth is a
    nonnegative martingale from 1, so by Ville's inequality :math:`p = 1 / \max_i \max(K^+_i, K^-_i)/2` is a valid
    p-value for any distribution on [0, 1]: no normality, no symmetry, no minimum sample."""
    x = as_array(x)
    m = np.asarray(means, np.float64)[:, None]
    lam = _bets(x, alpha)[..., None, :]
    dev = x[..., None, :] - m
    with np.errstate(divide="ignore"):  # c/0 caps nothing; a wealth of 0 is a log of -inf, never the maximum
        up, down = np.minimum(lam, c / m), np.minimum(lam, c / (1 - m))
        log_wealth = np.maximum(np.log1p(up * dev).cumsum(-1), np.log1p(-down * dev).cumsum(-1)).max(-1)
    return np.minimum(1.0, np.exp(np.log(2.0) - log_wealth))


RANGE_TOLERANCE = 1e-6
"""How far, as a share of the range, a score may stray outside it and count as round-off (curves are float32)."""
BETTING_GRID = np.linspace(0.0, 1.0, 2001)
"""The means a betting interval is tested at; its ends are widened to the next point out."""


def _betting_mean(x: Array, alpha: float) -> tuple[Array, Array, Array]:
    """Interval ``(low, high)`` of the mean of ``x`` in [0, 1] at level ``1 - alpha``, and the p-values on
    :data:`BETTING_GRID` (in chunks: the grid times the seeds times the experiments)."""
    flat = x.reshape(-1, x.shape[-1])
    p = np.concatenate([betting_p(flat[i:i + 64], BETTING_GRID, alpha) for i in range(0, len(flat), 64)])
    kept = p > alpha
    step = BETTING_GRID[1]
    lo = np.maximum(BETTING_GRID[kept.argmax(-1)] - step, 0.0)
    hi = np.minimum(BETTING_GRID[len(BETTING_GRID) - 1 - kept[:, ::-1].argmax(-1)] + step, 1.0)
    return lo.reshape(x.shape[:-1]), hi.reshape(x.shape[:-1]), p.reshape(*x.shape[:-1], -1)


def _unit(x: Array, low: float, high: float) -> Array:
    """Scores mapped from [low, high] to [0, 1]; round-off of float32 logs (1e-6 of the range) is clipped."""
    x = (x - low) / (high - low)
    if np.any(x < -RANGE_TOLERANCE) or np.any(x > 1 + RANGE_TOLERANCE):
        raise ValueError(f"a score lies outside the value range [{low:g}, {high:g}]")
    return np.clip(x, 0.0, 1.0)


def betting_sides(b, t, value_range: tuple[float, float], confidence: float = 0.95) -> tuple[tuple, tuple]:
    """Each side's betting interval of its mean at level ``1 - alpha/2`` (Bonferroni: both hold together
    with probability at least ``1 - alpha``), for scores in ``value_range``: ``((L_B, U_B), (L_T, U_T))``."""
    alpha = 2 * check_confidence(confidence)
    a, w = float(value_range[0]), float(value_range[1]) - float(value_range[0])
    (lb, ub, _), (lt, ut, _) = (_betting_mean(_unit(as_array(x), a, a + w), alpha / 2) for x in (b, t))
    return (a + w * lb, a + w * ub), (a + w * lt, a + w * ut)


def betting_interval(b, t, value_range: tuple[float, float], paired: bool = False,
                     confidence: float = 0.95) -> tuple[Array, Array, Array]:
    r"""Interval of ``mean(t) - mean(b)`` for scores known to lie in ``value_range`` = [a, a + w], valid for any
    distribution there (learn-or-not seeds included), and its p-value of no difference: ``(low, high, p)``.

    Paired: the betting interval of the differences' mean, :math:`(d + w) / 2w \in [0, 1]`. Unpaired: each
    side's interval at level :math:`1 - \alpha/2` (:func:`betting_sides`), the difference of the ends,
    :math:`[L_T - U_B,\ U_T - L_B]`; its p-value is twice the smallest level at which both sides reject one
    value between their means. It is wide with few seeds (with 6 pairs or fewer it cannot exclude 0: a pair
    multiplies the wealth by at most 1 + c = 1.75, and 1.75^6 / 2 < 20), because only the range, not the
    seeds' spread, bounds what the unseen seeds could do."""
    alpha = 2 * check_confidence(confidence)
    b, t = _pairs(b, t, paired)
    a, w = float(value_range[0]), float(value_range[1]) - float(value_range[0])
    b, t = _unit(b, a, a + w), _unit(t, a, a + w)
    if paired:
        lo, hi, p = _betting_mean((t - b + 1) / 2, alpha)
        return w * (2 * lo - 1), w * (2 * hi - 1), p[..., len(BETTING_GRID) // 2]
    (lb, ub, pb), (lt, ut, pt) = _betting_mean(b, alpha / 2), _betting_mean(t, alpha / 2)
    mb, mt = b.mean(-1)[..., None], t.mean(-1)[..., None]
    between = (BETTING_GRID >= np.minimum(mb, mt)) & (BETTING_GRID <= np.maximum(mb, mt))
    p0 = np.minimum(1.0, 2 * np.where(between, np.maximum(pb, pt), np.inf).min(-1))
    return w * (lt - ub), w * (ut - lb), p0


INTERVALS = {"t": t_interval, "welch": welch_interval, "studentized": studentized_interval,
             "bca": bca_interval, "percentile": percentile_interval}
"""Candidate intervals of a mean difference that build on the seeds' spread (``--interval``; the report's
default is :func:`betting_interval`, or none without a range); ``t`` is the best of them by the coverage measured in
``tests/test_coverage.py`` (the only candidate at or near the promised level with 3 to 10 seeds)."""


def fieller_interval(b, t, paired: bool = False, confidence: float = 0.95) -> tuple[float, float]:
    r"""Fieller's interval for the ratio of means :math:`\rho = \mu_T / \mu_B`.

    The set of :math:`\rho` with :math:`(\bar t - \rho \bar b)^2 \le q^2 (v_t - 2\rho c + \rho^2 v_b)`
    (:math:`v` = squared standard errors, :math:`c` their covariance when paired, :math:`q` the t
    quantile). It is a bounded interval only when the denominator's own interval excludes 0
    (:math:`\bar b^2 > q^2 v_b`); otherwise ``(nan, nan)``: no honest bounded interval exists."""
    alpha = check_confidence(confidence)
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
    sign = 1.0 if as_array(area_baseline).mean() > 0 else -1.0
    ends = sorted((sign * (lo - 1), sign * (hi - 1)))
    return ends[0], ends[1]


def paired_probability_of_improvement(baseline, transfer) -> float:
    r""":math:`\frac1n\sum_i 1[t_i > b_i] + \tfrac12 1[t_i = b_i]` over pairs ``(b_i, t_i)``."""
    d = as_array(transfer) - as_array(baseline)
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

    alpha = check_confidence(confidence)
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

    d = as_array(transfer) - as_array(baseline)
    wins, losses = int((d > 0).sum()), int((d < 0).sum())
    return 1.0 if wins + losses == 0 else float(stats.binomtest(wins, wins + losses, 0.5).pvalue)


PERMUTATION_DRAWS = 9999
"""Draws of :func:`permutation_test` where the arrangements outnumber them."""


def enumerated(n: int, paired: bool, n_other: int | None = None, n_resamples: int = PERMUTATION_DRAWS) -> bool:
    """Whether :func:`permutation_test` counts every arrangement (an exact p-value) of ``n`` pairs (``2^n``
    sign patterns) or of ``n`` and ``n_other`` runs (``C(n + m, n)`` relabellings), rather than drawing
    ``n_resamples`` of them (a Monte Carlo p-value)."""
    arrangements = 2 ** n if paired else math.comb(n + (n if n_other is None else n_other), n)
    return arrangements <= n_resamples


def permutation_test(baseline, transfer, paired: bool = False, statistic: str = "mean", seed: int = 0,
                     n_resamples: int = PERMUTATION_DRAWS) -> float:
    """Two-sided permutation test that transfer changes nothing (``scipy.stats.permutation_test``):
    paired, the two runs of each pair swapped (the differences' signs flipped); unpaired, the runs
    relabelled. ``statistic``: ``"mean"`` (the mean difference) or ``"poi"`` (the Mann-Whitney
    estimate). Exact while the arrangements number at most ``n_resamples`` (up to 13 pairs; 5 + 5 runs
    have 252), else a seeded Monte Carlo p-value; its false-positive rate is at most the level at any
    number of seeds."""
    from scipy import stats

    b, t = as_array(baseline), as_array(transfer)
    if statistic == "mean":
        def stat(x, y, axis=-1):
            return y.mean(axis) - x.mean(axis)
    elif statistic == "poi":
        def stat(x, y, axis=-1):
            diff = np.moveaxis(y, axis, -1)[..., None, :] - np.moveaxis(x, axis, -1)[..., :, None]
            return ((diff > 0) + 0.5 * (diff == 0)).mean(axis=(-2, -1)) - 0.5
    else:
        raise ValueError(f"unknown statistic '{statistic}'")
    if np.ptp(np.concatenate([b, t])) == 0 or min(len(b), len(t)) < 2:  # one run a side: no test to make
        return 1.0
    res = stats.permutation_test((b, t), stat, permutation_type="samples" if paired else "independent",
                                 vectorized=True, n_resamples=n_resamples, alternative="two-sided",
                                 rng=np.random.default_rng(seed))
    return float(min(1.0, res.pvalue))


STRATIFIED_EXACT_PAIRS = 40
"""Up to this many pairs in all the stratified sign-flip test counts every sign pattern (two halves of at most
2^20 sums each, met by sorting); above it, a seeded Monte Carlo."""


STRATIFIED_RESAMPLES = 99_999
"""Random sign patterns of the stratified test's Monte Carlo: its smallest p is 1e-5, room for Holm over methods."""


def stratified_sign_flip(strata: Sequence, seed: int = 0, n_resamples: int = STRATIFIED_RESAMPLES,
                         exact_pairs: int = STRATIFIED_EXACT_PAIRS) -> tuple[float, float]:
    r"""Two-sided exact sign-flip test that a method changes nothing on any target of a family:
    ``(statistic, p)``.

    ``strata``: one sequence of paired differences :math:`d_{ji} = T_{ji} - B_{ji}` a stratum (a target with its
    own baseline). The statistic is the sum over strata of the per-stratum mean difference,
    :math:`S = \sum_j ar d_j`, so every target weighs alike whatever its seed count. Under no effect each pair's
    two runs are exchangeable, so each :math:`d_{ji}` keeps or flips its sign with probability 1/2, within its
    stratum and independently of every other: :math:`p = \#\{arepsilon : |S(arepsilon)| \ge |S|\} / 2^N`
    over all :math:`2^N` patterns of the :math:`N` pairs (exact up to ``exact_pairs``), else
    :math:`(b + 1)/(m + 1)` with :math:`b` of :math:`m` = ``n_resamples`` seeded random patterns at least as
    extreme. Valid at any seed count with no range or normality; one stratum gives the paired sign-flip test of
    the mean (:func:`permutation_test`)."""
    groups = [as_array(x).ravel() for x in strata]
    if not groups or any(g.size == 0 for g in groups):
        raise ValueError("every stratum needs at least one paired difference")
    terms = np.concatenate([g / g.size for g in groups])
    observed = float(terms.sum())
    tol = 1e-9 * float(np.abs(terms).sum())  # sums of the same terms in another order differ in the last bits
    if abs(observed) <= tol:
        return observed, 1.0
    if terms.size <= exact_pairs:
        half = terms.size // 2
        a, b = _signed_sums(terms[:half]), np.sort(_signed_sums(terms[half:]))
        at_least = b.size - np.searchsorted(b, abs(observed) - a - tol, side="left")
        at_most = np.searchsorted(b, -abs(observed) - a + tol, side="right")
        return observed, float((at_least + at_most).sum()) / 2.0 ** terms.size
    rng = np.random.default_rng(seed)
    extreme = 0
    for start in range(0, n_resamples, 10_000):
        signs = rng.choice((-1.0, 1.0), size=(min(10_000, n_resamples - start), terms.size))
        extreme += int((np.abs(signs @ terms) >= abs(observed) - tol).sum())
    return observed, (extreme + 1) / (n_resamples + 1)


def _signed_sums(x: Array) -> Array:
    """:math:`\\sum_i \varepsilon_i x_i` for every one of the :math:`2^n` sign patterns :math:`\varepsilon`."""
    sums = np.zeros(1)
    for v in x:
        sums = np.concatenate([sums + v, sums - v])
    return sums


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

    x = as_array(x)
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


def tost(b, t, paired: bool, margin: float) -> float:
    r"""TOST p-value that the mean difference of ``t`` over ``b`` lies within :math:`\pm` ``margin``: paired t on
    :math:`d_i = t_i - b_i`, or Welch's standard error with Hsu's degrees of freedom (:func:`equivalence_test`);
    it assumes normal (differences of) scores, as a t interval does."""
    b, t = np.asarray(b, float), np.asarray(t, float)
    estimate, se, df = _difference_and_se(b, t, paired)
    return equivalence_test(float(estimate), float(se), float(df), float(margin))


def trend(frames, values) -> tuple[float, float, int]:
    """Least-squares slope of ``values`` on ``frames``, its standard error and ``n - 2`` degrees of
    freedom: the test of whether a curve still changes over its final evaluations."""
    f, v = checked_curve(frames, values)
    if f.size < 3:
        raise ValueError("a trend needs at least 3 evaluations")
    fc = f - f.mean()
    sxx = float((fc * fc).sum())
    slope = float((fc * (v - v.mean())).sum() / sxx)
    resid = v - v.mean() - slope * fc
    se = math.sqrt(float((resid * resid).sum()) / (f.size - 2) / sxx)
    return slope, se, f.size - 2
