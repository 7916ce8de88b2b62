"""Sentences that state a result, rendered from a report's numbers under fixed rules.

A researcher quotes sentences, not tables, so every sentence that states a result is built here from the
``transfer_metrics.json`` (or sweep summary) it summarises, and only these words carry a verdict:

- **a difference** is called higher / lower only when the exact randomization test (sign-flip over pairs,
  permutation of runs), which keeps its level at any seed count and assumes no range or normality, rejects
  "no effect" at ``LEVEL``, Holm-adjusted where a family is read together; its intervals are the magnitudes
  beside it, each named with what it assumes (the report's ``<key>_assumes``: the t interval normal
  differences, the median's order statistics independent pairs only, the betting interval the worst case over
  the declared range), never the gate. Otherwise the difference is
  "undecided at N pairs", naming the test's p-value, and a design too small for the test to reach the
  level at all (fewer than 6 pairs) says so. Only where no exact test exists does an interval decide ("no
  evidence of a difference at this budget", "no interval, so no verdict", "no interval without the
  curves' range").

The functions take plain dicts (the report's JSON as loaded) and compute no new statistic other than the
estimate of how many seeds would decide (:func:`betting_seeds`).
"""
from __future__ import annotations

import math
from typing import Mapping, NamedTuple, Sequence

import numpy as np

from drltg.analysis import stats
from drltg.analysis.stats import ASSUMES

LEVEL = 0.05
"""The level of every verdict drltg states (reports, sweep summaries, the board): the one home of 0.05."""
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


class Adjusted(NamedTuple):
    """A difference's two p-values, each Holm-adjusted within the family it is read in: ``t``, the test
    behind its interval; ``exact``, the sign-flip or permutation test, which assumes no normality;
    ``size``, how many differences the family holds."""

    t: float | None
    exact: float | None
    size: int = 1


def exact_p(metrics: Mapping, name: str) -> float | None:
    """The exact test's p-value behind metric ``name``: ``<name>_p_exact`` of a mean difference; P(T > B)'s
    own (an exact sign or permutation test already); for transfer_ratio the mean return gain's (the same
    areas compared: no effect on one is no effect on the other)."""
    if name == "transfer_ratio":
        name = "mean_return_gain"
    if name.startswith("probability_of_improvement"):
        return metrics.get(f"{name}_p_value")
    return metrics.get(f"{name}_p_exact")


def direction(value: float, ci: Sequence | None, p_adjusted: float | Adjusted | None = None,
              level: float = LEVEL) -> int:
    """+1 / −1 by the sign of ``value`` when the exact randomization test (``p_adjusted.exact``: sign-flip over
    pairs, permutation of runs; Holm-adjusted in its family) rejects "no effect" at ``level``, else 0: the one
    rule behind every higher / lower word. The test keeps its level at any seed count and needs no range or
    normality; the interval beside it is a magnitude, not the gate. Only where no exact test was made (a plain
    p-value given, or none) does the interval decide: +1 / −1 when it lies above / below 0 and the p-value,
    where given, is below ``level``."""
    t, exact, _ = p_adjusted if isinstance(p_adjusted, Adjusted) else (p_adjusted, None, 1)
    if exact is not None:
        return (1 if value > 0 else -1) if exact < level and signed(value) != signed(0) else 0
    if not excludes_zero(ci) or (t is not None and not t < level):
        return 0
    return 1 if ci[0] > 0 else -1


def smallest_exact_p(n: int, paired: bool, n_other: int | None = None) -> float:
    """The smallest two-sided p-value the exact test can give: :math:`2/2^n` for the sign-flip test over ``n``
    pairs, :math:`2/\binom{n + m}{n}` for the permutation test of ``n`` and ``m`` runs. Below ``level`` only
    from 6 pairs (0.031; 5 give 0.0625) or 4 + 4 runs (0.029)."""
    if paired:
        return min(1.0, 2 / 2 ** n)
    return min(1.0, 2 / math.comb(n + (n if n_other is None else n_other), n))


