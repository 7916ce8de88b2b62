"""`drltg bench tune --method NAME`, `drltg bench run --method NAME` and `drltg bench report`: a method's
setting chosen on tuning seeds, the method on the benchmark's tier, and the leaderboard that places it among
the reference rows."""
from __future__ import annotations

import argparse
import os
from pathlib import Path

from drltg.analysis import figure_style
from drltg.bench.suite import LATEST, SUITES

REFERENCE = Path("results") / "bench"
"""The reference rows of a drltg checkout, used where ``--reference`` is not given and this folder exists."""


def _common(p: argparse.ArgumentParser, reference: bool = True) -> None:
    p.add_argument("--import", dest="imports", action="append", default=argparse.SUPPRESS, metavar="MODULE",
                   help="import MODULE first, e.g. one that registers your method (repeatable)")
    p.add_argument("--tier", default="quick", help="the suite's tier: quick (default) or manipulation")
    p.add_argument("--suite", default=LATEST, choices=sorted(SUITES), help=f"suite version (default {LATEST})")
    p.add_argument("--out", type=Path, default=Path("runs") / "bench",
                   help="your bench folder (default runs/bench; re-run to resume)")
    if reference:
        p.add_argument("--reference", default=None, help=f"the reference rows' folder (default {REFERENCE} where it "
                       "exists; 'none': no reference, train every source and baseline)")


def add_arguments(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="bench_command", metavar="{sources,tune,run,report}", parser_class=type(p))
    sub.required = True
    sources_p = sub.add_parser("sources", help="train the tier's sources, the teachers every row shares (suites "
                                               "that declare them)")
    tune_p = sub.add_parser("tune", help="try a method's declared settings on tuning seeds (--method none: the "
                                         "baseline's); bench run applies the choice")
    run_p = sub.add_parser("run", help="train one method on a tier, reusing the reference's sources and baselines "
                                       "(and its tuned setting, where bench tune chose one)")
    for q in (sources_p, tune_p, run_p):
        if q is not sources_p:
            q.add_argument("--method", required=True, help="a transfer method (built-in or registered by --import); "
                           "with tune, 'none' for the baseline")
        _common(q, reference=q is not sources_p)
        q.add_argument("--smoke", action="store_true", help="2 seeds, budgets / 50: checks the path, never ranked")
        q.add_argument("--workers", type=int, default=os.cpu_count(), help="runs in parallel (default: CPU count)")
        q.add_argument("--backend", choices=("local", "ray"), default="local")
        q.add_argument("--no-seed-groups", action="store_true", help="train every run in its own task")
        q.add_argument("--no-progress", action="store_true", help="no progress bar")
        q.add_argument("--dry-run", action="store_true", help="list the tier's work group by group (units of work, "
                       "seed groups and their sizes, frames left); train nothing")
    report_p = sub.add_parser("report", help="the leaderboard: your rows among the reference rows")
    _common(report_p)
    report_p.add_argument("--board", type=Path, help="where to write it (default OUT/SUITE/TIER/board)")
    report_p.add_argument("--reps", type=int, default=2000, help="bootstrap resamples of each interval")
    figure_style.add_arguments(report_p)


def _reference(text: str | None) -> Path | None:
    if text is None:
        return REFERENCE if REFERENCE.is_dir() else None
    return None if text == "none" else Path(text)


def copied_sentence(n: int, reference: str | None) -> str:
    """How many source and baseline runs a bench run copied, and from where, as a sentence for any count."""
    where = f"from {reference}" if reference else "(no reference)"
    if n == 0:
        return f"no source or baseline runs were copied {where}"
    if n == 1:
        return f"1 source or baseline run was copied {where}"
    return f"{n} source and baseline runs were copied {where}"


