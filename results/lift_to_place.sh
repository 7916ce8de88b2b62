#!/usr/bin/env bash
# Lift -> Lift+Place and Lift -> Lift+Place-with-barrier from the Lift demonstrator, against plain SAC
# on the targets' sparse success reward:
#   bash results/lift_to_place.sh        (RUNS=runs/sweep-lift-to-place WORKERS=2 by default)
# Trains examples/sweeps/lift-to-place.yaml (2 pairs x 3 paired seeds x 20k frames: baselines and
# demonstrations with behaviour cloning; 12 runs, about 10 minutes each on one core; re-running
# finishes what is missing), keeps every run's curve and config in results/sweep-lift-to-place/ and
# reports the evaluation return (threshold 1: a placed cube), and, in METHOD/report-STAGE/, the
# success rate (the cube placed) and the lifted rate (the cube lifted, the stage the source knows).
set -euo pipefail
RUNS=${RUNS:-runs/sweep-lift-to-place}
WORKERS=${WORKERS:-2}
DRLTG=${DRLTG:-drltg}
PYTHON=${PYTHON:-python}
OUT=results/sweep-lift-to-place

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
