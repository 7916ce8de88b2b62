"""Print the committed transfer results as one Markdown table: python results/summarize.py [DIR]"""
import json
import sys
from pathlib import Path

root = Path(sys.argv[1] if len(sys.argv) > 1 else Path(__file__).parent)


def cell(m, key):
    value, ci = m.get(key), m.get(f"{key}_ci")
    if value is None:
        return "not reached" if key.startswith("time_to") else "n/a"
    text = f"{value:+.2f}" if not key.startswith("time_to") else f"{value / 1000:.0f}k"
    return text + (f" [{ci[0]:+.2f}, {ci[1]:+.2f}]" if ci else "")


print("| pair | method | jumpstart | asymptotic | transfer ratio | threshold | frames to threshold (B / T) | P(T > B) | seeds |")
print("|---|---|---|---|---|---|---|---|---|")
for path in sorted(root.glob("*/*/transfer_metrics.json")):
    report = json.loads(path.read_text())
    m, threshold = report["metrics"], report["settings"]["threshold"]
    pair, method = path.parent.parent.name, path.parent.name
    ttt = f"{cell(m, 'time_to_threshold_baseline')} / {cell(m, 'time_to_threshold_transfer')}"
    print(f"| {pair} | {method} | {cell(m, 'jumpstart')} | {cell(m, 'asymptotic_performance')} | "
          f"{cell(m, 'transfer_ratio')} | {threshold:g} | {ttt} | {m['probability_of_improvement']:.2f} | "
          f"{m['n_seeds_baseline']} + {m['n_seeds_transfer']} |")
