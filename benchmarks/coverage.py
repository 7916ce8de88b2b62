"""Coverage of the report's default intervals and false-positive rates of its tests, on simulated seeds; suite
``coverage`` (``python -m benchmarks coverage``: the default and the t interval's table, ``tests/test_coverage.py`` is
the fast check).

    python -m benchmarks.coverage [--experiments 4000] > results/coverage/README.md   # a few minutes
    python -m benchmarks.coverage --learn-or-not > results/coverage/learn-or-not.md
    python -m benchmarks.coverage --power > results/coverage/power.md

Each simulated experiment draws per-seed scores for a baseline and a transfer side whose true
difference is known, builds the interval the report would build, and counts whether it holds the
truth; the tests are run where transfer changes nothing (both sides drawn alike) and counted when they
reject at 0.05. Every draw comes from ``numpy.random.default_rng(seed)``: the same call prints the same
table. Per-seed scores (paired designs share a seed effect between the two runs of a pair):

``normal``     B ~ N(0, 1), T ~ 1 + N(0, 1.5^2); paired: + a shared N(0, 1)
``lognormal``  B = exp(s + e), T = exp(s + 0.3 + e'), e, e' ~ N(0, 0.5^2), s ~ N(0, 1) shared by a pair
               (a multiplicative seed effect: a few seeds score far higher than the rest)
``bimodal``    a seed fails (score 0) with probability 0.5 (B) or 0.25 (T), else N(4, 0.5^2); paired: +
               a shared N(0, 0.5^2)
``rate``       a success rate over 16 episodes, the seed's own rate ~ Beta(2, 2) (B) or Beta(3, 1.5) (T)
``learn-50``, ``learn-80``  learn or not, as in a study: a score is a run's mean success rate over 21
               evaluations of 10 episodes; a seed that learns reaches its success q ~ Beta(40, 10) over 4
               evaluations from evaluation 3 to 5, one that does not scores 0. The baseline never learns; a
               transfer seed learns with probability 0.5 or 0.8 (under no effect, both sides learn with it);
               paired seeds share q and the evaluation where learning starts
"""
from __future__ import annotations

import argparse
import functools
import time

import numpy as np

from drltg.analysis import metrics as M
from drltg.analysis import stats

SHAPES = ("normal", "lognormal", "bimodal", "rate")
"""The shapes of the report's coverage claim (``drltg.report.COVERAGE_CLAIM``)."""
LEARN = {"learn-50": 0.5, "learn-80": 0.8}
"""The chance that a transfer seed learns, per learn-or-not shape."""


def _learned(q: np.ndarray, start: np.ndarray, rng) -> np.ndarray:
    """A learning run's score: its mean success over 21 evaluations of 10 episodes, success ramping from 0
    at evaluation ``start`` to ``q`` four evaluations later."""
    ramp = np.clip((np.arange(21) - start[..., None]) / 4, 0, 1)
    return (rng.binomial(10, q[..., None] * ramp) / 10).mean(-1)


LEARNED = float(_learned(np.random.default_rng(96).beta(40, 10, 200_000),
                         np.random.default_rng(95).integers(3, 6, 200_000), np.random.default_rng(94)).mean())
"""The mean score of a seed that learns (200k simulated runs)."""
MEANS = {"normal": (0.0, 1.0), "lognormal": (float(np.exp(0.625)), float(np.exp(0.925))), "bimodal": (2.0, 3.0),
         "rate": (0.5, 2 / 3), **{shape: (0.0, p * LEARNED) for shape, p in LEARN.items()}}
"""The true mean score of each side (B, T) when transfer has an effect."""
DESIGNS = ("paired", "unpaired")
SEEDS = (3, 5, 10)
LEVEL = 0.95
TARGET = 0.93


