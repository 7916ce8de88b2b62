"""Print the committed transfer results as one Markdown table: python results/summarize.py [DIR]

DIR is a sweep's results folder, PAIR/ALGO[/VARIANT]/METHOD/report/ (default: results/sweep-fourrooms-graded).
The table is results/regions/sweeps.py's ``sweep_table``, the one results/README.md shows: cells are transfer - baseline
with the report's 95% interval, the mean return gain's p-value Holm-adjusted over the sweep, "final" where a side's
curve was not shown to have converged, and the sustained time to threshold (upper median) with the count of seeds
that hold it.
"""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # drltg and results.regions, also under runpy
from results.regions.sweeps import sweep_table  # noqa: E402

root = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).parent / "sweep-fourrooms-graded"
print(sweep_table(root), end="")
