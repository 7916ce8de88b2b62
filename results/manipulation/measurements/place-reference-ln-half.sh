#!/usr/bin/env bash
# The upper reference on Lift+Place with the stabilisers of the lift-sac-ln-half source: SAC with
# LayerNorm critics, half of every batch from the target's own demonstrator (demonstrator:lift-place: it
# lifts, carries and places), behaviour cloning at weight 10, keep_best; 3 seeds x 100k frames, evaluated
# every 5k frames on 10 episodes. Does it stop the collapses of demonstrations-reference-place?
#   bash results/manipulation/measurements/place-reference-ln-half.sh
# trains in RUNS/measurements/place-reference-ln-half/seed-<s> (WORKERS at a time; re-running resumes),
# keeps each run's curves, config and weights here (keep_source.py), evaluates its best.pt on 50 episodes
# and plays best.pt and last.pt on the same 10 episodes (collapse.py).
set -euo pipefail
RUNS=${RUNS:-runs/manipulation}
WORKERS=${WORKERS:-2}
DRLTG=${DRLTG:-drltg}
NAME=place-reference-ln-half
ARGS="--frames 100000 -o transfer.method=demonstrations -o transfer.source=demonstrator:lift-place
  -o network.layer_norm=critics -o transfer.demo_ratio=0.5
  -o eval.every=5000 -o eval.episodes=10 -o checkpoint.every=5000 -o checkpoint.keep_best=true"
export OMP_NUM_THREADS=1 MKL_NUM_THREADS=1
mkdir -p "$RUNS/measurements/$NAME"
for s in 0 100 200; do
  run=$RUNS/measurements/$NAME/seed-$s
  [ -f "$run/summary.json" ] && continue
  resume=""
  [ -f "$run/config.yaml" ] && resume=--resume
  echo "$DRLTG train lift-place --seed $s --run-dir $run $resume --no-progress $(echo $ARGS) >> $run.log 2>&1"
done | xargs -r -d '\n' -P "$WORKERS" -I{} bash -c '{}'
for s in 0 100 200; do
  kept=results/manipulation/measurements/$NAME/seed-$s
  [ -f "$kept/checkpoints/last.pt" ] || ${PYTHON:-python} results/manipulation/keep_source.py "$RUNS/measurements/$NAME/seed-$s" "$kept"
  ls "$kept"/evaluate-best-*-50ep.json > /dev/null 2>&1 || $DRLTG evaluate "$kept" --checkpoint best --episodes 50
done
${PYTHON:-python} results/manipulation/measurements/collapse.py "$NAME"
