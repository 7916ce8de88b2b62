"""Print the committed transfer results as one Markdown table: python results/summarize.py [DIR]

DIR holds transfer_metrics.json files: a sweep's PAIR/ALGO[/VARIANT]/METHOD/report/ and reports of their own
(default: results/sweep-fourrooms-graded).
Cells are transfer - baseline with the report's 95% interval; "final" marks an asymptotic difference
taken while a side's curve was not shown to have converged; time to threshold is the sustained rule's upper median,
with the share of seeds that reach it.
"""
import json
import sys
from pathlib import Path

from drltg.analysis.tables import estimate, render

root = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).parent / "sweep-fourrooms-graded"


def cell(m, key, fmt="+.2f"):
    return estimate(m.get(key), m.get(f"{key}_ci"), fmt)


def time_to(m, side):
    value, share = m.get(f"time_to_threshold_{side}"), m.get(f"threshold_reached_{side}", 0)
    return estimate(value, fmt=lambda x: f"{x / 1000:.0f}k", missing="—") + f" ({share:.0%})"


rows = [("pair", "method", "mean return gain", "jumpstart", "asymptotic", "transfer ratio",
         "frames to threshold, B / T (seeds reaching it)", "P(T > B)")]
for path in sorted(root.rglob("transfer_metrics.json")):
    report = json.loads(path.read_text())
    parts = path.parent.relative_to(root).parts
    if parts[-1] == "report":  # a sweep's PAIR/ALGO[/VARIANT]/METHOD/report
        pair, _, *variant, method, _ = parts
        experiment = " ".join([pair, *variant])
    else:  # a report of its own, e.g. one learner against another
        settings = report["settings"]
        experiment, method = "/".join(parts), f"{settings['transfer_label']} vs {settings['baseline_label']}"
    m, conv = report["metrics"], report["settings"].get("convergence", {})
    moving = any(str(v) != "converged" for v in (conv.values() if isinstance(conv, dict) else []))
    rows.append((experiment, method, cell(m, "mean_return_gain"), cell(m, "jumpstart"),
                 cell(m, "asymptotic_performance") + (" (final)" if moving else ""), cell(m, "transfer_ratio"),
                 f"{time_to(m, 'baseline')} / {time_to(m, 'transfer')}", cell(m, "probability_of_improvement", ".2f")))
print(render(rows, "markdown"), end="")
