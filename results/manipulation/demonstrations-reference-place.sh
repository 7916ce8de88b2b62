#!/usr/bin/env bash
# The upper reference on Lift+Place: demonstrations from the scripted demonstrator of the target itself
#   bash results/manipulation/demonstrations-reference-place.sh   (examples/sweeps/manipulation-rows/demonstrations-reference-place.yaml;
#   row.sh says how). Its runs, baselines included, go to RUNS/reference: its transfer runs share the method
#   folder name (demonstrations) with the row that transfers from the Lift source.
RUNS=${RUNS:-runs/manipulation}/reference exec bash "$(dirname "$0")/row.sh" demonstrations-reference-place
