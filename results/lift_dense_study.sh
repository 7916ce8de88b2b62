#!/usr/bin/env bash
# A short study of SAC's update-to-data ratio, batch size and network width on Lift's dense reward:
#   bash results/lift_dense_study.sh   (RUNS=runs/study WORKERS=2; re-running skips finished runs, resumes the rest)
# Each variant changes one setting of the manipulation defaults (one update per frame, batch 256, 2x256 nets) and
# trains lift-dense for 30k frames in one process (env.parallel=false), evaluated every 10k frames on 4 episodes;
# the curves and configs are kept in results/lift-dense-study/VARIANT/seed-S/.
set -euo pipefail
RUNS=${RUNS:-runs/study} WORKERS=${WORKERS:-2} DRLTG=${DRLTG:-drltg}
declare -A OVERRIDES=([default]="" [utd-0.5]="-o optim.updates_per_batch=50"
  [utd-2]="-o optim.updates_per_batch=200" [batch-128]="-o buffer.batch_size=128" [batch-512]="-o buffer.batch_size=512" [hidden-128]="-o network.hidden=[128,128]")
JOBS="default/0 utd-0.5/0 utd-0.5/1 utd-2/0 batch-128/0 batch-512/0 hidden-128/0 hidden-128/1"
for job in $JOBS; do
  variant=${job%/*} seed=${job#*/} dir=$RUNS/${job%/*}/seed-${job#*/}; resume=""
  [ -f "$dir/summary.json" ] && continue; [ -f "$dir/config.yaml" ] && resume=--resume
  echo "$DRLTG train lift-dense --seed $seed --frames 30000 --run-dir $dir --no-progress $resume -o eval.every=10000" \
    "-o checkpoint.every=10000 -o env.parallel=false ${OVERRIDES[$variant]}"
done | xargs -r -d '\n' -P "$WORKERS" -I{} bash -c '{}'
for job in $JOBS; do
  dst=results/lift-dense-study/${job%/*}/seed-${job#*/}; mkdir -p "$dst"
  cp "$RUNS/${job%/*}/seed-${job#*/}"/{config.yaml,eval.csv,summary.json} "$dst/"
done
