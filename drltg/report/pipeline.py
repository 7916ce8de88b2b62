"""The pipeline: read both sides, check, align, score, compute the metrics, describe, write."""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

from drltg.analysis.figure_style import DEFAULT, FigureStyle
from drltg.report.align import align
from drltg.report.checks import check_runs, nothing_learned
from drltg.report.curves import Curve, read_curves
from drltg.report.describe import describe, plot_curves
from drltg.report.inference import metric_values, records_of, trend
from drltg.report.outputs import check_out_dir, fresh_dir, render
from drltg.report.scores import score_runs, stack
from drltg.report.settings import ReportSettings, settings_of
from drltg.store import rundir


def transfer_report(
    baseline: str | Path | Sequence[str | Path] | Sequence[Curve],
    transfer: str | Path | Sequence[str | Path] | Sequence[Curve],
    out_dir: str | Path | None = None,
    *,
    figure: FigureStyle = DEFAULT,
    **settings,
) -> dict:
    """Read both run sets, compute the metrics, write the four report files; return the JSON object.

    ``baseline`` and ``transfer`` are paths (runs, directories of runs, globs) or lists of
    :class:`~drltg.report.curves.Curve`. ``out_dir`` defaults to a fresh folder named after the runs in the
    working directory. Keyword settings are those of ``drltg report`` (``threshold=150`` or ``"80%"``,
    ``budget``, ``crossing``, ``paired``, ``source_frames``, ...: the fields of :class:`ReportSettings`);
    ``figure`` how the plot is drawn (size, style, DPI, format: :class:`~drltg.analysis.figure_style.FigureStyle`).
    The returned dict also holds ``"scores"`` (the per-seed DataFrame) and ``"out_dir"``.
    """
    s = settings_of(settings)
    if out_dir is not None:
        check_out_dir(Path(out_dir))
    runs = read_runs(baseline, s), read_runs(transfer, s)
    result = compute(*runs, **settings)
    files = render(result, figure)
    st = result["settings"]
    out = Path(out_dir) if out_dir is not None else fresh_dir(
        f"report-{st['transfer_label']}-vs-{st['baseline_label']}", _beside([*runs[0], *runs[1]]))
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
    learned_nothing = nothing_learned(sides, window.threshold, window.budget)
    if learned_nothing:
        warnings.append(learned_nothing)
    described = {**describe(s, sides, window, trends, warnings, metrics), "learned_nothing": bool(learned_nothing)}
    per_seed = {side: records_of(df) for side, df in by_side.items()}
    return {"metrics": metrics, "settings": described, "per_seed": per_seed,
            "scores": scores, "curves": plot_curves(sides, window, scores, described)}


def read_runs(runs, s: ReportSettings) -> list[Curve]:
    """Curves as given, or read from paths with the settings' log format and tag."""
    if isinstance(runs, Curve):
        return [runs]
    if isinstance(runs, (list, tuple)) and runs and all(isinstance(r, Curve) for r in runs):
        return list(runs)
    return read_curves(runs, format=s.format, tag=s.tag)


def report_from_curves(frames, baseline, transfer, *, paired: bool = True, **settings) -> dict:
    """The report of learning curves already in memory, without reading or writing a file.

    ``frames`` is the frame of each evaluation (shape ``(evaluations,)``); ``baseline`` and ``transfer`` hold
    one curve a seed (``(seeds, evaluations)``). ``paired``: row ``i`` of both sides shares seed ``i`` (the
    report then compares the pairs' differences), which needs as many rows on both sides. Keyword settings
    are :func:`transfer_report`'s. Returns the dict ``transfer_metrics.json`` holds: ``metrics`` (with each
    comparison's ``_verdict``), ``settings`` and ``per_seed``."""
    import numpy as np

    from drltg.errors import UsageError

    grid = np.asarray(frames, dtype=np.float64)
    sides = {name: np.atleast_2d(np.asarray(rows, dtype=np.float64)) for name, rows in
             (("baseline", baseline), ("transfer", transfer))}
    if grid.ndim != 1:
        raise UsageError(f"frames must be one frame per evaluation (1-D), got shape {grid.shape}.")
    for name, rows in sides.items():
        if rows.ndim != 2 or rows.shape[1] != len(grid):
            raise UsageError(f"{name} must be seeds x evaluations with {len(grid)} evaluations (one per frame), "
                             f"got shape {rows.shape}.")
    if paired and len(sides["baseline"]) != len(sides["transfer"]):
        raise UsageError(f"paired curves need as many baseline as transfer seeds, got {len(sides['baseline'])} and "
                         f"{len(sides['transfer'])}; pass paired=False for independent runs.")

    def curves(name: str) -> list[Curve]:
        offset = 0 if paired or name == "baseline" else len(sides["baseline"])
        return [Curve(grid, row, f"{name}[{i}]", f"{name}[{i}]", config={"seed": offset + i})
                for i, row in enumerate(sides[name])]

    result = compute(curves("baseline"), curves("transfer"), **settings)
    return {"metrics": result["metrics"], "settings": result["settings"], "per_seed": result["per_seed"]}



def _beside(runs: Sequence[Curve]) -> Path | None:
    """The folder that holds every run (the default report folder lands there, beside the runs, not in the
    working directory), above any run directory; ``None`` for curves that are no files."""
    import os

    files = [Path(c.source).resolve() for c in runs if Path(c.source).is_file()]
    if not files:
        return None
    common = Path(os.path.commonpath([str(f.parent) for f in files]))
    while common != common.parent and any((p / rundir.EVAL).is_file() or (p / rundir.SUMMARY).is_file()
                                          for p in [common, *common.parents]):
        common = common.parent  # never inside a run
    return common if os.access(common, os.W_OK | os.X_OK) else None
