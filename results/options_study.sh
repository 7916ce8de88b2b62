#!/usr/bin/env bash
# "Do options transfer better than plain SAC under model reuse?" on the FourRooms near and far pairs:
#   bash results/options_study.sh        (RUNS=runs/options WORKERS=2 by default)
# For each learner (SAC, soft option-critic with K = 4 and K = 2): 5 source runs on fourrooms/northeast
# (40k frames), then 5 baseline and 5 model-reuse runs (20k frames) per pair. Both pairs have the same
# source task, so the far experiment reuses the near experiment's source runs (same configs and seeds).
# Re-running finishes what is missing.
set -euo pipefail
RUNS=${RUNS:-runs/options}
WORKERS=${WORKERS:-2}
DRLTG=${DRLTG:-drltg}
COMMON=(--method model-reuse --seeds 5 --frames 20000 --source-frames 40000 --threshold 0.5
        -o eval.every=1000 --workers "$WORKERS")
mkdir -p "$RUNS/logs"

study() {
  local name=$1; shift
  $DRLTG experiment fourrooms-near "${COMMON[@]}" "$@" --out "$RUNS/$name/fourrooms-near"
  mkdir -p "$RUNS/$name/fourrooms-far"
  [ -e "$RUNS/$name/fourrooms-far/source" ] || cp -r "$RUNS/$name/fourrooms-near/source" "$RUNS/$name/fourrooms-far/"
  $DRLTG experiment fourrooms-far "${COMMON[@]}" "$@" --out "$RUNS/$name/fourrooms-far"
}

study sac --algo sac > "$RUNS/logs/sac.log" 2>&1
study soc-k4 --algo soc -o soc.num_options=4 > "$RUNS/logs/soc-k4.log" 2>&1
study soc-k2 --algo soc -o soc.num_options=2 > "$RUNS/logs/soc-k2.log" 2>&1

# Into results/options/PAIR/LEARNER/: each learner's own transfer report (model reuse vs its baseline),
# and PAIR/soc-kK-vs-sac/: SOC's model-reuse runs against SAC's (both on the target task).
for pair in fourrooms-near fourrooms-far; do
  for name in sac soc-k4 soc-k2; do
    mkdir -p "results/options/$pair/$name"
    cp "$RUNS/$name/$pair"/report/transfer_metrics.{json,csv} "$RUNS/$name/$pair"/report/transfer_plot.png \
      "results/options/$pair/$name/"
  done
  for k in 4 2; do
    $DRLTG report --baseline "$RUNS/sac/$pair/transfer" --transfer "$RUNS/soc-k$k/$pair/transfer" \
      --baseline-label "SAC + model reuse" --transfer-label "SOC K=$k + model reuse" --threshold 0.5 \
      --out "results/options/$pair/soc-k$k-vs-sac" > /dev/null
    rm -f "results/options/$pair/soc-k$k-vs-sac/transfer_plot.svg"
  done
done
