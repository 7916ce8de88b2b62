#!/usr/bin/env bash
# Demonstrations, Lift -> Lift+Place with barrier, from the learned Lift source (SAC).
#   bash results/manipulation/demonstrations-barrier.sh   (examples/sweeps/manipulation-rows/demonstrations-barrier.yaml; row.sh says how)
exec bash "$(dirname "$0")/row.sh" demonstrations-barrier