def draw(shape: str, design: str, n: int, experiments: int, rng, null: bool = False) -> tuple:
    """``[experiments, n]`` baseline and transfer scores and the true mean difference (0 when ``null``)."""
    size = (experiments, n)
    paired = design == "paired"
    if shape == "normal":
        shared = rng.normal(0, 1, size) if paired else 0.0
        b = shared + rng.normal(0, 1, size)
        t = shared + (0.0 if null else 1.0) + rng.normal(0, 1 if null else 1.5, size)
        return b, t, 0.0 if null else 1.0
    if shape == "lognormal":
        s = rng.normal(0, 1, size)
        sb = s if paired else rng.normal(0, 1, size)
        lift = 0.0 if null else 0.3
        b, t = np.exp(sb + rng.normal(0, 0.5, size)), np.exp(s + lift + rng.normal(0, 0.5, size))
        return b, t, float(np.exp(lift + 0.625) - np.exp(0.625))  # E exp(N(m, v)) = exp(m + v/2)
    if shape == "bimodal":
        shared = rng.normal(0, 0.5, size) if paired else 0.0
        fail_t = 0.5 if null else 0.25
        b = np.where(rng.random(size) < 0.5, 0.0, rng.normal(4, 0.5, size)) + shared
        t = np.where(rng.random(size) < fail_t, 0.0, rng.normal(4, 0.5, size)) + shared
        return b, t, 4 * (0.5 - fail_t)
    if shape in LEARN:
        p = LEARN[shape]
        q, start = rng.beta(40, 10, size), rng.integers(3, 6, size)
        qb, sb = (q, start) if paired else (rng.beta(40, 10, size), rng.integers(3, 6, size))
        b = np.where(rng.random(size) < (p if null else 0.0), _learned(qb, sb, rng), 0.0)
        t = np.where(rng.random(size) < p, _learned(q, start, rng), 0.0)
        return b, t, 0.0 if null else p * LEARNED
    if shape == "rate":  # a pair's two seeds share their luck u: each side's rate is its quantile u
        from scipy import stats

        u = rng.random(size)
        pb = stats.beta(2, 2).ppf(u if paired else rng.random(size))
        pt = stats.beta(2, 2).ppf(u) if null else stats.beta(3, 1.5).ppf(u)
        return rng.binomial(16, pb) / 16, rng.binomial(16, pt) / 16, MEANS[shape][1] - MEANS[shape][0]
    raise ValueError(shape)


def covered(lo, hi, truth) -> float:
    return float(((np.asarray(lo) <= truth) & (truth <= np.asarray(hi))).mean())


def difference_coverage(shape, design, n, experiments, seed) -> tuple[float, float, float, float]:
    """The t interval (paired, or Welch's standard error with Hsu's degrees of freedom), cut to +-1 for
    rates as the report cuts it, and the two bootstrap candidates (``--interval studentized`` and ``bca``,
    1000 resamples): (t coverage, largest |end| of t, bootstrap-t coverage, BCa coverage). An undefined
    interval (no spread in the sample) counts as a miss."""
    b, t, truth = draw(shape, design, n, experiments, np.random.default_rng(seed))
    paired = design == "paired"
    lo, hi = stats.t_interval(b, t, paired=paired, confidence=LEVEL)
    if shape == "rate" or shape in LEARN:
        lo, hi = np.maximum(lo, -1.0), np.minimum(hi, 1.0)
    boot = [covered(*stats.INTERVALS[name](b, t, paired=paired, confidence=LEVEL, n_resamples=1000, seed=seed + 1),
                    truth) for name in ("studentized", "bca")]
    return covered(lo, hi, truth), float(np.nanmax(np.abs(np.concatenate([lo, hi])))), *boot


