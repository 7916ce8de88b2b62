#!/usr/bin/env bash
# place-reference-ln-half with the registered shaping potential added (reward-shaping+demonstrations):
# Phi grows as the lifted cube nears the target, so a cube set down beside it (where the collapsed
# place-reference-ln-half policies leave some, collapse.csv) is worth less than one over it. Does it keep
# the policy placing to the end? 3 seeds x 100k frames, evaluated every 5k frames on 10 episodes (unshaped).
#   bash results/manipulation/measurements/place-reference-ln-half-shaped.sh
# Trains, keeps, evaluates and replays it as measure.sh says.
NAME=place-reference-ln-half-shaped
TASK=lift-place
ARGS="--frames 100000 -o transfer.method=reward-shaping+demonstrations -o transfer.source=demonstrator:lift-place
  -o network.layer_norm=critics -o transfer.demo_ratio=0.5
  -o eval.every=5000 -o eval.episodes=10 -o checkpoint.every=5000 -o checkpoint.keep_best=true"
. "$(dirname "$0")/measure.sh"
