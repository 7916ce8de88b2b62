"""Coverage of the report's intervals, measured on simulated experiments.

Each experiment draws per-seed scores for both sides with a known true difference of the means
(1.0), builds the interval, and checks whether it contains the truth. All experiments of one setting
are one vectorised call, so thousands run in well under a second for the t-interval.

    python tests/test_coverage.py      # the full table (all candidate methods), about a minute
"""
from __future__ import annotations

import functools

import numpy as np
import pytest

from drltg.analysis import metrics as M
from drltg.analysis import stats

TRUE_DIFFERENCE = 1.0


def draw(shape: str, design: str, n: int, experiments: int, rng) -> tuple[np.ndarray, np.ndarray]:
    """``[experiments, n]`` baseline and transfer scores with ``mean(T) - mean(B) = 1``.

    normal: noise N(0, 1) for the baseline, N(0, 1.5^2) for the transfer side (unequal spreads);
    skewed: centred exponential noise (skewness 2), scale 1 and 2; bimodal: a seed fails (-2) with
    probability 1/2 or succeeds (+2), plus N(0, 0.5^2). Paired designs add a seed effect N(0, 1) shared by
    the two runs of a pair. (``benchmarks/coverage.py`` measures the full table.)"""
    size = (experiments, n)
    if shape == "normal":
        eb, et = rng.normal(0, 1, size), rng.normal(0, 1.5, size)
    elif shape == "skewed":
        eb, et = rng.exponential(1, size) - 1, 2 * (rng.exponential(1, size) - 1)
    elif shape == "bimodal":
        eb, et = (np.where(rng.random(size) < 0.5, -2.0, 2.0) + rng.normal(0, 0.5, size) for _ in range(2))
    else:
        raise ValueError(shape)
    seed_effect = rng.normal(0, 1, size) if design == "paired" else 0.0
    return seed_effect + eb, seed_effect + TRUE_DIFFERENCE + et


def coverage(method: str, shape: str, design: str, n: int, experiments: int = 4000, seed: int = 0,
             confidence: float = 0.95, n_resamples: int = 1000) -> float:
    """Fraction of simulated experiments whose interval contains the true difference."""
    rng = np.random.default_rng(seed)
    b, t = draw(shape, design, n, experiments, rng)
    kw = {} if method in ("t", "welch") else dict(n_resamples=n_resamples, seed=seed + 1)
    lo, hi = stats.INTERVALS[method](b, t, paired=design == "paired", confidence=confidence, **kw)
    return float(((lo <= TRUE_DIFFERENCE) & (TRUE_DIFFERENCE <= hi)).mean())


@pytest.mark.parametrize("design", ["paired", "unpaired"])
@pytest.mark.parametrize("shape", ["normal", "skewed"])
def test_default_interval_keeps_its_promise_at_five_seeds(shape, design):
    # 10000 experiments: the standard error of a coverage near 0.94 is 0.0024
    assert coverage("t", shape, design, n=5, experiments=10_000) >= 0.93


@pytest.mark.parametrize("design", ["paired", "unpaired"])
def test_default_interval_on_bimodal_scores_at_ten_seeds(design):
    assert coverage("t", "bimodal", design, n=10, experiments=4000) >= 0.93


@pytest.mark.parametrize("n", [3, 10])
def test_default_interval_at_three_and_ten_seeds(n):
    for shape in ("normal", "skewed"):
        for design in ("paired", "unpaired"):
            assert coverage("t", shape, design, n=n, experiments=2000) >= 0.90


def test_percentile_bootstrap_under_covers_with_five_seeds():
    """The interval the report used before: about 0.88 where 0.95 is promised."""
    assert coverage("percentile", "normal", "unpaired", n=5, experiments=1000, n_resamples=500) < 0.91


@functools.lru_cache
def true_probability_of_improvement(shape: str, samples: int = 1_000_000) -> float:
    """P(T > B) for one baseline and one transfer draw; the shared seed effect of a pair cancels, so
    the paired P(T_i > B_i) is the same number."""
    b, t = draw(shape, "unpaired", samples, 1, np.random.default_rng(99))
    return float((t > b).mean())


def poi_coverage(shape: str, design: str, n: int, experiments: int = 2000, seed: int = 0) -> float:
    """Coverage of the score interval of P(T > B) (Wilson over pairs, Newcombe unpaired)."""
    truth = true_probability_of_improvement(shape)
    b, t = draw(shape, design, n, experiments, np.random.default_rng(seed))
    paired = design == "paired"
    hits = 0
    for bi, ti in zip(b, t):
        p = stats.paired_probability_of_improvement(bi, ti) if paired else M.probability_of_improvement(bi, ti)
        lo, hi = stats.poi_interval(p, n, n, paired)
        hits += lo <= truth <= hi
    return hits / experiments