def ratio_coverage(shape, design, n, experiments, seed, offset: float = 5.0) -> tuple[float, float]:
    """Fieller's interval of transfer_ratio (scores shifted by ``offset`` so the baseline mean is away from
    0): (coverage among the bounded intervals, share reported without one)."""
    b, t, _ = draw(shape, design, n, experiments, np.random.default_rng(seed))
    b, t = b + offset, t + offset
    mean_b, mean_t = MEANS[shape]
    ratio = (mean_t + offset) / (mean_b + offset) - 1
    hits = nulls = 0
    for bi, ti in zip(b, t):
        lo, hi = stats.ratio_interval(bi, ti, design == "paired", LEVEL)
        if np.isnan(lo):
            nulls += 1
        else:
            hits += lo <= ratio <= hi
    bounded = experiments - nulls
    return (hits / bounded if bounded else float("nan")), nulls / experiments


@functools.lru_cache
def true_poi(shape, design) -> float:
    """P(T > B) with ties one half: over a pair's two runs (paired), or two independent runs."""
    b, t, _ = draw(shape, design, 1_000_000, 1, np.random.default_rng(98))
    if design == "unpaired":
        t = np.random.default_rng(97).permutation(t[0])[None]
    return float(((t > b) + 0.5 * (t == b)).mean())


def poi_coverage(shape, design, n, experiments, seed) -> tuple[float, float, float]:
    """Clopper-Pearson over pairs or Newcombe's method 5: (coverage, lowest end, highest end)."""
    b, t, _ = draw(shape, design, n, experiments, np.random.default_rng(seed))
    truth, paired = true_poi(shape, design), design == "paired"
    ends = []
    for bi, ti in zip(b, t):
        p = stats.paired_probability_of_improvement(bi, ti) if paired else M.probability_of_improvement(bi, ti)
        ends.append(stats.poi_interval(p, n, n, paired, LEVEL))
    lo, hi = np.array(ends).T
    return covered(lo, hi, truth), float(lo.min()), float(hi.max())


RANGES = {"rate": (0.0, 1.0), **dict.fromkeys(LEARN, (0.0, 1.0))}
"""The shapes whose range a report knows (a rate's, a success rate's): the default interval is a betting
interval there; the others' range is unknown, so the default withholds the interval."""


def default_coverage(shape, design, n, experiments, seed) -> tuple[str, str, str]:
    """The report's default (``--interval auto``): (coverage of the betting interval, share of experiments
    without any effect in which it excludes 0, share of experiments with the effect in which it does), or
    ("withheld", "none", "none") where the range is unknown."""
    if shape not in RANGES:
        return "withheld", "none", "none"
    paired = design == "paired"
    b, t, truth = draw(shape, design, n, experiments, np.random.default_rng(seed))
    lo, hi, _ = stats.betting_interval(b, t, RANGES[shape], paired)
    b, t, _ = draw(shape, design, n, experiments, np.random.default_rng(seed + 7), null=True)
    lo0, hi0, _ = stats.betting_interval(b, t, RANGES[shape], paired)
    return (f"{covered(lo, hi, truth):.3f}", f"{((lo0 > 0) | (hi0 < 0)).mean():.3f}",
            f"{((lo > 0) | (hi < 0)).mean():.3f}")


def false_positives(shape, design, n, experiments, seed) -> tuple[float, float]:
    """Where transfer changes nothing: the share of experiments whose mean difference's p_value (the t
    test, or the exact permutation test where the scores look skewed or bimodal) and whose P(T > B)
    p_value (sign test over pairs, permutation test of the Mann-Whitney estimate) are below 0.05."""
    b, t, _ = draw(shape, design, n, experiments, np.random.default_rng(seed), null=True)
    paired = design == "paired"
    p_t = stats.t_test(b, t, paired)
    mean_hits = poi_hits = 0
    for i, (bi, ti) in enumerate(zip(b, t)):
        shaped = stats.shape_of(ti - bi) if paired else (stats.shape_of(bi) or stats.shape_of(ti))
        p = stats.permutation_test(bi, ti, paired, seed=i, n_resamples=999) if shaped else p_t[i]
        mean_hits += bool(p < 0.05)
        q = (stats.sign_test(bi, ti) if paired
             else stats.permutation_test(bi, ti, statistic="poi", seed=i, n_resamples=999))
        poi_hits += q < 0.05
    return mean_hits / experiments, poi_hits / experiments


