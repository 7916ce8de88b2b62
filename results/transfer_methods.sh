#!/usr/bin/env bash
# Reproduces the grid transfer-method results, 5 seeds per side (FourRooms: examples/sweeps/fourrooms-graded.yaml):
#   bash results/transfer_methods.sh        (RUNS=runs/results WORKERS=2 by default)
# Every experiment trains 5 source runs (40k frames), 5 baseline and 5 transfer runs (20k frames)
# and writes RUNS/<pair>/<method>/report/. Policy reuse reuses the model-reuse experiment's source and
# baseline runs (same configs, same seeds), so both methods are compared on the same runs.
# Re-running finishes what is missing.
set -euo pipefail
RUNS=${RUNS:-runs/results}
WORKERS=${WORKERS:-2}
DRLTG=${DRLTG:-drltg}
REUSE_PAIRS=${REUSE_PAIRS-gridrooms-near gridrooms-far}
SHAPING_PAIRS=${SHAPING_PAIRS-gridrooms-near gridrooms-far}
COMMON=(--seeds 5 --frames 20000 --source-frames 40000 --threshold 0.5 -o eval.every=1000 --workers "$WORKERS")
mkdir -p "$RUNS/logs"

reuse() {
  local pair=$1
  $DRLTG experiment "$pair" --method model-reuse "${COMMON[@]}" --out "$RUNS/$pair/model-reuse"
  mkdir -p "$RUNS/$pair/policy-reuse"
  for side in source baseline; do
    [ -e "$RUNS/$pair/policy-reuse/$side" ] || cp -r "$RUNS/$pair/model-reuse/$side" "$RUNS/$pair/policy-reuse/"
  done
  $DRLTG experiment "$pair" --method policy-reuse "${COMMON[@]}" --out "$RUNS/$pair/policy-reuse"
}

for pair in $REUSE_PAIRS; do
  reuse "$pair" > "$RUNS/logs/$pair.reuse.log" 2>&1 &
done
for pair in $SHAPING_PAIRS; do
  $DRLTG experiment "$pair" --method reward-shaping "${COMMON[@]}" --out "$RUNS/$pair/reward-shaping" \
    > "$RUNS/logs/$pair.reward-shaping.log" 2>&1 &
done
wait