def run(args: argparse.Namespace) -> int:
    from drltg.bench import bench_report, bench_run
    from drltg.bench.board import board_table, pair_table
    from drltg.bench.run import tier_root

    if args.bench_command == "sources":
        from drltg.bench.sources import bench_sources

        entries = bench_sources(tier=args.tier, out=args.out, version=args.suite, smoke=args.smoke,
                                workers=args.workers, group_seeds=not args.no_seed_groups,
                                progress=not args.no_progress, dry_run=args.dry_run)
        if args.dry_run:
            print("\n".join(entries["plan"]))
            return 0
        judged = [e for e in entries.values() if e["met"] is not None]
        whole = len(entries) - len(judged)
        print(f"{sum(e['met'] for e in judged)} of {len(judged)} sources met their success criterion"
              + (f" ({whole} more trained their whole budget: their group declares none)" if whole else "")
              + "; their digests are in "
              f"{tier_root(args.out, args.suite, args.tier, args.smoke) / 'sources' / 'sources.json'}. "
              f"Next: drltg bench tune --method none --suite {args.suite} --out {args.out}")
        return 0
    reference = _reference(args.reference)
    if args.bench_command == "tune":
        from drltg.bench.tune import bench_tune

        record = bench_tune(args.method, tier=args.tier, out=args.out, version=args.suite, reference=reference,
                            smoke=args.smoke, workers=args.workers, backend=args.backend,
                            group_seeds=not args.no_seed_groups, progress=not args.no_progress, dry_run=args.dry_run)
        if args.dry_run:
            print("\n".join(record["plan"]))
            return 0
        score = "mean AUC" if args.method == "none" else "mean FT"
        for tried in record["settings"]:
            shown = ", ".join(f"{k}={v}" for k, v in tried["setting"].items()) or "the defaults"
            where = f"{tried['group']}: " if "group" in tried else ""
            if tried["score"] is None:
                print(f"{where}{shown}: nothing to try (a budget of 1)")
            else:
                print(f"{where}{shown}: {score} {tried['score']:+.3f} over {len(tried['per_pair'])} pairs")
        if args.method == "none":
            chosen = "; ".join(f"{g}: {', '.join(f'{k}={v}' for k, v in c.items()) or 'the defaults'}"
                               for g, c in record["choice"].items())
            after = f"drltg bench tune --method METHOD --suite {args.suite} --out {args.out}"
        else:
            chosen = ", ".join(f"{k}={v}" for k, v in record["choice"].items()) or "the defaults (no search declared)"
            after = f"drltg bench run --method {args.method} --suite {args.suite} --out {args.out}"
        print(f"{args.method}: chose {chosen} of {record['budget']} setting{'s' * (record['budget'] != 1)} on seeds "
              f"{', '.join(map(str, record['seeds']))}. Next: {after}")
        return 0
    if args.bench_command == "run":
        record = bench_run(args.method, tier=args.tier, out=args.out, version=args.suite, reference=reference,
                           smoke=args.smoke, workers=args.workers, backend=args.backend,
                           group_seeds=not args.no_seed_groups, progress=not args.no_progress, imports=args.imports,
                           dry_run=args.dry_run)
        if args.dry_run:
            print("\n".join(record["plan"]))
            return 0
        entry = record["methods"][args.method]
        for pair, why in entry["left_out"].items():
            print(f"left out: {pair}: {why}")
        print(f"{args.method} on {args.suite} {args.tier}{' (smoke)' if args.smoke else ''}: done; "
              f"{copied_sentence(entry['copied'], entry['reference'])}. "
              f"Next: drltg bench report --out {args.out}" + (" --reference none" if reference is None else ""))
        return 0
    board, folder = bench_report(out=args.out, reference=reference, version=args.suite, tier=args.tier,
                                 board_dir=args.board, reps=args.reps, figure=figure_style.from_args(args))
    print(board_table(board))
    print(pair_table(board))
    print(f"leaderboard: {folder / 'leaderboard.md'} (JSON, performance profiles and curves beside it)")
    return 0