REASONS = {
    "normal": "too few seeds for the spread to be estimated at the promised precision",
    "lognormal": ("the pairs' differences are right-skewed (a multiplicative seed effect): a sample that misses the "
                  "few high seeds has a low mean and a small spread at once, so the interval ends too low"),
    "bimodal": ("with few seeds the share of failed seeds in a sample strays far from its rate, and the spread "
                "the sample shows with it"),
    "rate": "too few seeds for the spread of the rates to be estimated at the promised precision",
    **dict.fromkeys(LEARN, "a sample in which every transfer seed learns (or none does) shows no sign of the other "
                           "mode, so the interval sits on the mode it saw"),
}


def _bootstrap_note(name: str, t: float, boot_t: float, bca: float) -> str:
    """Whether a bootstrap candidate would have done better for the mean difference, from the numbers."""
    if not name.startswith("the mean difference"):
        return ""
    if max(boot_t, bca) > t:
        return f"; a bootstrap interval does better here ({max(boot_t, bca):.3f}) but not across the table"
    return f"; the bootstrap candidates do worse ({boot_t:.3f}, {bca:.3f})"


def table(experiments: int, seed: int = 0, shapes=SHAPES) -> str:
    slow = max(experiments // 4, 200)
    lines = [
        "| scores | design | seeds | default (auto): betting or withheld | false claims: default | power: default | "
        "mean difference (t) | transfer_ratio (Fieller; share without one) | "
        "P(T > B) | false positives: mean difference | false positives: P(T > B) | not default: bootstrap-t | "
        "not default: BCa |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    short = []
    for shape in shapes:
        for design in DESIGNS:
            for n in SEEDS:
                auto, auto_fp, auto_power = default_coverage(shape, design, n, experiments, seed)
                cov, biggest, boot_t, bca = difference_coverage(shape, design, n, experiments, seed)
                ratio, nulls = ratio_coverage(shape, design, n, slow, seed)
                poi, low, high = poi_coverage(shape, design, n, slow, seed)
                fp_mean, fp_poi = false_positives(shape, design, n, slow, seed)
                where = f"{shape} {design} {n}"
                for name, value in (("the mean difference's t interval", cov), ("Fieller's ratio interval", ratio),
                                    ("the P(T > B) interval", poi)):
                    if not value >= TARGET:
                        short.append(f"- {name}: {value:.3f} ({where} seeds): {REASONS[shape]}"
                                     + _bootstrap_note(name, cov, boot_t, bca))
                lines.append(f"| {shape} | {design} | {n} | {auto} | {auto_fp} | {auto_power} | {cov:.3f} | "
                             f"{ratio:.3f} ({nulls:.0%}) | {poi:.3f} | {fp_mean:.3f} | {fp_poi:.3f} | {boot_t:.3f} | "
                             f"{bca:.3f} |")
                if shape == "rate":
                    assert biggest <= 1.0 and 0.0 <= low and high <= 1.0  # the ranges the report promises
    below = "\n".join(short) or "- none"
    return ("\n".join(lines) + f"\n\nBelow {TARGET} (the level each interval is held to), of t and Fieller's "
            "(`--interval t`):\n\n" + below + "\n")


def power_table(experiments: int = 300, seed: int = 3) -> str:
    """How often the default (betting) interval excludes 0 on learn-or-not scores with the effect, by seeds."""
    lines = ["| seeds | " + " | ".join(f"{shape} {design}" for shape in LEARN for design in DESIGNS) + " |",
             "|---|" + "---|" * (len(LEARN) * len(DESIGNS))]
    for n in (5, 10, 15, 20, 30):
        cells = []
        for shape in LEARN:
            for design in DESIGNS:
                b, t, _ = draw(shape, design, n, experiments, np.random.default_rng(seed))
                lo, hi, _ = stats.betting_interval(b, t, RANGES[shape], design == "paired")
                cells.append(f"{((lo > 0) | (hi < 0)).mean():.2f}")
        lines.append(f"| {n} | " + " | ".join(cells) + " |")
    return ("# Power of the default interval on learn-or-not scores\n\n"
            f"Made by `python -m benchmarks.coverage --power` ({experiments} experiments a cell, seeded): the "
            "share of experiments in which the betting interval excludes 0 where transfer has the effect of "
            "results/coverage/learn-or-not.md (the baseline never learns; a transfer seed learns with probability "
            "0.5 or 0.8). It holds its level for any scores, and pays for it in seeds.\n\n" + "\n".join(lines) + "\n")


HEADER = """# {title}

Made by `python -m benchmarks.coverage{flags} --experiments {experiments}` ({seconds:.0f} s on this machine;
seeded, so the same command prints the same table). Coverage of the report's 95% intervals: the share of
simulated experiments whose interval holds the true value. The default (`--interval auto`) is a betting
interval where the scores' range is known (rates: [0, 1]) and no interval where it is not; `--interval t`
gives the t interval, Fieller's for the ratio, as the next columns measure them. Power: the share of
experiments with the effect in which the default interval excludes 0 (it is wide: with 6 pairs or fewer it
never does) ({experiments} experiments per cell
for the mean difference, {slow} for the others: standard errors about {se_fast:.3f} and {se_slow:.3f} near 0.95).
False positives: the share of experiments without any effect in which the report's p_value is below 0.05
({slow} experiments: standard error about {se_fp:.3f} near 0.05). The score shapes are those of the
script's docstring; `rate`{learn} intervals are cut to [-1, 1] (differences) and lie in [0, 1] (P(T > B)).

"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--experiments", type=int, default=4000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--learn-or-not", action="store_true", help="the learn-or-not shapes (results/coverage/"
                        "learn-or-not.md), which the report's coverage claim does not name")
    parser.add_argument("--power", action="store_true", help="the default interval's power on learn-or-not "
                        "scores at 5 to 30 seeds (results/coverage/power.md)")
    args = parser.parse_args()
    if args.power:
        print(power_table(), end="")
        return
    start = time.perf_counter()
    body = table(args.experiments, args.seed, tuple(LEARN) if args.learn_or_not else SHAPES)
    slow = max(args.experiments // 4, 200)
    title = ("Coverage on learn-or-not scores (shapes the report's coverage claim does not name)" if args.learn_or_not
             else "Coverage of the report's intervals")
    print(HEADER.format(title=title, flags=" --learn-or-not" if args.learn_or_not else "",
                        learn=" and learn-or-not" if args.learn_or_not else "", experiments=args.experiments,
                        seconds=time.perf_counter() - start, slow=slow,
                        se_fast=(0.95 * 0.05 / args.experiments) ** 0.5, se_slow=(0.95 * 0.05 / slow) ** 0.5,
                        se_fp=(0.95 * 0.05 / slow) ** 0.5) + body, end="")


def _cells(markdown: str) -> list[dict]:
    rows = [line.strip("|").split("|") for line in markdown.splitlines() if line.startswith("| ") and "---" not in line]
    header = [c.strip() for c in rows[0]]
    return [dict(zip(header, (c.strip() for c in row))) for row in rows[1:]]


def run(device: str = "cpu", quick: bool = False) -> dict:
    experiments = 400 if quick else 4000
    start = time.perf_counter()
    cells = _cells(table(experiments, 0, SHAPES + tuple(LEARN)))
    seconds = time.perf_counter() - start
    below = [c for c in cells if c["default (auto): betting or withheld"] != "withheld"
             and float(c["default (auto): betting or withheld"]) < 0.93]
    return {"experiments": experiments, "seconds": round(seconds, 1), "cells": cells,
            "default_below_0.93": len(below), "target": "the default covers >= 0.93 or is withheld in every cell"}


if __name__ == "__main__":
    main()
