#!/usr/bin/env bash
# pi-reuse, Lift -> Lift+Place with barrier, from the learned Lift source (SAC).
#   bash results/manipulation/pi-reuse-barrier.sh   (examples/sweeps/manipulation-rows/pi-reuse-barrier.yaml; row.sh says how)
exec bash "$(dirname "$0")/row.sh" pi-reuse-barrier
