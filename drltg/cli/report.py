"""``drltg report``: did the transfer method help? Metrics, a plot and tables from learning curves.

The command's options and output; the report itself is :mod:`drltg.report`."""
from __future__ import annotations

import argparse
import math
import sys
from dataclasses import asdict, fields

from drltg.analysis import figure_style, tables
from drltg.errors import UsageError
from drltg.report import ReportSettings, find_matrix_cells, format_table, transfer_matrix, transfer_report


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``drltg report``'s options: the run sets, ``--out`` and ``--matrix``, then one option per
    :class:`ReportSettings` field that has a flag."""
    groups = {"runs": parser.add_argument_group("runs"), "metrics": parser.add_argument_group("metrics")}
    io_ = groups["runs"]
    io_.add_argument("--baseline", nargs="+", metavar="PATH",
                     help="baseline (no transfer) runs: run dirs, a dir of seed runs, log files or globs")
    io_.add_argument("--transfer", nargs="+", metavar="PATH", help="transfer runs, same forms as --baseline")
    io_.add_argument("--matrix", metavar="DIR",
                     help="DIR/<source>/<target>/{baseline,transfer}: a heatmap of --metric over all pairs")
    io_.add_argument("--metric", default="mean_return_gain", help="metric for the --matrix heatmap "
                     "(default: mean_return_gain)")
    io_.add_argument("--out", metavar="DIR", help="output folder (default: a fresh folder named after the runs)")
    figure_style.add_arguments(parser)
    for f in fields(ReportSettings):
        meta = f.metadata
        if meta.get("flag"):
            groups[meta["group"]].add_argument(meta["flag"], dest=f.name, default=f.default, **meta["kwargs"])


def run(args) -> int:
    settings = asdict(ReportSettings.from_args(args))  # every option is checked before any run is read
    figure = figure_style.from_args(args)
    drawn = figure.formats("svg")
    if args.matrix:
        if args.baseline or args.transfer:
            raise UsageError("--matrix builds its own baseline/transfer pairs; drop --baseline and --transfer.")
        del settings["baseline_label"], settings["transfer_label"]
        result = transfer_matrix(find_matrix_cells(args.matrix), args.out, args.metric, figure=figure, **settings)
        for cell in result["cells"]:
            for w in cell["settings"]["warnings"]:
                print(f"warning: {cell['source']} -> {cell['target']}: {w}", file=sys.stderr)
        rows = [("source \\ target", *result["targets"])] + [
            (source, *("-" if math.isnan(v) else f"{v:.4g}" for v in row))
            for source, row in zip(result["sources"], result["table"])]
        print(f"{args.metric}:")
        print(tables.render(rows, "text", align="l" + "r" * len(result["targets"])), end="")
        across = result["across_cells"]
        if across is not None:
            print(f"across all {len(across['pairs'])} paired cell(s), {across['seed_pairs']} seed pairs: "
                  f"{across['verdict']} (mean over cells of the mean return gain {across['mean_difference']:+.4g}; "
                  f"{across['test']} test, p = {across['p']:.3g})")
        agg = result["aggregates"]
        if agg is not None:
            (iqm, (lo, hi)), (poi, (plo, phi)) = agg["difference"]["iqm"], agg["probability_of_improvement"]
            print(f"aggregates over {len(agg['pairs'])} cells x {agg['runs_per_pair']} runs (rliable, 95% stratified "
                  f"bootstrap): IQM difference {iqm:+.4g} [{lo:+.4g}, {hi:+.4g}], P(T > B) {poi:.3g} [{plo:.3g}, "
                  f"{phi:.3g}]; all in transfer_matrix.json")
        print(f"wrote {result['out_dir']}/transfer_matrix.{{{','.join([*drawn, 'csv', 'json'])}}}")
        return 0
    if not args.baseline or not args.transfer:
        raise UsageError("give both --baseline and --transfer runs (or --matrix DIR).")
    result = transfer_report(args.baseline, args.transfer, args.out, figure=figure, **settings)
    for w in result["settings"]["warnings"]:
        print(f"warning: {w}", file=sys.stderr)
    print(format_table(result))
    from drltg.analysis.claims import headline

    print("\n" + headline(result))
    plots = f"{{{','.join(drawn)}}}" if len(drawn) > 1 else drawn[0]
    print(f"\nwrote {result['out_dir']}/transfer_metrics.{{json,csv}} and transfer_plot.{plots}")
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
