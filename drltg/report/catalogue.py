"""The metrics a report computes, one entry each, and the order of its table."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from drltg.report.settings import SIDES


def _asymptote_note(st: dict, side: str | None) -> str:
    moving = [f"{s} {v}" for s, v in st.get("convergence", {}).items() if v != "converged"]
    return f"final performance, not an asymptote: {', '.join(moving)}" if moving else ""


def _trend_note(st: dict, side: str | None) -> str:
    return st.get("convergence", {}).get(side, "")


TOTAL_TIME = "total time: source frames counted"
COMPARISONS = ("difference", "ratio", "poi")


@dataclass(frozen=True)
class Metric:
    """One metric of the report: how it is computed from a per-seed score column (``score``).

    Comparisons of the sides (B = baseline, T = transfer, L = mean of each side's seeds), each with its
    ``--confidence`` interval in ``<name>_ci``, its p-values, and, where ``iqm``, the interquartile mean of
    each side as L in ``<name>_iqm``: ``difference`` L(T) - L(B); ``ratio`` (L(A_T) - L(A_B)) /
    |L(A_B)|; ``poi`` P(T > B). Summaries of each side in ``sides`` (``name`` holds ``{side}``): ``mean``
    over seeds; ``time`` the upper median of the runs' crossing frames; ``reached`` the share of runs that
    cross; ``count`` the seeds; ``trend`` the change of the mean curve over the last ``--trend-window``, with
    its interval. ``note``: the table's remark, a text or a function of the report's settings and the side."""

    name: str
    kind: str
    score: str | None = None
    iqm: bool = False
    sides: tuple[str, ...] = SIDES
    note: str | Callable[[dict, str | None], str] = ""

    def key(self, side: str | None = None) -> str:
        return self.name.format(side=side)

    def rows(self) -> list[tuple[str, str | None, bool]]:
        """``(name, side, is_iqm)`` of each row this metric gives in the table."""
        if self.kind in COMPARISONS:
            return [(self.name, None, False)] + ([(f"{self.name}_iqm", None, True)] if self.iqm else [])
        return [(self.key(side), side, False) for side in self.sides]


METRICS = (
    Metric("mean_return_gain", "difference", "mean_return", iqm=True),
    Metric("jumpstart", "difference", "initial_performance", iqm=True),
    Metric("asymptotic_performance", "difference", "final_performance", iqm=True, note=_asymptote_note),
    Metric("transfer_ratio", "ratio", "total_reward", iqm=True, note="changes when a constant is added to rewards"),
    Metric("probability_of_improvement", "poi", "total_reward"),
    Metric("probability_of_improvement_initial", "poi", "initial_performance"),
    Metric("probability_of_improvement_final", "poi", "final_performance"),
    Metric("mean_return_gain_with_source", "difference", "mean_return_total_time", note=TOTAL_TIME),
    Metric("total_reward_{side}", "mean", "total_reward"),
    Metric("initial_performance_{side}", "mean", "initial_performance"),
    Metric("final_performance_{side}", "mean", "final_performance"),
    Metric("time_to_threshold_{side}", "time", "time_to_threshold"),
    Metric("threshold_reached_{side}", "reached", "time_to_threshold"),
    Metric("time_to_threshold_{side}_with_source", "time", "time_to_threshold_with_source", sides=("transfer",),
           note=TOTAL_TIME),
    Metric("n_seeds_{side}", "count"),
    Metric("final_trend_{side}", "trend", note=_trend_note),
)
TABLE_ROWS = (
    "mean_return_gain", "jumpstart", "asymptotic_performance", "transfer_ratio",
    "total_reward_baseline", "total_reward_transfer",
    "time_to_threshold_baseline", "time_to_threshold_transfer",
    "threshold_reached_baseline", "threshold_reached_transfer",
    "initial_performance_baseline", "initial_performance_transfer",
    "final_performance_baseline", "final_performance_transfer",
    "final_trend_baseline", "final_trend_transfer",
    "probability_of_improvement", "probability_of_improvement_initial", "probability_of_improvement_final",
    "mean_return_gain_iqm", "jumpstart_iqm", "asymptotic_performance_iqm", "transfer_ratio_iqm",
    "mean_return_gain_with_source", "time_to_threshold_transfer_with_source",
    "n_seeds_baseline", "n_seeds_transfer",
)


def table_rows() -> dict[str, tuple[Metric, str | None, bool]]:
    """Every metric name -> (its entry, its side, whether it is the IQM version), in the order of the table
    and the CSV: ``TABLE_ROWS`` first, then any metric it does not place, in ``METRICS`` order."""
    rows = {name: (metric, side, iqm) for metric in METRICS for name, side, iqm in metric.rows()}
    return {name: rows[name] for name in dict.fromkeys([*TABLE_ROWS, *rows]) if name in rows}


def of_kind(*kinds: str) -> list[Metric]:
    return [metric for metric in METRICS if metric.kind in kinds]
