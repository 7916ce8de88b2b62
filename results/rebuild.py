"""Keep a sweep's curves in results/ and rebuild every report and table from them.

    python results/rebuild.py results/NAME [--from runs/SWEEP] [--threshold 0.5]

``--from`` copies, for every run of a ``drltg sweep`` folder, the files that define and record it
(``config.yaml``, ``eval.csv``, ``summary.json``: small text; no checkpoints or logs) into
``results/NAME`` with the same layout, and writes ``transfer.source`` relative to the run directory, so
the folder can be moved and read anywhere. Then, with or without ``--from``, every
``PAIR/ALGO[/VARIANT]/METHOD/transfer`` is reported against the ``baseline`` beside it with ``drltg report``
into ``METHOD/report/`` (JSON, CSV and the PNG plot), and the folder gets ``summary.{csv,md}`` and the
``transfer_matrix.png`` heatmap and the aggregates over pairs, as ``drltg sweep`` writes them. The same curves always give the same
reports (a test re-runs one and compares it with the committed JSON).
"""
from __future__ import annotations

import argparse
import os
import shutil
import sys
from pathlib import Path

import yaml

# Python puts this script's folder first on the path, where results/coverage/ would shadow the coverage
# package that numba (imported by rliable's bootstrap library) probes for.
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

from drltg.analysis.report import transfer_report  # noqa: E402
from drltg.experiments.summary import plot_transfer_matrix, summary_aggregates, summary_tables  # noqa: E402
from drltg.store import rundir  # noqa: E402

KEPT = ("config.yaml", "eval.csv", "summary.json")


def keep_curves(sweep: Path, dest: Path, only: list[str] = ()) -> int:
    """Copy every complete run's defining files from ``sweep`` to ``dest`` (only those under one of the
    folders ``only``, relative to ``sweep``, where given); returns how many runs."""
    count = 0
    for summary in sorted(sweep.rglob("summary.json")):
        run = summary.parent
        if only and not any(run.relative_to(sweep).is_relative_to(folder) for folder in only):
            continue
        target = dest / run.relative_to(sweep)
        target.mkdir(parents=True, exist_ok=True)
        for name in KEPT:
            shutil.copyfile(run / name, target / name)
        cfg = yaml.safe_load((target / "config.yaml").read_text())
        source = cfg["transfer"].get("source")
        if source and Path(source).is_absolute() and Path(source).is_relative_to(sweep):
            cfg["transfer"]["source"] = os.path.relpath(dest / Path(source).relative_to(sweep), target)
            rundir.atomic_write(target / "config.yaml", yaml.safe_dump(cfg, sort_keys=False))
        count += 1
    return count


def rebuild(root: Path, threshold) -> list[dict]:
    """Report every ``PAIR/ALGO[/VARIANT]/METHOD/transfer`` folder under ``root`` against the ``baseline``
    beside its method folder; write the summary files."""
    rows = []
    for transfer in sorted(root.glob("**/transfer")):
        method_dir = transfer.parent
        group = method_dir.parent
        if not (group / "baseline").is_dir():
            continue
        pair, algo, *variant = group.relative_to(root).parts
        result = transfer_report(group / "baseline", transfer, method_dir / "report", threshold=threshold,
                                 baseline_label="no transfer", transfer_label=method_dir.name)
        (method_dir / "report" / "transfer_plot.svg").unlink()  # the PNG is kept; the SVG is rebuilt on demand
        rows.append({"pair": pair, "algo": algo, "variant": "/".join(variant), "method": method_dir.name,
                     "report": str((method_dir / "report").relative_to(root)), "metrics": result["metrics"],
                     "per_seed": result["per_seed"], "value_range": result["settings"].get("value_range")})
    csv_text, md_text = summary_tables(rows)
    rundir.write_files(root, {"summary.csv": csv_text.encode(), "summary.md": md_text.encode(),
                              "transfer_matrix.png": plot_transfer_matrix(rows), **summary_aggregates(rows)})
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("root", type=Path, help="the results folder, e.g. results/sweep-fourrooms-graded")
    parser.add_argument("--from", dest="sweep", type=Path, help="a drltg sweep folder to take the curves from")
    parser.add_argument("--only", action="append", default=[], metavar="FOLDER",
                        help="with --from, keep only the runs under FOLDER (relative to the sweep; repeatable)")
    parser.add_argument("--threshold", default="0.5", help="report threshold (default 0.5)")
    args = parser.parse_args()
    if args.sweep is not None:
        print(f"kept {keep_curves(args.sweep.resolve(), args.root.resolve(), args.only)} runs from {args.sweep}")
    rows = rebuild(args.root, float(args.threshold) if not args.threshold.endswith("%") else args.threshold)
    print(f"rebuilt {len(rows)} reports and {args.root / 'summary.md'}")


if __name__ == "__main__":
    main()
