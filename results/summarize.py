"""Print the committed transfer results as one Markdown table: python results/summarize.py [DIR]

DIR holds PAIR/ALGO/METHOD/report/transfer_metrics.json files (default: results/sweep-fourrooms-graded).
Cells are transfer - baseline with the report's 95% interval; "final" marks an asymptotic difference
taken while a side's curve was still moving; time to threshold is the sustained rule's upper median,
with the share of seeds that reach it.
"""
import json
import sys
from pathlib import Path

root = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).parent / "sweep-fourrooms-graded"


def cell(m, key, sign="+"):
    value, ci = m.get(key), m.get(f"{key}_ci")
    if value is None:
        return "n/a"
    return f"{value:{sign}.2f}" + (f" [{ci[0]:{sign}.2f}, {ci[1]:{sign}.2f}]" if ci else "")


def time_to(m, side):
    value, share = m.get(f"time_to_threshold_{side}"), m.get(f"threshold_reached_{side}", 0)
    return (f"{value / 1000:.0f}k" if value is not None else "—") + f" ({share:.0%})"


print("| pair | method | mean return gain | jumpstart | asymptotic | transfer ratio | frames to threshold, B / T "
      "(seeds reaching it) | P(T > B) |")
print("|---|---|---|---|---|---|---|---|")
for path in sorted(root.glob("*/*/*/report/transfer_metrics.json")):
    report = json.loads(path.read_text())
    m, conv = report["metrics"], report["settings"].get("convergence", {})
    pair, method = path.parents[3].name, path.parents[1].name
    moving = any("still" in str(v) for v in (conv.values() if isinstance(conv, dict) else []))
    asym = cell(m, "asymptotic_performance") + (" (final)" if moving else "")
    print(f"| {pair} | {method} | {cell(m, 'mean_return_gain')} | {cell(m, 'jumpstart')} | {asym} | "
          f"{cell(m, 'transfer_ratio')} | {time_to(m, 'baseline')} / {time_to(m, 'transfer')} | "
          f"{cell(m, 'probability_of_improvement', sign='')} |")
