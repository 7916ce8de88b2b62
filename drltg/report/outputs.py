"""Stage 6, write: the text table, JSON, CSV and plot files, written atomically."""
from __future__ import annotations

import json
import os
import re
from pathlib import Path

from drltg.analysis import tables
from drltg.analysis.figure_style import DEFAULT, FigureStyle
from drltg.analysis.stats import ASSUMES
from drltg.analysis.tables import number
from drltg.errors import UsageError
from drltg.report.catalogue import of_kind, table_rows
from drltg.store import rundir


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
    rows = [("metric", "value", f"{round(100 * st['confidence'])}% CI", "CI assumes", "p", "p (Holm)", "note")]
    rows += [(row_label(name, st), _shown(name, value, st["threshold"]), tables.interval((lo, hi)),
              m.get(f"{name}_ci_assumes", "") if tables.interval((lo, hi)) else "", _p(p), _p(adjusted),
              _note(name, st)) for name, value, lo, hi, p, adjusted in metrics_rows(m)]
    table = tables.render(rows, "text", align="lrllrrl").rstrip("\n")
    block = magnitudes_table(result)
    if not block:
        return head + table
    return (f"{head}{block}\n\nevery metric with its own interval and the p-value of that interval's test (the "
            "CI assumes column names it; a worst-case interval can hold 0 where the exact test above decides)\n"
            f"{table}")


def row_label(name: str, st: dict) -> str:
    """A metric's name as a table shows it: ``mean_success_rate_gain`` for ``mean_return_gain`` when the curves
    are ``--tag success_rate``, as the headline names it (the JSON keeps the metric's own key)."""
    tag = st.get("tag")
    if not tag or "return" in tag or "reward" in tag or "return" not in name:
        return name
    return name.replace("return", re.sub(r"\W+", "_", tag).strip("_"))


def magnitudes_table(result: dict, style: str = "text") -> str:
    """The mean differences' verdicts (the exact test's) beside their magnitudes, each column headed by what it
    assumes: the t interval, the median difference's order-statistic interval, and the betting interval as the
    worst case over the declared range; empty where the report gives no verdict."""
    m, st = result["metrics"], result["settings"]
    names = [metric.name for metric in of_kind("difference") if f"{metric.name}_verdict" in m]
    if not names:
        return ""
    level = f"{round(100 * st['confidence'])}%"
    rng = st.get("value_range")
    columns = [("_t_interval", f"mean, {'paired ' if st.get('paired') else ''}t {level}", None),
               ("_median_interval", f"median, order statistics (>= {level})", "_median"),
               ("_ci", "worst case over the declared range" + (f" [{number(rng[0])}, {number(rng[1])}]" if rng else ""),
                None)]
    columns = [c for c in columns if any(m.get(f"{n}{c[0]}_assumes") for n in names)
               and (c[0] != "_ci" or any(m.get(f"{n}_ci_assumes") == ASSUMES["range"] for n in names))]
    assumes = {key: next(m[f"{n}{key}_assumes"] for n in names if m.get(f"{n}{key}_assumes")) for key, *_ in columns}
    rows = [("metric", "verdict (exact test)", *(head for _, head, _ in columns)),
            ("", "assumes exchangeable runs under no effect", *(f"assumes {assumes[key]}" for key, *_ in columns))]
    for n in names:
        p = m[f"{n}_verdict_p"]
        verdict = f"{m[f'{n}_verdict']} ({m[f'{n}_verdict_test']}, p {'< 0.001' if p < 0.001 else f'= {p:.3f}'}"
        if m[f"{n}_verdict"] == "equivalent":  # TOST, unlike the exact test, assumes what a t interval does
            verdict += f", assuming {ASSUMES['normal differences' if st.get('paired') else 'normal scores']}"
        verdict += ")"
        cells = [tables.estimate(m[n] if point is None else m.get(f"{n}{point}"), m.get(f"{n}{key}"))
                 if m.get(f"{n}{key}") else "" for key, _, point in columns]
        rows.append((row_label(n, st), verdict, *cells))
    title = "verdict: each mean difference's exact test, and its magnitudes beside it, each with what it assumes\n"
    return title + tables.render(rows, style).rstrip("\n")


def _p(p) -> str:
    return "" if p is None else "<0.001" if p < 0.001 else f"{p:.3f}"


def _family_line(st: dict) -> str:
    family = st.get("family") or {}
    if not family.get("size"):
        return "family: no p-values (too few seeds or no spread)"
    return (f"family: {family['size']} intervals read together; p (Holm) adjusts each p-value over all "
            f"{family['size']}")


def render(result: dict, figure: FigureStyle = DEFAULT) -> dict[str, bytes]:
    """The report's files as bytes (nothing is written here), the plot drawn as ``figure`` says."""
    from drltg.analysis.plot import files, plot_transfer

    m, st = result["metrics"], result["settings"]
    public = {"metrics": m, "settings": st, "per_seed": result["per_seed"]}
    return {
        "transfer_metrics.json": json_text(public).encode(),
        "transfer_metrics.csv": tables.render(
            [("metric", "value", "ci_low", "ci_high", "p_value", "p_adjusted"), *metrics_rows(m)], "csv").encode(),
        **files("transfer_plot", plot_transfer(result, style=figure)),
    }


def json_text(obj) -> str:
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
