#!/usr/bin/env bash
# Pendulum-v1, gravity 10 -> 15 (pair pendulum-heavier), model reuse against plain SAC, 5 paired seeds x 6k frames:
#   bash results/pendulum_heavier.sh   (RUNS=runs/pendulum-heavier; re-running finishes the rest)
# kept in results/pendulum-heavier/, reported (threshold -400: swung up and held), the prose regenerated.
set -euo pipefail
RUNS=${RUNS:-runs/pendulum-heavier} DRLTG=${DRLTG:-drltg} PYTHON=${PYTHON:-python} OUT=results/pendulum-heavier

OMP_NUM_THREADS=1 nice -n 19 $DRLTG experiment pendulum-heavier --method model-reuse --seeds 5 \
  --source-frames 6000 --frames 6000 --out "$RUNS" --threshold -400 \
  -o eval.episodes=10 -o log.tensorboard=false
$PYTHON -c "import sys; sys.path.insert(0, 'results'); from rebuild import keep_curves; from pathlib import Path; \
print(keep_curves(Path('$RUNS'), Path('$OUT')), 'runs kept')"
$DRLTG report --baseline "$OUT/baseline" --transfer "$OUT/transfer" --threshold -400 --baseline-label "no transfer" \
  --transfer-label "model reuse from g=10" --out "$OUT/report" > /dev/null
rm -f "$OUT/report/transfer_plot.svg"
$PYTHON results/claims.py
