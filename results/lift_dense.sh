#!/usr/bin/env bash
# SAC on robosuite Lift with robosuite's dense reward (task lift-dense), the reward of the earlier implementation's
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

# Keep the curves and configs, and set them beside the earlier implementation's SB3 SAC curve on the same
# frame axis (its one run as "baseline", drltg's runs as "transfer"; unpaired).
mkdir -p results/lift-dense/sac
for seed in $SEEDS; do
  src="$RUNS/lift-dense/sac/seed-$seed"; dst="results/lift-dense/sac/seed-$seed"; mkdir -p "$dst"
  for f in config.yaml eval.csv summary.json; do [ -f "$src/$f" ] && cp "$src/$f" "$dst/"; done
done
budget=$(for seed in $SEEDS; do tail -n 1 "results/lift-dense/sac/seed-$seed/eval.csv" | cut -d, -f1; done | sort -n | head -n 1)
$DRLTG report --baseline tests/data/sb3_runs/lift_shaped_sac --transfer results/lift-dense/sac \
  --baseline-label "earlier implementation, SB3 SAC (1 run)" --transfer-label "drltg SAC" \
  --threshold 50 --budget "$budget" --out results/lift-dense/vs-seed
rm -f results/lift-dense/vs-seed/transfer_plot.svg
