#!/usr/bin/env bash
# Soft option-critic, 4 options, model reuse, Lift -> Lift+Place: starts from the SOC-4 Lift source's weights.
#   bash results/manipulation/soc-model-reuse-place.sh   (examples/sweeps/manipulation-rows/soc-model-reuse-place.yaml; row.sh says how)
exec bash "$(dirname "$0")/row.sh" soc-model-reuse-place
