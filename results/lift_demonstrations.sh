#!/usr/bin/env bash
# Lift from the scripted demonstrator three ways (examples/sweeps/lift-demonstrations.yaml, 12 runs of 30k frames):
#   bash results/lift_demonstrations.sh  (RUNS=runs/sweep-lift-demonstrations WORKERS=1; re-running finishes the rest)
# kept and reported (return, threshold 100; METHOD/report-success/: success rate, threshold 0.8) in results/.
set -euo pipefail
RUNS=${RUNS:-runs/sweep-lift-demonstrations} WORKERS=${WORKERS:-1} DRLTG=${DRLTG:-drltg} PYTHON=${PYTHON:-python} OUT=results/sweep-lift-demonstrations

$DRLTG sweep examples/sweeps/lift-demonstrations.yaml --out "$RUNS" --workers "$WORKERS"
$PYTHON results/rebuild.py "$OUT" --from "$RUNS" --threshold 100
for method in demonstrations policy-reuse jumpstart; do
  $DRLTG report --baseline "$OUT/lift/sac/baseline" --transfer "$OUT/lift/sac/$method/transfer" \
    --tag success_rate --threshold 0.8 --baseline-label "no transfer" --transfer-label "$method" \
    --out "$OUT/lift/sac/$method/report-success" > /dev/null
  rm -f "$OUT/lift/sac/$method/report-success/transfer_plot.svg"
done

# The variants tried before the defaults (results/README.md gives their commands): 10 demonstration
# episodes instead of 50, 3 seeds, against the same baselines.
V=results/lift-demonstrations-variants
$DRLTG report --baseline "$OUT/lift/sac/baseline" --transfer "$V/bc-10-episodes" --tag success_rate \
  --threshold 0.8 --baseline-label "no transfer" --transfer-label "demonstrations, 10 episodes" \
  --out "$V/bc-10-episodes-report-success" > /dev/null
rm -f "$V/bc-10-episodes-report-success/transfer_plot.svg"
