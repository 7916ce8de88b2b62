#!/usr/bin/env bash
# place-reference-ln-half with demonstrations collected under action noise (transfer.demo_noise=0.1: the
# demonstrator still places in 10 of 10 episodes at sigma 0.1, placement-diagnostics/noise.csv). The
# collapsed place-reference-ln-half policies still act as the demonstrator at its own states
# (demonstrated.csv), so they fail in states the demonstrations do not cover; noisy episodes cover the
# states around its path and how it recovers from them. Does that keep the policy placing to the end?
# 3 seeds x 100k frames, evaluated every 5k frames on 10 episodes.
#   bash results/manipulation/measurements/place-reference-ln-half-noisy.sh
# Trains, keeps, evaluates and replays it as measure.sh says.
NAME=place-reference-ln-half-noisy
TASK=lift-place
ARGS="--frames 100000 -o transfer.method=demonstrations -o transfer.source=demonstrator:lift-place
  -o transfer.demo_noise=0.1 -o network.layer_norm=critics -o transfer.demo_ratio=0.5
  -o eval.every=5000 -o eval.episodes=10 -o checkpoint.every=5000 -o checkpoint.keep_best=true"
. "$(dirname "$0")/measure.sh"
