"""How often each test says yes: its level on null shapes and its power on effects, by simulation.

A procedure that can never say yes at the seed counts RL affords is as wrong as one that says yes too
often, so both are measured on the shapes RL scores take: paired runs ``(B_i, T_i)`` of ``n`` seeds drawn
from a *shape*, under no effect (B and T from one distribution, a seed effect shared within the pair) and
under an effect. Three tests of a paired mean difference at level ``alpha``, two-sided:

- ``sign-flip``: the exact randomization test drltg's verdicts use (:func:`drltg.analysis.stats.permutation_test`,
  paired): all :math:`2^n` sign patterns of the differences while they number at most 2^16, else 9,999
  random ones (the observed pattern counted, so the p-value stays valid);
- ``t``: the paired t test;
- ``betting``: the range-bounded betting test (:func:`drltg.analysis.stats.betting_interval`), on the shapes
  whose range is known.

``sequential`` runs the rule of ``--seeds auto`` (:data:`drltg.analysis.sequential`) on the same draws:
looks at the pairs :func:`drltg.analysis.sequential.looks` plans up to ``n``, each a sign-flip test at its
share of ``alpha``, stopping at the first that decides.

    python -m drltg.analysis.operating --out results/verdicts   # the committed table (about 2 minutes)
"""
from __future__ import annotations

import argparse
import itertools
import json
import os
import warnings
from pathlib import Path
from typing import Callable

import numpy as np

from drltg.analysis import sequential, stats

Draw = Callable[[np.random.Generator, int, int], tuple[np.ndarray, np.ndarray]]
"""``draw(rng, reps, n)``: ``reps`` paired experiments of ``n`` seeds, baseline and transfer scores (reps x n)."""


def _paired(side: Callable, effect: Callable | None = None, seed_sd: float = 0.0) -> Draw:
    def draw(rng, reps, n):
        shared = rng.normal(0.0, seed_sd, (reps, n)) if seed_sd else 0.0
        b = side(rng, (reps, n)) + shared
        t = side(rng, (reps, n)) + shared
        return b, (t if effect is None else effect(rng, b, t))
    return draw


def _learn_or_not(p_b: float, p_t: float) -> Draw:
    def draw(rng, reps, n):
        return (rng.random((reps, n)) < p_b).astype(float), (rng.random((reps, n)) < p_t).astype(float)
    return draw


def _manipulation(gain: float, sd: float) -> Draw:
    """Returns on [0, 500]: a baseline spread over the range, the transfer run of the pair ``gain`` +- ``sd``
    from it (clipped to the range)."""
    def draw(rng, reps, n):
        b = rng.uniform(0.0, 500.0, (reps, n))
        return b, np.clip(b + rng.normal(gain, sd, (reps, n)), 0.0, 500.0)
    return draw


NULLS: dict[str, tuple[Draw, tuple[float, float] | None]] = {
    "normal": (_paired(lambda rng, s: rng.normal(0.0, 1.0, s), seed_sd=1.0), None),
    "skewed": (_paired(lambda rng, s: rng.lognormal(0.0, 1.0, s)), None),
    "learn-or-not": (_learn_or_not(0.5, 0.5), (0.0, 1.0)),
    "wide range": (_manipulation(0.0, 25.0), (0.0, 500.0)),
}
"""Shapes of no effect, with the range their scores lie in where it is known."""

EFFECTS: dict[str, tuple[Draw, tuple[float, float] | None]] = {
    "normal, gain/sd 1.5": (_paired(lambda rng, s: rng.normal(0.0, 1.0 / np.sqrt(2), s),
                                    effect=lambda rng, b, t: t + 1.5, seed_sd=1.0), None),
    "learn-or-not +0.5": (_learn_or_not(0.25, 0.75), (0.0, 1.0)),
    "returns on [0, 500], -22 +- 25": (_manipulation(-22.0, 25.0), (0.0, 500.0)),
}
"""Effects the FourRooms sweeps and the manipulation rows show (the paired differences' mean over sd)."""


