#!/usr/bin/env bash
# Demonstrations, Lift -> Lift+Place: 50 episodes of the learned Lift source (SAC), 1/4 of every batch,
#   bash results/manipulation/demonstrations-place.sh   (examples/sweeps/manipulation-rows/demonstrations-place.yaml; row.sh says how)
exec bash "$(dirname "$0")/row.sh" demonstrations-place