def ratio_coverage(shape: str, design: str, n: int, experiments: int = 2000, seed: int = 0,
                   baseline_mean: float = 5.0) -> tuple[float, float]:
    """Fieller's interval of transfer_ratio with the baseline mean at ``baseline_mean`` (true ratio
    1 / baseline_mean): (coverage among bounded intervals, fraction reported as null)."""
    b, t = draw(shape, design, n, experiments, np.random.default_rng(seed))
    b, t = b + baseline_mean, t + baseline_mean
    truth = TRUE_DIFFERENCE / baseline_mean
    hits = nulls = 0
    for bi, ti in zip(b, t):
        lo, hi = stats.ratio_interval(bi, ti, design == "paired")
        if np.isnan(lo):
            nulls += 1
        else:
            hits += lo <= truth <= hi
    bounded = experiments - nulls
    return (hits / bounded if bounded else float("nan")), nulls / experiments


def test_ratio_and_probability_intervals_at_five_seeds():
    for design in ("paired", "unpaired"):
        covered, nulls = ratio_coverage("normal", design, 5, experiments=1000)
        assert covered >= 0.93 and nulls < 0.05
        assert poi_coverage("normal", design, 5, experiments=500) >= 0.93


def test_newcombe_interval_covers_at_three_seeds_a_side():
    """Newcombe's method 5 (N = (n + m)/2; test_metrics checks it against the published example)."""
    for shape in ("normal", "bimodal"):
        assert poi_coverage(shape, "unpaired", 3, experiments=1000) >= 0.95


@pytest.mark.parametrize("n", [5, 10])
def test_tests_of_no_effect_keep_their_false_positive_rate(n):
    """Both sides drawn alike: the sign test over pairs (P(T > B)) and the t test behind the paired interval
    reject at 0.05 in at most 5 % of experiments (plus two standard errors of the estimate)."""
    rng = np.random.default_rng(n)
    b, t = rng.normal(0, 1, (4000, n)), rng.normal(0, 1, (4000, n))
    sign = np.mean([stats.sign_test(bi, ti) < 0.05 for bi, ti in zip(b, t)])
    assert sign <= 0.05  # exact: at most the level (5 pairs: 0, since p >= 1/16)
    assert (stats.t_test(b, t, paired=True) < 0.05).mean() <= 0.05 + 2 * np.sqrt(0.05 * 0.95 / 4000)
    wilson_like = np.mean([stats.poi_interval(stats.paired_probability_of_improvement(bi, ti), n, n, True)[0] > 0.5
                           for bi, ti in zip(b, t)])
    assert wilson_like <= 0.05  # the interval over pairs excludes 1/2 no more often than the sign test rejects


def table(experiments: int = 4000) -> str:
    rows = ["| scores | design | seeds | " + " | ".join(stats.INTERVALS) + " |",
            "|---|---|---|" + "---|" * len(stats.INTERVALS)]
    for shape in ("normal", "skewed"):
        for design in ("paired", "unpaired"):
            for n in (3, 5, 10):
                cells = [f"{coverage(m, shape, design, n, experiments):.3f}" for m in stats.INTERVALS]
                rows.append(f"| {shape} | {design} | {n} | " + " | ".join(cells) + " |")
    rows += ["", "| scores | design | seeds | transfer_ratio (Fieller; null share) | P(T > B) (score) |",
             "|---|---|---|---|---|"]
    for shape in ("normal", "skewed"):
        for design in ("paired", "unpaired"):
            for n in (3, 5, 10):
                covered, nulls = ratio_coverage(shape, design, n)
                rows.append(f"| {shape} | {design} | {n} | {covered:.3f} ({nulls:.0%} null) | "
                            f"{poi_coverage(shape, design, n):.3f} |")
    return "\n".join(rows)


if __name__ == "__main__":
    print(table())


def test_the_report_s_coverage_claim_matches_the_committed_simulation():
    """Every cell of results/coverage below 0.93 is one the report names as an exception, and no
    exception is a cell that reaches it (the claim neither hides a shortfall nor gives up a success)."""
    from pathlib import Path

    from drltg.report import COVERAGE_EXCEPTIONS

    text = (Path(__file__).resolve().parents[1] / "results" / "coverage" / "README.md").read_text()
    rows = [line.strip("|").split("|") for line in text.splitlines() if line.startswith("| ") and "---" not in line]
    header = [c.strip() for c in rows[0]]
    short = set()
    for cells in rows[1:]:
        cells = [c.strip() for c in cells]
        shape, design, seeds = cells[0], cells[1], int(cells[2])
        for column in ("mean difference (t)", "transfer_ratio (Fieller; share without one)", "P(T > B)"):
            if float(cells[header.index(column)].split()[0]) < 0.93:
                short.add((shape, design, seeds))
        assert float(cells[header.index("false positives: P(T > B)")]) <= 0.05 + 3 * (0.05 * 0.95 / 1000) ** 0.5

    def excepted(cell):
        return any(cell[:2] == e[:2] and e[2] in (None, cell[2]) for e in COVERAGE_EXCEPTIONS)

    assert all(excepted(cell) for cell in short), short
    for shape, design, seeds in COVERAGE_EXCEPTIONS:
        assert any(c[:2] == (shape, design) and seeds in (None, c[2]) for c in short), (shape, design, seeds)


