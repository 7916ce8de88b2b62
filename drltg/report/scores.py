"""Stage 3, score: one row of per-seed scores per run, with ``side`` and ``pair`` columns."""
from __future__ import annotations

import numpy as np
import pandas as pd

from drltg.analysis import metrics as M
from drltg.analysis.tables import number
from drltg.errors import UsageError
from drltg.report.align import Window
from drltg.report.checks import Sides, run_name, seed_of
from drltg.report.curves import Curve
from drltg.report.inference import num
from drltg.report.settings import ReportSettings


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
        return num(M.time_to_threshold(frames, y, threshold, stop))
    return num(M.sustained_time_to_threshold(frames, y, threshold, stop, s.sustain))


def _run_scores(c: Curve, w: Window, s: ReportSettings) -> dict:
    r"""Initial performance (mean of the first K evaluations), final performance (mean of the evaluations in
    the asymptote window), area :math:`\int_{start}^{budget} y`, mean return = area / span, time to threshold."""
    k = int(s.jumpstart_window)
    lo, hi = M.final_window(w.start, w.budget, float(s.asymptote_window))
    inside = c.frames <= w.budget
    if inside.sum() < k:
        raise UsageError(
            f"{run_name(c)} has {int(inside.sum())} evaluations within the budget, fewer than --jumpstart-window {k}."
        )
    window = (c.frames >= lo) & (c.frames <= hi)
    if not window.any():
        raise UsageError(
            f"{run_name(c)} has no evaluation in the asymptote window [{number(lo)}, {number(hi)}] frames; "
            "widen --asymptote-window."
        )
    area = M.area_under_curve(c.frames, c.values, w.start, w.budget)
    return dict(
        label=c.label,
        source=str(c.source),
        seed=seed_of(c),
        first_frame=num(c.frames[0]),
        last_frame=num(c.frames[-1]),
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
        times.append(None if crossed is None else num(crossed + source))
    by_side["transfer"]["source_frames"] = num(source)
    by_side["transfer"]["time_to_threshold_with_source"] = pd.Series(times, dtype=object)
