"""The report's settings: every choice of ``drltg report``, checked once."""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field, fields

from drltg.analysis import metrics as M
from drltg.analysis import stats
from drltg.errors import UsageError
from drltg.report.curves import FORMATS

SIDES = ("baseline", "transfer")
MAX_LENGTH_RATIO = 2.0  # longest / shortest run beyond which a default budget would hide too much
PLOT_POINTS = 100  # the display line is smoothed to about this many evaluation windows
MIN_SEEDS = 3  # fewer seeds on a side leave an interval without a usable spread estimate
MIN_TREND_POINTS = 4  # a line through fewer points leaves under 2 degrees of freedom for its error
CONFIG_KEYS_PER_RUN = ("seed", "frames", "device", "threads", "log", "checkpoint", "transfer.source", "tuned_on")


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
    interval: str = _option("auto", "--interval", choices=("auto", *stats.INTERVALS),
                            help="interval of the mean differences (default: auto, a betting interval valid for "
                            "any scores within --value-range, none where the range is unknown; t and the "
                            "bootstrap ones assume what results/coverage measures; the bootstrap ones use "
                            "--bootstrap and --seed)")
    confidence: float = _option(0.95, "--confidence", type=float, help="confidence level (default: 0.95)")
    bootstrap: int = _option(10_000, "--bootstrap", type=int, metavar="N",
                             help="resamples of a bootstrap --interval (default: 10000)")
    seed: int = _option(0, "--seed", type=int, help="seed of a bootstrap --interval (default: 0)")
    ratio_eps: float = _option(0.01)
    equivalence_margin: float | None = _option(
        None, "--equivalence-margin", type=float, metavar="DELTA",
        help="a mean difference the exact test leaves undecided is 'equivalent' where two one-sided t tests "
             "(TOST) put it within +-DELTA, in the metric's units (default: no equivalence verdict)")
    task: str | None = _option(None, "--task", metavar="TASK",
                               help="the drltg task (or its Gymnasium id, drltg/<task>-v0) foreign logs were "
                               "trained on: the report takes its declared return range, as for drltg's runs")
    value_range: object = _option(None, "--value-range", metavar="LOW,HIGH",
                                  help="the range every value of the curves lies in, e.g. 0,500 for a reward in "
                                  "[0, 1] over 500 steps (default: 0,1 for a rate, else unknown)")

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
        self.value_range = parse_range(self.value_range)
        need(self.equivalence_margin is None or (math.isfinite(float(self.equivalence_margin))
                                                 and float(self.equivalence_margin) > 0),
             f"--equivalence-margin must be a finite number above 0, got {self.equivalence_margin}.")
        if self.task is not None:
            task_returns(str(self.task))  # an unknown task is one sentence before any run is read
        need(self.crossing in ("sustained", "first"), f"--crossing must be sustained or first, got '{self.crossing}'.")
        need(not (self.sustain is not None and self.crossing == "first"),
             "--sustain applies to a sustained crossing; drop it or --crossing first.")
        need(0.0 < float(self.confidence) < 1.0, f"--confidence must lie in (0, 1), got {self.confidence}.")
        need(int(self.bootstrap) >= 100, f"--bootstrap needs at least 100 resamples, got {self.bootstrap}.")
        need(0 <= int(self.seed) < 2**32, f"--seed must be an integer in [0, 2**32 - 1], got {self.seed}.")
        need(self.interval == "auto" or self.interval in stats.INTERVALS,
             f"unknown --interval '{self.interval}'; choose one of auto, {', '.join(stats.INTERVALS)}.")
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


def task_returns(name: str) -> tuple[float, float] | None:
    """The return range the drltg task ``name`` (or its Gymnasium id ``drltg/<task>-v0``) declares with its
    default options; one sentence for a name that is neither."""
    from drltg.envs.registry import TASKS, get_task
    from drltg.gymnasium_ids import task_id

    for task in list(TASKS):
        try:
            if task_id(task) == name.removeprefix("drltg:"):
                name = task
        except ValueError:  # a task whose name cannot be an id
            continue
    return get_task(name).return_range()


def parse_range(value) -> tuple[float, float] | None:
    """``"0,500"`` or ``(0, 500)`` -> (0.0, 500.0): finite, low < high."""
    if value is None:
        return None
    parts = value.split(",") if isinstance(value, str) else list(value)
    try:
        low, high = (float(x) for x in parts)
    except (TypeError, ValueError):
        raise UsageError(f"--value-range '{value}' is not LOW,HIGH (e.g. 0,500).") from None
    if not (math.isfinite(low) and math.isfinite(high) and low < high):
        raise UsageError(f"--value-range needs finite LOW < HIGH, got {low:g},{high:g}.")
    if not math.isfinite(high - low):
        raise UsageError(f"--value-range {low:g},{high:g} is wider than a float holds (HIGH - LOW overflows); "
                         "give the returns' real range.")
    return low, high


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
