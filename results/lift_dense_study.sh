#!/usr/bin/env bash
# A short study of SAC's update-to-data ratio, batch size and network width on Lift's dense reward:
#   bash results/lift_dense_study.sh      (RUNS=runs/study by default; one run at a time per core in $CORES)
# Each variant changes one setting of the manipulation defaults (one update per frame, batch 256, 2x256
# nets) and trains lift-dense for 30k frames from seed 0, evaluated every 10k frames on 4 episodes, in
# one process (env.parallel=false) pinned to one core, so its frames/s compare. Re-running resumes what
# is left; the curves and configs are kept in results/lift-dense-study/VARIANT/seed-0/.
set -euo pipefail
RUNS=${RUNS:-runs/study}
CORES=${CORES:-0 1}
DRLTG=${DRLTG:-drltg}
declare -A VARIANTS=(
  [default]=""
  [utd-0.5]="-o optim.updates_per_batch=50"
  [utd-2]="-o optim.updates_per_batch=200"
  [batch-512]="-o buffer.batch_size=512"
  [hidden-128]="-o network.hidden=[128,128]"
)
queue=("${!VARIANTS[@]}")
run() {  # run VARIANT CORE
  local dir="$RUNS/$1/seed-0" resume=()
  [ -f "$dir/summary.json" ] && return
  [ -f "$dir/config.yaml" ] && resume=(--resume)
  # shellcheck disable=SC2086
  taskset -c "$2" $DRLTG train lift-dense --seed 0 --frames 30000 --run-dir "$dir" --no-progress "${resume[@]}" \
    -o eval.every=10000 -o checkpoint.every=10000 -o env.parallel=false ${VARIANTS[$1]}
}
read -ra cores <<< "$CORES"
for ((i = 0; i < ${#queue[@]}; i += ${#cores[@]})); do
  for j in "${!cores[@]}"; do
    [ $((i + j)) -lt ${#queue[@]} ] && run "${queue[$((i + j))]}" "${cores[$j]}" &
  done
  wait
done

for name in "${queue[@]}"; do
  src="$RUNS/$name/seed-0"; dst="results/lift-dense-study/$name/seed-0"; mkdir -p "$dst"
  for f in config.yaml eval.csv summary.json; do cp "$src/$f" "$dst/"; done
done
