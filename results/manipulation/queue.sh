#!/usr/bin/env bash
# The manipulation study in one command: bash results/manipulation/queue.sh
#   (RUNS=runs/manipulation WORKERS=2 DRLTG=drltg PYTHON=python by default; ROWS="..." picks rows)
# 1. The kept sources, RUNS/sources/NAME/seed-<s> for seeds 0, 100, 200, that every row reuses:
#    lift-sac-ln-half  SAC on Lift with LayerNorm critics and 50 episodes of the scripted demonstrator
#               (1/2 of every batch, behaviour cloning at weight 10), 60k frames;
#    lift-soc4  the soft option-critic with 4 options on Lift with the same demonstrations (each credited
#               to an option drawn from its policy over options), SOC_FRAMES frames (default 60k).
#    Each keeps its best evaluated checkpoint (checkpoint.keep_best), which the rows reuse
#    (transfer.source_checkpoint=best), and is evaluated at it on 50 fresh episodes (drltg evaluate).
#    A complete run is skipped and an interrupted one resumed; WORKERS at a time; their curves, configs,
#    weights and that evaluation are kept in results/manipulation/sources/ (keep_source.py).
#    A source kept there is copied into RUNS rather than trained again (the rows then reuse the committed
#    weights); TRAIN_SOURCES=1 trains every missing source anew.
# 2. Every row in ROWS order (results/manipulation/ROW.sh); a row already reported is skipped.
set -euo pipefail
RUNS=${RUNS:-runs/manipulation}
WORKERS=${WORKERS:-2}
DRLTG=${DRLTG:-drltg}
SOC_FRAMES=${SOC_FRAMES:-60000}
ROWS=${ROWS:-"lift-shaping pi-reuse-place pi-reuse-barrier model-reuse-place soc-model-reuse-place
  demonstrations-place demonstrations-barrier combined-place combined-barrier demonstrations-reference-place
  demonstrations-reference-barrier"}
SEEDS="0 100 200"
EVAL="-o eval.every=5000 -o eval.episodes=10 -o checkpoint.every=5000 -o checkpoint.keep_best=true"
declare -A SOURCE=(
  [lift-sac-ln-half]="--frames 60000 -o transfer.method=demonstrations -o transfer.source=demonstrator:lift -o network.layer_norm=critics -o transfer.demo_ratio=0.5"
  [lift-soc4]="--algo soc --options 4 --frames $SOC_FRAMES -o transfer.method=demonstrations -o transfer.source=demonstrator:lift"
)
export OMP_NUM_THREADS=1 MKL_NUM_THREADS=1

for name in "${!SOURCE[@]}"; do
  for s in $SEEDS; do
    run=$RUNS/sources/$name/seed-$s
    kept=results/manipulation/sources/$name/seed-$s
    mkdir -p "$RUNS/sources/$name"
    if [ -z "${TRAIN_SOURCES:-}" ] && [ ! -e "$run" ] && [ -f "$kept/summary.json" ]; then
      cp -r "$kept" "$run"
    fi
    [ -f "$run/summary.json" ] && continue
    resume=""
    [ -f "$run/config.yaml" ] && resume=--resume
    echo "$DRLTG train lift --seed $s --run-dir $run $resume --no-progress ${SOURCE[$name]} $EVAL >> $run.log 2>&1"
  done
done | xargs -r -d '\n' -P "$WORKERS" -I{} bash -c '{}'

for name in "${!SOURCE[@]}"; do
  for s in $SEEDS; do
    final=$(grep -o '"success_rate": [0-9.]*' "$RUNS/sources/$name/seed-$s/summary.json" | tail -1)
    echo "source $name seed $s: final ${final:-success_rate unknown}"
    kept=results/manipulation/sources/$name/seed-$s
    [ -f "$kept/checkpoints/last.pt" ] || ${PYTHON:-python} results/manipulation/keep_source.py "$RUNS/sources/$name/seed-$s" "$kept"
    ls "$kept"/evaluate-best-*-50ep.json > /dev/null 2>&1 || $DRLTG evaluate "$kept" --checkpoint best --episodes 50
  done
done

for row in $ROWS; do
  bash "results/manipulation/$row.sh"
done
