"""drltg bench: a versioned transfer benchmark. A suite version fixes each tier's pairs, budgets, seeds and
evaluation (:mod:`drltg.bench.suite`); ``bench_run`` trains one method on a tier beside a reference's
sources and baselines (:mod:`drltg.bench.run`); ``bench_report`` ranks it among the reference rows with
verdicts per pair and in aggregate (:mod:`drltg.bench.board`, :mod:`drltg.bench.report`)."""
from drltg.bench.board import leaderboard
from drltg.bench.report import bench_report
from drltg.bench.run import bench_run
from drltg.bench.suite import LATEST, SUITES, get_tier

__all__ = ["bench_run", "bench_report", "leaderboard", "get_tier", "SUITES", "LATEST"]
