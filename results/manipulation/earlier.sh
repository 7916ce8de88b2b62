#!/usr/bin/env bash
# The earlier implementation's manipulation rows, one run per side (tests/data/sb3_runs: Stable-Baselines3
# 1.6 logs, robosuite 1.4, seed 69), reported with drltg's report so they sit beside the study's rows:
#   bash results/manipulation/earlier.sh     (seconds; writes results/manipulation/earlier/ROW/, each run's whole
#   length, and ROW/at-100k/, cut at the study's 100k frames)
# Where the earlier logs hold both sides of a row. Their evaluation return is the earlier tasks' own reward:
# lift_shaped_sac is evaluated on robosuite's dense reward and lift_sparse_sac on the sparse one, so the
# lift-shaping row mixes two reward scales; no SOC run without transfer was logged, so soc-model-reuse-place
# sets the SOC run beside the SAC run on Lift+Place. No SAC model-reuse run was logged.
set -euo pipefail
DRLTG=${DRLTG:-drltg}
LOGS=tests/data/sb3_runs
OUT=results/manipulation/earlier
rows=(
  "lift-shaping lift_sparse_sac lift_shaped_sac"
  "pi-reuse-place liftplace_sac liftplace_sac_policyreuse"
  "pi-reuse-barrier liftplacebarrier_sac liftplacebarrier_sac_policyreuse"
  "soc-model-reuse-place liftplace_sac liftplace_soc4"
)
for row in "${rows[@]}"; do
  read -r name baseline transfer <<< "$row"
  $DRLTG report --baseline "$LOGS/$baseline" --transfer "$LOGS/$transfer" \
    --baseline-label "$baseline (1 run)" --transfer-label "$transfer (1 run)" --out "$OUT/$name" > /dev/null
  rm -f "$OUT/$name/transfer_plot.svg"
  $DRLTG report --baseline "$LOGS/$baseline" --transfer "$LOGS/$transfer" --budget 100000 \
    --baseline-label "$baseline (1 run)" --transfer-label "$transfer (1 run)" --out "$OUT/$name/at-100k" > /dev/null
  rm -f "$OUT/$name/at-100k/transfer_plot."{svg,png}
done
