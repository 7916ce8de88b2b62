"""Write the Pendulum study's numbers into results/README.md from its committed report:

    python results/pendulum_summary.py           # rewrites the block between the pendulum-heavier markers
    python results/pendulum_summary.py --check   # exit 1 if the README's block is not what the report gives

Every number and every sentence stating a result in the block is computed here from
results/pendulum-heavier/report/transfer_metrics.json.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

from drltg.analysis.tables import estimate, render
from drltg.training.rundir import atomic_write

HERE = Path(__file__).resolve().parent
REPORT = HERE / "pendulum-heavier" / "report" / "transfer_metrics.json"
README = HERE / "README.md"
BEGIN, END = "<!-- pendulum-heavier:begin -->", "<!-- pendulum-heavier:end -->"


def _cell(m: dict, key: str, fmt: str = "+.0f") -> str:
    return estimate(m.get(key), m.get(f"{key}_ci"), fmt)


def _time_to(m: dict, side: str) -> str:
    value, share = m.get(f"time_to_threshold_{side}"), m.get(f"threshold_reached_{side}", 0)
    return estimate(value, fmt=lambda x: f"{x / 1000:.1f}k", missing="—") + f" ({share:.0%})"


def _verdict(m: dict, key: str, what: str, family: int) -> str:
    """One sentence: the sign of the effect where its interval excludes 0, with the raw p-value and Holm's
    over the report's family of intervals; "no difference shown" otherwise."""
    value, ci = m.get(key), m.get(f"{key}_ci")
    if value is None or ci is None:
        return f"The report gives no interval for the {what}."
    lo, hi = ci
    estimate_ = f"{value:+.0f} [{lo:+.0f}, {hi:+.0f}]"
    if lo <= 0 <= hi:
        return f"No difference in the {what} is shown: {estimate_} includes 0."
    p, adjusted = m.get(f"{key}_p_value"), m.get(f"{key}_p_adjusted")
    sentence = f"Model reuse {'raised' if lo > 0 else 'lowered'} the {what}: {estimate_}"
    if p is None or adjusted is None:
        return sentence + "."
    sentence += f" (p = {p:.2g}; {adjusted:.2g} with Holm's adjustment over the report's {family} intervals)"
    return sentence + ("." if adjusted < 0.05 else ", which read together with the others does not hold at 0.05.")


def block(report: dict) -> str:
    """The README block: the table row and the sentences, from the report alone."""
    m, s = report["metrics"], report["settings"]
    family = s.get("family", {}).get("size", 0)
    rows = [("mean return gain", "jumpstart", "last 10% of the budget", "final return, B / T",
             f"frames to {s['threshold']:g}, B / T (seeds reaching it)", "P(T > B)"),
            (_cell(m, "mean_return_gain"), _cell(m, "jumpstart"), _cell(m, "asymptotic_performance"),
             f"{m['final_performance_baseline']:.0f} / {m['final_performance_transfer']:.0f}",
             f"{_time_to(m, 'baseline')} / {_time_to(m, 'transfer')}",
             estimate(m.get("probability_of_improvement"), m.get("probability_of_improvement_ci"), ".2f"))]
    lines = [
        render(rows, "markdown").rstrip("\n"),
        "",
        f"{m['n_seeds_baseline']} baseline and {m['n_seeds_transfer']} transfer runs, "
        f"{'paired by seed' if s['paired'] else 'unpaired'}, over frames {s['start']}–{s['budget']}. "
        + " ".join([
            _verdict(m, "jumpstart", "return of the first evaluation (jumpstart)", family),
            _verdict(m, "mean_return_gain", "mean return over the budget (mean return gain)", family),
            _verdict(m, "asymptotic_performance", "return over the last 10% of the budget", family),
        ]),
    ]
    return "\n".join(lines) + "\n"


def main(argv: list[str]) -> int:
    text = README.read_text()
    head, rest = text.split(BEGIN + "\n", 1)
    _, tail = rest.split(END, 1)
    new = head + BEGIN + "\n" + block(json.loads(REPORT.read_text())) + END + tail
    if "--check" in argv:
        return 0 if new == text else 1
    atomic_write(README, new)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
