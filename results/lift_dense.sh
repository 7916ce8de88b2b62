#!/usr/bin/env bash
# SAC on Lift with robosuite's dense reward (lift-dense), 150k frames a seed, beside the earlier implementation's
# curve on that reward (tests/data/sb3_runs/lift_shaped_sac):  bash results/lift_dense.sh  (RUNS=runs/results
# SEEDS="0 1"; runs side by side; re-running resumes), evaluated every 10k frames on 4 episodes.
set -euo pipefail
RUNS=${RUNS:-runs/results} SEEDS=${SEEDS:-0 1} FRAMES=${FRAMES:-150000} DRLTG=${DRLTG:-drltg}
for seed in $SEEDS; do
  dir="$RUNS/lift-dense/sac/seed-$seed" resume=(); [ -f "$dir/config.yaml" ] && resume=(--resume)
  $DRLTG train lift-dense --seed "$seed" --frames "$FRAMES" --run-dir "$dir" --no-progress "${resume[@]}" \
    -o eval.every=10000 -o checkpoint.every=10000 &
done
wait
# the curves and configs kept, beside the earlier SB3 SAC run on the same frame axis (unpaired)
for seed in $SEEDS; do
  mkdir -p results/lift-dense/sac/seed-$seed
  cp "$RUNS/lift-dense/sac/seed-$seed"/{config.yaml,eval.csv,summary.json} results/lift-dense/sac/seed-$seed/
done
budget=$(for s in $SEEDS; do tail -n 1 results/lift-dense/sac/seed-$s/eval.csv | cut -d, -f1; done | sort -n | head -1)
$DRLTG report --baseline tests/data/sb3_runs/lift_shaped_sac --transfer results/lift-dense/sac \
  --baseline-label "earlier implementation, SB3 SAC (1 run)" --transfer-label "drltg SAC" \
  --threshold 50 --budget "$budget" --out results/lift-dense/vs-seed
rm -f results/lift-dense/vs-seed/transfer_plot.svg
