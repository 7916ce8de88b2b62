r"""``drltg report``: did the transfer method help? Metrics, a plot and tables from learning curves.

    drltg report --baseline RUNS... --transfer RUNS... [--threshold 150 | --threshold 80%] [--out DIR]
    drltg report --matrix DIR [--metric transfer_ratio] [--out DIR]

Both sides are read with :func:`drltg.curves.read_curves` (run directories, directories of seed runs,
globs, SB3 / TensorBoard / CSVLogger logs). Curves are compared on the target task over a common
interval ``[start, budget]``: ``start`` is the latest first evaluation of any run (frame 0 for drltg
runs), ``budget`` the shortest run's last evaluation unless ``--budget`` sets it; nothing is invented
past a run's last evaluation. Every score is computed per seed, then aggregated over seeds (B =
baseline, T = transfer, L = mean over seeds; formulas in :mod:`drltg.metrics`):

``jumpstart``                 L(mean of the first K evaluations of T) - L(same of B)
``asymptotic_performance``    L(mean of T's evaluations in [budget - FRAC (budget - start), budget]) - same of B
``total_reward_<side>``       L(A), A = trapezoid area under the curve on the real frame axis over
                              [start, budget] (the value at the budget interpolated between evaluations)
``transfer_ratio``            (L(A_T) - L(A_B)) / |L(A_B)| = A_T / A_B - 1 when A_B > 0; stays positive
                              for a better transfer curve when A_B < 0; null (with a warning) when
                              |L(A_B)| <= 0.01 x (budget - start) x max |y|
``time_to_threshold_<side>``  median over seeds of the first evaluation frame <= budget whose (raw, or
                              ``--smooth`` W) value is >= threshold; a seed that never reaches it counts
                              as infinitely late, and null means "not reached" (the median is infinite)
``threshold_reached_<side>``  fraction of seeds that reach the threshold within the budget
``initial_performance_<side>``, ``final_performance_<side>``  the per-side terms of the two differences
``probability_of_improvement`` P(T > B) = mean over all (baseline seed, transfer seed) pairs of
                              1[a_T > a_B] + 0.5 x 1[a_T = a_B], on the areas (``_initial``, ``_final``:
                              on the initial / final performances)
``<name>_iqm``                the same difference with the interquartile mean over seeds as L
``<name>_ci``                 percentile bootstrap interval (each side's seeds resampled with replacement,
                              ``--bootstrap`` N times, seeded by ``--seed``), where both sides have >= 2 seeds
``n_seeds_baseline``, ``n_seeds_transfer``

Options: ``--baseline``/``--transfer`` PATH... (runs, directories of seed runs, files or globs),
``--format`` {auto,drltg,sb3,sb3-monitor,tensorboard,csvlogger}, ``--tag`` (column or scalar tag),
``--threshold`` (a number, or ``P%`` of the highest value of the baseline's mean-over-seeds curve),
``--budget`` FRAMES, ``--jumpstart-window`` K (default 1), ``--asymptote-window`` FRAC (default 0.1),
``--smooth`` W (trailing moving average before time-to-threshold), ``--plot-smooth`` W (drawn lines
only), ``--bootstrap`` N (10000), ``--confidence`` (0.95), ``--seed`` (0), ``--baseline-label``,
``--transfer-label``, ``--out`` DIR (default: a fresh ``report-<transfer>-vs-<baseline>`` folder in the
working directory), ``--matrix`` DIR with ``--metric`` NAME.

Outputs (written through temporary files and ``os.replace``, and only once every input is read and
checked): ``transfer_metrics.json`` (``metrics``, ``settings`` with every choice and warning,
``per_seed``), ``transfer_metrics.csv`` (``metric,value,ci_low,ci_high``), ``transfer_plot.png`` and
``.svg``; ``--matrix`` writes ``transfer_matrix.{png,svg,csv,json}``.
"""
from __future__ import annotations

import argparse
import csv
import io
import json
import math
import os
import re
import sys
from pathlib import Path
from typing import Iterable, Sequence

