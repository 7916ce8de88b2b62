#!/usr/bin/env bash
# The earlier implementation's own place tasks, step 2: the Lift source its rows reuse, SAC on lift-dense
# (robosuite's dense Lift reward, as the earlier implementation trained its source), before the rows.
#   bash results/seed_sources.sh      (RUNS=runs/seed-tasks by default; re-running resumes; CORE=0 pins one core)
#   ALGO=soc bash results/seed_sources.sh   the SOC-4 source (the soft option-critic, 4 options), in lift-dense-soc4
# Seeds 60, 61, 62 (target seed s reuses source seed s + 50, so no source and target run share a seed) as one
# seed group in one process, 500k frames each, the manipulation defaults (replay 1e6,
# batch 256, 2x256 nets, lr 3e-4, one update per frame, 2 envs a seed, 5k random warm-up frames), evaluated
# every 10k frames on 10 episodes; checkpoints every 20k frames and the best evaluation's (checkpoint.keep_best).
# A source holds when its success rate over the second half of training never falls below 0.7 and averages
# at least 0.9 on these 10-episode evaluations. Then keeps every seed's config.yaml, eval.csv (and summary.json
# once finished) in results/seed-tasks/sources/lift-dense-sac/.
set -euo pipefail
RUNS=${RUNS:-runs/seed-tasks}
DRLTG=${DRLTG:-drltg}
ALGO=${ALGO:-sac}
if [ "$ALGO" = soc ]; then name=lift-dense-soc4; learner=(--algo soc -o soc.num_options=4); else name=lift-dense-sac; learner=(); fi
dir=$RUNS/sources/$name
resume=(); [ -f "$dir/seed-60/config.yaml" ] && resume=(--resume)
pin=(); [ -n "${CORE:-}" ] && pin=(taskset -c "$CORE")
"${pin[@]}" $DRLTG train lift-dense "${learner[@]}" --seed 60 --seeds 3 --frames 500000 --run-dir "$dir" --no-progress \
  "${resume[@]}" -o eval.every=10000 -o eval.episodes=10 -o checkpoint.every=20000 -o checkpoint.keep_best=true || true
for run in "$dir"/seed-*; do
  keep=results/seed-tasks/sources/$name/${run##*/}; mkdir -p "$keep"
  for f in config.yaml eval.csv summary.json; do [ -f "$run/$f" ] && cp "$run/$f" "$keep/"; done
done
