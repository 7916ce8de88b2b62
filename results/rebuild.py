"""Keep a sweep's curves in results/ and report them, or re-make committed reports under today's rules.

    python results/rebuild.py results/NAME [--from runs/SWEEP [--only FOLDER ...]] [--threshold 0.5]
    python results/rebuild.py --again [FOLDER ...]      # default: every report under results/

``--from`` copies each finished run's ``config.yaml``, ``eval.csv`` and ``summary.json`` from a ``drltg sweep``
folder in its layout (``transfer.source`` made relative), then every ``PAIR/ALGO[/VARIANT]/METHOD/transfer`` is
reported against the ``baseline`` beside it into ``METHOD/report/``. ``--again`` writes each
``transfer_metrics.json`` again from the runs and choices it records, today's defaults for the rest. A sweep's
``summary.md``, aggregates and ``transfer_matrix.png`` are rebuilt as ``drltg sweep`` writes them.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
from pathlib import Path

# Python puts this script's folder first on the path, where results/coverage/ would shadow the coverage
# package that numba (imported by rliable's bootstrap library) probes for.
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

import yaml  # noqa: E402

from drltg.experiments.summary import plot_transfer_matrix, summary_aggregates, summary_tables  # noqa: E402
from drltg.report import transfer_report  # noqa: E402
from drltg.store import rundir  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
GIVEN = ("baseline_label", "transfer_label", "tag", "format", "crossing", "sustain", "smooth", "jumpstart_window",
         "asymptote_window", "trend_window", "convergence_margin", "confidence", "bootstrap", "seed", "ratio_eps",
         "allow_mixed", "allow_mismatch", "include_unfinished")  # the settings a report records as given


def keep_curves(sweep: Path, dest: Path, only: list[str] = ()) -> int:
    """Copy every finished run's files from ``sweep`` to ``dest`` (only under ``only``'s folders, where given)."""
    count = 0
    for summary in sorted(sweep.rglob("summary.json")):
        run = summary.parent
        if only and not any(run.relative_to(sweep).is_relative_to(folder) for folder in only):
            continue
        target = dest / run.relative_to(sweep)
        target.mkdir(parents=True, exist_ok=True)
        for name in ("config.yaml", "eval.csv", "summary.json"):
            shutil.copyfile(run / name, target / name)
        cfg = yaml.safe_load((target / "config.yaml").read_text())
        source = cfg["transfer"].get("source")
        if source and Path(source).is_absolute() and Path(source).is_relative_to(sweep):
            cfg["transfer"]["source"] = os.path.relpath(dest / Path(source).relative_to(sweep), target)
            rundir.atomic_write(target / "config.yaml", yaml.safe_dump(cfg, sort_keys=False))
        count += 1
    return count


def report_again(path: Path) -> dict:
    """The report at ``path`` written again from its own runs and settings, without the outputs it lacked."""
    st = json.loads(path.read_text())["settings"]
    kw = {k: st[k] for k in GIVEN if k in st} | {"threshold": st.get("threshold_given")}
    if st.get("budget_source") == "--budget":
        kw["budget"] = st["budget"]
    if st.get("value_range_given") is not None:  # else the range is found again: a rate's, or the task's
        kw["value_range"] = tuple(st["value_range_given"])
    runs = {side: [_here(p) for p in st[side]] for side in ("baseline", "transfer")}
    outputs = ("transfer_metrics.csv", "transfer_plot.png", "transfer_plot.svg")
    absent = [name for name in outputs if not (path.parent / name).exists()]
    result = transfer_report(runs["baseline"], runs["transfer"], path.parent, **kw)
    for name in absent:
        (path.parent / name).unlink(missing_ok=True)
    return result


def _here(path: str) -> Path:
    """A run's path relative to the repository (a report written on another checkout names its absolute path)."""
    parts = Path(path).parts
    if not Path(path).is_absolute():
        return Path(path)
    return Path(*parts[min(parts.index(top) for top in ("results", "tests") if top in parts):])


def summarise(folder: Path, results: dict[Path, dict]) -> None:
    """A sweep-shaped folder's summary files from its ``PAIR/ALGO[/VARIANT]/METHOD/report``s."""
    rows = []
    for report, result in sorted(results.items()):
        if report.name != "report" or not report.is_relative_to(folder):
            continue
        pair, algo, *variant = report.parent.parent.relative_to(folder).parts
        rows.append({"pair": pair, "algo": algo, "variant": "/".join(variant), "method": report.parent.name,
                     "report": str(report.relative_to(folder)), "metrics": result["metrics"],
                     "per_seed": result["per_seed"], "value_range": result["settings"].get("value_range")})
    csv_text, md_text = summary_tables(rows)
    rundir.write_files(folder, {"summary.csv": csv_text.encode(), "summary.md": md_text.encode(),
                                **plot_transfer_matrix(rows), **summary_aggregates(rows)})


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folders", nargs="*", type=Path)
    parser.add_argument("--again", action="store_true")
    parser.add_argument("--from", dest="sweep", type=Path)
    parser.add_argument("--only", action="append", default=[])
    parser.add_argument("--threshold", default="0.5")
    args = parser.parse_args()
    folders = [Path(os.path.relpath(f.resolve(), ROOT)) for f in args.folders or [ROOT / "results"]]
    sweep = args.sweep.resolve() if args.sweep is not None else None
    os.chdir(ROOT)  # the reports name their runs relative to the repository
    results = {}
    if args.again:
        for path in sorted({p for f in folders for p in f.glob("**/transfer_metrics.json")}):
            results[path.parent] = report_again(path)
            print(f"[{len(results)}] {path}", flush=True)
    else:
        root = folders[0]
        if sweep is not None:
            print(f"kept {keep_curves(sweep, root, args.only)} runs from {sweep}")
        threshold = args.threshold if args.threshold.endswith("%") else float(args.threshold)
        for transfer in sorted(root.glob("**/transfer")):
            if (transfer.parent.parent / "baseline").is_dir():
                out = transfer.parent / "report"
                results[out] = transfer_report(transfer.parent.parent / "baseline", transfer, out, threshold=threshold,
                                               baseline_label="no transfer", transfer_label=transfer.parent.name)
                (out / "transfer_plot.svg").unlink()  # the PNG is kept; the SVG is rebuilt on demand
        summarise(root, results)
        print(f"rebuilt {len(results)} reports and {root / 'summary.md'}")
        return
    for md in sorted({m for f in folders for m in f.glob("**/summary.md")}):
        if (md.parent / "summary.csv").exists():
            summarise(md.parent, results)
            print(f"summary: {md}")


if __name__ == "__main__":
    main()
