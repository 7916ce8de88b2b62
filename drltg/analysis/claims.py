"""Sentences that state a result, rendered from a report's numbers under fixed rules.

A researcher quotes sentences, not tables, so every sentence that states a result is built here from the
``transfer_metrics.json`` (or sweep summary) it summarises, and only these words carry a verdict:

- **a difference** is called higher / lower only when its interval excludes 0 and, where a family of
  intervals is read together, its Holm-adjusted p-value is below ``LEVEL`` too; otherwise the sentence
  says "no evidence of a difference at this budget" (or, for a non-zero difference that has no interval,
  "no interval, so no verdict");
- **best** only when every pairwise difference to the others excludes 0 (after Holm over those pairs);
- **every seed** only when every seed does; otherwise the count ("3 of 5 seeds") is given;
- **a threshold** is "first reached" for a first crossing, and "held" (sustained) only under the report's
  sustained rule, whose sentence states how many evaluations after the crossing confirm it.

The functions take plain dicts (the report's JSON as loaded) and never compute a new statistic other than
the paired comparison between two methods that share their seeds (:func:`pairwise`).
"""
from __future__ import annotations

import math
from typing import Mapping, Sequence

import numpy as np

from drltg.analysis import stats

LEVEL = 0.05
MINUS = "\u2212"
NO_EVIDENCE = "no evidence of a difference at this budget"
NO_INTERVAL = "no interval, so no verdict"
LABELS = {
    "mean_return_gain": "mean return gain",
    "jumpstart": "jumpstart",
    "asymptotic_performance": "asymptotic difference",
    "transfer_ratio": "transfer ratio",
    "probability_of_improvement": "P(T > B)",
}


def signed(x: float, digits: int = 2) -> str:
    """``+1.08`` / ``−0.41`` (a true minus sign); ``+0.00`` for a value that rounds to zero."""
    text = f"{x:+.{digits}f}"
    if float(text) == 0:
        text = f"+{0:.{digits}f}"
    return text.replace("-", MINUS)


def estimate(value: float, ci: Sequence | None = None, digits: int = 2) -> str:
    """``+1.08 [+0.91, +1.24]``; the value alone where there is no interval."""
    if not has_interval(ci):
        return signed(value, digits)
    return f"{signed(value, digits)} [{signed(ci[0], digits)}, {signed(ci[1], digits)}]"


def has_interval(ci: Sequence | None) -> bool:
    return ci is not None and ci[0] is not None and ci[1] is not None


def excludes_zero(ci: Sequence | None) -> bool:
    return has_interval(ci) and (ci[0] > 0 or ci[1] < 0)


def direction(ci: Sequence | None, p_adjusted: float | None = None, level: float = LEVEL) -> int:
    """+1 / −1 when the interval lies above / below 0 (and the family's adjusted p is below ``level``
    where one is given), else 0: the one rule behind every higher / lower / no-evidence word."""
    if not excludes_zero(ci):
        return 0
    if p_adjusted is not None and not p_adjusted < level:
        return 0
    return 1 if ci[0] > 0 else -1


def verdict(value: float, ci: Sequence | None, p_adjusted: float | None = None, family: int | None = None,
            higher: str = "higher with transfer", lower: str = "lower with transfer") -> str:
    """``+1.08 [+0.91, +1.24], higher with transfer`` or ``...: no evidence of a difference at this budget``;
    an interval that excludes 0 but is held back by the family's adjustment says so, naming the adjusted
    p-value (and the family's size when given). A non-zero difference without an interval (every pair
    gave the same one, or the ratio is unbounded) has no verdict either way."""
    sign = direction(ci, p_adjusted)
    text = estimate(value, ci)
    if sign > 0:
        return f"{text}, {higher}"
    if sign < 0:
        return f"{text}, {lower}"
    if excludes_zero(ci) and p_adjusted is not None:
        of = "" if family is None else f" of {family}"
        return f"{text}: {NO_EVIDENCE} after Holm's adjustment (adjusted p = {p_text(p_adjusted)}{of})"
    if signed(value) != signed(0) and not has_interval(ci):
        return f"{text}: {NO_INTERVAL}"
    return f"{text}: {NO_EVIDENCE}"