def sign_flip_p(d: np.ndarray, rng: np.random.Generator, exact_up_to: int = 16, n_random: int = 9999) -> np.ndarray:
    """Two-sided sign-flip p-values of the mean of each row of ``d`` (reps x n): the share of sign patterns
    whose ``|mean|`` is at least the observed (within a relative 1e-12, as scipy counts ties)."""
    reps, n = d.shape
    if n <= exact_up_to:
        signs = np.array(list(itertools.product((1.0, -1.0), repeat=n)))
        counted, total = 0, len(signs)
    else:
        signs = rng.choice((1.0, -1.0), (n_random, n))
        counted, total = 1, n_random + 1  # the observed pattern is one of the arrangements
    observed = np.abs(d.mean(axis=1))
    out = np.empty(reps)
    for start in range(0, reps, 256):
        block = d[start:start + 256]
        flipped = np.abs(block @ signs.T) / n
        hits = (flipped >= observed[start:start + 256, None] * (1 - 1e-12)).sum(axis=1)
        out[start:start + 256] = (hits + counted) / total
    return out


def t_p(b: np.ndarray, t: np.ndarray) -> np.ndarray:
    from scipy import stats as sst

    d = t - b
    with np.errstate(divide="ignore", invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # rows whose differences are all alike: no t test
        p = sst.ttest_1samp(d, 0.0, axis=1).pvalue
    return np.where(np.isnan(p), 1.0, p)


def betting_p(b: np.ndarray, t: np.ndarray, value_range: tuple[float, float], alpha: float) -> np.ndarray:
    return np.array([stats.betting_interval(x, y, value_range, True, 1 - alpha)[2] for x, y in zip(b, t)])


def sequential_claims(b: np.ndarray, t: np.ndarray, rng: np.random.Generator, alpha: float) -> np.ndarray:
    """Whether ``--seeds auto``'s rule decides each experiment, looking at its first pairs in turn."""
    claimed = np.zeros(len(b), bool)
    for look in sequential.looks(b.shape[1], alpha):
        p = sign_flip_p(t[:, :look.pairs] - b[:, :look.pairs], rng)
        claimed |= p < look.alpha
    return claimed


def rates(draw: Draw, value_range, n: int, reps: int, alpha: float, seed: int) -> dict[str, float | None]:
    """The share of ``reps`` experiments of ``n`` pairs in which each test rejects "no effect" at ``alpha``."""
    rng = np.random.default_rng(seed)
    b, t = draw(rng, reps, n)
    out = {"sign-flip": float((sign_flip_p(t - b, rng) < alpha).mean()),
           "t": float((t_p(b, t) < alpha).mean()),
           "betting": None if value_range is None else float((betting_p(b, t, value_range, alpha) < alpha).mean())}
    out["sequential"] = float(sequential_claims(b, t, rng, alpha).mean())
    return out


def table(counts=(6, 10, 20), reps: int = 2000, alpha: float = 0.05, seed: int = 0) -> dict:
    """Level (false claims) on every null shape and power on every effect, at each count of pairs."""
    def rows(shapes):
        return {name: {str(n): rates(draw, rng_range, n, reps, alpha, seed + i)
                       for i, n in enumerate(counts)}
                for name, (draw, rng_range) in shapes.items()}
    return {"alpha": alpha, "reps": reps, "seed": seed, "pairs": list(counts),
            "level": rows(NULLS), "power": rows(EFFECTS)}


def markdown(result: dict) -> str:
    tests = ("sign-flip", "t", "betting", "sequential")

    def cell(x):
        return "—" if x is None else f"{x:.3f}"

    lines = []
    for part, title in (("level", "False claims under no effect (at most alpha is right)"),
                        ("power", "Power: the share of experiments that decide")):
        lines += [f"**{title}**, alpha = {result['alpha']}, {result['reps']} simulated experiments a cell:", "",
                  "| shape | pairs | " + " | ".join(tests) + " |", "|---|---|" + "---|" * len(tests)]
        for shape, by_n in result[part].items():
            for n, r in by_n.items():
                lines.append(f"| {shape} | {n} | " + " | ".join(cell(r[k]) for k in tests) + " |")
        lines.append("")
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m drltg.analysis.operating", description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, required=True, help="folder for operating.json and operating.md")
    p.add_argument("--reps", type=int, default=2000)
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    result = table(reps=args.reps, seed=args.seed)
    args.out.mkdir(parents=True, exist_ok=True)
    for name, text in (("operating.json", json.dumps(result, indent=1) + "\n"), ("operating.md", markdown(result))):
        tmp = args.out / f".{name}.tmp"  # written whole, then renamed: never half a table
        tmp.write_text(text)
        os.replace(tmp, args.out / name)
    print(markdown(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
