#!/usr/bin/env bash
# Lift -> Lift+Place (and with barrier) from the Lift demonstrator (examples/sweeps/lift-to-place.yaml, 12 runs):
#   bash results/lift_to_place.sh   (RUNS=runs/sweep-lift-to-place WORKERS=2; re-running finishes the rest)
# kept and reported (return, threshold 1; METHOD/report-STAGE/: success and lifted rate, 0.8) in results/.
set -euo pipefail
RUNS=${RUNS:-runs/sweep-lift-to-place} WORKERS=${WORKERS:-2} DRLTG=${DRLTG:-drltg} PYTHON=${PYTHON:-python} OUT=results/sweep-lift-to-place

$DRLTG sweep examples/sweeps/lift-to-place.yaml --out "$RUNS" --workers "$WORKERS"
$PYTHON results/rebuild.py "$OUT" --from "$RUNS" --threshold 1
for pair in lift-to-place lift-to-place-barrier; do
  for stage in success lifted; do
    $DRLTG report --baseline "$OUT/$pair/sac/baseline" --transfer "$OUT/$pair/sac/demonstrations/transfer" \
      --tag "${stage}_rate" --threshold 0.8 --baseline-label "no transfer" \
      --transfer-label "Lift demonstrations" --out "$OUT/$pair/sac/demonstrations/report-$stage" > /dev/null
    rm -f "$OUT/$pair/sac/demonstrations/report-$stage/transfer_plot.svg"
  done
done
