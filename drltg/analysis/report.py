r"""``drltg report``: did the transfer method help? Metrics, a plot and tables from learning curves.

    drltg report --baseline RUNS... --transfer RUNS... [--threshold 150 | --threshold 80%] [--out DIR]
    drltg report --matrix DIR [--metric mean_return_gain] [--out DIR]

The report is one pipeline (:func:`transfer_report`, :func:`compute`):

1. read: both sides with :func:`drltg.analysis.curves.read_curves` (run directories, directories of seed runs,
   globs, SB3 / TensorBoard / CSVLogger logs);
2. check (:func:`check_runs`): no run twice, one task, one configuration a side, paired or not;
3. align (:func:`align`): every curve is compared on the target task over a common interval
   ``[start, budget]``: ``start`` is the latest first evaluation of any run (frame 0 for drltg runs),
   ``budget`` the shortest run's last evaluation unless ``--budget`` sets it; nothing is invented past a
   run's last evaluation;
4. score (:func:`score_runs`): the per-seed scores, one row per run (``result["scores"]``, a DataFrame
   with ``side`` and ``pair`` columns);
5. metrics (:func:`metric_values`): each entry of ``METRICS`` turns score columns into a metric and its
   interval, so a new metric is one entry there; ``TABLE_ROWS`` places it in the table;
6. write (:func:`render`): JSON, CSV (through :mod:`drltg.analysis.tables`) and the plot.

The per-seed scores are aggregated (B = baseline, T = transfer, A = area, span = budget - start, L = the
mean of each side's seeds, which for pairs equals the mean of ``d_i = T_i - B_i``; ``*_iqm``: L = the
interquartile mean of each side; formulas in :mod:`drltg.analysis.metrics`):

``mean_return_gain``          L(A_T / span) - L(A_B / span): return gained per frame on average over the
                              budget; unchanged when a constant is added to every reward (the headline)
``jumpstart``                 L(mean of the first K evaluations of T) - L(same of B)
``asymptotic_performance``    L(mean of T's evaluations in [budget - FRAC span, budget]) - same of B; a
                              final performance, not an asymptote, unless the equivalence test (TOST)
                              shows each side's mean curve changes by less than ``--convergence-margin``
                              x its range over the last ``--trend-window``
``transfer_ratio``            (L(A_T) - L(A_B)) / |L(A_B)|; changes when a constant is added to rewards;
                              null when |L(A_B)| <= 0.01 x span x max |y|
``time_to_threshold_<side>``  per run: the first evaluation from which it stays >= threshold until the
                              budget, over at least 2 later evaluations (``--sustain K``: for K >= 2
                              evaluations; ``--crossing first``: the first evaluation >= threshold);
                              per side: the upper median over seeds, a frame a run had, by which a strict
                              majority of seeds has crossed; null = no majority
``final_trend_<side>``        change of the mean curve over the last ``--trend-window`` (least squares)
``probability_of_improvement`` P(T > B): paired, the fraction of pairs with T_i > B_i; unpaired, over all
                              (B seed, T seed) combinations; ties 1/2; on the areas (``_initial``,
                              ``_final``: on the initial / final performances)
``*_with_source``             total time (Taylor & Stone 2009, sec. 3.1): a transfer run has first spent
                              S source frames (``transfer.source``'s config or ``--source-frames``), so
                              both sides are compared at equal total frames: mean return over
                              [start + S, budget] of B against T's first span - S target frames; the
                              transfer's time to threshold + S
``<name>_ci``                 ``--confidence`` interval: paired t or Welch/Hsu t for mean differences,
                              Fieller for the ratio, Clopper-Pearson (pairs) or Newcombe (unpaired) for
                              P(T > B); inside the quantity's range (a rate's difference within [-1, 1]);
                              absent (with the reason in ``settings.warnings``) below 3 seeds a side,
                              without spread, or for a ratio whose denominator's interval contains 0
``<name>_p_value``            two-sided p-value of no effect, from the test behind the interval (t test;
                              sign test or exact permutation test for P(T > B)); the exact permutation
                              test's where the per-seed scores are skewed or bimodal (``settings.p_values``)
``<name>_p_adjusted``         Holm's adjustment over the report's family: every metric with a p-value
                              (``settings.family`` names them)
``<name>_p_exact``            (mean differences) the exact permutation test of no effect, valid at any
                              number of seeds and any shape of scores

Pairing: drltg runs are paired when every baseline seed (``config.yaml``) has exactly one transfer run
with the same seed; ``--paired`` pairs foreign logs in the order given. ``settings.pairing`` says which
and why. A side must hold one configuration (``--allow-mixed`` to override) and no run twice.

Outputs (written through temporary files and ``os.replace``, and only once every input is read and
checked): ``transfer_metrics.json`` (``metrics``, ``settings`` with every choice and warning,
``per_seed``), ``transfer_metrics.csv`` (``metric,value,ci_low,ci_high,p_value,p_adjusted``),
``transfer_plot.png`` and ``.svg``; ``--matrix`` writes ``transfer_matrix.{png,svg,csv,json}``. All options:
:class:`ReportSettings`.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import re
import sys
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
import pandas as pd

from drltg import safe_yaml
from drltg.analysis import metrics as M
from drltg.analysis import tables
from drltg.analysis.curves import FORMATS, Curve, read_curves
from drltg.analysis.run_state import partition
from drltg.analysis.tables import number
from drltg.errors import UsageError
from drltg.store import rundir

SIDES = ("baseline", "transfer")
MAX_LENGTH_RATIO = 2.0  # longest / shortest run beyond which a default budget would hide too much
PLOT_POINTS = 100  # the display line is smoothed to about this many evaluation windows
MIN_SEEDS = 3  # fewer seeds on a side leave an interval without a usable spread estimate
MIN_TREND_POINTS = 4  # a line through fewer points leaves under 2 degrees of freedom for its error
CONFIG_KEYS_PER_RUN = ("seed", "frames", "device", "threads", "log", "checkpoint", "transfer.source")


def _option(default, flag=None, group="metrics", **argparse_kwargs):
    """A report setting; ``flag`` (and the argparse keywords) make it a ``drltg report`` option."""
    return field(default=default, metadata=dict(flag=flag, group=group, kwargs=argparse_kwargs))


@dataclass
class ReportSettings:
    """Every choice of ``drltg report``: the keyword settings of :func:`compute` and
    :func:`transfer_report`, and (through each field's ``flag``) the command-line options."""

    format: str = _option("auto", "--format", "runs", choices=FORMATS,
                          help="log format (default: auto-detect)")
    tag: str | None = _option(None, "--tag", "runs", help="column / scalar tag to read (defaults: return_mean "
                              "in eval.csv, eval/mean_reward in progress.csv, r in monitor.csv, "
                              "eval/return_mean or eval/mean_reward in TensorBoard / CSVLogger logs)")
    baseline_label: str | None = _option(None, "--baseline-label", "runs",
                                         help="name of the baseline in the plot and table")
    transfer_label: str | None = _option(None, "--transfer-label", "runs",
                                         help="name of the transfer runs in the plot and table")
    allow_mixed: bool = _option(False, "--allow-mixed", "runs", action="store_true",
                                help="accept runs of different configs or methods under one side")
    allow_mismatch: bool = _option(False, "--allow-mismatch", "runs", action="store_true",
                                   help="compare baseline and transfer runs whose settings differ in what a curve "
                                   "means (task options, learner, network, evaluation, frames); the differences "
                                   "are listed in the report")
    include_unfinished: bool = _option(False, "--include-unfinished", "runs", action="store_true",
                                       help="count diverged and incomplete drltg runs and eval.csv files without "
                                       "config.yaml (listed and left out by default)")
    threshold: object = _option(None, "--threshold", help="return to reach for time-to-threshold: a "
                                "number (150) or a percentage of the best baseline mean performance (80%%)")
    crossing: str = _option("sustained", "--crossing", choices=("sustained", "first"),
                            help="sustained (default): the first evaluation from which the run stays at or "
                            "above the threshold (see --sustain); first: the first evaluation at or above it")
    sustain: int | None = _option(None, "--sustain", type=int, metavar="K",
                                  help="a sustained crossing holds for K >= 2 consecutive evaluations, the "
                                  "crossing included (default: for the rest of the budget, over at least "
                                  f"{M.SUSTAIN_AFTER} evaluations after the crossing)")
    budget: object = _option(None, "--budget", help="compare over the first FRAMES frames (default: the "
                             "shortest run's last evaluation); accepts 200000, 200k, 1.5M")
    jumpstart_window: int = _option(1, "--jumpstart-window", type=int, metavar="K",
                                    help="jumpstart = mean of the first K evaluations (default: 1)")
    asymptote_window: float = _option(0.1, "--asymptote-window", type=float, metavar="FRAC",
                                      help="asymptotic performance = mean over the last FRAC of the budget "
                                      "(default: 0.1)")
    trend_window: float = _option(0.25, "--trend-window", type=float, metavar="FRAC",
                                  help="the convergence test fits a line to the mean curve over the last "
                                  "FRAC of the budget (default: 0.25)")
    convergence_margin: float = _option(0.1, "--convergence-margin", type=float, metavar="FRAC",
                                        help="a side's mean curve is 'converged' only where the equivalence "
                                        "test (TOST) shows its change over the trend window within +-FRAC x the "
                                        "curve's range over the budget (default: 0.1)")
    smooth: int | None = _option(None, "--smooth", type=int, metavar="W",
                                 help="moving average over W evaluations before time-to-threshold (and a "
                                 "fractional threshold's best baseline); default: raw curve")
    plot_smooth: int | None = _option(None, "--plot-smooth", type=int, metavar="W",
                                      help="moving average for the plotted lines only (default: --smooth, "
                                      f"else about {PLOT_POINTS} windows per curve; 1 = raw)")
    paired: bool | None = _option(None, "--paired", action="store_const", const=True,
                                  help="pair baseline and transfer run i (by seed when the runs record one, "
                                  "else in the order given); default: paired when drltg runs share seeds")
    source_frames: object = _option(None, "--source-frames", metavar="N",
                                    help="frames of source training per transfer run, for the total-time "
                                    "metrics (default: read from drltg runs' transfer.source)")
    interval: str = _option("t", "--interval", choices=tuple(M.INTERVALS),
                            help="interval of the mean differences (default: t, the one whose coverage "
                            "holds in simulation; the bootstrap ones use --bootstrap and --seed)")
    confidence: float = _option(0.95, "--confidence", type=float, help="confidence level (default: 0.95)")
    bootstrap: int = _option(10_000, "--bootstrap", type=int, metavar="N",
                             help="resamples of a bootstrap --interval (default: 10000)")
    seed: int = _option(0, "--seed", type=int, help="seed of a bootstrap --interval (default: 0)")
    ratio_eps: float = _option(0.01)
    value_range: tuple | None = _option(None)  # (low, high) of the curves' values; default: [0, 1] for a rate

    def __post_init__(self):
        """Check every setting before any run is read (one sentence each)."""
        def need(ok, text):
            if not ok:
                raise UsageError(text)

        parse_threshold(self.threshold)
        parse_frames(self.budget)
        need(int(self.jumpstart_window) >= 1, f"--jumpstart-window must be at least 1, got {self.jumpstart_window}.")
        for name in ("asymptote_window", "trend_window"):
            value = float(getattr(self, name))
            need(0.0 < value <= 1.0, f"--{name.replace('_', '-')} must lie in (0, 1], got {value}.")
        need(self.smooth is None or int(self.smooth) >= 1,
             f"--smooth must be at least 1 evaluation, got {self.smooth}.")
        need(self.plot_smooth is None or int(self.plot_smooth) >= 1,
             f"--plot-smooth must be at least 1 evaluation, got {self.plot_smooth}.")
        need(self.sustain is None or int(self.sustain) >= 2,
             f"--sustain must be at least 2 evaluations (the crossing and one after it), got {self.sustain}.")
        need(float(self.convergence_margin) > 0,
             f"--convergence-margin must be positive, got {self.convergence_margin}.")
        need(self.value_range is None or (len(self.value_range) == 2
                                          and float(self.value_range[0]) < float(self.value_range[1])),
             f"value_range must be (low, high) with low < high, got {self.value_range}.")
        need(self.crossing in ("sustained", "first"), f"--crossing must be sustained or first, got '{self.crossing}'.")
        need(not (self.sustain is not None and self.crossing == "first"),
             "--sustain applies to a sustained crossing; drop it or --crossing first.")
        need(0.0 < float(self.confidence) < 1.0, f"--confidence must lie in (0, 1), got {self.confidence}.")
        need(int(self.bootstrap) >= 100, f"--bootstrap needs at least 100 resamples, got {self.bootstrap}.")
        need(0 <= int(self.seed) < 2**32, f"--seed must be an integer in [0, 2**32 - 1], got {self.seed}.")
        need(self.interval in M.INTERVALS,
             f"unknown --interval '{self.interval}'; choose one of {', '.join(M.INTERVALS)}.")
        need(self.format in FORMATS, f"unknown log format '{self.format}'; choose one of {', '.join(FORMATS)}.")
        if self.source_frames is not None:
            frames = parse_frames(self.source_frames, "--source-frames")
            need(frames >= 0, f"--source-frames must be at least 0, got {self.source_frames}.")
            self.source_frames = frames

    @classmethod
    def from_args(cls, args) -> "ReportSettings":
        return cls(**{f.name: getattr(args, f.name) for f in fields(cls) if f.metadata.get("flag")})


SETTINGS_DEFAULTS = {f.name: f.default for f in fields(ReportSettings)}


LARGEST = 1e15
"""The largest magnitude of a threshold, a frame count or a seed's span the report accepts: beyond it a
number is a typo (and floats lose whole units, plots their ticks)."""


def _bounded(value: float, text, option: str, what: str) -> float:
    if not math.isfinite(value) or abs(value) > LARGEST:
        raise UsageError(f"{option} '{text}' must be a finite {what} of magnitude at most {LARGEST:.0e}.")
    return value


def parse_threshold(threshold) -> tuple[float | None, float | None]:
    """``150`` -> (150, None); ``"80%"`` -> (None, 0.8); a non-finite or huge value is refused."""
    if threshold is None:
        return None, None
    if isinstance(threshold, str):
        text = threshold.strip()
        percent = text.endswith("%")
        try:
            value = float(text[:-1] if percent else text)
        except ValueError:
            raise UsageError(
                f"--threshold '{threshold}' is neither a number (e.g. 150) nor a percentage of the best "
                "baseline performance (e.g. 80%)."
            ) from None
        if percent:
            return None, _bounded(value, threshold, "--threshold", "percentage") / 100.0
        return _bounded(value, threshold, "--threshold", "number"), None
    return _bounded(float(threshold), threshold, "--threshold", "number"), None


def parse_frames(text, option: str = "--budget") -> float | None:
    """``"1e6"``, ``"500k"``, ``"1.5M"`` -> frames."""
    if text is None:
        return text
    if isinstance(text, (int, float)):
        return _bounded(text, text, option, "number of frames")
    m = re.fullmatch(r"\s*([0-9.eE+-]+)\s*([kKmM]?)\s*", str(text))
    try:
        value = float(m.group(1)) * {"": 1, "k": 1e3, "m": 1e6}[m.group(2).lower()]
    except (AttributeError, ValueError):
        raise UsageError(f"{option} '{text}' is not a number of frames (e.g. 200000, 200k, 1.5M).") from None
    return _bounded(value, text, option, "number of frames")


def settings_of(settings: dict) -> ReportSettings:
    """Keyword settings checked and completed; a name that is no setting is a programming error."""
    unknown = set(settings) - set(SETTINGS_DEFAULTS)
    if unknown:
        raise TypeError(f"unknown report settings: {', '.join(sorted(unknown))}")
    return ReportSettings(**settings)


# ------------------------------------------------------------------------------------------ metrics
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


def _of_kind(*kinds: str) -> list[Metric]:
    return [metric for metric in METRICS if metric.kind in kinds]


# ----------------------------------------------------------------------------------------- pipeline
def transfer_report(
    baseline: str | Path | Sequence[str | Path] | Sequence[Curve],
    transfer: str | Path | Sequence[str | Path] | Sequence[Curve],
    out_dir: str | Path | None = None,
    **settings,
) -> dict:
    """Read both run sets, compute the metrics, write the four report files; return the JSON object.

    ``baseline`` and ``transfer`` are paths (runs, directories of runs, globs) or lists of
    :class:`~drltg.analysis.curves.Curve`. ``out_dir`` defaults to a fresh folder named after the runs in the
    working directory. Keyword settings are those of ``drltg report`` (``threshold=150`` or ``"80%"``,
    ``budget``, ``crossing``, ``paired``, ``source_frames``, ...: the fields of :class:`ReportSettings`).
    The returned dict also holds ``"scores"`` (the per-seed DataFrame) and ``"out_dir"``.
    """
    s = settings_of(settings)
    if out_dir is not None:
        check_out_dir(Path(out_dir))
    result = compute(read_runs(baseline, s), read_runs(transfer, s), **settings)
    files = render(result)
    st = result["settings"]
    out = Path(out_dir) if out_dir is not None else fresh_dir(
        f"report-{st['transfer_label']}-vs-{st['baseline_label']}")
    rundir.write_directory(out, files)
    return {"metrics": result["metrics"], "settings": st, "per_seed": result["per_seed"],
            "scores": result["scores"], "out_dir": str(out)}


def compute(baseline: Sequence[Curve], transfer: Sequence[Curve], **settings) -> dict:
    """Metrics of ``transfer`` against ``baseline`` (lists of curves, one per seed), without writing.

    Returns ``{"metrics", "settings", "per_seed", "scores", "curves"}``: ``scores`` is the per-seed
    DataFrame (one row per run), ``per_seed`` the same as JSON rows per side, ``curves`` the arrays the
    plot draws. Keyword settings: the fields of :class:`ReportSettings`."""
    s = settings_of(settings)
    warnings: list[str] = []
    sides = check_runs(baseline, transfer, s, warnings)
    window = align(sides, s, warnings)
    by_side = score_runs(sides, window, s, warnings)
    scores = stack(by_side, sides.paired)
    trends = {side: trend(runs, window, s) for side, runs in sides.items()}
    metrics = metric_values(scores, trends, sides.paired, window, s, warnings)
    described = describe(s, sides, window, trends, warnings, metrics)
    return {"metrics": metrics, "settings": described, "per_seed": {side: _records(df) for side, df in by_side.items()},
            "scores": scores, "curves": plot_curves(sides, window, scores, described)}


def read_runs(runs, s: ReportSettings) -> list[Curve]:
    """Curves as given, or read from paths with the settings' log format and tag."""
    if isinstance(runs, Curve):
        return [runs]
    if isinstance(runs, (list, tuple)) and runs and all(isinstance(r, Curve) for r in runs):
        return list(runs)
    return read_curves(runs, format=s.format, tag=s.tag)


# ------------------------------------------------------------------------------- 1. check the runs
@dataclass
class Sides:
    """Both run sets once checked; when paired, ``transfer[i]`` is the pair of ``baseline[i]``."""

    baseline: list[Curve]
    transfer: list[Curve]
    task: str | None
    paired: bool
    pairing: str

    def items(self) -> tuple[tuple[str, list[Curve]], ...]:
        return ("baseline", self.baseline), ("transfer", self.transfer)

    @property
    def runs(self) -> list[Curve]:
        return self.baseline + self.transfer


def check_runs(baseline: Sequence[Curve], transfer: Sequence[Curve], s: ReportSettings,
               warnings: list[str]) -> Sides:
    """No run twice, one task, one configuration a side (unless ``--allow-mixed``), and the pairing."""
    baseline, transfer = list(baseline), list(transfer)
    if not baseline or not transfer:
        raise UsageError("both a baseline and a transfer run set are needed.")
    baseline, left_b = partition("baseline", baseline, bool(s.include_unfinished), warnings)
    transfer, left_t = partition("transfer", transfer, bool(s.include_unfinished), warnings)
    for side, runs, left in (("baseline", baseline, left_b), ("transfer", transfer, left_t)):
        if not runs:
            raise UsageError(f"no {side} run can be counted, each is {' or '.join(left)} "
                             f"({', '.join(r for runs in left.values() for r in runs)}); finish them, or pass "
                             "--include-unfinished.")
    _check_duplicates(baseline, transfer)
    _check_copies(baseline, transfer, bool(s.allow_mixed or s.include_unfinished))
    task = _check_tasks(baseline, transfer)
    for side, runs in (("baseline", baseline), ("transfer", transfer)):
        _check_configs(side, runs, bool(s.allow_mixed), warnings)
    _check_sides(baseline, transfer, bool(s.allow_mismatch), warnings)
    paired, pairing, transfer = _pairing(baseline, transfer, s.paired)
    return Sides(baseline, transfer, task, paired, pairing)


def _name(curve: Curve) -> str:
    return f"'{curve.label}' ({curve.source})"


def _check_duplicates(baseline: Sequence[Curve], transfer: Sequence[Curve]) -> None:
    """The same log file named twice would count as two seeds."""
    seen: dict[Path, str] = {}
    for side, curves in (("baseline", baseline), ("transfer", transfer)):
        for c in curves:
            if not Path(c.source).exists():
                continue
            key = Path(c.source).resolve()
            if seen.get(key) == side:
                raise UsageError(f"'{c.source}' is given twice among the {side} runs; a run counts as one "
                                 "seed, so name it once.")
            if key in seen:
                raise UsageError(f"'{c.source}' is both a baseline and a transfer run; compare two "
                                 "different run sets.")
            seen[key] = side


def _check_copies(baseline: Sequence[Curve], transfer: Sequence[Curve], allow_pooled: bool) -> None:
    """Two drltg runs with the same config, seed included, and the same curve are one run copied (or
    trained twice from one seed: the same run again); counted twice they would fake a seed. A side that
    pools drltg runs with logs that carry no config cannot be checked for one configuration: refused
    unless ``allow_pooled`` (``--allow-mixed``, or ``--include-unfinished`` for config-less drltg runs)."""
    for side, curves in (("baseline", baseline), ("transfer", transfer)):
        seen: dict[str, Curve] = {}
        for c in curves:
            if not c.config or c.config.get("seed") is None:
                continue
            key = json.dumps([c.config, c.frames.tolist(), c.values.tolist()], sort_keys=True, default=str)
            if key in seen:
                raise UsageError(f"{_name(c)} and {_name(seen[key])} are the same run (same config, seed "
                                 f"{c.config.get('seed')}, same curve); a run counts as one seed, so give it once.")
            seen[key] = c
        with_config = [c for c in curves if c.config]
        if with_config and len(with_config) < len(curves) and not allow_pooled:
            other = next(c for c in curves if not c.config)
            raise UsageError(f"the {side} runs pool drltg runs ({_name(with_config[0])}) with logs that carry no "
                             f"config ({_name(other)}), so one configuration a side cannot be checked; report "
                             "each kind apart, or pass --allow-mixed.")


def _check_tasks(baseline: Sequence[Curve], transfer: Sequence[Curve]) -> str | None:
    for side, curves in (("baseline", baseline), ("transfer", transfer)):
        known = [c for c in curves if c.task]
        if len({c.task for c in known}) > 1:
            a, b = known[0], next(c for c in known if c.task != known[0].task)
            raise UsageError(
                f"the {side} runs mix tasks: {_name(a)} is on '{a.task}' but {_name(b)} on '{b.task}'."
            )
    b = next((c for c in baseline if c.task), None)
    t = next((c for c in transfer if c.task), None)
    if b and t and b.task != t.task:
        raise UsageError(
            f"baseline and transfer are on different tasks: {_name(b)} is on '{b.task}' but "
            f"{_name(t)} on '{t.task}'; compare runs on the same target task."
        )
    return (b or t).task if (b or t) else None


def _flat(config: dict, prefix: str = "") -> dict:
    out = {}
    for key, value in config.items():
        if isinstance(value, dict):
            out.update(_flat(value, f"{prefix}{key}."))
        else:
            out[f"{prefix}{key}"] = value
    return out


def _check_configs(side: str, curves: Sequence[Curve], allow_mixed: bool, warnings: list[str]) -> None:
    """One side must be one method and one configuration (seeds, lengths, devices and sources may differ;
    a key a config saved by an older drltg lacks stands for its default, the built-in methods' options
    included). The task registry is never imported here (it needs torch), so an ``env.*`` key that only
    some configs set cannot be checked against its default: it is not compared, and a warning says so.
    Each config is compared with the fullest one (the most keys: the newest drltg's)."""
    known = [c for c in curves if c.config]
    if len(known) < 2:
        return
    from drltg.config import config_changes, env_keys_set_once

    first = max(known, key=lambda c: len(_flat(c.config)))
    unchecked: set[str] = set()
    for c in known:
        if c is first:
            continue
        ref, other = _flat(first.config), _flat(c.config)
        unchecked.update(env_keys_set_once(first.config, c.config))
        diff = [k for k in config_changes(first.config, c.config, env_defaults=False)
                if not any(k == p or k.startswith(p + ".") for p in CONFIG_KEYS_PER_RUN)]
        if diff:
            k = diff[0]
            more = f" ({len(diff)} keys differ)" if len(diff) > 1 else ""
            text = (f"the {side} runs mix configurations: {_name(first)} has {k}={ref.get(k, '(unset)')} "
                    f"but {_name(c)} has {k}={other.get(k, '(unset)')}{more}")
            if not allow_mixed:
                raise UsageError(text + "; compare one configuration per side, or pass --allow-mixed.")
            warnings.append(text + " (accepted by --allow-mixed).")
            return
    if unchecked:
        keys = sorted(unchecked)
        warnings.append(f"some {side} configs were saved without {', '.join(keys[:3])}"
                        + (f" and {len(keys) - 3} more env settings" if len(keys) > 3 else "")
                        + "; those keys are not compared (their defaults are the task's, which the report "
                        "does not load).")


PER_RUN = ("seed", "device", "threads", "log", "checkpoint", "transfer")
"""Config sections and keys that do not change what a curve means (``transfer`` is what the report compares)."""


def _check_sides(baseline: Sequence[Curve], transfer: Sequence[Curve], allow: bool, warnings: list[str]) -> None:
    """Baseline and transfer runs must share every setting that changes what their curves mean: the task's
    options, the learner and its network, buffer, collector and optimizer, the evaluation's episodes and
    interval, and the frames; a mismatch is refused, or with ``--allow-mismatch`` listed in the report."""
    from drltg.config import config_changes

    configs = [max((c for c in side if c.config), key=lambda c: len(_flat(c.config)), default=None)
               for side in (baseline, transfer)]
    if None in configs:
        return
    b, t = configs
    keys = [k for k in config_changes(b.config, t.config, env_defaults=False)
            if k.split(".")[0] not in PER_RUN]
    if not keys:
        return
    ref, other = _flat(b.config), _flat(t.config)
    leaves = [x for k in keys for x in sorted({x for x in (*ref, *other) if x == k or x.startswith(f"{k}.")})]
    text = ", ".join(f"{k} ({ref.get(k, '(unset)')} vs {other.get(k, '(unset)')})" for k in leaves)
    if not allow:
        raise UsageError(f"the baseline {_name(b)} and transfer {_name(t)} runs differ in settings that change what "
                         f"a curve means: {text}; compare like with like, or pass --allow-mismatch.")
    warnings.append(f"baseline and transfer settings differ (--allow-mismatch): {text}")


def _seed(curve: Curve):
    seed = (curve.config or {}).get("seed")
    return seed if isinstance(seed, int) and not isinstance(seed, bool) else None


def _pairing(baseline: list[Curve], transfer: list[Curve], paired: bool | None) -> tuple[bool, str, list[Curve]]:
    """Whether the runs are analysed in pairs, why, and the transfer runs in the baseline's order."""
    sb, st = [_seed(c) for c in baseline], [_seed(c) for c in transfer]
    recorded = all(s is not None for s in sb + st)
    one_to_one = recorded and len(set(sb)) == len(sb) and len(set(st)) == len(st) and set(sb) == set(st)
    if paired is False:
        return False, "unpaired: paired=False was given", transfer
    if one_to_one:
        order = {s: c for s, c in zip(st, transfer)}
        how = "--paired" if paired else "drltg runs"
        return True, (f"paired by seed ({how}): each baseline run has the transfer run with the same seed "
                      "in its config.yaml"), [order[s] for s in sb]
    if recorded:
        why = (f"the baseline seeds {sorted(sb)} and transfer seeds {sorted(st)} do not match one to one")
        if paired:
            raise UsageError(f"--paired cannot pair these runs: {why}.")
        return False, f"unpaired: {why}", transfer
    if paired:
        if len(baseline) != len(transfer):
            raise UsageError(f"--paired needs as many transfer runs as baseline runs (got {len(baseline)} "
                             f"baseline, {len(transfer)} transfer).")
        return True, "paired in the order given (--paired; the logs record no seed)", transfer
    return False, ("unpaired: not every run records its seed (foreign logs); pass --paired when run i of "
                   "both sides shares seed and initial weights"), transfer


# ------------------------------------------------------------------------- 2. align on one window
@dataclass
class Window:
    """What both sides are compared on: frames ``[start, budget]``, the threshold, the source frames
    behind each transfer run, and ``scale`` = span x max |y| (the yardstick of a near-zero baseline area)."""

    start: float
    budget: float
    budget_source: str
    threshold: float | None
    threshold_basis: str | None
    source_frames: list[float] | None
    source_basis: str
    scale: float
    value_range: tuple[float, float] | None = None


RATE_SUFFIX = "_rate"
"""A curve column (or the last part of a tag) ending so holds a rate in [0, 1] (``success_rate``,
``lifted_rate``): its differences' intervals stay in [-1, 1], unless a run's values leave [0, 1]."""


def align(sides: Sides, s: ReportSettings, warnings: list[str]) -> Window:
    """The common interval of all runs, the threshold in return units and the source training behind
    each transfer run."""
    runs = sides.runs
    start, budget, budget_source = _interval(runs, parse_frames(s.budget), warnings)
    no_zero = [c for c in runs if c.frames[0] > 0]
    if no_zero:
        frames = sorted({c.frames[0] for c in no_zero})
        warnings.append(
            f"{len(no_zero)} of {len(runs)} runs have no frame-0 evaluation; the jumpstart compares their "
            f"first {int(s.jumpstart_window)} evaluation(s) (from frame {number(frames[0])})."
        )
    threshold, basis = _threshold(sides.baseline, start, budget, s)
    source_frames, source_basis = _source_frames(sides.transfer, s)
    if source_frames is not None and not any(source_frames):
        source_basis += "; no source training, so the total-time view equals the target-only one"
    grid = _grid(runs, start, budget)
    largest = max(float(np.abs(np.interp(grid, c.frames, c.values)).max()) for c in runs)
    scale = (budget - start) * largest
    if not math.isfinite(scale * len(grid)):
        raise UsageError(f"values up to {largest:.3g} over {number(budget - start)} frames overflow the areas' "
                         "float64 range; rescale the curves (e.g. report them in other units).")
    _check_grids(sides, start, budget, warnings)
    return Window(start, budget, budget_source, threshold, basis, source_frames, source_basis, scale,
                  _value_range(runs, s, warnings))


def _value_range(runs: Sequence[Curve], s: ReportSettings, warnings: list[str]) -> tuple[float, float] | None:
    """``value_range`` as given, else [0, 1] for a rate (``RATE_SUFFIX``); ``None`` when unbounded, or when
    a run's values leave the range (then a warning names it)."""
    given = s.value_range
    if given is None and not (s.tag and str(s.tag).split("/")[-1].endswith(RATE_SUFFIX)):
        return None
    lo, hi = (0.0, 1.0) if given is None else (float(given[0]), float(given[1]))
    outside = next((c for c in runs if c.values.min() < lo or c.values.max() > hi), None)
    if outside is not None:
        warnings.append(f"{_name(outside)} has values outside [{lo:g}, {hi:g}], so the intervals are not "
                        "bounded to that range.")
        return None
    return lo, hi


def _spacing(c: Curve, start: float, budget: float) -> float | None:
    f = c.frames[(c.frames >= start) & (c.frames <= budget)]
    return float(np.median(np.diff(f))) if f.size > 1 else None


def _episodes(c: Curve):
    return ((c.config or {}).get("eval") or {}).get("episodes")


def _check_grids(sides: Sides, start: float, budget: float, warnings: list[str]) -> None:
    """Runs evaluated on different grids, or over different numbers of episodes, are compared on the
    real frame axis (areas) and by their own evaluations (initial and final performance); a warning names
    one run of each kind, so that the difference is seen."""
    spaced = [(c, _spacing(c, start, budget)) for c in sides.runs]
    spaced = [(c, x) for c, x in spaced if x is not None]
    if spaced:
        (a, sa), (b, sb) = min(spaced, key=lambda x: x[1]), max(spaced, key=lambda x: x[1])
        if sb > 1.1 * sa:
            warnings.append(
                f"the runs are evaluated on different grids: {_name(a)} every {number(sa)} frames, {_name(b)} "
                f"every {number(sb)}; areas are taken on the real frame axis, but initial and final "
                "performance average different numbers of evaluations.")
    gaps = [(c, float(np.diff(c.frames[(c.frames >= start) & (c.frames <= budget)]).max()), x) for c, x in spaced]
    gapped = [(c, gap, x) for c, gap, x in gaps if gap > 2.5 * x]  # x: the run's median spacing
    if gapped:
        c, gap, x = max(gapped, key=lambda g: g[1] / g[2])
        warnings.append(f"{len(gapped)} run(s) skip evaluations: {_name(c)} has a gap of {number(gap)} frames where it "
                        f"is evaluated every {number(x)}; the curve is interpolated across it.")
    counted = [(c, _episodes(c)) for c in sides.runs if isinstance(_episodes(c), int)]
    if counted and len({e for _, e in counted}) > 1:
        (a, ea), (b, eb) = min(counted, key=lambda x: x[1]), max(counted, key=lambda x: x[1])
        warnings.append(f"the runs' evaluations average different numbers of episodes: {_name(a)} {ea}, "
                        f"{_name(b)} {eb}; their values are comparable in expectation, not in noise.")


def _interval(curves: Sequence[Curve], budget: float | None, warnings: list[str]) -> tuple[float, float, str]:
    start = max(c.frames[0] for c in curves)
    firsts = sorted({c.frames[0] for c in curves})
    if len(firsts) > 1:
        warnings.append(
            f"runs start at different frames ({number(firsts[0])} to {number(firsts[-1])}); areas and "
            f"the asymptote window start at frame {number(start)}."
        )
    shortest = min(curves, key=lambda c: c.frames[-1])
    longest = max(curves, key=lambda c: c.frames[-1])
    latest = max(curves, key=lambda c: c.frames[0])
    foreign = [c for c in curves if c.config is None]
    if budget is None:
        budget, source = float(shortest.frames[-1]), "the shortest run's last evaluation"
        if foreign:  # logs of another library: their whole overlap, said
            source = (f"the range every run covers: from {_name(latest)}'s first evaluation (frame "
                      f"{number(start)}) to {_name(shortest)}'s last (frame {number(budget)})")
        elif longest.frames[-1] > MAX_LENGTH_RATIO * budget:
            raise UsageError(
                f"run lengths differ too much: {_name(shortest)} ends at frame {number(budget)} but "
                f"{_name(longest)} at {number(longest.frames[-1])}; pass --budget FRAMES to compare "
                "over a budget you choose."
            )
    else:
        budget, source = float(budget), "--budget"
        if shortest.frames[-1] < budget:
            raise UsageError(
                f"{_name(shortest)} ends at frame {number(shortest.frames[-1])}, before the budget of "
                f"{number(budget)} frames; lower --budget (points are never invented past a run's end)."
            )
    if budget <= start:
        raise UsageError(
            f"the budget ({number(budget)} frames) must lie after the latest first evaluation "
            f"({number(start)}, in {_name(max(curves, key=lambda c: c.frames[0]))})."
        )
    cut = [c for c in curves if c.frames[-1] > budget]
    if cut:
        warnings.append(
            f"{len(cut)} of {len(curves)} runs truncated to the common budget of {number(budget)} frames"
            + ("" if source == "--budget" else f", where {_name(shortest)} ends")
            + ": " + ", ".join(f"{c.label} (ends at {number(c.frames[-1])})" for c in cut) + "."
        )
    return float(start), budget, source


def _grid(curves: Sequence[Curve], start: float, budget: float) -> np.ndarray:
    frames = np.concatenate([c.frames[(c.frames >= start) & (c.frames <= budget)] for c in curves])
    return np.unique(np.concatenate([[start, budget], frames]))


def _on_grid(curves: Sequence[Curve], grid: np.ndarray, smooth: int | None = None) -> np.ndarray:
    """[n_seeds, len(grid)]: each run (optionally smoothed) linearly interpolated inside its range."""
    rows = []
    for c in curves:
        v = M.moving_average(c.values, smooth) if smooth and smooth > 1 else c.values
        rows.append(np.interp(grid, c.frames, v))
    return np.stack(rows)


def _threshold(baseline, start, budget, s: ReportSettings) -> tuple[float | None, str | None]:
    absolute, frac = parse_threshold(s.threshold)
    if frac is None:
        return absolute, None if absolute is None else "absolute"
    smooth = int(s.smooth) if s.smooth else None
    best = float(_on_grid(baseline, _grid(baseline, start, budget), smooth).mean(axis=0).max())
    if best <= 0:
        raise UsageError(
            f"--threshold {s.threshold} is a fraction of the best baseline performance, which is "
            f"{best:.4g} (not positive); give an absolute threshold instead."
        )
    return frac * best, f"{frac:g} x best baseline mean performance ({best:.6g})"


def _source_frames(transfer: Sequence[Curve], s: ReportSettings) -> tuple[list[float] | None, str]:
    """Frames of source training behind each transfer run, and where they come from."""
    if s.source_frames is not None:
        return [float(s.source_frames)] * len(transfer), "--source-frames"
    frames = []
    for c in transfer:
        if c.config is None:
            return None, "not given: pass --source-frames N for logs without a drltg config.yaml"
        source = (c.config.get("transfer") or {}).get("source")
        if source is None or str(source).startswith("demonstrator:"):
            frames.append(0.0)
            continue
        found = _frames_of_run(Path(c.source).parent, str(source))
        if found is None:
            return None, (f"unknown: the source run '{source}' of {_name(c)} has no readable config.yaml "
                          "with frames; pass --source-frames N")
        frames.append(found)
    return frames, "the source run's config.yaml frames (transfer.source of each run; 0 without a source run)"


def _frames_of_run(run_dir: Path, source: str) -> float | None:

    path = Path(source).expanduser()
    for candidate in ([path] if path.is_absolute() else [Path.cwd() / path, run_dir / path, run_dir.parent / path]):
        config = candidate / "config.yaml"
        if config.is_file():
            try:
                frames = (safe_yaml.load(config.read_text(), f"'{config}'") or {}).get("frames")
            except (UsageError, AttributeError):
                return None
            return float(frames) if isinstance(frames, (int, float)) else None
    return None


# ----------------------------------------------------------------------------- 3. per-seed scores
def score_runs(sides: Sides, w: Window, s: ReportSettings, warnings: list[str]) -> dict[str, pd.DataFrame]:
    """Per side, one row per run (in pair order when paired): the per-seed scores every metric is built from,
    and the total-time ones where source frames are known. Each side keeps its own column types, which the
    JSON's ``per_seed`` shows (a side whose crossing frames are all whole numbers lists them as integers)."""
    by_side = {side: pd.DataFrame([_run_scores(c, w, s) for c in runs]) for side, runs in sides.items()}
    if w.source_frames is not None and any(w.source_frames):
        _with_source(sides, by_side, w, s, warnings)
    return by_side


def stack(by_side: dict[str, pd.DataFrame], paired: bool) -> pd.DataFrame:
    """One frame of every run: ``side``, ``pair`` (the pair's index when paired, else None), then its scores."""
    return pd.DataFrame([{"side": side, "pair": i if paired else None, **row}
                         for side, df in by_side.items() for i, row in enumerate(df.to_dict("records"))])


def _smoothed(c: Curve, s: ReportSettings) -> np.ndarray:
    return M.moving_average(c.values, s.smooth) if s.smooth and s.smooth > 1 else c.values


def _crossing(frames, y, threshold, stop, s: ReportSettings) -> float | None:
    if threshold is None or stop < frames[0]:
        return None
    if s.crossing == "first":
        return _num(M.time_to_threshold(frames, y, threshold, stop))
    return _num(M.sustained_time_to_threshold(frames, y, threshold, stop, s.sustain))


def _run_scores(c: Curve, w: Window, s: ReportSettings) -> dict:
    r"""Initial performance (mean of the first K evaluations), final performance (mean of the evaluations in
    the asymptote window), area :math:`\int_{start}^{budget} y`, mean return = area / span, time to threshold."""
    k = int(s.jumpstart_window)
    lo, hi = M.final_window(w.start, w.budget, float(s.asymptote_window))
    inside = c.frames <= w.budget
    if inside.sum() < k:
        raise UsageError(
            f"{_name(c)} has {int(inside.sum())} evaluations within the budget, fewer than --jumpstart-window {k}."
        )
    window = (c.frames >= lo) & (c.frames <= hi)
    if not window.any():
        raise UsageError(
            f"{_name(c)} has no evaluation in the asymptote window [{number(lo)}, {number(hi)}] frames; "
            "widen --asymptote-window."
        )
    area = M.area_under_curve(c.frames, c.values, w.start, w.budget)
    return dict(
        label=c.label,
        source=str(c.source),
        seed=_seed(c),
        first_frame=_num(c.frames[0]),
        last_frame=_num(c.frames[-1]),
        initial_performance=M.initial_performance(c.values[inside], k),
        final_performance=float(c.values[window].mean()),
        total_reward=area,
        mean_return=area / (w.budget - w.start),
        time_to_threshold=_crossing(c.frames, _smoothed(c, s), w.threshold, w.budget, s),
    )


def _with_source(sides: Sides, by_side: dict, w: Window, s: ReportSettings, warnings: list[str]) -> None:
    r"""Taylor & Stone's total-time view on one budget: a transfer run has first spent ``S`` frames
    on the source task, so after ``x`` frames in total it has ``x - S`` target frames.

    Both sides are compared at equal total experience, over the window ``[start + S, budget]``:
    ``mean_return_total_time`` is the baseline's mean return there, and the transfer run's over its
    first ``budget - S - start`` target frames, :math:`\frac{1}{span - S}\int_{start}^{budget - S} y_T`.
    Time to threshold with source: :math:`\tau + S`, with :math:`\tau` reached within
    ``budget - S`` target frames."""
    start, budget, frames = w.start, w.budget, w.source_frames
    span = budget - start
    if len(set(frames)) > 1:
        warnings.append(f"the transfer runs' source runs differ in length ({', '.join(number(f) for f in frames)} "
                        "frames); the total-time metrics need one source budget and are left out.")
        return
    source = frames[0]
    if source >= span:
        warnings.append(f"the source training ({number(source)} frames) uses up the whole budget of {number(span)} "
                        "frames, so there is no total-time comparison within it; compare longer runs.")
        return
    width = span - source
    by_side["baseline"]["mean_return_total_time"] = [
        M.area_under_curve(c.frames, c.values, start + source, budget) / width for c in sides.baseline]
    by_side["transfer"]["mean_return_total_time"] = [
        M.area_under_curve(c.frames, c.values, start, budget - source) / width for c in sides.transfer]
    times = []
    for c in sides.transfer:
        crossed = _crossing(c.frames, _smoothed(c, s), w.threshold, budget - source, s)
        times.append(None if crossed is None else _num(crossed + source))
    by_side["transfer"]["source_frames"] = _num(source)
    by_side["transfer"]["time_to_threshold_with_source"] = pd.Series(times, dtype=object)


# -------------------------------------------------------------------------------------- 4. metrics
def metric_values(scores: pd.DataFrame, trends: dict, paired: bool, w: Window, s: ReportSettings,
                  warnings: list[str]) -> dict:
    """The ``metrics`` object, stage by stage (the JSON keeps this order): seed counts; comparisons of the
    sides with their intervals; each side's summaries; the trends of the mean curves."""
    sides = {side: scores[scores["side"] == side] for side in SIDES}
    m: dict = {}
    for metric in _of_kind("count"):
        m.update({metric.key(side): len(sides[side]) for side in metric.sides})
    n_b, n_t = len(sides["baseline"]), len(sides["transfer"])
    enough = min(n_b, n_t) >= MIN_SEEDS
    if not enough:
        warnings.append(f"intervals need at least {MIN_SEEDS} seeds per side (got {n_b} baseline, "
                        f"{n_t} transfer); none are reported.")
    for metric in _of_kind(*COMPARISONS):
        if metric.score in scores:
            b = sides["baseline"][metric.score].to_numpy(np.float64)
            t = sides["transfer"][metric.score].to_numpy(np.float64)
            m.update(_compare(metric, b, t, paired, w, s, enough, warnings))
    for side in SIDES:
        for metric in _of_kind("mean", "time", "reached"):
            if side in metric.sides and metric.score in scores:
                m[metric.key(side)] = _summary(metric, sides[side][metric.score], w.threshold)
    for metric in _of_kind("trend"):
        for side in metric.sides:
            m.update(_trend_values(metric, side, trends[side], s, warnings))
    return _with_holm(m)


def _with_holm(m: dict) -> dict:
    """``<name>_p_adjusted`` after each ``<name>_p_value``: Holm's adjustment over every p-value of the
    report, the family of intervals read together."""
    family = [k for k in m if k.endswith("_p_value")]
    adjusted = dict(zip(family, M.holm([m[k] for k in family])))
    out = {}
    for key, value in m.items():
        out[key] = value
        if key in adjusted:
            out[key.removesuffix("_p_value") + "_p_adjusted"] = adjusted[key]
    return out


def family_of(metrics: dict) -> list[str]:
    """The metrics whose p-values are adjusted together (those with an interval and a test)."""
    return [k.removesuffix("_p_value") for k in metrics if k.endswith("_p_value")]


def _compare(metric: Metric, b: np.ndarray, t: np.ndarray, paired: bool, w: Window, s: ReportSettings,
             enough: bool, warnings: list[str]) -> dict:
    """``<name>``, and where an honest interval exists ``<name>_ci`` with its p-values; ``<name>_iqm``."""
    eps = float(s.ratio_eps)
    value = _estimate(metric, b, t, paired, M.mean, w.scale, eps)
    out = {metric.name: value}
    if metric.kind == "ratio" and value is None:
        why = ("every curve is 0 at every evaluation in the window" if w.scale == 0 else
               f"the baseline area ({b.mean():.4g}) is within {eps * 100:g}% of the largest possible area "
               f"({w.scale:.4g}) of zero")
        warnings.append(f"{why}, so transfer_ratio is undefined (null); compare mean_return_gain instead.")
    if enough:
        ci, why = _confidence_interval(metric, value, b, t, paired, w, s)
        if ci is not None:
            out[f"{metric.name}_ci"] = ci
            out.update(_p_values(metric, b, t, paired, s, warnings))
        elif why:
            warnings.append(why)
    if metric.iqm:
        out[f"{metric.name}_iqm"] = _estimate(metric, b, t, paired, M.interquartile_mean, w.scale, eps)
    return out


def _estimate(metric: Metric, b: np.ndarray, t: np.ndarray, paired: bool, location, scale, eps):
    """The metric with ``location`` taken of each side: one definition per name, paired or not (for
    the mean, the mean of the pairs' differences; P(T > B) alone counts pairs when paired)."""
    if metric.kind == "difference":
        return float(location(t) - location(b))
    if metric.kind == "ratio":
        return M.transfer_ratio(b, t, location=location, scale=scale, eps=eps)
    return M.paired_probability_of_improvement(b, t) if paired else M.probability_of_improvement(b, t)


def _confidence_interval(metric: Metric, value, b, t, paired: bool, w: Window,
                         s: ReportSettings) -> tuple[list | None, str | None]:
    """``([low, high], None)``, or ``(None, reason)`` where no honest interval exists."""
    conf = float(s.confidence)
    if metric.kind == "poi":
        return list(M.poi_interval(value, len(b), len(t), paired, conf)), None
    if metric.kind == "ratio":
        if value is None:
            return None, None
        lo, hi = M.ratio_interval(b, t, paired, conf)
        if math.isnan(lo):
            return None, (f"{metric.name} has no interval: the interval of the baseline's mean area "
                          "contains 0, so the ratio's would be unbounded.")
        return [lo, hi], None
    kw = {} if s.interval in ("t", "welch") else dict(n_resamples=int(s.bootstrap), seed=int(s.seed))
    lo, hi = (float(x) for x in M.INTERVALS[s.interval](b, t, paired=paired, confidence=conf, **kw))
    if math.isfinite(lo) and math.isfinite(hi) and hi > lo:
        return _within(lo, hi, w.value_range), None
    if paired and np.ptp(t - b) <= M.roundoff(b, t):
        why = f"every pair gives the same difference ({float(t[0] - b[0]):.4g}), so there is no spread to scale"
    elif not paired and max(np.ptp(b), np.ptp(t)) <= M.roundoff(b, t):
        why = "each side's seeds give identical values, so there is no spread to scale"
    else:
        why = f"the {s.interval} interval is undefined for these scores"
    return None, f"{metric.name} has no interval: {why}."


def _within(lo: float, hi: float, value_range) -> list[float]:
    """A difference of two means of values in ``[a, b]`` lies in ``[-(b - a), b - a]``: the interval is cut
    there (the truth lies inside, so the cut never lowers coverage)."""
    if value_range is None:
        return [lo, hi]
    span = float(value_range[1]) - float(value_range[0])
    return [max(lo, -span), min(hi, span)]


def _p_values(metric: Metric, b, t, paired: bool, s: ReportSettings, warnings: list[str]) -> dict:
    """``<name>_p_value`` (and ``<name>_p_exact`` for a mean difference): see ``settings.p_values``."""
    name = f"{metric.name}_p_value"
    if metric.kind == "poi":
        p = M.sign_test(b, t) if paired else M.permutation_test(b, t, statistic="poi", seed=int(s.seed))
        return {name: p}
    t_p = float(M.t_test(b, t, paired))
    if metric.kind == "ratio":  # Fieller's interval contains 0 exactly where this test accepts
        return {name: t_p}
    exact = M.permutation_test(b, t, paired, seed=int(s.seed))
    shapes = [x for x in ([M.shape_of(t - b)] if paired else [M.shape_of(b), M.shape_of(t)]) if x]
    if shapes:
        scores = "per-pair differences" if paired else "per-seed scores"
        warnings.append(f"{metric.name}: the {scores} look {shapes[0]}, so its p_value is the exact permutation "
                        f"test's ({exact:.3g}, not the t test's {t_p:.3g}); the t interval may cover less than "
                        "promised for such scores.")
        return {name: exact, f"{metric.name}_p_exact": exact}
    return {name: t_p, f"{metric.name}_p_exact": exact}


def _summary(metric: Metric, column: pd.Series, threshold: float | None):
    """A side's mean over seeds; or its upper-median crossing frame (a frame a run had, by which a strict
    majority has crossed) and the share of runs that cross, both null without a threshold."""
    if metric.kind == "mean":
        return float(column.mean())
    if threshold is None:
        return None
    times = [None if _missing(x) else x for x in column]
    if metric.kind == "time":
        return _num(M.censored_median(times, upper=True))
    return sum(x is not None for x in times) / len(times)


def trend(curves: Sequence[Curve], w: Window, s: ReportSettings) -> dict:
    r"""Has the side's mean curve converged over the last ``trend_window`` of the budget?

    Least-squares line through the mean over seeds at every evaluation frame of that window; the
    change over the window, :math:`c = \hat\beta (f_1 - f_0)`, with its t-interval (n - 2 degrees of
    freedom) and the equivalence margin :math:`\delta` = ``convergence_margin`` x the mean curve's range
    over the budget. ``converged`` only where two one-sided tests show :math:`|c| < \delta`; ``still
    rising`` / ``still falling`` where the interval excludes 0; else undetermined, with the reason."""
    start, budget = w.start, w.budget
    lo = budget - float(s.trend_window) * (budget - start)
    frames = np.unique(np.concatenate([c.frames[(c.frames >= lo) & (c.frames <= budget)] for c in curves]))
    progress = float(np.ptp(_on_grid(curves, _grid(curves, start, budget)).mean(axis=0)))
    margin = float(s.convergence_margin) * progress
    out = dict(window=[_num(lo), _num(budget)], n_points=int(frames.size), margin=margin)
    if frames.size < MIN_TREND_POINTS:
        return {**out, "change": None, "ci": None, "p_value": None, "p_equivalence": None,
                "verdict": f"undetermined (too few evaluations: {frames.size} in the window, "
                           f"{MIN_TREND_POINTS} needed)"}
    mean = _on_grid(curves, frames).mean(axis=0)
    slope, se, df = M.trend(frames, mean)
    span = budget - lo
    change, se_change = slope * span, se * span
    half = M.t_quantile(0.5 + float(s.confidence) / 2, df) * se_change
    alpha = 1.0 - float(s.confidence)
    p_equivalence = M.equivalence_test(change, se_change, df, margin)
    if progress == 0:  # a constant mean curve has nothing left to change
        p_equivalence = 0.0
    if se_change > 0:
        p_value = 2 * _t_sf(abs(change) / se_change, df)
    else:  # the mean lies on a line: its change is exact
        p_value = 1.0 if change == 0 else 0.0
    if p_equivalence < alpha:
        verdict = "converged"
    elif abs(change) > half:
        verdict = "still rising" if change > 0 else "still falling"
    else:
        verdict = (f"undetermined (the change is neither shown within +-{margin:.3g} nor shown to differ "
                   "from 0)")
    ci = _within(change - half, change + half, w.value_range)
    return {**out, "change": change, "ci": ci, "p_value": p_value, "p_equivalence": p_equivalence,
            "verdict": verdict}


def _t_sf(x: float, df: float) -> float:
    from scipy import stats

    return float(stats.t.sf(x, df))


def _trend_values(metric: Metric, side: str, tr: dict, s: ReportSettings, warnings: list[str]) -> dict:
    """``final_trend_<side>`` with its interval and p-value, and a warning for a side whose curve still moves."""
    out = {metric.key(side): tr["change"]}
    if tr["ci"] is not None:
        out[f"{metric.key(side)}_ci"] = tr["ci"]
        out[f"{metric.key(side)}_p_value"] = tr["p_value"]
    if tr["verdict"].startswith("still"):
        warnings.append(
            f"the {side} mean curve is {tr['verdict']} over the last {100 * float(s.trend_window):g}% of the "
            f"budget ({tr['change']:+.4g} [{tr['ci'][0]:+.4g}, {tr['ci'][1]:+.4g}] from frame "
            f"{number(tr['window'][0])} to {number(tr['window'][1])}): asymptotic_performance compares final "
            "performances, not asymptotes.")
    return out


def _missing(x) -> bool:
    return x is None or (isinstance(x, float) and math.isnan(x))


def _num(x):
    if x is None:
        return None
    x = float(x)
    return int(x) if x.is_integer() and abs(x) < 2**53 else x


def _records(df: pd.DataFrame) -> list[dict]:
    """JSON-ready rows: NaN cells as None, numpy scalars as Python numbers."""
    return [{k: (None if _missing(v) else v.item() if isinstance(v, np.generic) else v) for k, v in row.items()}
            for row in df.to_dict("records")]


# ------------------------------------------------------------------------------ 5. describe, plot
def describe(s: ReportSettings, sides: Sides, w: Window, trends: dict, warnings: list[str],
             metrics: dict | None = None) -> dict:
    """The report's ``settings``: every choice made, with the reasons and warnings."""
    family = family_of(metrics or {})
    lo, hi = M.final_window(w.start, w.budget, float(s.asymptote_window))
    return {
        "baseline": [str(c.source) for c in sides.baseline],
        "transfer": [str(c.source) for c in sides.transfer],
        "baseline_label": s.baseline_label or _side_label(sides.baseline, "baseline"),
        "transfer_label": s.transfer_label or _side_label(sides.transfer, "transfer"),
        "task": sides.task,
        "format": s.format,
        "tag": s.tag,
        "start": _num(w.start),
        "budget": _num(w.budget),
        "budget_source": w.budget_source,
        "paired": sides.paired,
        "pairing": sides.pairing,
        "jumpstart_window": int(s.jumpstart_window),
        "asymptote_window": float(s.asymptote_window),
        "asymptote_frames": [_num(lo), _num(hi)],
        "trend_window": float(s.trend_window),
        "convergence": {side: tr["verdict"] for side, tr in trends.items()},
        "convergence_rule": (f"converged only where two one-sided tests (TOST, level {1 - float(s.confidence):g}) "
                             "show that the mean curve's change over the trend window lies within +-"
                             f"{float(s.convergence_margin):g} x its range over the budget (margin: "
                             + ", ".join(f"{side} {tr['margin']:.4g}" for side, tr in trends.items()) + ")"),
        "convergence_margin": float(s.convergence_margin),
        "threshold": w.threshold,
        "threshold_given": s.threshold,
        "threshold_basis": w.threshold_basis,
        "crossing": s.crossing,
        "sustain": s.sustain,
        "sustain_after": None if s.crossing == "first" or s.sustain else M.SUSTAIN_AFTER,
        "time_to_threshold_rule": _crossing_rule(s),
        "median_rule": ("upper median over seeds: the earliest of the runs' own crossing frames by which a "
                        "strict majority of seeds has crossed; null when no strict majority does"),
        "source_frames": None if w.source_frames is None else [_num(f) for f in w.source_frames],
        "source_frames_basis": w.source_basis,
        "smooth": int(s.smooth) if s.smooth else None,
        "ratio_eps": float(s.ratio_eps),
        "ratio_scale": w.scale,
        "interval": _interval_rule(s, sides.paired, w),
        "value_range": None if w.value_range is None else list(w.value_range),
        "p_values": _p_value_rule(sides.paired),
        "family": {"size": len(family), "metrics": family, "adjustment": (
            f"Holm over these {len(family)} p-values: the chance of any false finding among them stays "
            f"below the level at which they are read")},
        "confidence": float(s.confidence),
        "bootstrap": int(s.bootstrap),
        "seed": int(s.seed),
        "location": ("mean of each side's seeds (for pairs, the mean of their differences); *_iqm: the "
                     "interquartile mean of each side"),
        "warnings": warnings,
        "plot_smooth": _plot_smooth(sides.runs, w, s),
    }


def _side_label(curves: Sequence[Curve], default: str) -> str:
    if len(curves) == 1:
        return curves[0].label
    parents = {Path(c.source).resolve().parent.parent if Path(c.source).is_file()
               else Path(c.source).resolve().parent for c in curves}
    name = parents.pop().name if len(parents) == 1 else ""
    return name or default


def _crossing_rule(s: ReportSettings) -> str:
    if s.crossing == "first":
        return "first evaluation at or above the threshold (--crossing first)"
    if s.sustain:
        return (f"first evaluation from which the run stays at or above the threshold for {s.sustain} "
                "evaluations, the crossing included")
    return ("first evaluation from which the run stays at or above the threshold until the budget, over at "
            f"least {M.SUSTAIN_AFTER} evaluations after it (a crossing at either of the last {M.SUSTAIN_AFTER} "
            "evaluations is not yet sustained)")


def _interval_rule(s: ReportSettings, paired: bool, w: Window) -> str:
    level = f"{100 * float(s.confidence):g}%"
    diff = {"t": "paired t-interval on the per-pair differences" if paired else
            "t-interval with Welch's standard error and Hsu's min(n_B, n_T) - 1 degrees of freedom",
            "welch": "paired t-interval" if paired else "Welch t-interval",
            "studentized": "studentized (bootstrap-t) interval", "bca": "BCa bootstrap interval",
            "percentile": "percentile bootstrap interval"}[s.interval]
    bounded = ("" if w.value_range is None else
               f"; the values lie in [{w.value_range[0]:g}, {w.value_range[1]:g}], so every difference's interval "
               f"is cut to +-{w.value_range[1] - w.value_range[0]:g} (the truth lies inside, coverage is kept)")
    poi = "Clopper-Pearson's exact interval over pairs" if paired else "Newcombe's score interval (method 5)"
    return (f"{level}: {diff} for the mean differences; Fieller's interval for transfer_ratio; {poi} for the "
            f"probabilities of improvement, inside [0, 1]; none with fewer than {MIN_SEEDS} seeds on a side"
            f"{bounded}. {COVERAGE_CLAIM}")


COVERAGE_CLAIM = ("In simulation (results/coverage) these intervals cover at least 93% of the time with 3 to 10 "
                  "seeds on normal, bimodal and success-rate scores, except for paired scores with a strong "
                  "multiplicative seed effect (right-skewed differences) and paired bimodal scores at 3 seeds "
                  "(and at 5 for transfer_ratio); no bootstrap interval measured did better there.")
COVERAGE_EXCEPTIONS = (("lognormal", "paired", None), ("bimodal", "paired", 3), ("bimodal", "paired", 5))
"""(scores, design, seeds or None for any) of results/coverage where the claim above does not hold; a test
checks the committed table against it."""


def _p_value_rule(paired: bool) -> str:
    test = "the paired t test" if paired else "the t test with Welch's standard error and Hsu's degrees of freedom"
    poi = "the exact sign test over pairs (ties dropped)" if paired else \
        "the exact permutation test of the Mann-Whitney estimate"
    return (f"two-sided, of no effect: {test} behind each mean difference's interval (transfer_ratio's too, "
            f"whose Fieller interval excludes 0 exactly where it rejects), unless the per-seed scores look skewed "
            f"or bimodal (from {M.SHAPE_MIN_SEEDS} seeds: D'Agostino's skewness test at 0.05, Sarle's "
            "bimodality coefficient above 5/9), where the exact permutation test's p-value is used (given in "
            f"*_p_exact for every mean difference); {poi} for P(T > B); the slope's t test for final_trend_*")


def _plot_smooth(runs: Sequence[Curve], w: Window, s: ReportSettings) -> int:
    """The plotted lines' moving-average width: ``--plot-smooth``, else ``--smooth``, else about
    ``PLOT_POINTS`` windows per curve."""
    n_evals = int(np.median([int((c.frames <= w.budget).sum()) for c in runs]))
    return int(s.plot_smooth or (int(s.smooth) if s.smooth else None) or max(1, n_evals // PLOT_POINTS))


def plot_curves(sides: Sides, w: Window, scores: pd.DataFrame, described: dict) -> dict:
    """Per side, what the plot draws: the (smoothed) mean on a common grid, a t-interval band over seeds
    where there are enough, the raw runs and each run's crossing frame."""
    width, confidence = described["plot_smooth"], described["confidence"]
    curves = {}
    for side, runs in sides.items():
        grid = _grid(runs, w.start, w.budget)
        ys = _on_grid(runs, grid, width)
        band = None
        if len(runs) >= MIN_SEEDS:
            half = M.t_quantile(0.5 + confidence / 2, len(runs) - 1) * ys.std(0, ddof=1) / math.sqrt(len(runs))
            band = (ys.mean(0) - half, ys.mean(0) + half)
            if w.value_range is not None:  # a rate's mean lies in its range
                band = tuple(np.clip(x, *w.value_range) for x in band)
        times = [None if _missing(x) else x for x in scores.loc[scores["side"] == side, "time_to_threshold"]]
        curves[side] = dict(grid=grid, mean=ys.mean(axis=0), band=band, smooth=width,
                            runs=[(c.frames, c.values) for c in runs], times=times)
    return curves


# ------------------------------------------------------------------------------------------ outputs
def metrics_rows(metrics: dict) -> list[tuple[str, object, object, object, object, object]]:
    """``(metric, value, ci_low, ci_high, p_value, p_adjusted)`` rows in the table's order (the metrics the
    report gave)."""
    rows = []
    for name in table_rows():
        if name in metrics:
            ci = metrics.get(f"{name}_ci") or (None, None)
            rows.append((name, metrics[name], ci[0], ci[1], metrics.get(f"{name}_p_value"),
                         metrics.get(f"{name}_p_adjusted")))
    return rows


def _note(name: str, st: dict) -> str:
    metric, side, iqm = table_rows()[name]
    if iqm:
        return ""
    return metric.note(st, side) if callable(metric.note) else metric.note


def _shown(name: str, value, threshold) -> str:
    if name.startswith(("time_to_threshold", "threshold_reached")) and threshold is None:
        return "-"
    if value is None:
        return "not reached" if name.startswith("time_to") else "null"
    return number(value)


def format_table(result: dict) -> str:
    """The metrics as an aligned text table (intervals only where they exist; notes on the right)."""
    m, st = result["metrics"], result["settings"]
    head = (
        f"{st['transfer_label']} (transfer, {m['n_seeds_transfer']} seed(s)) vs "
        f"{st['baseline_label']} (baseline, {m['n_seeds_baseline']} seed(s))"
        + (f" on {st['task']}" if st["task"] else "") + "\n"
        + f"budget {number(st['budget'])} frames from frame {number(st['start'])}"
        + ("" if st["threshold"] is None else f"; threshold {st['threshold']:.4g}")
        + f"; {st.get('pairing', 'unpaired').split(':')[0]}\n"
        + _family_line(st) + "\n\n"
    )
    rows = [("metric", "value", f"{round(100 * st['confidence'])}% CI", "p", "p (Holm)", "note")]
    rows += [(name, _shown(name, value, st["threshold"]), tables.interval((lo, hi)), _p(p), _p(adjusted),
              _note(name, st)) for name, value, lo, hi, p, adjusted in metrics_rows(m)]
    return head + tables.render(rows, "text", align="lrlrrl").rstrip("\n")


def _p(p) -> str:
    return "" if p is None else "<0.001" if p < 0.001 else f"{p:.3f}"


def _family_line(st: dict) -> str:
    family = st.get("family") or {}
    if not family.get("size"):
        return "family: no p-values (too few seeds or no spread)"
    return (f"family: {family['size']} intervals read together; p (Holm) adjusts each p-value over all "
            f"{family['size']}")


def render(result: dict) -> dict[str, bytes]:
    """The report's files as bytes (nothing is written here)."""
    from drltg.analysis.plot import plot_transfer

    m, st = result["metrics"], result["settings"]
    public = {"metrics": m, "settings": st, "per_seed": result["per_seed"]}
    png, svg = plot_transfer(result)
    return {
        "transfer_metrics.json": _json_text(public).encode(),
        "transfer_metrics.csv": tables.render(
            [("metric", "value", "ci_low", "ci_high", "p_value", "p_adjusted"), *metrics_rows(m)], "csv").encode(),
        "transfer_plot.png": png,
        "transfer_plot.svg": svg,
    }


def _json_text(obj) -> str:
    return json.dumps(obj, indent=2, allow_nan=False) + "\n"


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]+", "-", text).strip("-.") or "runs"


def fresh_dir(name: str, parent: Path | None = None) -> Path:
    """``parent/name``, or ``name-2``, ``name-3``, ... if it exists (never the working directory itself)."""
    parent = Path.cwd() if parent is None else Path(parent)
    base = parent / _slug(name)
    path, i = base, 2
    while path.exists():
        path, i = base.with_name(f"{base.name}-{i}"), i + 1
    return path


def check_out_dir(out: Path, option: str = "--out") -> None:
    """An output folder must be a folder (or creatable as one) that this process can write, and never a
    run directory or a folder inside one (a report's files would mix with the run's own)."""
    rundir.refuse_special(out, option)
    runs = [p for p in [out, *out.resolve().parents] if (p / rundir.EVAL).is_file() or (p / rundir.SUMMARY).is_file()]
    run = runs[0] if runs else None
    if run is not None:
        raise UsageError(f"{option} '{out}' is {'' if run == out else 'inside '}the run directory '{run}'; write the "
                         "report to a folder of its own.")
    if out.exists() and not out.is_dir():
        raise UsageError(f"{option} '{out}' is a file, not a folder.")
    existing = next((p for p in [out, *out.parents] if p.exists()), None)
    if existing is not None and not existing.is_dir():
        raise UsageError(f"{option} '{out}' lies inside '{existing}', which is a file, not a folder.")
    if existing is not None and not os.access(existing, os.W_OK | os.X_OK):
        raise UsageError(f"{option} '{out}' cannot be written: '{existing}' is read-only for this user.")


# ------------------------------------------------------------------------------------------- matrix
def find_matrix_cells(directory: str | Path) -> dict[tuple[str, str], tuple[Path, Path]]:
    """``DIR/<source>/<target>/{baseline,transfer}`` -> ``{(source, target): (baseline, transfer)}``."""
    directory = Path(directory)
    if not directory.is_dir():
        raise UsageError(f"--matrix '{directory}' is not a directory.")
    cells = {}
    for source in sorted(p for p in directory.iterdir() if p.is_dir()):
        for target in sorted(p for p in source.iterdir() if p.is_dir()):
            b, t = target / "baseline", target / "transfer"
            if b.is_dir() and t.is_dir():
                cells[(source.name, target.name)] = (b, t)
            elif b.is_dir() or t.is_dir():
                missing = "transfer" if b.is_dir() else "baseline"
                raise UsageError(f"'{target}' has no '{missing}' folder beside its other run set.")
    if not cells:
        raise UsageError(
            f"--matrix '{directory}' holds no <source>/<target>/baseline + transfer run folders."
        )
    return cells


def check_metric(metric: str, option: str = "--metric") -> None:
    """``metric`` must be one the report computes."""
    if metric not in table_rows():
        raise UsageError(f"unknown {option} '{metric}'; choose one of {', '.join(table_rows())}.")


def transfer_matrix(
    cells: dict[tuple[str, str], tuple],
    out_dir: str | Path | None = None,
    metric: str = "mean_return_gain",
    **settings,
) -> dict:
    """One report per (source, target) cell, summarised as a heatmap of ``metric`` plus CSV and JSON."""
    check_metric(metric)
    s = settings_of(settings)
    if out_dir is not None:
        check_out_dir(Path(out_dir))
    results = {cell: compute(read_runs(b, s), read_runs(t, s), **settings) for cell, (b, t) in sorted(cells.items())}
    sources = sorted({s for s, _ in results})
    targets = sorted({t for _, t in results})
    table = np.full((len(sources), len(targets)), np.nan)
    for (source, target), r in results.items():
        v = r["metrics"][metric]
        table[sources.index(source), targets.index(target)] = np.nan if v is None else v
    from drltg.analysis.plot import plot_matrix

    png, svg = plot_matrix(table, sources, targets, metric)
    grid_csv = tables.render([("source", *targets)] + [
        (source, *(None if np.isnan(v) else float(v) for v in row)) for source, row in zip(sources, table)
    ], "csv")
    obj = {
        "metric": metric,
        "cells": [{"source": source, "target": target, "metrics": r["metrics"], "settings": r["settings"]}
                  for (source, target), r in results.items()],
    }
    out = Path(out_dir) if out_dir is not None else fresh_dir(f"matrix-{metric}")
    rundir.write_files(out, {
        "transfer_matrix.csv": grid_csv.encode(),
        "transfer_matrix.json": _json_text(obj).encode(),
        "transfer_matrix.png": png,
        "transfer_matrix.svg": svg,
    })
    return {**obj, "out_dir": str(out), "table": table.tolist(), "sources": sources, "targets": targets}


# ---------------------------------------------------------------------------------------------- CLI
def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``drltg report``'s options: the run sets, ``--out`` and ``--matrix``, then one option per
    :class:`ReportSettings` field that has a flag."""
    groups = {"runs": parser.add_argument_group("runs"), "metrics": parser.add_argument_group("metrics")}
    io_ = groups["runs"]
    io_.add_argument("--baseline", nargs="+", metavar="PATH",
                     help="baseline (no transfer) runs: run dirs, a dir of seed runs, log files or globs")
    io_.add_argument("--transfer", nargs="+", metavar="PATH", help="transfer runs, same forms as --baseline")
    io_.add_argument("--matrix", metavar="DIR",
                     help="DIR/<source>/<target>/{baseline,transfer}: a heatmap of --metric over all pairs")
    io_.add_argument("--metric", default="mean_return_gain", help="metric for the --matrix heatmap "
                     "(default: mean_return_gain)")
    io_.add_argument("--out", metavar="DIR", help="output folder (default: a fresh folder named after the runs)")
    for f in fields(ReportSettings):
        meta = f.metadata
        if meta.get("flag"):
            groups[meta["group"]].add_argument(meta["flag"], dest=f.name, default=f.default, **meta["kwargs"])


def run(args) -> int:
    settings = asdict(ReportSettings.from_args(args))  # every option is checked before any run is read
    if args.matrix:
        if args.baseline or args.transfer:
            raise UsageError("--matrix builds its own baseline/transfer pairs; drop --baseline and --transfer.")
        del settings["baseline_label"], settings["transfer_label"]
        result = transfer_matrix(find_matrix_cells(args.matrix), args.out, args.metric, **settings)
        for cell in result["cells"]:
            for w in cell["settings"]["warnings"]:
                print(f"warning: {cell['source']} -> {cell['target']}: {w}", file=sys.stderr)
        rows = [("source \\ target", *result["targets"])] + [
            (source, *("-" if math.isnan(v) else f"{v:.4g}" for v in row))
            for source, row in zip(result["sources"], result["table"])]
        print(f"{args.metric}:")
        print(tables.render(rows, "text", align="l" + "r" * len(result["targets"])), end="")
        print(f"wrote {result['out_dir']}/transfer_matrix.{{png,svg,csv,json}}")
        return 0
    if not args.baseline or not args.transfer:
        raise UsageError("give both --baseline and --transfer runs (or --matrix DIR).")
    result = transfer_report(args.baseline, args.transfer, args.out, **settings)
    for w in result["settings"]["warnings"]:
        print(f"warning: {w}", file=sys.stderr)
    print(format_table(result))
    from drltg.analysis.claims import headline

    print("\n" + headline(result))
    print(f"\nwrote {result['out_dir']}/transfer_metrics.{{json,csv}} and transfer_plot.{{png,svg}}")
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="drltg report", description=__doc__.splitlines()[0])
    add_arguments(parser)
    args = parser.parse_args(argv)
    try:
        return run(args)
    except UsageError as err:
        print(f"drltg report: error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