import numpy as np

from drltg import metrics as M
from drltg.curves import FORMATS, Curve, read_curves
from drltg.errors import UsageError

DIFFERENCES = ("jumpstart", "asymptotic_performance", "transfer_ratio")
MAX_LENGTH_RATIO = 2.0  # longest / shortest run beyond which a default budget would hide too much
PLOT_POINTS = 100  # the display line is smoothed to about this many evaluation windows

SETTINGS_DEFAULTS = dict(
    format="auto",
    tag=None,
    threshold=None,
    budget=None,
    jumpstart_window=1,
    asymptote_window=0.1,
    smooth=None,
    plot_smooth=None,
    bootstrap=10_000,
    confidence=0.95,
    seed=0,
    ratio_eps=0.01,
    baseline_label=None,
    transfer_label=None,
)


# ------------------------------------------------------------------------------------------ compute
def _parse_threshold(threshold) -> tuple[float | None, float | None]:
    """``150`` -> (150, None); ``"80%"`` -> (None, 0.8)."""
    if threshold is None:
        return None, None
    if isinstance(threshold, str):
        text = threshold.strip()
        try:
            if text.endswith("%"):
                return None, float(text[:-1]) / 100.0
            return float(text), None
        except ValueError:
            raise UsageError(
                f"--threshold '{threshold}' is neither a number (e.g. 150) nor a percentage of the best "
                "baseline performance (e.g. 80%)."
            ) from None
    return float(threshold), None


def parse_frames(text) -> float | None:
    """``"1e6"``, ``"500k"``, ``"1.5M"`` -> frames."""
    if text is None or isinstance(text, (int, float)):
        return text
    m = re.fullmatch(r"\s*([0-9.eE+-]+)\s*([kKmM]?)\s*", str(text))
    try:
        value = float(m.group(1)) * {"": 1, "k": 1e3, "m": 1e6}[m.group(2).lower()]
    except (AttributeError, ValueError):
        raise UsageError(f"--budget '{text}' is not a number of frames (e.g. 200000, 200k, 1.5M).") from None
    return value


def _name(curve: Curve) -> str:
    return f"'{curve.label}' ({curve.source})"


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


