#!/usr/bin/env bash
# The earlier implementation's own place tasks (lift-place-seed, lift-place-barrier-seed), step 1: SAC with no
# transfer on lift-place-seed, to see whether the baseline leaves the floor before the rows spend their budget.
#   bash results/seed_tasks.sh        (RUNS=runs/seed-tasks by default; re-running resumes; CORE=1 pins one core)
# Seeds 10, 11, 12 (never used to choose a recipe: the manipulation defaults were chosen on seed 0) as one seed
# group in one process, 300k frames each, the manipulation defaults (replay 1e6, batch 256, 2x256 nets, lr 3e-4,
# one update per frame, 2 envs a seed, 5k random warm-up frames), evaluated every 10k frames on 10 episodes.
# Then keeps every seed's config.yaml, eval.csv (and summary.json once finished) in results/seed-tasks/.
set -euo pipefail
RUNS=${RUNS:-runs/seed-tasks}
DRLTG=${DRLTG:-drltg}
dir=$RUNS/lift-place-seed/sac/baseline
resume=(); [ -f "$dir/seed-10/config.yaml" ] && resume=(--resume)
pin=(); [ -n "${CORE:-}" ] && pin=(taskset -c "$CORE")
"${pin[@]}" $DRLTG train lift-place-seed --seed 10 --seeds 3 --frames 300000 --run-dir "$dir" --no-progress \
  "${resume[@]}" -o eval.every=10000 -o eval.episodes=10 -o checkpoint.every=20000 || true
for run in "$dir"/seed-*; do
  keep=results/seed-tasks/lift-place-seed/sac/baseline/${run##*/}; mkdir -p "$keep"
  for f in config.yaml eval.csv summary.json; do if [ -f "$run/$f" ]; then cp "$run/$f" "$keep/"; fi; done
done
