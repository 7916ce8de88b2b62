#!/usr/bin/env bash
# "Do options transfer better than plain SAC under model reuse?" on FourRooms near and far: SAC and SOC K=4
# (examples/sweeps/options.yaml), then SOC K=2 (options-k2.yaml), sources to success 0.9, 10 seed pairs; a
# rerun resumes, then rebuilds results/sweep-options/ and results/sweep-options-k2/ (curves, reports,
# sources.md, head-to-head/PAIR: that SOC's model-reuse runs against SAC's, paired by seed):
#   RUNS=runs/sweep-options WORKERS=2 bash results/sweep-options/study.sh
set -euo pipefail
RUNS=${RUNS:-runs/sweep-options} WORKERS=${WORKERS:-2} DRLTG=${DRLTG:-drltg} PYTHON=${PYTHON:-python}
SAC=results/sweep-options

for K in 4 2; do
  if [ $K = 4 ]; then SPEC=options RUN=$RUNS OUT=$SAC; else SPEC=options-k2 RUN=$RUNS-k2 OUT=$SAC-k2; fi
  $DRLTG sweep "examples/sweeps/$SPEC.yaml" --out "$RUN" --workers "$WORKERS"
  mkdir -p "$OUT" && find "$OUT" -mindepth 1 -maxdepth 1 ! -name study.sh -exec rm -rf {} +
  $PYTHON results/rebuild.py "$OUT" --from "$RUN"
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
    $DRLTG report --baseline "$SAC/$pair/sac/model-reuse/transfer" --transfer "$OUT/$pair/soc/model-reuse/transfer" \
      --baseline-label "SAC + model reuse" --transfer-label "SOC K=$K + model reuse" --threshold 0.5 \
      --allow-mismatch --out "$OUT/head-to-head/$pair" > /dev/null
    rm -f "$OUT/head-to-head/$pair/transfer_plot.svg"
  done
done
