#!/usr/bin/env bash
# Model reuse + demonstrations, Lift -> Lift+Place: the learned Lift source's weights and its episodes.
#   bash results/manipulation/combined-place.sh   (examples/sweeps/manipulation-rows/combined-place.yaml; row.sh says how)
exec bash "$(dirname "$0")/row.sh" combined-place
