"""Re-run every committed report under the current rules, from its committed curves and the settings it records.

    python results/rereport.py [FOLDER ...]      # default: every transfer_metrics.json under results/

Each ``transfer_metrics.json`` names its runs (``settings.baseline``, ``settings.transfer``) and the choices
it was made with (labels, tag, threshold as given, budget where given, crossing rule, windows, confidence);
the report is written again in place with those choices and today's defaults for everything else (the
interval rule above all). A folder with a ``summary.md`` (a sweep's or a row's) gets its summary tables
and transfer-matrix plot rebuilt from the new reports, as ``drltg sweep`` writes them. Run
``python results/claims.py`` afterwards: the prose quotes these reports.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

# Python puts this script's folder first on the path, where results/coverage/ would shadow the coverage
# package that numba (imported by rliable's bootstrap library) probes for.
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

from drltg.analysis.report import transfer_report  # noqa: E402
from drltg.experiments.summary import plot_transfer_matrix, summary_aggregates, summary_tables  # noqa: E402
from drltg.store import rundir  # noqa: E402

RESULTS = Path(__file__).resolve().parent
ROOT = RESULTS.parent
GIVEN = ("baseline_label", "transfer_label", "tag", "format", "crossing", "sustain", "smooth", "jumpstart_window",
         "asymptote_window", "trend_window", "convergence_margin", "confidence", "bootstrap", "seed", "ratio_eps",
         "allow_mixed", "allow_mismatch", "include_unfinished")
"""Settings a report records as they were given."""
OUTPUTS = ("transfer_metrics.csv", "transfer_plot.png", "transfer_plot.svg")


def rereport(path: Path) -> dict:
    """Write the report at ``path`` (a transfer_metrics.json) again from its own runs and settings."""
    old = json.loads(path.read_text())
    st = old["settings"]
    kw = {k: st[k] for k in GIVEN if k in st}
    kw["threshold"] = st.get("threshold_given")
    if st.get("budget_source") == "--budget":
        kw["budget"] = st["budget"]
    if st.get("value_range_given") is not None:  # else the range is found again: a rate's, or the task's
        kw["value_range"] = tuple(st["value_range_given"])
    runs = {side: [_here(p) for p in st[side]] for side in ("baseline", "transfer")}
    kept = {f for f in OUTPUTS if (path.parent / f).exists()}
    result = transfer_report(runs["baseline"], runs["transfer"], path.parent, **kw)
    for name in set(OUTPUTS) - kept:  # the outputs the committed report did without (a plot, its SVG)
        (path.parent / name).unlink(missing_ok=True)
    return result


def _here(path: str) -> Path:
    """A run's path relative to the repository (reports written on another checkout name its absolute path)."""
    parts = Path(path).parts
    if not Path(path).is_absolute():
        return Path(path)
    return Path(*parts[min(parts.index(top) for top in ("results", "tests") if top in parts):])


def summary(folder: Path, results: dict[Path, dict]) -> None:
    """``summary.{csv,md}`` and ``transfer_matrix.png`` of a sweep-shaped folder from its ``METHOD/report``s."""
    rows = []
    for path, result in sorted(results.items()):
        report = path.parent
        if report.name != "report" or not report.is_relative_to(folder):
            continue
        pair, algo, *variant = report.parent.parent.relative_to(folder).parts
        rows.append({"pair": pair, "algo": algo, "variant": "/".join(variant), "method": report.parent.name,
                     "report": str(report.relative_to(folder)), "metrics": result["metrics"],
                     "per_seed": result["per_seed"], "value_range": result["settings"].get("value_range")})
    csv_text, md_text = summary_tables(rows)
    rundir.write_files(folder, {"summary.csv": csv_text.encode(), "summary.md": md_text.encode(),
                                "transfer_matrix.png": plot_transfer_matrix(rows), **summary_aggregates(rows)})


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folders", nargs="*", type=Path, default=[RESULTS])
    args = parser.parse_args()
    os.chdir(ROOT)  # the reports name their runs relative to the repository
    paths = sorted({p.resolve() for f in args.folders for p in f.resolve().glob("**/transfer_metrics.json")})
    results = {}
    for i, path in enumerate(paths, 1):
        results[path] = rereport(path)
        print(f"[{i}/{len(paths)}] {path.relative_to(ROOT)}", flush=True)
    for md in sorted({m for f in args.folders for m in f.resolve().glob("**/summary.md")}):
        if (md.parent / "summary.csv").exists():
            summary(md.parent, results)
            print(f"summary: {md.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
