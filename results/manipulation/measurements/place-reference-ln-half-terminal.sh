#!/usr/bin/env bash
# place-reference-ln-half on a Lift+Place whose episodes end when the cube is placed
# (env.terminate_on_success=true): the reward is 1 at the step that places and the return at most 1, where
# the task as registered pays 1 for every step the cube rests on the target, up to a discounted 100.
# Evaluation counts an episode that ever placed, as before, so the success rates compare. Does the bounded
# target keep the policy placing to the end? 3 seeds x 100k frames, evaluated every 5k frames on 10 episodes.
#   bash results/manipulation/measurements/place-reference-ln-half-terminal.sh
# Trains, keeps, evaluates and replays it as measure.sh says.
NAME=place-reference-ln-half-terminal
TASK=lift-place
ARGS="--frames 100000 -o env.terminate_on_success=true -o transfer.method=demonstrations
  -o transfer.source=demonstrator:lift-place -o network.layer_norm=critics -o transfer.demo_ratio=0.5
  -o eval.every=5000 -o eval.episodes=10 -o checkpoint.every=5000 -o checkpoint.keep_best=true"
. "$(dirname "$0")/measure.sh"
