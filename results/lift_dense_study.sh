#!/usr/bin/env bash
# A short study of SAC's update-to-data ratio, batch size and network width on Lift's dense reward:
#   bash results/lift_dense_study.sh      (RUNS=runs/study by default; one run per core in $CORES at a time)
# Each variant changes one setting of the manipulation defaults (one update per frame, batch 256, 2x256
# nets) and trains lift-dense for 30k frames, evaluated every 10k frames on 4 episodes, in one process
# (env.parallel=false). Seed 0 of "default" repeats the first 30k frames of results/lift-dense's seed 0
# (and seed 1 those of its seed 1). Re-running skips finished runs and resumes interrupted ones; the
# curves and configs are kept in results/lift-dense-study/VARIANT/seed-S/.
set -euo pipefail
RUNS=${RUNS:-runs/study}
CORES=${CORES:-0 1}
DRLTG=${DRLTG:-drltg}
declare -A OVERRIDES=(
  [default]=""
  [utd-0.5]="-o optim.updates_per_batch=50"
  [utd-2]="-o optim.updates_per_batch=200"
  [batch-128]="-o buffer.batch_size=128"
  [batch-512]="-o buffer.batch_size=512"
  [hidden-128]="-o network.hidden=[128,128]"
)
RUNS_TO_DO=(default/0 utd-0.5/0 utd-0.5/1 utd-2/0 batch-128/0 batch-512/0 hidden-128/0 hidden-128/1)

run() {  # run VARIANT/SEED CORE
  local variant=${1%/*} seed=${1#*/}
  local dir="$RUNS/$variant/seed-$seed" resume=()
  [ -f "$dir/summary.json" ] && return
  [ -f "$dir/config.yaml" ] && resume=(--resume)
  # shellcheck disable=SC2086
  taskset -c "$2" $DRLTG train lift-dense --seed "$seed" --frames 30000 --run-dir "$dir" --no-progress \
    "${resume[@]}" -o eval.every=10000 -o checkpoint.every=10000 -o env.parallel=false ${OVERRIDES[$variant]}
}
read -ra cores <<< "$CORES"
for ((i = 0; i < ${#RUNS_TO_DO[@]}; i += ${#cores[@]})); do
  for j in "${!cores[@]}"; do
    if [ $((i + j)) -lt ${#RUNS_TO_DO[@]} ]; then run "${RUNS_TO_DO[$((i + j))]}" "${cores[$j]}" & fi
  done
  wait
done

for job in "${RUNS_TO_DO[@]}"; do
  src="$RUNS/${job%/*}/seed-${job#*/}"; dst="results/lift-dense-study/${job%/*}/seed-${job#*/}"; mkdir -p "$dst"
  for f in config.yaml eval.csv summary.json; do cp "$src/$f" "$dst/"; done
done