def test_words(n: int, paired: bool, n_other: int | None = None) -> str:
    """The randomization test behind a verdict, named as it was made: ``exact sign-flip test`` where every
    arrangement was counted, ``sign-flip test (Monte Carlo, 9,999 draws)`` where they were drawn."""
    from drltg.analysis.stats import PERMUTATION_DRAWS, enumerated

    name = "sign-flip" if paired else "permutation"
    if enumerated(n, paired, n_other):
        return f"exact {name} test"
    return f"{name} test (Monte Carlo, {PERMUTATION_DRAWS:,} draws)"


def verdict(value: float, ci: Sequence | None, p_adjusted: float | Adjusted | None = None,
            family: int | None = None, higher: str = "higher with transfer", lower: str = "lower with transfer",
            design: tuple[int, bool] | None = None, about: int | None = None, bare: bool = False) -> str:
    """``+1.08 [+0.91, +1.24], higher with transfer (exact sign-flip test, p = 0.031)`` or ``...: undecided at 5
    pairs (...)``: the word comes from :func:`direction`, the exact test's p-value (Holm-adjusted where a
    family is read together) is named beside it. A design too small for the exact test to reach the level at
    all says so (3 pairs: p >= 0.25). Where no exact test was made, the interval decides as before: "no
    evidence of a difference at this budget" for one holding 0, "no interval, so no verdict" for a non-zero
    difference without one; ``about``: the seeds at which a range-bounded interval that holds 0 would decide
    (:func:`betting_seeds`); ``bare``: the value alone, its intervals said apart (:func:`magnitudes`)."""
    t, exact, size = p_adjusted if isinstance(p_adjusted, Adjusted) else (p_adjusted, None, 1)
    sign = direction(value, ci, p_adjusted)
    text = signed(value) if bare else estimate(value, ci)
    if exact is not None:
        k = max(family or 1, size)
        after = " after Holm" if k > 1 else ""
        test = "exact test" if design is None else test_words(*design)
        said = f"{test}, p = {p_text(exact)}{after}"
        if sign:
            return f"{text}, {higher if sign > 0 else lower} ({said})"
        if design is None:
            return f"{text}: undecided ({said})"
        n, paired = design
        seeds_ = f"{n} {'pairs' if paired else 'seeds a side'}"
        floor = smallest_exact_p(n, paired)
        if floor >= LEVEL / k:
            return (f"{text}: undecided at {seeds_}, which cannot decide (the {test} gives no p below "
                    f"{p_text(floor)}; p = {p_text(exact)}{after})")
        return f"{text}: undecided at {seeds_} ({said})"
    if sign > 0:
        return f"{text}, {higher}"
    if sign < 0:
        return f"{text}, {lower}"
    if excludes_zero(ci) and t is not None:
        of = "" if family is None else f" of {family}"
        return f"{text}: {NO_EVIDENCE} after Holm's adjustment (adjusted p = {p_text(t)}{of})"
    if signed(value) != signed(0) and not has_interval(ci):
        return f"{text}: {NO_INTERVAL}"
    if about is not None and design is not None and signed(value) != signed(0):
        n, paired = design
        return (f"{text}: no verdict at {n} {'pairs' if paired else 'seeds a side'}; about {about} would decide it "
                "if further seeds scored like these (estimate)")
    return f"{text}: {NO_EVIDENCE}"


SCORES = {"mean_return_gain": "mean_return", "jumpstart": "initial_performance",
          "asymptotic_performance": "final_performance"}
"""The per-seed score each mean difference compares."""


