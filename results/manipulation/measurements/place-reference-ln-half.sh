#!/usr/bin/env bash
# The upper reference on Lift+Place with the stabilisers of the lift-sac-ln-half source: SAC with
# LayerNorm critics, half of every batch from the target's own demonstrator (demonstrator:lift-place: it
# lifts, carries and places), behaviour cloning at weight 10, keep_best; 3 seeds x 100k frames, evaluated
# every 5k frames on 10 episodes. Does it stop the collapses of demonstrations-reference-place?
#   bash results/manipulation/measurements/place-reference-ln-half.sh
# Trains, keeps, evaluates and replays it as measure.sh says.
NAME=place-reference-ln-half
TASK=lift-place
ARGS="--frames 100000 -o transfer.method=demonstrations -o transfer.source=demonstrator:lift-place
  -o network.layer_norm=critics -o transfer.demo_ratio=0.5
  -o eval.every=5000 -o eval.episodes=10 -o checkpoint.every=5000 -o checkpoint.keep_best=true"
. "$(dirname "$0")/measure.sh"
