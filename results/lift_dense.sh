#!/usr/bin/env bash
# SAC on robosuite Lift with robosuite's dense reward (task lift-dense), the reward of the seed project's
# lift_shaped_sac curve (tests/data/sb3_runs/lift_shaped_sac), 150k frames per seed:
#   bash results/lift_dense.sh            (RUNS=runs/results SEEDS="0 1" by default; runs side by side)
# Manipulation defaults (replay 1e6, batch 256, 2x256 nets, lr 3e-4, one update per frame, 2 envs,
# 5k random warm-up frames), evaluated every 10k frames on 4 episodes. Re-running resumes what is left.
set -euo pipefail
RUNS=${RUNS:-runs/results}
SEEDS=${SEEDS:-0 1}
FRAMES=${FRAMES:-150000}
DRLTG=${DRLTG:-drltg}

for seed in $SEEDS; do
  dir="$RUNS/lift-dense/sac/seed-$seed"
  resume=(); [ -f "$dir/config.yaml" ] && resume=(--resume)
  $DRLTG train lift-dense --seed "$seed" --frames "$FRAMES" --run-dir "$dir" --no-progress "${resume[@]}" \
    -o eval.every=10000 -o checkpoint.every=10000 &
done
wait
