#!/usr/bin/env bash
# pi-reuse, Lift -> Lift+Place: the learned Lift source (SAC) acts with probability 0.95^h at step h.
#   bash results/manipulation/pi-reuse-place.sh   (examples/sweeps/manipulation-rows/pi-reuse-place.yaml; row.sh says how)
exec bash "$(dirname "$0")/row.sh" pi-reuse-place
