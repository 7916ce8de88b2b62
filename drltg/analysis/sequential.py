r"""Seeds until decided: the group-sequential plan of ``drltg experiment --seeds auto``.

Paired seeds are added in rounds and the headline metric is tested after each round (a *look*) by the
exact sign-flip test; the experiment stops at the first look that decides, or at the cap. Testing again
after adding seeds would inflate the false-claim rate if every look used the full level, so look
:math:`k` of :math:`K` tests at :math:`\alpha_k = \alpha / K` (Bonferroni spending): whatever the dependence
between looks, :math:`P(\text{any look rejects} \mid \text{no effect}) \le \sum_k \alpha_k = \alpha`. The
looks are planned before the first seed (``looks(max_pairs)``): the first at 8 pairs, where the sign-flip
test's smallest p (2/2^8 = 0.0078) is below a share of 0.05 split four ways, then every 4 pairs, the last at
the cap. ``drltg.analysis.operating`` measures the rule's false claims and power beside the fixed-n tests.
"""
from __future__ import annotations

from dataclasses import dataclass

FIRST = 8
"""Pairs at the first look."""
STEP = 4
"""Pairs added between looks."""


@dataclass(frozen=True)
class Look:
    pairs: int
    alpha: float


def looks(max_pairs: int, alpha: float = 0.05) -> list[Look]:
    """The looks of a plan capped at ``max_pairs``: at 8, 12, 16, ... pairs and at the cap, each at ``alpha``
    over their number; a cap below 8 is one look at the cap with the whole ``alpha``."""
    if max_pairs < 1:
        raise ValueError("a sequential plan needs at least one pair")
    counts = [n for n in range(FIRST, max_pairs, STEP)] + [max_pairs]
    return [Look(n, alpha / len(counts)) for n in counts]


def record(plan: list[Look], p_values: list[float], test: str = "sign-flip") -> dict:
    """What the report keeps of the rule: the plan, each look taken with its p-value, and why it stopped
    (``decided`` at a look whose p is below its share, or ``cap`` after the last)."""
    taken = [{"pairs": look.pairs, "alpha": look.alpha, "p": p} for look, p in zip(plan, p_values)]
    last = taken[-1]
    decided = last["p"] < last["alpha"]
    if not decided and len(taken) < len(plan):
        raise ValueError("a plan stops early only at a look that decides")
    return {"rule": f"exact {test} test at {len(plan)} planned looks, alpha split equally (Bonferroni)",
            "looks": [{"pairs": look.pairs, "alpha": look.alpha} for look in plan],
            "taken": taken, "stopped": "decided" if decided else "cap", "pairs": last["pairs"]}
