#!/usr/bin/env bash
# The upper reference on Lift+Place: demonstrations from the scripted demonstrator of the target itself
#   bash results/manipulation/demonstrations-reference-place.sh   (examples/sweeps/manipulation-rows/demonstrations-reference-place.yaml;
#   row.sh says how). Its transfer runs go to RUNS/reference, as they share the method folder name
#   (demonstrations) with the row that transfers from the Lift source; its baselines are those of the
#   other rows on the target, copied from RUNS (BASELINES) where they are complete.
RUNS=${RUNS:-runs/manipulation}
BASELINES=$RUNS RUNS=$RUNS/reference exec bash "$(dirname "$0")/row.sh" demonstrations-reference-place