def p_text(p: float) -> str:
    return "<0.001" if p < 0.001 else f"{p:.3g}"


def seeds(k: int, n: int) -> str:
    """"every seed (5 of 5)", "no seed (0 of 5)" or "3 of 5 seeds": "every" only when it is every one."""
    if n <= 0:
        raise ValueError("no seeds to count")
    if k == n:
        return f"every seed ({k} of {n})"
    if k == 0:
        return f"no seed (0 of {n})"
    return f"{k} of {n} seeds"


def agree(k: int, n: int, singular: str, plural: str) -> str:
    """The verb that goes with :func:`seeds` (``every seed holds``, ``3 of 5 seeds hold``)."""
    return singular if k in (0, 1, n) else plural


def frames(x: float) -> str:
    """``4k`` for whole thousands, ``17.5k`` otherwise (frame counts of evaluations)."""
    k = x / 1000
    return f"{k:.0f}k" if abs(k - round(k)) < 0.05 else f"{k:.1f}k"


def threshold_sentence(report: Mapping, side: str = "transfer", who: str | None = None) -> str:
    """How many of a side's seeds reach the report's threshold under its rule, and the median frame.

    "every seed" only when every seed does; the median is the report's upper median (``null`` without a
    strict majority, then only the count is given)."""
    st, per_seed = report["settings"], report["per_seed"][side]
    threshold = st.get("threshold")
    if threshold is None:
        raise ValueError("the report has no threshold")
    times = [r.get("time_to_threshold") for r in per_seed]
    reached = [t for t in times if t is not None]
    who = who or side
    k, n = len(reached), len(times)
    if st.get("crossing") == "first":
        text = (f"{who}: {seeds(k, n)} {agree(k, n, 'reaches', 'reach')} {threshold:g} at least once "
                "(a first crossing, not a sustained one)")
    else:
        span = (f"for {st['sustain']} evaluations in a row (sustained)" if st.get("sustain") else
                f"to the end (sustained: at least {st.get('sustain_after', 2)} evaluations after the crossing)")
        text = f"{who}: {seeds(k, n)} {agree(k, n, 'holds', 'hold')} {threshold:g} {span}"
    if reached:
        first = sorted(reached)
        if len(reached) == len(times):
            text += f", the last of them from {frames(first[-1])} frames"
        else:
            text += f", from {', '.join(frames(t) for t in first)} frames"
    median = report["metrics"].get(f"time_to_threshold_{side}")
    if median is not None and len(reached) < len(times):
        text += f" (upper median over seeds {frames(median)})"
    return text


def report_sentences(report: Mapping, metrics: Sequence[str] = ("mean_return_gain",)) -> list[str]:
    """The conclusions of one report: each named metric against 0, read within the report's family
    (Holm over ``settings.family``), and each side's threshold count."""
    m, st = report["metrics"], report["settings"]
    family = (st.get("family") or {}).get("size")
    out = []
    for name in metrics:
        if m.get(name) is None:
            continue
        label = LABELS.get(name, name.replace("_", " "))
        said = verdict(m[name], m.get(f"{name}_ci"), m.get(f"{name}_p_adjusted"), family)
        out.append(f"{label.capitalize()}: {said}.")
    if st.get("threshold") is not None:
        for side in ("baseline", "transfer"):
            out.append(threshold_sentence(report, side).capitalize() + ".")
    return out


def per_seed_scores(report: Mapping, side: str, score: str = "mean_return") -> dict:
    """``{seed: score}`` of one side (seeds from the runs' configs)."""
    return {r["seed"]: r[score] for r in report["per_seed"][side] if r.get("seed") is not None}


