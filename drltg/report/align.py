"""Stage 2, align: every curve on one evaluation window ``[start, budget]``, nothing invented past a
run's last evaluation."""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from drltg import safe_yaml
from drltg.analysis import metrics as M
from drltg.analysis import stats
from drltg.analysis.tables import number
from drltg.errors import UsageError
from drltg.report.checks import Sides, run_name
from drltg.report.curves import Curve
from drltg.report.settings import MAX_LENGTH_RATIO, ReportSettings, parse_frames, parse_threshold, task_returns
from drltg.store.rundir import DEMONSTRATOR, EVAL, SUMMARY


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
    grid = eval_grid(runs, start, budget)
    largest = max(float(np.abs(np.interp(grid, c.frames, c.values)).max()) for c in runs)
    scale = (budget - start) * largest
    if not math.isfinite(scale * len(grid)):
        raise UsageError(f"values up to {largest:.3g} over {number(budget - start)} frames overflow the areas' "
                         "float64 range; rescale the curves (e.g. report them in other units).")
    _check_grids(sides, start, budget, warnings)
    return Window(start, budget, budget_source, threshold, basis, source_frames, source_basis, scale,
                  _value_range(runs, s, warnings))


def _value_range(runs: Sequence[Curve], s: ReportSettings, warnings: list[str]) -> tuple[float, float] | None:
    """``value_range`` as given, else [0, 1] for a rate (``RATE_SUFFIX``), else the return range the runs' task
    declares for their env options (drltg runs' returns: :meth:`TaskSpec.return_range`); ``None`` when unknown, or
    when a run's values leave the range (then a warning names it)."""
    given = s.value_range
    if given is None and s.tag and str(s.tag).split("/")[-1].endswith(RATE_SUFFIX):
        given = (0.0, 1.0)
    if given is None and s.task is not None:  # the user names the task foreign logs of its returns come from
        given = task_returns(s.task)
    if given is None and s.tag in (None, "return_mean"):
        given = _task_returns(runs)
    if given is None:
        return None
    lo, hi = float(given[0]), float(given[1])
    tol = stats.RANGE_TOLERANCE * (hi - lo)
    outside = next((c for c in runs if c.values.min() < lo - tol or c.values.max() > hi + tol), None)
    if outside is not None:
        warnings.append(f"{run_name(outside)} has values outside [{lo:g}, {hi:g}], so the intervals are not "
                        "bounded to that range.")
        return None
    return lo, hi


def _task_returns(runs: Sequence[Curve]) -> tuple[float, float] | None:
    """The one return range every run's task declares for its env options (``None`` for a foreign log, a task
    this process does not know, or runs whose ranges differ)."""
    from drltg.envs.registry import TASKS

    ranges = set()
    for c in runs:
        task = (c.config or {}).get("task")
        if not c.source.name == EVAL or task not in TASKS:
            return None
        ranges.add(TASKS[task].return_range((c.config or {}).get("env")))
    return ranges.pop() if len(ranges) == 1 else None


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
                f"the runs are evaluated on different grids: {run_name(a)} every {number(sa)} frames, {run_name(b)} "
                f"every {number(sb)}; areas are taken on the real frame axis, but initial and final "
                "performance average different numbers of evaluations.")
    gaps = [(c, float(np.diff(c.frames[(c.frames >= start) & (c.frames <= budget)]).max()), x) for c, x in spaced]
    gapped = [(c, gap, x) for c, gap, x in gaps if gap > 2.5 * x]  # x: the run's median spacing
    if gapped:
        c, gap, x = max(gapped, key=lambda g: g[1] / g[2])
        warnings.append(f"{len(gapped)} run(s) skip evaluations: {run_name(c)} has a gap of {number(gap)} frames "
                        f"where it is evaluated every {number(x)}; the curve is interpolated across it.")
    counted = [(c, _episodes(c)) for c in sides.runs if isinstance(_episodes(c), int)]
    if counted and len({e for _, e in counted}) > 1:
        (a, ea), (b, eb) = min(counted, key=lambda x: x[1]), max(counted, key=lambda x: x[1])
        warnings.append(f"the runs' evaluations average different numbers of episodes: {run_name(a)} {ea}, "
                        f"{run_name(b)} {eb}; their values are comparable in expectation, not in noise.")


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
            source = (f"the range every run covers: from {run_name(latest)}'s first evaluation (frame "
                      f"{number(start)}) to {run_name(shortest)}'s last (frame {number(budget)})")
        elif longest.frames[-1] > MAX_LENGTH_RATIO * budget:
            raise UsageError(
                f"run lengths differ too much: {run_name(shortest)} ends at frame {number(budget)} but "
                f"{run_name(longest)} at {number(longest.frames[-1])}; pass --budget FRAMES to compare "
                "over a budget you choose."
            )
    else:
        budget, source = float(budget), "--budget"
        if shortest.frames[-1] < budget:
            raise UsageError(
                f"{run_name(shortest)} ends at frame {number(shortest.frames[-1])}, before the budget of "
                f"{number(budget)} frames; lower --budget (points are never invented past a run's end)."
            )
    if budget <= start:
        raise UsageError(
            f"the budget ({number(budget)} frames) must lie after the latest first evaluation "
            f"({number(start)}, in {run_name(max(curves, key=lambda c: c.frames[0]))})."
        )
    cut = [c for c in curves if c.frames[-1] > budget]
    if cut:
        warnings.append(
            f"{len(cut)} of {len(curves)} runs truncated to the common budget of {number(budget)} frames"
            + ("" if source == "--budget" else f", where {run_name(shortest)} ends")
            + ": " + ", ".join(f"{c.label} (ends at {number(c.frames[-1])})" for c in cut) + "."
        )
    return float(start), budget, source


