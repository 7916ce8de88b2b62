#!/usr/bin/env bash
# One measurement, sourced by NAME.sh beside it after it sets NAME, TASK and ARGS (drltg train's flags):
# trains TASK with ARGS for seeds 0, 100, 200 in RUNS/measurements/NAME/seed-<s> (RUNS=runs/manipulation,
# WORKERS=2 at a time; a finished run is skipped, an interrupted one resumed), keeps each run's curves,
# config and weights in results/manipulation/measurements/NAME/ (keep_source.py), evaluates its best.pt
# on 50 episodes and plays best.pt and last.pt on the same 10 episodes (collapse.py).
set -euo pipefail
RUNS=${RUNS:-runs/manipulation}
WORKERS=${WORKERS:-2}
DRLTG=${DRLTG:-drltg}
export OMP_NUM_THREADS=1 MKL_NUM_THREADS=1
mkdir -p "$RUNS/measurements/$NAME"
for s in 0 100 200; do
  run=$RUNS/measurements/$NAME/seed-$s
  [ -f "$run/summary.json" ] && continue
  resume=""
  [ -f "$run/config.yaml" ] && resume=--resume
  echo "$DRLTG train $TASK --seed $s --run-dir $run $resume --no-progress $(echo $ARGS) >> $run.log 2>&1"
done | xargs -r -d '\n' -P "$WORKERS" -I{} bash -c '{}'
for s in 0 100 200; do
  kept=results/manipulation/measurements/$NAME/seed-$s
  [ -f "$kept/checkpoints/last.pt" ] || ${PYTHON:-python} results/manipulation/keep_source.py "$RUNS/measurements/$NAME/seed-$s" "$kept"
  ls "$kept"/evaluate-best-*-50ep.json > /dev/null 2>&1 || $DRLTG evaluate "$kept" --checkpoint best --episodes 50
done
${PYTHON:-python} results/manipulation/measurements/collapse.py "$NAME"
