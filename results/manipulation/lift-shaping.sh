#!/usr/bin/env bash
# Reward shaping on Lift: Lift's registered potential (reach, grasp, lift) added as gamma Phi(s') - Phi(s)
#   bash results/manipulation/lift-shaping.sh   (examples/sweeps/manipulation-rows/lift-shaping.yaml; row.sh says how)
exec bash "$(dirname "$0")/row.sh" lift-shaping
