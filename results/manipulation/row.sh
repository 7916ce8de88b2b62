#!/usr/bin/env bash
# One row of the manipulation study: bash results/manipulation/row.sh ROW (each ROW.sh beside it calls it).
# Trains examples/sweeps/manipulation-rows/ROW.yaml in RUNS (default runs/manipulation), beside the other
# rows: one target's baselines serve every row on it, and the transfer run of seed s reuses the kept source
# run RUNS/sources/NAME/seed-<s> (queue.sh trains them first). WORKERS runs at a time (default 2, both
# cores); re-running finishes what is missing, and a row whose report is in results/ is skipped (FORCE=1
# reports it again). Then keeps the row's curves and configs (its baselines, transfer runs and the source
# runs they reuse, in the runs' layout) in results/manipulation/ROW/, reports the evaluation return at the
# spec's threshold in PAIR/ALGO/METHOD/report/, and in report-STAGE/ the success rate (threshold 0.8 on
# Lift, 0.5 on the placing targets) and, on the placing targets, the lifted rate (0.8).
set -euo pipefail
ROW=$1
RUNS=${RUNS:-runs/manipulation}
WORKERS=${WORKERS:-2}
DRLTG=${DRLTG:-drltg}
PYTHON=${PYTHON:-python}
SPEC=${SPECS:-examples/sweeps/manipulation-rows}/$ROW.yaml
OUT=results/manipulation/$ROW

read -r PAIR ALGO METHOD THRESHOLD SOURCE < <($PYTHON - "$SPEC" <<'PY'
import sys
import yaml
spec = yaml.safe_load(open(sys.argv[1]))
source = (spec.get("overrides") or {}).get("transfer.source")
print(spec["pairs"][0], spec["algos"][0], spec["methods"][0], spec["threshold"],
      source.split("/")[-2] if source and "{seed}" in source else "-")
PY
)
GROUP=$PAIR/$ALGO
if [ -z "${FORCE:-}" ] && [ -f "$OUT/$GROUP/$METHOD/report/transfer_metrics.json" ]; then
  echo "$ROW: reported in $OUT (FORCE=1 to report again)"
  exit 0
fi

# BASELINES=DIR: the complete baselines of the same config in DIR (trained beside the other rows) serve this
# row too: their defining files are copied in (the sweep refuses a copy whose config differs).
if [ -n "${BASELINES:-}" ]; then
  for run in "$BASELINES/$GROUP/baseline"/seed-*; do
    copy=$RUNS/$GROUP/baseline/${run##*/}
    [ -f "$run/summary.json" ] && [ ! -e "$copy" ] || continue
    mkdir -p "$copy"
    cp "$run/config.yaml" "$run/eval.csv" "$run/summary.json" "$copy/"
  done
fi
mkdir -p "$RUNS/specs"
sed "s#runs/manipulation/sources/#$RUNS/sources/#" "$SPEC" > "$RUNS/specs/$ROW.yaml"
$DRLTG sweep "$RUNS/specs/$ROW.yaml" --out "$RUNS" --workers "$WORKERS" --no-seed-groups  # every run alone, as its pair

only=(--only "$GROUP/baseline" --only "$GROUP/$METHOD")
[ "$SOURCE" != - ] && only+=(--only "sources/$SOURCE")
$PYTHON results/rebuild.py "$OUT" --from "$RUNS" "${only[@]}" --threshold "$THRESHOLD"
if [ "$PAIR" = lift ]; then stages="success:0.8"; else stages="success:0.5 lifted:0.8"; fi
for stage in $stages; do
  tag=${stage%%:*}
  $DRLTG report --baseline "$OUT/$GROUP/baseline" --transfer "$OUT/$GROUP/$METHOD/transfer" --tag "${tag}_rate" \
    --threshold "${stage##*:}" --baseline-label "no transfer" --transfer-label "$METHOD" \
    --out "$OUT/$GROUP/$METHOD/report-$tag" > /dev/null
  rm -f "$OUT/$GROUP/$METHOD/report-$tag/transfer_plot.svg"
done