def _interval(curves: Sequence[Curve], budget: float | None, warnings: list[str]) -> tuple[float, float, str]:
    start = max(c.frames[0] for c in curves)
    firsts = sorted({c.frames[0] for c in curves})
    if len(firsts) > 1:
        warnings.append(
            f"runs start at different frames ({_fmt(firsts[0])} to {_fmt(firsts[-1])}); areas and "
            f"the asymptote window start at frame {_fmt(start)}."
        )
    shortest = min(curves, key=lambda c: c.frames[-1])
    longest = max(curves, key=lambda c: c.frames[-1])
    if budget is None:
        budget, source = float(shortest.frames[-1]), "the shortest run's last evaluation"
        if longest.frames[-1] > MAX_LENGTH_RATIO * budget:
            raise UsageError(
                f"run lengths differ too much: {_name(shortest)} ends at frame {_fmt(budget)} but "
                f"{_name(longest)} at {_fmt(longest.frames[-1])}; pass --budget FRAMES to compare "
                "over a budget you choose."
            )
    else:
        budget, source = float(budget), "--budget"
        if shortest.frames[-1] < budget:
            raise UsageError(
                f"{_name(shortest)} ends at frame {_fmt(shortest.frames[-1])}, before the budget of "
                f"{_fmt(budget)} frames; lower --budget (points are never invented past a run's end)."
            )
    if budget <= start:
        raise UsageError(
            f"the budget ({_fmt(budget)} frames) must lie after the latest first evaluation "
            f"({_fmt(start)}, in {_name(max(curves, key=lambda c: c.frames[0]))})."
        )
    cut = [c for c in curves if c.frames[-1] > budget]
    if cut:
        warnings.append(
            f"{len(cut)} of {len(curves)} runs truncated to the common budget of {_fmt(budget)} frames: "
            + ", ".join(f"{c.label} (ends at {_fmt(c.frames[-1])})" for c in cut) + "."
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


def _scores(curves, *, start, budget, k, fraction, threshold, smooth) -> list[dict]:
    lo, hi = M.final_window(start, budget, fraction)
    out = []
    for c in curves:
        inside = c.frames <= budget
        if inside.sum() < k:
            raise UsageError(
                f"{_name(c)} has {int(inside.sum())} evaluations within the budget, fewer than "
                f"--jumpstart-window {k}."
            )
        window = (c.frames >= lo) & (c.frames <= hi)
        if not window.any():
            raise UsageError(
                f"{_name(c)} has no evaluation in the asymptote window [{_fmt(lo)}, {_fmt(hi)}] frames; "
                "widen --asymptote-window."
            )
        y = M.moving_average(c.values, smooth) if smooth and smooth > 1 else c.values
        out.append(dict(
            label=c.label,
            source=str(c.source),
            first_frame=_num(c.frames[0]),
            last_frame=_num(c.frames[-1]),
            initial_performance=M.initial_performance(c.values[inside], k),
            final_performance=float(c.values[window].mean()),
            total_reward=M.area_under_curve(c.frames, c.values, start, budget),
            time_to_threshold=None if threshold is None else _num(M.time_to_threshold(c.frames, y, threshold, budget)),
        ))
    return out


def compute(
    baseline: Sequence[Curve],
    transfer: Sequence[Curve],
    **settings,
) -> dict:
    """Metrics of ``transfer`` against ``baseline`` (lists of curves, one per seed), without writing.

    Returns ``{"metrics", "settings", "per_seed", "curves"}``; ``curves`` holds the arrays the plot
    draws. Keyword settings: see ``SETTINGS_DEFAULTS`` and ``add_arguments``.
    """
    unknown = set(settings) - set(SETTINGS_DEFAULTS)
    if unknown:
        raise TypeError(f"unknown report settings: {', '.join(sorted(unknown))}")
    s = {**SETTINGS_DEFAULTS, **settings}
    baseline, transfer = list(baseline), list(transfer)
    if not baseline or not transfer:
        raise UsageError("both a baseline and a transfer run set are needed.")
    k, fraction, smooth = int(s["jumpstart_window"]), float(s["asymptote_window"]), s["smooth"]
    if k < 1:
        raise UsageError(f"--jumpstart-window must be at least 1, got {k}.")
    if not 0.0 < fraction <= 1.0:
        raise UsageError(f"--asymptote-window must lie in (0, 1], got {fraction}.")
    if smooth is not None and int(smooth) < 1:
        raise UsageError(f"--smooth must be at least 1 evaluation, got {smooth}.")
    if not 0.0 < float(s["confidence"]) < 1.0:
        raise UsageError(f"--confidence must lie in (0, 1), got {s['confidence']}.")
    if int(s["bootstrap"]) < 100:
        raise UsageError(f"--bootstrap needs at least 100 resamples, got {s['bootstrap']}.")
    smooth = int(smooth) if smooth else None
    warnings: list[str] = []
    task = _check_tasks(baseline, transfer)
    start, budget, budget_source = _interval(baseline + transfer, parse_frames(s["budget"]), warnings)
    no_zero = [c for c in baseline + transfer if c.frames[0] > 0]
    if no_zero:
        frames = sorted({c.frames[0] for c in no_zero})
        warnings.append(
            f"{len(no_zero)} of {len(baseline) + len(transfer)} runs have no frame-0 evaluation; the "
            f"jumpstart compares their first {k} evaluation(s) (from frame {_fmt(frames[0])})."
        )

    absolute, frac = _parse_threshold(s["threshold"])
    grid_b = _grid(baseline, start, budget)
    if frac is not None:
        best = float(_on_grid(baseline, grid_b, smooth).mean(axis=0).max())
        if best <= 0:
            raise UsageError(
                f"--threshold {s['threshold']} is a fraction of the best baseline performance, which is "
                f"{best:.4g} (not positive); give an absolute threshold instead."
            )
        absolute = frac * best
    threshold = absolute

    common = dict(start=start, budget=budget, k=k, fraction=fraction, threshold=threshold, smooth=smooth)
    per_b, per_t = _scores(baseline, **common), _scores(transfer, **common)
    col = lambda rows, key: np.array([r[key] for r in rows], dtype=np.float64)  # noqa: E731
    ib, it = col(per_b, "initial_performance"), col(per_t, "initial_performance")
    fb, ft = col(per_b, "final_performance"), col(per_t, "final_performance")
    ab, at = col(per_b, "total_reward"), col(per_t, "total_reward")
    scale = (budget - start) * max(
        float(np.abs(c.values[(c.frames >= start) & (c.frames <= budget)]).max()) for c in baseline + transfer
    )
    eps = float(s["ratio_eps"])

    m: dict = {"n_seeds_baseline": len(baseline), "n_seeds_transfer": len(transfer)}
    m["jumpstart"] = M.jumpstart(ib, it)
    m["asymptotic_performance"] = M.asymptotic_performance(fb, ft)
    m["total_reward_baseline"] = float(ab.mean())
    m["total_reward_transfer"] = float(at.mean())
    m["transfer_ratio"] = M.transfer_ratio(ab, at, scale=scale, eps=eps)
    if m["transfer_ratio"] is None:
        warnings.append(
            f"the baseline area ({ab.mean():.4g}) is within {eps:g} of the largest possible area "
            f"({scale:.4g}) from zero, so transfer_ratio is undefined (null); compare total_reward_* instead."
        )
    ttt = {}
    for side, rows in (("baseline", per_b), ("transfer", per_t)):
        times = [r["time_to_threshold"] for r in rows]
        ttt[side] = times
        m[f"time_to_threshold_{side}"] = None if threshold is None else _num(M.censored_median(times))
        m[f"threshold_reached_{side}"] = (
            None if threshold is None else sum(t is not None for t in times) / len(times)
        )
    m["initial_performance_baseline"], m["initial_performance_transfer"] = float(ib.mean()), float(it.mean())
    m["final_performance_baseline"], m["final_performance_transfer"] = float(fb.mean()), float(ft.mean())
    m["probability_of_improvement"] = M.probability_of_improvement(ab, at)
    m["probability_of_improvement_initial"] = M.probability_of_improvement(ib, it)
    m["probability_of_improvement_final"] = M.probability_of_improvement(fb, ft)
    iqm = M.interquartile_mean
    m["jumpstart_iqm"] = M.jumpstart(ib, it, location=iqm)
    m["asymptotic_performance_iqm"] = M.asymptotic_performance(fb, ft, location=iqm)
    m["transfer_ratio_iqm"] = M.transfer_ratio(ab, at, location=iqm, scale=scale, eps=eps)

    boot = dict(n_resamples=int(s["bootstrap"]), confidence=float(s["confidence"]), seed=int(s["seed"]))
    if len(baseline) >= 2 and len(transfer) >= 2:
        diff = M.difference_statistic()
        for name, b, t, stat in (
            ("jumpstart", ib, it, diff),
            ("asymptotic_performance", fb, ft, diff),
            ("transfer_ratio", ab, at, M.ratio_statistic(scale=scale, eps=eps)),
            ("probability_of_improvement", ab, at, M.poi_statistic),
            ("probability_of_improvement_initial", ib, it, M.poi_statistic),
            ("probability_of_improvement_final", fb, ft, M.poi_statistic),
        ):
            lo, hi = M.bootstrap_ci(stat, b, t, **boot)
            m[f"{name}_ci"] = None if math.isnan(lo) else [lo, hi]
    else:
        warnings.append(
            f"confidence intervals need at least 2 seeds per side (got {len(baseline)} baseline, "
            f"{len(transfer)} transfer); none are reported."
        )

    labels = {
        "baseline": s["baseline_label"] or _side_label(baseline, "baseline"),
        "transfer": s["transfer_label"] or _side_label(transfer, "transfer"),
    }
    lo, hi = M.final_window(start, budget, fraction)
    settings_out = {
        "baseline": [str(c.source) for c in baseline],
        "transfer": [str(c.source) for c in transfer],
        "baseline_label": labels["baseline"],
        "transfer_label": labels["transfer"],
        "task": task,
        "format": s["format"],
        "tag": s["tag"],
        "start": _num(start),
        "budget": _num(budget),
        "budget_source": budget_source,
        "jumpstart_window": k,
        "asymptote_window": fraction,
        "asymptote_frames": [_num(lo), _num(hi)],
        "threshold": threshold,
        "threshold_given": s["threshold"],
        "threshold_basis": None if threshold is None else (
            "absolute" if frac is None else f"{frac:g} x best baseline mean performance ({best:.6g})"
        ),
        "smooth": smooth,
        "ratio_eps": eps,
        "ratio_scale": scale,
        "bootstrap": boot["n_resamples"],
        "confidence": boot["confidence"],
        "seed": boot["seed"],
        "location": "mean over seeds (and interquartile mean in *_iqm)",
        "warnings": warnings,
    }
    n_evals = int(np.median([int((c.frames <= budget).sum()) for c in baseline + transfer]))
    w = s["plot_smooth"] or smooth or max(1, n_evals // PLOT_POINTS)
    settings_out["plot_smooth"] = w
    curves = {}
    for side, runs, grid in (("baseline", baseline, grid_b), ("transfer", transfer, _grid(transfer, start, budget))):
        ys = _on_grid(runs, grid, w)
        band = None
        if len(runs) >= 2:
            band = _band(ys, boot)
        curves[side] = dict(grid=grid, mean=ys.mean(axis=0), band=band, smooth=w,
                            runs=[(c.frames, c.values) for c in runs], times=ttt[side])
    return {"metrics": m, "settings": settings_out, "per_seed": {"baseline": per_b, "transfer": per_t},
            "curves": curves}


def _band(ys: np.ndarray, boot: dict, chunk: int = 64) -> tuple[np.ndarray, np.ndarray]:
    """Bootstrap interval of the mean over seeds at every grid point (same resamples everywhere)."""
    lows, highs = [], []
    for j in range(0, ys.shape[1], chunk):
        lo, hi = M.bootstrap_ci(lambda x: x.mean(axis=1), ys[:, j:j + chunk], **boot)
        lows.append(lo), highs.append(hi)
    return np.concatenate(lows), np.concatenate(highs)


def _side_label(curves: Sequence[Curve], default: str) -> str:
    if len(curves) == 1:
        return curves[0].label
    parents = {Path(c.source).resolve().parent.parent if Path(c.source).is_file()
               else Path(c.source).resolve().parent for c in curves}
    name = parents.pop().name if len(parents) == 1 else ""
    return name or default


# ------------------------------------------------------------------------------------------ outputs
def _num(x):
    if x is None:
        return None
    x = float(x)
    return int(x) if x.is_integer() and abs(x) < 2**53 else x


def _fmt(x, digits: int = 4) -> str:
    if x is None:
        return "not reached"
    x = float(x)
    if x.is_integer() and abs(x) >= 1000:
        return f"{int(x):,}"
    return f"{x:.{digits}g}"


METRIC_ORDER = (
    "jumpstart", "asymptotic_performance", "transfer_ratio",
    "total_reward_baseline", "total_reward_transfer",
    "time_to_threshold_baseline", "time_to_threshold_transfer",
    "threshold_reached_baseline", "threshold_reached_transfer",
    "initial_performance_baseline", "initial_performance_transfer",
    "final_performance_baseline", "final_performance_transfer",
    "probability_of_improvement", "probability_of_improvement_initial", "probability_of_improvement_final",
    "jumpstart_iqm", "asymptotic_performance_iqm", "transfer_ratio_iqm",
    "n_seeds_baseline", "n_seeds_transfer",
)


def metrics_rows(metrics: dict) -> list[tuple[str, object, object, object]]:
    """``(metric, value, ci_low, ci_high)`` rows in a fixed order."""
    rows = []
    for name in METRIC_ORDER:
        ci = metrics.get(f"{name}_ci") or (None, None)
        rows.append((name, metrics[name], ci[0], ci[1]))
    return rows


def format_table(result: dict) -> str:
    """The metrics as an aligned text table."""
    m, st = result["metrics"], result["settings"]
    conf = f"{round(100 * st['confidence'])}% CI"
    lines = [
        f"{st['transfer_label']} (transfer, {m['n_seeds_transfer']} seed(s)) vs "
        f"{st['baseline_label']} (baseline, {m['n_seeds_baseline']} seed(s))"
        + (f" on {st['task']}" if st["task"] else ""),
        f"budget {_fmt(st['budget'])} frames from frame {_fmt(st['start'])}"
        + ("" if st["threshold"] is None else f"; threshold {st['threshold']:.4g}"),
    ]
    rows = [("metric", "value", conf)]
    for name, value, lo, hi in metrics_rows(m):
        if name.startswith("time_to_threshold") and st["threshold"] is None:
            shown = "-"
        elif name.startswith("threshold_reached") and value is None:
            shown = "-"
        elif value is None:
            shown = "null" if not name.startswith("time_to") else "not reached"
        else:
            shown = _fmt(value)
        rows.append((name, shown, "" if lo is None else f"[{_fmt(lo)}, {_fmt(hi)}]"))
    w0, w1 = max(len(r[0]) for r in rows), max(len(r[1]) for r in rows)
    lines.append("")
    lines += [f"{a:<{w0}}  {b:>{w1}}  {c}".rstrip() for a, b, c in rows]
    lines[3:4] = [lines[3], "-" * len(lines[3])]
    return "\n".join(lines)


def _csv_text(rows: Iterable[Sequence]) -> str:
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    for row in rows:
        writer.writerow(["" if v is None else v for v in row])
    return buf.getvalue()


def _json_text(obj) -> str:
    return json.dumps(obj, indent=2, allow_nan=False) + "\n"


def _atomic_write(path: Path, data: bytes) -> None:
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_files(out_dir: Path, files: dict[str, bytes]) -> None:
    """Create ``out_dir`` and write every file through a temporary file and ``os.replace``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    for name, data in files.items():
        _atomic_write(out_dir / name, data)


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


def render(result: dict) -> dict[str, bytes]:
    """The report's files as bytes (nothing is written here)."""
    from drltg.report_plot import plot_transfer

    m, st = result["metrics"], result["settings"]
    public = {"metrics": m, "settings": st, "per_seed": result["per_seed"]}
    png, svg = plot_transfer(result)
    return {
        "transfer_metrics.json": _json_text(public).encode(),
        "transfer_metrics.csv": _csv_text([("metric", "value", "ci_low", "ci_high"),
                                           *metrics_rows(m)]).encode(),
        "transfer_plot.png": png,
        "transfer_plot.svg": svg,
    }


def transfer_report(
    baseline: str | Path | Sequence[str | Path] | Sequence[Curve],
    transfer: str | Path | Sequence[str | Path] | Sequence[Curve],
    out_dir: str | Path | None = None,
    **settings,
) -> dict:
    """Read both run sets, compute the metrics, write the four report files; return the JSON object.

    ``baseline`` and ``transfer`` are paths (runs, directories of runs, globs) or lists of
    :class:`~drltg.curves.Curve`. ``out_dir`` defaults to a fresh folder named after the runs in the
    working directory. Keyword settings are those of ``drltg report`` (``threshold=150`` or ``"80%"``,
    ``budget``, ``jumpstart_window``, ``asymptote_window``, ``smooth``, ``plot_smooth``, ``format``,
    ``tag``, ``bootstrap``, ``confidence``, ``seed``, ``ratio_eps``, ``baseline_label``,
    ``transfer_label``). The returned dict also holds ``"out_dir"``.
    """
    read = dict(format=settings.get("format", "auto"), tag=settings.get("tag"))
    runs_b = _as_curves(baseline, **read)
    runs_t = _as_curves(transfer, **read)
    result = compute(runs_b, runs_t, **settings)
    files = render(result)
    st = result["settings"]
    out = Path(out_dir) if out_dir is not None else fresh_dir(
        f"report-{st['transfer_label']}-vs-{st['baseline_label']}")
    write_files(out, files)
    return {"metrics": result["metrics"], "settings": st, "per_seed": result["per_seed"],
            "out_dir": str(out)}


def _as_curves(runs, format: str, tag: str | None) -> list[Curve]:
    if isinstance(runs, Curve):
        return [runs]
    if isinstance(runs, (list, tuple)) and runs and all(isinstance(r, Curve) for r in runs):
        return list(runs)
    return read_curves(runs, format=format, tag=tag)


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


MATRIX_METRICS = ("jumpstart", "asymptotic_performance", "transfer_ratio", "total_reward_transfer",
                  "time_to_threshold_transfer", "probability_of_improvement")


def transfer_matrix(
    cells: dict[tuple[str, str], tuple],
    out_dir: str | Path | None = None,
    metric: str = "transfer_ratio",
    **settings,
) -> dict:
    """One report per (source, target) cell, summarised as a heatmap of ``metric`` plus CSV and JSON."""
    if metric not in METRIC_ORDER:
        raise UsageError(f"unknown --metric '{metric}'; choose one of {', '.join(METRIC_ORDER)}.")
    read = dict(format=settings.get("format", "auto"), tag=settings.get("tag"))
    results = {}
    for (source, target), (b, t) in sorted(cells.items()):
        results[(source, target)] = compute(_as_curves(b, **read), _as_curves(t, **read), **settings)
    sources = sorted({s for s, _ in results})
    targets = sorted({t for _, t in results})
    table = np.full((len(sources), len(targets)), np.nan)
    for (s, t), r in results.items():
        v = r["metrics"][metric]
        table[sources.index(s), targets.index(t)] = np.nan if v is None else v
    from drltg.report_plot import plot_matrix

    png, svg = plot_matrix(table, sources, targets, metric)
    grid_csv = _csv_text([("source", *targets)] + [
        (s, *(None if np.isnan(v) else float(v) for v in row)) for s, row in zip(sources, table)
    ])
    obj = {
        "metric": metric,
        "cells": [{"source": s, "target": t, "metrics": r["metrics"], "settings": r["settings"]}
                  for (s, t), r in results.items()],
    }
    out = Path(out_dir) if out_dir is not None else fresh_dir(f"matrix-{metric}")
    write_files(out, {
        "transfer_matrix.csv": grid_csv.encode(),
        "transfer_matrix.json": _json_text(obj).encode(),
        "transfer_matrix.png": png,
        "transfer_matrix.svg": svg,
    })
    return {**obj, "out_dir": str(out), "table": table.tolist(), "sources": sources, "targets": targets}


# ---------------------------------------------------------------------------------------------- CLI
def add_arguments(parser: argparse.ArgumentParser) -> None:
    io_ = parser.add_argument_group("runs")
    io_.add_argument("--baseline", nargs="+", metavar="PATH",
                     help="baseline (no transfer) runs: run dirs, a dir of seed runs, log files or globs")
    io_.add_argument("--transfer", nargs="+", metavar="PATH", help="transfer runs, same forms as --baseline")
    io_.add_argument("--matrix", metavar="DIR",
                     help="DIR/<source>/<target>/{baseline,transfer}: a heatmap of --metric over all pairs")
    io_.add_argument("--metric", default="transfer_ratio", help="metric for the --matrix heatmap "
                     "(default: transfer_ratio)")
    io_.add_argument("--format", choices=FORMATS, default="auto", help="log format (default: auto-detect)")
    io_.add_argument("--tag", help="column / scalar tag to read (defaults: return_mean in eval.csv, "
                     "eval/mean_reward in progress.csv, r in monitor.csv, eval/return_mean or "
                     "eval/mean_reward in TensorBoard / CSVLogger logs)")
    io_.add_argument("--out", metavar="DIR", help="output folder (default: a fresh folder named after the runs)")
    io_.add_argument("--baseline-label", help="name of the baseline in the plot and table")
    io_.add_argument("--transfer-label", help="name of the transfer runs in the plot and table")
    mt = parser.add_argument_group("metrics")
    mt.add_argument("--threshold", help="return to reach for time-to-threshold: a number (150) or a "
                    "percentage of the best baseline mean performance (80%%)")
    mt.add_argument("--budget", help="compare over the first FRAMES frames (default: the shortest run's "
                    "last evaluation); accepts 200000, 200k, 1.5M")
    mt.add_argument("--jumpstart-window", type=int, default=1, metavar="K",
                    help="jumpstart = mean of the first K evaluations (default: 1)")
    mt.add_argument("--asymptote-window", type=float, default=0.1, metavar="FRAC",
                    help="asymptotic performance = mean over the last FRAC of the budget (default: 0.1)")
    mt.add_argument("--smooth", type=int, metavar="W", help="moving average over W evaluations before "
                    "time-to-threshold (and a fractional threshold's best baseline); default: raw curve")
    mt.add_argument("--plot-smooth", type=int, metavar="W", help="moving average for the plotted lines "
                    f"only (default: --smooth, else about {PLOT_POINTS} windows per curve; 1 = raw)")
    mt.add_argument("--bootstrap", type=int, default=10_000, metavar="N",
                    help="bootstrap resamples of the seeds (default: 10000)")
    mt.add_argument("--confidence", type=float, default=0.95, help="confidence level (default: 0.95)")
    mt.add_argument("--seed", type=int, default=0, help="bootstrap seed (default: 0)")


def _settings_from(args) -> dict:
    return dict(
        format=args.format, tag=args.tag, threshold=args.threshold, budget=args.budget,
        jumpstart_window=args.jumpstart_window, asymptote_window=args.asymptote_window,
        smooth=args.smooth, plot_smooth=args.plot_smooth, bootstrap=args.bootstrap,
        confidence=args.confidence, seed=args.seed, baseline_label=args.baseline_label,
        transfer_label=args.transfer_label,
    )


def run(args) -> int:
    settings = _settings_from(args)
    if args.matrix:
        if args.baseline or args.transfer:
            raise UsageError("--matrix builds its own baseline/transfer pairs; drop --baseline and --transfer.")
        settings.pop("baseline_label"), settings.pop("transfer_label")
        result = transfer_matrix(find_matrix_cells(args.matrix), args.out, args.metric, **settings)
        for cell in result["cells"]:
            for w in cell["settings"]["warnings"]:
                print(f"warning: {cell['source']} -> {cell['target']}: {w}", file=sys.stderr)
        rows = [("source \\ target", *result["targets"])] + [
            (s, *("-" if math.isnan(v) else f"{v:.4g}" for v in row))
            for s, row in zip(result["sources"], result["table"])]
        widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
        print(f"{args.metric}:")
        for r in rows:
            print("  ".join(c.rjust(w) if i else c.ljust(w) for i, (c, w) in enumerate(zip(r, widths))))
        print(f"wrote {result['out_dir']}/transfer_matrix.{{png,svg,csv,json}}")
        return 0
    if not args.baseline or not args.transfer:
        raise UsageError("give both --baseline and --transfer runs (or --matrix DIR).")
    result = transfer_report(args.baseline, args.transfer, args.out, **settings)
    for w in result["settings"]["warnings"]:
        print(f"warning: {w}", file=sys.stderr)
    print(format_table(result))
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