def verdict_of(report: Mapping, name: str, p_adjusted: Adjusted | None = None, family: int | None = None,
               **words) -> str:
    """:func:`verdict` of metric ``name`` of a report, read alone (its exact test's own p-value) or in a family
    (``p_adjusted``), saying why there is no interval where the report withheld one, and, for a range-bounded
    interval that holds 0, about how many seeds would decide."""
    m, st = report["metrics"], report["settings"]
    if m.get(f"{name}_verdict") == "equivalent":
        labelled = magnitudes(report, name)
        return (f"{estimate(m[name])}, equivalent ({m[f'{name}_verdict_test']}, p = "
                f"{p_text(m[f'{name}_verdict_p'])}; the exact test could not tell it from no effect)"
                + ("" if labelled is None else f"; {labelled}"))
    ci, design = m.get(f"{name}_ci"), design_of(report)
    p = p_adjusted if p_adjusted is not None else Adjusted(None, exact_p(m, name))
    labelled = magnitudes(report, name)
    if p.exact is not None:
        said = verdict(m[name], ci, p, family, design=design, bare=labelled is not None, **words)
        plan = f"{name}_pairs_for_80_power"
        if plan in m and m.get(f"{name}_verdict") == "undecided" and ": undecided" in said:
            need = "more than 1,000" if m[plan] is None else f"about {m[plan]}"
            said += (f"; {need} pairs would give this difference 80% power (planned from its mean and the 80% "
                     "upper bound of its spread, for a test at 0.05 alone)")
        return said if labelled is None else f"{said}; {labelled}"
    auto = st.get("interval_method") == "auto" and design[0] >= 3
    if auto and not has_interval(ci) and st.get("value_range") is None and m.get(name) is not None:
        return f"{estimate(m[name])}: {NO_RANGE}"
    about = None
    if auto and has_interval(ci) and not excludes_zero(ci) and name in SCORES:
        rows = report["per_seed"]
        b, t = ([r[SCORES[name]] for r in rows[side]] for side in ("baseline", "transfer"))
        about = betting_seeds(b, t, st["value_range"], design[1], max(family or 1, p.size))
    return verdict(m[name], ci, p, family, design=design, about=about, **words)


NO_RANGE = "no interval without the curves' range (--value-range), so no verdict"
RANGE_ONLY = ASSUMES["range"]
"""The label a report gives a betting interval (``<key>_assumes``): the worst case over the range, not a gate."""


def magnitudes(report: Mapping, name: str) -> str | None:
    """The intervals beside a difference's verdict, each named with what it assumes, from the report's labels
    (``<key>_assumes``): ``95% intervals: mean [+0.10, +0.70] by paired t, assuming normal differences; median
    +0.38 [+0.05, +0.80] by order statistics (at 98.4%), assuming independent pairs, any shape; [−0.20, +0.90]
    as the worst case over the declared range [−0.3, 1]``. ``None`` for a report without labels."""
    m, st = report["metrics"], report["settings"]
    if f"{name}_ci_assumes" not in m and f"{name}_t_interval_assumes" not in m:
        return None
    parts, t_ci, median_ci = [], m.get(f"{name}_t_interval"), m.get(f"{name}_median_interval")
    if t_ci:
        t = "paired t" if st.get("paired") else "t with Welch's standard error"
        parts.append(f"mean {interval_text(t_ci)} by {t}, assuming {m[f'{name}_t_interval_assumes']}")
    if median_ci:
        parts.append(f"median {estimate(m[f'{name}_median'], median_ci)} by order statistics (at "
                     f"{100 * m[f'{name}_median_interval_level']:.1f}%), assuming "
                     f"{m[f'{name}_median_interval_assumes']}")
    if m.get(f"{name}_ci"):
        if m.get(f"{name}_ci_assumes") == RANGE_ONLY:
            rng = st.get("value_range")
            where = "" if rng is None else f" [{rng[0]:g}, {rng[1]:g}]"
            parts.append(f"{interval_text(m[f'{name}_ci'])} as the worst case over the declared range{where}")
        elif not t_ci:
            parts.append(f"{interval_text(m[f'{name}_ci'])}, assuming {m[f'{name}_ci_assumes']}")
    if not parts:
        return None
    return f"{100 * float(st.get('confidence', 0.95)):g}% intervals: " + "; ".join(parts)


def interval_text(ci: Sequence, digits: int = 2) -> str:
    return f"[{signed(ci[0], digits)}, {signed(ci[1], digits)}]"


