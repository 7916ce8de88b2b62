"""``drltg report --matrix``: one metric over every source/target cell, as a heatmap."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from drltg.analysis import tables
from drltg.analysis.figure_style import DEFAULT, FigureStyle
from drltg.errors import UsageError
from drltg.report.catalogue import table_rows
from drltg.report.outputs import check_out_dir, fresh_dir, json_text
from drltg.report.pipeline import compute, read_runs
from drltg.report.settings import settings_of
from drltg.store import rundir


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
    *,
    figure: FigureStyle = DEFAULT,
    **settings,
) -> dict:
    """One report per (source, target) cell, summarised as a heatmap of ``metric`` (drawn as ``figure`` says)
    plus CSV and JSON."""
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
    from drltg.analysis.plot import files, plot_matrix

    drawn = files("transfer_matrix", plot_matrix(table, sources, targets, metric, style=figure))
    grid_csv = tables.render([("source", *targets)] + [
        (source, *(None if np.isnan(v) else float(v) for v in row)) for source, row in zip(sources, table)
    ], "csv")
    obj = {
        "metric": metric,
        "cells": [{"source": source, "target": target, "metrics": r["metrics"], "settings": r["settings"]}
                  for (source, target), r in results.items()],
        "across_cells": across_cells(results, s.seed, 1.0 - float(s.confidence)),
        "aggregates": cell_aggregates(results, s.seed, float(s.confidence)),
    }
    out = Path(out_dir) if out_dir is not None else fresh_dir(f"matrix-{metric}")
    rundir.write_files(out, {
        "transfer_matrix.csv": grid_csv.encode(),
        "transfer_matrix.json": json_text(obj).encode(),
        **drawn,
    })
    return {**obj, "out_dir": str(out), "table": table.tolist(), "sources": sources, "targets": targets}


def across_cells(results: dict, seed: int = 0, level: float = 0.05) -> dict | None:
    """The transfer runs against the baseline over every cell at once (:func:`drltg.analysis.aggregate.across_pairs`:
    the stratified exact sign-flip test of the sum of the cells' mean return gains, a stratum a cell), with its
    verdict at ``level``: ``higher`` / ``lower`` / ``undecided``; ``None`` where no cell pairs its runs by seed."""
    from drltg.analysis.aggregate import across_pairs

    found = across_pairs([(f"{source} -> {target}", r["per_seed"]) for (source, target), r in results.items()],
                         seed=seed)
    if found is None:
        return None
    decided = found["p"] < level and found["mean_difference"] != 0
    return {**found, "verdict": ("higher" if found["mean_difference"] > 0 else "lower") if decided else "undecided"}


def cell_aggregates(results: dict, seed: int = 0, confidence: float = 0.95) -> dict | None:
    """rliable's aggregates of the transfer runs against the baseline over the cells
    (:func:`drltg.analysis.aggregate.sweep_aggregates`: IQM, median, mean, optimality gap and P(T > B) of the per-seed
    mean returns, normalised by each cell's value range where it has one, with stratified-bootstrap intervals);
    ``None`` for a single cell."""
    from drltg.analysis.aggregate import sweep_aggregates

    if len(results) < 2:
        return None
    rows = [{"pair": f"{source} -> {target}", "algo": "", "variant": "", "method": "transfer",
             "per_seed": r["per_seed"],
             "value_range": r["settings"].get("value_range")} for (source, target), r in results.items()]
    entries = sweep_aggregates(rows, seed=seed, confidence=confidence)
    return entries[0] if entries else None
