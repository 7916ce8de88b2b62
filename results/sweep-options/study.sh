#!/usr/bin/env bash
# "Do options transfer better than plain SAC under model reuse?" on the FourRooms near and far pairs:
#   bash results/sweep-options/study.sh        (RUNS=runs/sweep-options WORKERS=2 by default)
# The same command resumes the sweep where it stopped (finished runs are kept) and, once every run is done,
# rebuilds results/sweep-options/ from it; it replaces results/options_study.sh (the earlier 5-seed study's)
# once its results are committed.
# Trains examples/sweeps/options.yaml (SAC and the soft option-critic with K = 4 options: sources trained
# to success 0.9, capped at 100k frames, then baselines and model-reuse runs, 10 seeds each, in seed
# groups; re-running finishes what is missing), keeps its curves and reports in results/sweep-options/,
# lists each source's criterion (met or not, at which frame) in results/sweep-options/sources.md, and sets
# SOC's model-reuse runs against SAC's in results/sweep-options/head-to-head/PAIR/, paired by seed.
set -euo pipefail
RUNS=${RUNS:-runs/sweep-options}
WORKERS=${WORKERS:-2}
DRLTG=${DRLTG:-drltg}
PYTHON=${PYTHON:-python}
OUT=results/sweep-options

$DRLTG sweep examples/sweeps/options.yaml --out "$RUNS" --workers "$WORKERS"
# the curves of another spec (the earlier 5-seed study) must not be reported with these: all but this script go
find "$OUT" -mindepth 1 -maxdepth 1 ! -name study.sh -exec rm -rf {} +
$PYTHON results/rebuild.py "$OUT" --from "$RUNS"
$PYTHON - "$OUT" > "$OUT/sources.md" <<'PY'
import json, sys
from pathlib import Path
print("| algo | source | met success 0.9 | frames | success rate |\n|---|---|---|---|---|")
for summary in sorted(Path(sys.argv[1]).glob("fourrooms-near/*/source/seed-*/summary.json"),
                      key=lambda p: (p.parts[-4], int(p.parent.name.split("-")[1]))):
    stop = json.loads(summary.read_text())["stop_at_success"]
    rate = stop.get("success_rate", stop.get("best_success_rate"))
    print(f"| {summary.parts[-4]} | {summary.parent.name} | {'yes' if stop['met'] else 'no'} | {stop['frames']} | "
          f"{rate:g}{'' if stop['met'] else ' (best)'} |")
PY
for pair in fourrooms-near fourrooms-far; do
  $DRLTG report --baseline "$OUT/$pair/sac/model-reuse/transfer" --transfer "$OUT/$pair/soc/model-reuse/transfer" \
    --baseline-label "SAC + model reuse" --transfer-label "SOC K=4 + model reuse" --threshold 0.5 --allow-mismatch \
    --out "$OUT/head-to-head/$pair" > /dev/null
  rm -f "$OUT/head-to-head/$pair/transfer_plot.svg"
done