def pairwise(a: Mapping, b: Mapping, score: str = "mean_return") -> tuple[float, tuple[float, float] | None, float]:
    """Paired comparison of two methods' transfer runs on the same target: ``d_i = A_i − B_i`` over the seeds
    both share (runs with the same seed share the baseline's seed and initial weights), its mean, paired
    t-interval (``None`` without spread) and t-test p-value."""
    sa, sb = per_seed_scores(a, "transfer", score), per_seed_scores(b, "transfer", score)
    shared = sorted(set(sa) & set(sb))
    if len(shared) < 2:
        raise ValueError("two methods share fewer than 2 seeds: no paired comparison")
    x, y = np.array([sb[s] for s in shared]), np.array([sa[s] for s in shared])
    lo, hi = stats.t_interval(x, y, paired=True)
    p = stats.t_test(x, y, paired=True)
    ci = None if math.isnan(float(lo)) else (float(lo), float(hi))
    return float((y - x).mean()), ci, (1.0 if math.isnan(p) else float(p))


def best_sentence(reports: Mapping[str, Mapping], where: str, score: str = "mean_return") -> str:
    """Which method, if any, is best on one target: the one whose transfer runs beat every other's, each
    paired difference excluding 0 after Holm over all the pairs read; otherwise it names the leader and the
    rival it is not separated from."""
    names = sorted(reports)
    if len(names) < 2:
        raise ValueError("best needs at least two methods")
    means = {n: float(np.mean(list(per_seed_scores(reports[n], "transfer", score).values()))) for n in names}
    leader = max(names, key=means.get)
    pairs = [(leader, other, *pairwise(reports[leader], reports[other], score)) for other in names if other != leader]
    adjusted = stats.holm([p for *_, p in pairs])
    weakest = None
    for (_, other, diff, ci, _p), p_adj in zip(pairs, adjusted):
        if direction(ci, p_adj) <= 0 and (weakest is None or diff < weakest[1]):
            weakest = (other, diff, ci)
    if weakest is None:
        diffs = "; ".join(f"{other} {estimate(diff, ci)}" for _, other, diff, ci, _p in pairs)
        return (f"{where}: {leader} is best, ahead of every other method (paired by seed, Holm over "
                f"{len(pairs)}): {diffs}")
    other, diff, ci = weakest
    return (f"{where}: no method is best; {leader} leads, and its paired difference to {other} is "
            f"{estimate(diff, ci)}: {NO_EVIDENCE}")


def headline(report: Mapping, metric: str = "mean_return_gain") -> str:
    """One sentence that concludes a report: its headline metric, named in advance and read alone (the
    report's other metrics form the family that its p (Holm) column adjusts)."""
    m, st = report["metrics"], report["settings"]
    n_b, n_t = m["n_seeds_baseline"], m["n_seeds_transfer"]
    design = f"{n_t} paired seeds" if st.get("paired") else f"{n_t} + {n_b} seeds"
    label = LABELS.get(metric, metric.replace("_", " "))
    where = f"{st['transfer_label']} vs {st['baseline_label']}, {design}, {frames(st['budget'])} frames"
    if m.get(metric) is None:
        return f"Headline ({where}): {label} is not available."
    return f"Headline ({where}): {label} {verdict(m[metric], m.get(f'{metric}_ci'))}."


def fill_regions(text: str, regions: Mapping[str, str]) -> str:
    """``text`` with the body between ``<!-- claims:NAME -->`` and ``<!-- /claims:NAME -->`` replaced by
    ``regions[NAME]`` (each marker on a line of its own). A region named in ``regions`` whose markers are
    missing, or a marker left open, is an error: the prose would silently keep an old number."""
    for name, body in regions.items():
        start, end = f"<!-- claims:{name} -->\n", f"<!-- /claims:{name} -->"
        i = text.find(start)
        j = text.find(end, i + len(start)) if i >= 0 else -1
        if i < 0 or j < 0:
            raise ValueError(f"no region '{name}': add the lines '{start.strip()}' and '{end}' around it")
        if not body.endswith("\n"):
            body += "\n"
        text = text[:i + len(start)] + body + text[j:]
    return text
