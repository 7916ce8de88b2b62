#!/usr/bin/env bash
# drltg bench v1's reference rows, tier quick, kept in results/bench/v1/quick/ with their leaderboard:
#   bash results/bench.sh     (RUNS=runs/bench; about 2 hours on 2 cores; re-running resumes)
# 1. baselines and reward/value shaping, policy/model reuse on (grid) FourRooms: the graded and grid sweeps' runs (same
#    protocol); 2. every built-in method by `drltg bench run`; 3. configs, curves, summaries and the sources' networks
#    (what a user's bench run reuses) kept, the reports made again there (every run is there), each group's summary
#    of every method, the leaderboard.
set -euo pipefail && shopt -s nullglob && export OMP_NUM_THREADS=1
RUNS=${RUNS:-runs/bench} DRLTG=${DRLTG:-drltg} PYTHON=${PYTHON:-python} TIER=$RUNS/v1/quick KEEP=results/bench/v1/quick
METHODS="reward-shaping value-shaping policy-reuse jumpstart model-reuse demonstrations kickstarting sf-gpi" && mkdir -p "$TIER" "$KEEP"
for cell in results/sweep-{fourrooms-graded,gridrooms}/*/sac/{baseline,{reward,value}-shaping/transfer,{policy,model}-reuse/transfer}; do
  group=$(cut -d/ -f2 <<< "$cell" | sed 's/sweep-//; s/-graded//') to=$TIER/$group/${cell#results/*/}
  [ -d "$to" ] || { mkdir -p "$(dirname "$to")" && cp -r "$cell" "$to"; }
done
for m in $METHODS; do $DRLTG bench run --method "$m" --suite v1 --out "$RUNS" --reference none --workers 2 --no-progress; done
(cd "$TIER" && find . -name summary.json -printf '%h\n') | while read -r run; do
  mkdir -p "$KEEP/$run" && cp "$TIER/$run"/{config.yaml,eval.csv,summary.json} "$KEEP/$run/"
  [[ $run != */source/* ]] || { mkdir -p "$KEEP/$run/checkpoints" && cp "$TIER/$run/manifest.json" "$KEEP/$run/" &&
    cp "$TIER/$run/checkpoints/last.safetensors" "$KEEP/$run/checkpoints/"; }
done
for m in $METHODS; do $DRLTG bench run --method "$m" --suite v1 --out results/bench --reference none --no-progress > /dev/null; done
$PYTHON results/rebuild.py --again "$KEEP" > /dev/null  # each group summary of every method (a bench run summarises its own)
find "$KEEP" \( -name '*.png' -o -name '*.svg' -o -name '*.log' -o -name runs.csv \) -delete
$DRLTG bench report --suite v1 --out results/bench --reference results/bench && $PYTHON results/claims.py
