#!/usr/bin/env bash
# Model reuse + demonstrations, Lift -> Lift+Place with barrier, from the learned Lift source (SAC).
#   bash results/manipulation/combined-barrier.sh   (examples/sweeps/manipulation-rows/combined-barrier.yaml; row.sh says how)
exec bash "$(dirname "$0")/row.sh" combined-barrier