def eval_grid(curves: Sequence[Curve], start: float, budget: float) -> np.ndarray:
    frames = np.concatenate([c.frames[(c.frames >= start) & (c.frames <= budget)] for c in curves])
    return np.unique(np.concatenate([[start, budget], frames]))


def on_grid(curves: Sequence[Curve], grid: np.ndarray, smooth: int | None = None) -> np.ndarray:
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
    best = float(on_grid(baseline, eval_grid(baseline, start, budget), smooth).mean(axis=0).max())
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
    frames, stopped = [], False
    for c in transfer:
        if c.config is None:
            return None, "not given: pass --source-frames N for logs without a drltg config.yaml"
        source = (c.config.get("transfer") or {}).get("source")
        if source is None or str(source).startswith(DEMONSTRATOR):
            frames.append(0.0)
            continue
        found, ended = _frames_of_run(Path(c.source).parent, str(source))
        stopped = stopped or ended
        if found is None:
            return None, (f"unknown: the source run '{source}' of {run_name(c)} has no readable config.yaml "
                          "with frames; pass --source-frames N")
        frames.append(found)
    where = ", or those it trained where eval.stop_at_success ended it" if stopped else ""
    return frames, f"the source run's config.yaml frames{where} (transfer.source of each run; 0 without a source run)"


def _frames_of_run(run_dir: Path, source: str) -> tuple[float | None, bool]:
    """The frames behind the source run ``source`` (found from ``run_dir``), and whether eval.stop_at_success
    ended it early."""
    path = Path(source).expanduser()
    for candidate in ([path] if path.is_absolute() else [Path.cwd() / path, run_dir / path, run_dir.parent / path]):
        config = candidate / "config.yaml"
        if config.is_file():
            try:
                frames = (safe_yaml.load(config.read_text(), f"'{config}'") or {}).get("frames")
            except (UsageError, AttributeError):
                return None, False
            stopped = _stopped_at(candidate)
            if stopped is not None:
                return stopped, True
            return (float(frames) if isinstance(frames, (int, float)) else None), False
    return None, False


def _stopped_at(run_dir: Path) -> float | None:
    """The frames a source run trained when ``eval.stop_at_success`` ended it before its budget (its
    summary.json's ``stop_at_success``), else ``None``: its config's frames are the frames it trained."""
    import json

    try:
        stop = json.loads((run_dir / SUMMARY).read_text()).get("stop_at_success") or {}
    except (OSError, ValueError, AttributeError):
        return None
    frames = stop.get("frames") if isinstance(stop, dict) and stop.get("met") else None
    return float(frames) if isinstance(frames, (int, float)) and not isinstance(frames, bool) else None
