#!/usr/bin/env bash
# The manipulation study in one command: bash results/manipulation/run.sh   (hours; re-running finishes what is
# missing; RUNS=runs/manipulation WORKERS=2 DRLTG=drltg PYTHON=python; ROWS="..." picks rows, FORCE=1 reports a
# reported row again, TRAIN_SOURCES=1 trains the kept sources anew, EARLIER=1 reports the earlier runs alone).
# 1. The sources RUNS/sources/NAME/seed-<s>, seeds 0, 100, 200, each keeping its best checkpoint, which the rows
#    reuse (SOURCE below); one kept in results/manipulation/sources/ is copied rather than trained, then kept
#    without its training checkpoints (config, curve, summary, manifest, networks) and its best networks
#    evaluated on 50 fresh episodes.
# 2. Each row, examples/sweeps/manipulation-rows/ROW.yaml, by `drltg sweep --no-seed-groups` in RUNS (a target's
#    baselines serve every row on it; the reference rows' transfers go to RUNS/reference beside copies of the
#    others' complete baselines), kept and reported (rebuild.py) in results/manipulation/ROW/, with report-STAGE/
#    for the success rate (threshold 0.8 on Lift, 0.5 placing) and, placing, the lifted rate (0.8).
# 3. EARLIER=1: the earlier implementation's rows (tests/data/sb3_runs, a run a side) in earlier/ROW/, whole
#    and cut at the study's 100k frames (at-100k/).
set -euo pipefail
RUNS=${RUNS:-runs/manipulation} WORKERS=${WORKERS:-2} DRLTG=${DRLTG:-drltg} PYTHON=${PYTHON:-python}
ROWS=${ROWS:-"lift-shaping pi-reuse-place pi-reuse-barrier model-reuse-place soc-model-reuse-place
  demonstrations-place demonstrations-barrier combined-place combined-barrier demonstrations-reference-place
  demonstrations-reference-barrier"}
OUT=results/manipulation
EVAL="-o eval.every=5000 -o eval.episodes=10 -o checkpoint.every=5000 -o checkpoint.keep_best=true"
declare -A SOURCE=(
  [lift-sac-ln-half]="--frames 60000 -o transfer.method=demonstrations -o transfer.source=demonstrator:lift -o network.layer_norm=critics -o transfer.demo_ratio=0.5 -o transfer.bc_weight=10 -o transfer.bc_alpha=null -o transfer.bc_q_filter=false"
  [lift-soc4]="--algo soc --options 4 --frames 60000 -o transfer.method=demonstrations -o transfer.source=demonstrator:lift -o transfer.bc_weight=10 -o transfer.bc_alpha=null -o transfer.bc_q_filter=false"
)
export OMP_NUM_THREADS=1 MKL_NUM_THREADS=1
report() {  # BASELINE TRANSFER OUT LABELS... [drltg report flags]
  $DRLTG report --baseline "$1" --transfer "$2" --out "$3" "${@:4}" > /dev/null; rm -f "$3/transfer_plot.svg"
}
if [ -n "${EARLIER:-}" ]; then
  for row in "lift-shaping lift_sparse_sac lift_shaped_sac" "pi-reuse-place liftplace_sac liftplace_sac_policyreuse" \
    "pi-reuse-barrier liftplacebarrier_sac liftplacebarrier_sac_policyreuse" "soc-model-reuse-place liftplace_sac liftplace_soc4"; do
    read -r name b t <<< "$row"; labels=(--baseline-label "$b (1 run)" --transfer-label "$t (1 run)")
    report tests/data/sb3_runs/$b tests/data/sb3_runs/$t $OUT/earlier/$name "${labels[@]}"
    report tests/data/sb3_runs/$b tests/data/sb3_runs/$t $OUT/earlier/$name/at-100k "${labels[@]}" --budget 100000
    rm -f $OUT/earlier/$name/at-100k/transfer_plot.png
  done
  exit 0
fi
for name in "${!SOURCE[@]}"; do for s in 0 100 200; do
  run=$RUNS/sources/$name/seed-$s kept=$OUT/sources/$name/seed-$s; mkdir -p "$RUNS/sources/$name"
  [ -z "${TRAIN_SOURCES:-}" ] && [ ! -e "$run" ] && [ -f "$kept/summary.json" ] && cp -r "$kept" "$run"
  [ -f "$run/summary.json" ] && continue
  resume=""; [ -f "$run/config.yaml" ] && resume=--resume
  echo "$DRLTG train lift --seed $s --run-dir $run $resume --no-progress ${SOURCE[$name]} $EVAL >> $run.log 2>&1"
done; done | xargs -r -d '\n' -P "$WORKERS" -I{} bash -c '{}'
for name in "${!SOURCE[@]}"; do for s in 0 100 200; do
  kept=$OUT/sources/$name/seed-$s
  run=$RUNS/sources/$name/seed-$s; [ -f "$kept/summary.json" ] || { mkdir -p "$kept/checkpoints" &&
    cp "$run"/{config.yaml,eval.csv,summary.json,manifest.json} "$kept/" && cp "$run"/checkpoints/*.safetensors "$kept/checkpoints/"; }
  ls "$kept"/evaluate-best-*-50ep.json > /dev/null 2>&1 || $DRLTG evaluate "$kept" --checkpoint best --episodes 50
done; done
for row in $ROWS; do
  spec=examples/sweeps/manipulation-rows/$row.yaml runs=$RUNS
  read -r pair algo method threshold source < <($PYTHON -c 'import sys, yaml; s = yaml.safe_load(open(sys.argv[1]))
src = (s.get("overrides") or {}).get("transfer.source") or "-"
print(s["pairs"][0], s["algos"][0], s["methods"][0], s["threshold"], src.split("/")[-2] if "{seed}" in src else "-")' "$spec")
  group=$pair/$algo dest=$OUT/$row
  [ -z "${FORCE:-}" ] && [ -f "$dest/$group/$method/report/transfer_metrics.json" ] && continue
  if [[ $row == demonstrations-reference-* ]]; then  # its method folder is another row's: its own RUNS
    runs=$RUNS/reference
    for base in "$RUNS/$group/baseline"/seed-*; do copy=$runs/$group/baseline/${base##*/}
      [ -f "$base/summary.json" ] && [ ! -e "$copy" ] || continue
      mkdir -p "$copy"; cp "$base/config.yaml" "$base/eval.csv" "$base/summary.json" "$copy/"
    done
  fi
  mkdir -p "$runs/specs"; sed "s#runs/manipulation/sources/#$RUNS/sources/#" "$spec" > "$runs/specs/$row.yaml"
  $DRLTG sweep "$runs/specs/$row.yaml" --out "$runs" --workers "$WORKERS" --no-seed-groups
  only=(--only "$group/baseline" --only "$group/$method"); [ "$source" != - ] && only+=(--only "sources/$source")
  $PYTHON results/rebuild.py "$dest" --from "$runs" "${only[@]}" --threshold "$threshold"
  if [ "$pair" = lift ]; then stages="success:0.8"; else stages="success:0.5 lifted:0.8"; fi
  for stage in $stages; do
    report "$dest/$group/baseline" "$dest/$group/$method/transfer" "$dest/$group/$method/report-${stage%%:*}" \
      --tag "${stage%%:*}_rate" --threshold "${stage##*:}" --baseline-label "no transfer" --transfer-label "$method"
  done
done
