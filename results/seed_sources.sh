#!/usr/bin/env bash
# The earlier implementation's own place tasks, step 2: the Lift sources its rows reuse, SAC (or SOC-4) on lift-dense
# (robosuite's dense Lift reward, as the earlier implementation trained its source), before the rows.
#   bash results/seed_sources.sh              (RUNS=runs/seed-tasks by default; re-running resumes)
#   CORES="0 1" bash results/seed_sources.sh  one run per core at a time (default: CORES=1)
#   ALGO=soc bash results/seed_sources.sh     the SOC-4 source (the soft option-critic, 4 options), in lift-dense-soc4
# Seeds 60, 61, 62 (target seed s reuses source seed s + 50, so no source and target run share a seed), each its
# own run pinned to one core, its envs stepped in-process (on one core that is faster than a seed group:
# `python -m benchmarks lift-seeds`), 500k frames, the manipulation defaults (replay 1e6, batch 256, 2x256 nets,
# lr 3e-4, one update per frame, 2 envs, 5k random warm-up frames), evaluated every 10k frames on 10 episodes;
# checkpoints every 20k frames and the best evaluation's (checkpoint.keep_best). A source holds when its success
# rate over the second half of training never falls below 0.7 and averages at least 0.9 on these 10-episode
# evaluations. Then keeps every seed's config.yaml, eval.csv (and summary.json once finished) in
# results/seed-tasks/sources/NAME/.
set -euo pipefail
RUNS=${RUNS:-runs/seed-tasks}
DRLTG=${DRLTG:-drltg}
ALGO=${ALGO:-sac}
read -r -a cores <<< "${CORES:-1}"
if [ "$ALGO" = soc ]; then name=lift-dense-soc4; learner=(--algo soc -o soc.num_options=4); else name=lift-dense-sac; learner=(); fi
seeds=(60 61 62)

run_seed() {  # core seed
  local dir=$RUNS/sources/$name/seed-$2 resume=()
  [ -f "$dir/config.yaml" ] && resume=(--resume)
  taskset -c "$1" $DRLTG train lift-dense "${learner[@]}" --seed "$2" --frames 500000 --run-dir "$dir" --no-progress \
    "${resume[@]}" -o eval.every=10000 -o eval.episodes=10 -o checkpoint.every=20000 -o checkpoint.keep_best=true || true
}

for i in "${!cores[@]}"; do  # core i takes seeds i, i + len(cores), ...
  ( for ((k = i; k < ${#seeds[@]}; k += ${#cores[@]})); do run_seed "${cores[i]}" "${seeds[k]}"; done ) &
done
wait
for run in "$RUNS/sources/$name"/seed-*; do
  keep=results/seed-tasks/sources/$name/${run##*/}; mkdir -p "$keep"
  for f in config.yaml eval.csv summary.json; do [ -f "$run/$f" ] && cp "$run/$f" "$keep/"; done
done
