#!/usr/bin/env bash
# Suite v2's quick tier from nothing: the shared sources, the baseline's tuning, then every built-in method's
# tuning and row, and the board. Running it again resumes (finished runs are kept).
# Usage: results/bench/v2.sh [OUT]   (default results/bench)
set -euo pipefail
out=${1:-results/bench}
flags=(--suite v2 --out "$out" --no-progress)
drltg bench sources "${flags[@]}"
drltg bench tune --method none --reference none "${flags[@]}"
for method in model-reuse value-shaping policy-reuse kickstarting reward-shaping jumpstart demonstrations sf-gpi; do
  drltg bench tune --method "$method" --reference none "${flags[@]}"
  drltg bench run --method "$method" --reference none "${flags[@]}"
done
drltg bench report --suite v2 --out "$out" --reference none
