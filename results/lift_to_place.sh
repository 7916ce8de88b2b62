#!/usr/bin/env bash
# Lift -> Lift+Place with probabilistic policy reuse, the short CPU run in results/lift-to-place/:
#   bash results/lift_to_place.sh           (RUNS=runs/results WORKERS=2 by default)
# The past policy is the lift task's scripted demonstrator (reach, grasp, lift; it never places), so
# no source runs are trained. 2 seeds per side, 15k frames per run, SAC with the manipulation defaults
# (replay 1e6, batch 256, 2x256 nets, lr 3e-4, one update per frame) except 2k random warm-up frames
# and an evaluation (4 episodes) every 5k frames. upsilon = 0.99: psi_h = 0.99^h is 0.74 at step 30,
# when the demonstrator alone has lifted the cube; with 0.95 (0.21 at step 30) it mixed with random
# actions never lifted it in 6 probe episodes, with 0.99 in 3 of 6. Re-running finishes what is missing.
set -euo pipefail
RUNS=${RUNS:-runs/results}
WORKERS=${WORKERS:-2}
DRLTG=${DRLTG:-drltg}
OUT="$RUNS/lift-to-place/policy-reuse"

$DRLTG experiment lift-to-place --method policy-reuse --seeds 2 --frames 15000 \
  -o transfer.source=demonstrator:lift -o transfer.upsilon=0.99 \
  -o collector.init_random_frames=2000 -o eval.every=5000 \
  --threshold 1 --workers "$WORKERS" --out "$OUT"

mkdir -p results/lift-to-place/policy-reuse
cp "$OUT"/report/transfer_metrics.{json,csv} "$OUT"/report/transfer_plot.png results/lift-to-place/policy-reuse/

# With a SAC source trained on lift instead of the demonstrator (source runs in $OUT/source):
#   $DRLTG experiment lift-to-place --method policy-reuse --seeds 5 --frames 1000000 --source-frames 1000000 \
#     --threshold 1 --workers "$WORKERS" --out "$RUNS/lift-to-place/policy-reuse-sac"
