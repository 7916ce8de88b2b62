#!/usr/bin/env bash
# SAC model reuse, Lift -> Lift+Place: the learner starts from the learned Lift source's weights.
#   bash results/manipulation/model-reuse-place.sh   (examples/sweeps/manipulation-rows/model-reuse-place.yaml; row.sh says how)
exec bash "$(dirname "$0")/row.sh" model-reuse-place
