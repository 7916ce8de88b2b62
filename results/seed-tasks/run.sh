#!/usr/bin/env bash
# The seed's tasks, every run one drltg command: bash results/seed-tasks/run.sh  (RUNS=runs/seed-tasks WORKERS=2;
# re-running skips finished runs and resumes the others; hours). 1. the sources on lift-dense, seeds 60-62, 60k
# frames, with the demonstrator's 50 episodes, best.pt scored on 50 fresh episodes; 2. each row's baseline and
# transfer runs, seeds 10-12, 300k frames (transfer seed s reuses source seed s + 50 at best.pt), WORKERS at a
# time, the lift-place-seed SAC baselines first as one seed group (one process); 3. each row's reports into
# results/seed-tasks/ROW/.
set -euo pipefail
RUNS=${RUNS:-runs/seed-tasks} WORKERS=${WORKERS:-2} DRLTG=${DRLTG:-drltg}
export OMP_NUM_THREADS=1
train() {  # RUN_DIR TASK SEED FRAMES FLAGS...: one job line, resumed where it stopped, none once finished
  local dir=$1 task=$2 seed=$3 frames=$4; shift 4
  [ -f "$dir/summary.json" ] && return; mkdir -p "$(dirname "$dir")"; [ -f "$dir/config.yaml" ] && set -- --resume "$@"
  echo "$DRLTG train $task --seed $seed --frames $frames --run-dir $dir --no-progress $* > $dir.log 2>&1"
}
queue() { awk '!seen[$0]++' | xargs -r -d '\n' -P "$WORKERS" -I{} bash -c '{}'; }
SOURCE="-o eval.every=5000 -o eval.episodes=10 -o checkpoint.every=5000 -o checkpoint.keep_best=true
  -o transfer.method=demonstrations -o transfer.source=demonstrator:lift"
declare -A LEARNER=([lift-dense-sac]="-o network.layer_norm=critics -o transfer.demo_ratio=0.5"
                    [lift-dense-soc4]="--algo soc -o soc.num_options=4")
for s in 60 61 62; do for name in lift-dense-sac lift-dense-soc4; do
  train "$RUNS/sources/$name/seed-$s" lift-dense $s 60000 ${LEARNER[$name]} $SOURCE
done; done | queue
for name in lift-dense-sac lift-dense-soc4; do for s in 60 61 62; do
  $DRLTG evaluate "$RUNS/sources/$name/seed-$s" --checkpoint best --episodes 50
done; done
ROW="-o eval.every=10000 -o eval.episodes=10 -o checkpoint.every=20000"
base=$RUNS/lift-place-seed/sac/baseline resume=""; [ -f "$base/seed-10/config.yaml" ] && resume=--resume
[ -f "$base/seed-12/summary.json" ] ||
  $DRLTG train lift-place-seed --seed 10 --seeds 3 --frames 300000 --run-dir "$base" --no-progress $resume $ROW
for s in 10 11 12; do keep=results/seed-tasks/lift-place-seed/sac/baseline/seed-$s; mkdir -p "$keep"
  cp "$base/seed-$s"/{config.yaml,eval.csv,summary.json} "$keep/"; done
rows=(  # row | target | algo | its learner flags | baseline folder | transfer flags | source (none: -)
  "shaping-lift-seed|lift|sac||baseline|-o env.reward_shaping=true|-"
  "pi-reuse-place-seed|lift-place-seed|sac||baseline|-o transfer.method=policy-reuse|lift-dense-sac"
  "pi-reuse-barrier-seed|lift-place-barrier-seed|sac||baseline|-o transfer.method=policy-reuse|lift-dense-sac"
  "model-reuse-place-seed|lift-place-seed|sac|-o network.layer_norm=critics|baseline-ln|-o transfer.method=model-reuse|lift-dense-sac"
  "soc-model-reuse-place-seed|lift-place-seed|soc|-o soc.num_options=4|baseline|-o transfer.method=model-reuse|lift-dense-soc4")
for row in "${rows[@]}"; do IFS='|' read -r name task algo learner base extra source <<< "$row"
  for s in 10 11 12; do
    [ "$source" = - ] || extra+=" -o transfer.source=$RUNS/sources/$source/seed-$((s + 50)) -o transfer.source_checkpoint=best"
    train "$RUNS/$task/$algo/$base/seed-$s" "$task" $s 300000 --algo $algo $learner $ROW
    train "$RUNS/$task/$algo/$name/seed-$s" "$task" $s 300000 --algo $algo $learner $ROW $extra
    extra=${extra%% -o transfer.source=*}
  done
done | queue
for row in "${rows[@]}"; do IFS='|' read -r name task algo learner base extra source <<< "$row"
  out=results/seed-tasks/$name  # each run's curve and config kept beside the reports, which read them
  for side in baseline transfer; do for s in 10 11 12; do
    run=$RUNS/$task/$algo/$([ $side = baseline ] && echo "$base" || echo "$name")/seed-$s; mkdir -p "$out/$side/seed-$s"
    cp "$run/config.yaml" "$run/eval.csv" "$run/summary.json" "$out/$side/seed-$s/"
  done; done
  sides=(--baseline "$out/baseline" --transfer "$out/transfer" --baseline-label "no transfer"
         --transfer-label "$name")
  if [ "$task" = lift ]; then  # the two sides are paid by different rewards: Lift's success alone compares them
    $DRLTG report "${sides[@]}" --tag success_rate --threshold 0.5 --allow-mismatch --out "$out/report-success"
    continue
  fi
  $DRLTG report "${sides[@]}" --threshold 50 --out "$out/report"
  $DRLTG report "${sides[@]}" --tag success_rate --threshold 0.5 --out "$out/report-success"
  $DRLTG report "${sides[@]}" --tag lifted_rate --threshold 0.8 --out "$out/report-lifted"
done