def test_the_docs_sentence_on_learn_or_not_scores_matches_the_committed_simulation():
    """docs/report.md: on learn-or-not scores no interval measured covers 93% at 3 seeds, nor at 5 or 10
    where 80% of seeds learn (every candidate column of results/coverage/learn-or-not.md)."""
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    assert "no interval measured covers\n93% at 3 seeds, nor at 5 or 10 where 80% of seeds learn" in (
        root / "docs" / "report.md").read_text()
    text = (root / "results" / "coverage" / "learn-or-not.md").read_text()
    rows = [line.strip("|").split("|") for line in text.splitlines() if line.startswith("| ") and "---" not in line]
    header = [c.strip() for c in rows[0]]
    columns = ["mean difference (t)", "not default: bootstrap-t", "not default: BCa"]
    seen = set()
    for cells in rows[1:]:
        cells = [c.strip() for c in cells]
        shape, seeds = cells[0], int(cells[2])
        if seeds == 3 or shape == "learn-80":
            seen.add((shape, cells[1], seeds))
            assert all(float(cells[header.index(c)]) < 0.93 for c in columns), cells
    assert len(seen) == 8  # 2 designs x (learn-50 at 3; learn-80 at 3, 5, 10)


# --------------------------------------------------------------- the report's default: --interval auto
def bounded_draw(shape: str, design: str, n: int, experiments: int, rng, null: bool = False):
    """Scores in [0, 1] with known means: ``normal`` Beta(10, 10) against Beta(12, 8); ``skewed`` Beta(0.5, 5)
    against Beta(0.8, 4); ``learn-50`` / ``learn-80``: the baseline never learns (0), a transfer seed learns
    with probability 0.5 / 0.8 and then scores Beta(40, 10) (under ``null`` both sides learn alike). Paired
    seeds share their luck (one quantile u for both runs of a pair)."""
    from scipy import stats as sst

    size = (experiments, n)
    u = rng.random(size)
    v = u if design == "paired" else rng.random(size)
    if shape in ("normal", "skewed"):
        base, lift = {"normal": ((10, 10), (12, 8)), "skewed": ((0.5, 5), (0.8, 4))}[shape]
        top = base if null else lift
        b, t = sst.beta(*base).ppf(v), sst.beta(*top).ppf(u)
        return b, t, sst.beta(*top).mean() - sst.beta(*base).mean()
    p = {"learn-50": 0.5, "learn-80": 0.8}[shape]
    score = sst.beta(40, 10)
    t = np.where(rng.random(size) < p, score.ppf(u), 0.0)
    b = np.where(rng.random(size) < p, score.ppf(v), 0.0) if null else np.zeros(size)
    return b, t, 0.0 if null else p * score.mean()


@pytest.mark.parametrize("design", ["paired", "unpaired"])
@pytest.mark.parametrize("shape", ["normal", "skewed", "learn-50", "learn-80"])
def test_the_default_interval_covers_any_scores_in_their_range_and_rarely_claims_a_difference(shape, design):
    """3, 5 and 10 seeds, 200 experiments a cell (the standard error of a coverage near 0.95 is 0.015):
    coverage at least 0.93, and a difference claimed (the interval excludes 0) in at most 6% of experiments
    without one. ``benchmarks/coverage.py`` measures the thorough table."""
    for n in (3, 5, 10):
        b, t, truth = bounded_draw(shape, design, n, 200, np.random.default_rng(n))
        lo, hi, _ = stats.betting_interval(b, t, (0, 1), paired=design == "paired")
        assert ((lo <= truth) & (truth <= hi)).mean() >= 0.93, n
        b, t, _ = bounded_draw(shape, design, n, 200, np.random.default_rng(100 + n), null=True)
        lo, hi, p = stats.betting_interval(b, t, (0, 1), paired=design == "paired")
        assert ((lo > 0) | (hi < 0)).mean() <= 0.06 and (p < 0.05).mean() <= 0.06, n


def test_the_default_withholds_intervals_of_scores_of_unknown_range():
    """Skewed and bimodal scores of unknown range: no interval at any seed count (the t interval's coverage
    falls below 0.93 there: see the tests above and results/coverage), a sentence that says why instead."""
    from drltg import report
    from drltg.report.curves import Curve

    rng = np.random.default_rng(0)
    for n in (3, 5, 10):
        b, t = draw("skewed", "paired", n, 1, rng)
        runs = {side: [Curve((0, 10, 20), [x] * 3, f"{side}{i}", f"{side}{i}", config={"seed": i})
                       for i, x in enumerate(scores[0])] for side, scores in (("b", b), ("t", t))}
        res = report.compute(runs["b"], runs["t"])
        assert not any(k.endswith("_ci") and "probability" not in k for k in res["metrics"])
        assert any("no mean difference has an interval" in w for w in res["settings"]["warnings"])
