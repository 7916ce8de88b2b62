#!/usr/bin/env bash
# Gymnasium's Pendulum-v1, gravity 10 -> 15 (the pair pendulum-heavier), model reuse against plain SAC:
#   bash results/pendulum_heavier.sh      (RUNS=runs/pendulum-heavier by default)
# 5 paired seeds: a source run on pendulum/g10 per seed, then baseline and transfer on pendulum/g15, 6k
# frames each with the tasks' SAC settings (2x64 nets, one update per frame), evaluated every 1k frames on
# 10 episodes; 15 runs in one single-threaded process at the lowest priority. Re-running finishes what is
# missing. Keeps every run's curve and config in results/pendulum-heavier/, reports the evaluation return
# (threshold -400: the pendulum swung up and held) and regenerates results/README.md's sentences from it.
set -euo pipefail
RUNS=${RUNS:-runs/pendulum-heavier}
DRLTG=${DRLTG:-drltg}
PYTHON=${PYTHON:-python}
OUT=results/pendulum-heavier

OMP_NUM_THREADS=1 nice -n 19 $DRLTG experiment pendulum-heavier --method model-reuse --seeds 5 \
  --source-frames 6000 --frames 6000 --out "$RUNS" --threshold -400 \
  -o eval.episodes=10 -o log.tensorboard=false
$PYTHON -c "import sys; sys.path.insert(0, 'results'); from rebuild import keep_curves; from pathlib import Path; \
print(keep_curves(Path('$RUNS'), Path('$OUT')), 'runs kept')"
$DRLTG report --baseline "$OUT/baseline" --transfer "$OUT/transfer" --threshold -400 --baseline-label "no transfer" \
  --transfer-label "model reuse from g=10" --out "$OUT/report" > /dev/null
rm -f "$OUT/report/transfer_plot.svg"
$PYTHON results/claims.py
