#!/usr/bin/env bash
# Do options transfer better than plain SAC under model reuse? (examples/sweeps/options.yaml, FourRooms near, far)
#   bash results/options_study.sh   (RUNS=runs/sweep-options WORKERS=2; re-running finishes the rest)
# kept and reported in results/sweep-options/, then each SOC learner's model-reuse runs against SAC's (the graded
# sweep's: same seeds, budgets, evaluations) in head-to-head/PAIR-kK/, paired by seed.
set -euo pipefail
RUNS=${RUNS:-runs/sweep-options}
WORKERS=${WORKERS:-2}
DRLTG=${DRLTG:-drltg}
PYTHON=${PYTHON:-python}
OUT=results/sweep-options

# --no-seed-groups: the committed curves were trained run by run (a seed group draws its noise differently)
$DRLTG sweep examples/sweeps/options.yaml --out "$RUNS" --workers "$WORKERS" --no-seed-groups
$PYTHON results/rebuild.py "$OUT" --from "$RUNS"
for pair in fourrooms-near fourrooms-far; do
  for k in 2 4; do
    $DRLTG report --baseline "results/sweep-fourrooms-graded/$pair/sac/model-reuse/transfer" \
      --transfer "$OUT/$pair/soc/soc.num_options=$k/model-reuse/transfer" \
      --baseline-label "SAC + model reuse" --transfer-label "SOC K=$k + model reuse" --threshold 0.5 --allow-mismatch \
      --out "$OUT/head-to-head/$pair-k$k" > /dev/null
    rm -f "$OUT/head-to-head/$pair-k$k/transfer_plot.svg"
  done
done