def betting_seeds(b: Sequence[float], t: Sequence[float], value_range: Sequence[float], paired: bool,
                  family: int = 1, level: float = LEVEL, most: int = 1000) -> int | None:
    """About how many seeds a side (pairs, when paired) would let the betting test and the exact test decide,
    if further seeds scored like these (the sample repeated in turn), an estimate; ``None`` when no number up to
    ``most`` would (the two sides score alike)."""
    b, t = np.asarray(b, float), np.asarray(t, float)

    def decides(k: int) -> bool:
        tb, tt = np.resize(b, k), np.resize(t, k)
        return stats.betting_interval(tb, tt, value_range, paired, 1 - level)[2] < level / family

    exact = 2
    while (2 / 2 ** exact if paired else 2 / math.comb(2 * exact, exact)) >= level / family:
        exact += 1
    low, high = len(b), len(b)
    while not decides(high):
        low, high = high, 2 * high
        if high > most:
            return None
    while high - low > 1:
        mid = (low + high) // 2
        low, high = (low, mid) if decides(mid) else (mid, high)
    return max(high, exact)


def p_text(p: float) -> str:
    return "<0.001" if p < 0.001 else f"{p:.3g}"


def frames(x: float) -> str:
    """``4k`` for whole thousands, ``17.5k`` otherwise (frame counts of evaluations)."""
    k = x / 1000
    return f"{k:.0f}k" if abs(k - round(k)) < 0.05 else f"{k:.1f}k"


def design_of(report: Mapping) -> tuple[int, bool]:
    """``(seeds a side, paired)`` of a report: the fewer seeds of its two sides."""
    m = report["metrics"]
    return min(m["n_seeds_baseline"], m["n_seeds_transfer"]), bool(report["settings"].get("paired"))


def sequential_verdict(report: Mapping) -> str:
    """The mean return gain of an experiment run with ``--seeds auto`` (``settings.sequential``,
    :mod:`drltg.analysis.sequential`): decided at the look that stopped it, at that look's share of the level,
    or undecided at the cap; it says which look and why it stopped."""
    m, seq = report["metrics"], report["settings"]["sequential"]
    last, k, total = seq["taken"][-1], len(seq["taken"]), len(seq["looks"])
    labelled = magnitudes(report, "mean_return_gain")
    after = "" if labelled is None else f"; {labelled}"
    text = estimate(m["mean_return_gain"], None if labelled else m.get("mean_return_gain_ci"))
    look = (f"exact sign-flip test at look {k} of {total}, {last['pairs']} pairs: p = {p_text(last['p'])} against "
            f"its share {p_text(last['alpha'])} of {LEVEL:g}")
    if seq["stopped"] == "decided" and signed(m["mean_return_gain"]) != signed(0):
        word = "higher with transfer" if m["mean_return_gain"] > 0 else "lower with transfer"
        return f"{text}, {word} ({look}; seeds added until decided){after}"
    return f"{text}: undecided at the cap of {last['pairs']} pairs ({look}; seeds added until the cap){after}"


def headline(report: Mapping, metric: str = "mean_return_gain") -> str:
    """One sentence that concludes a report: its headline metric, named in advance and read alone (the
    report's other metrics form the family that its p (Holm) column adjusts)."""
    m, st = report["metrics"], report["settings"]
    n_b, n_t = m["n_seeds_baseline"], m["n_seeds_transfer"]
    design = f"{n_t} paired seeds" if st.get("paired") else f"{n_t} + {n_b} seeds"
    label = LABELS.get(metric, metric.replace("_", " "))
    if st.get("tag") and metric in SCORES:  # a report of another column than the return: name it
        label = label.replace("return", st["tag"].replace("_", " "))
    where = f"{st['transfer_label']} vs {st['baseline_label']}, {design}, {frames(st['budget'])} frames"
    if m.get(metric) is None:
        return f"Headline ({where}): {label} is not available."
    sequential = st.get("sequential") is not None and metric == "mean_return_gain"
    said = sequential_verdict(report) if sequential else verdict_of(report, metric)
    if st.get("learned_nothing"):
        said += ("; but no run of either side reached the threshold, so neither learned the task and this measures "
                 "nothing")
    return f"Headline ({where}): {label} {said}."
