#!/usr/bin/env bash
# Lift from the scripted demonstrator, three ways, against plain SAC on Lift's sparse reward:
#   bash results/lift_demonstrations.sh        (RUNS=runs/sweep-lift-demonstrations WORKERS=1 by default)
# Trains examples/sweeps/lift-demonstrations.yaml (3 seeds x 30k frames: baselines, demonstrations with
# behaviour cloning, policy reuse, jumpstart; 12 runs, about 20 minutes each on one core; re-running
# finishes what is missing), keeps every run's curve and config in results/sweep-lift-demonstrations/,
# reports the evaluation return (threshold 100) and, in METHOD/report-success/, the success rate
# (threshold 0.8, the target of a working method).
set -euo pipefail
RUNS=${RUNS:-runs/sweep-lift-demonstrations}
WORKERS=${WORKERS:-1}
DRLTG=${DRLTG:-drltg}
PYTHON=${PYTHON:-python}
OUT=results/sweep-lift-demonstrations

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
