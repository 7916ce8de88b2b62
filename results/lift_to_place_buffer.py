"""What the Lift -> Lift+Place runs collected: per run, the share of training frames (after the random
warm-up) in which the cube is grasped, has been lifted in the episode, or rests placed (reward > 0),
read from the replay buffer in each finished run's last checkpoint.

    python results/lift_to_place_buffer.py runs/results/lift-to-place/policy-reuse
"""
import sys
from pathlib import Path

import torch
import yaml

from drltg.envs.robosuite import LAYOUT

root = Path(sys.argv[1] if len(sys.argv) > 1 else "runs/results/lift-to-place/policy-reuse")
print("| run | frames | cube grasped | cube lifted | placed (reward > 0) |")
print("|---|---|---|---|---|")
for run in sorted(r.parent for r in root.glob("*/seed-*/summary.json")):  # finished runs
    warm_up = yaml.safe_load((run / "config.yaml").read_text())["collector"]["init_random_frames"]
    storage = torch.load(run / "checkpoints" / "last.pt", weights_only=False)["buffer"]["_storage"]
    frames = storage["_len"]
    obs = storage["_storage"]["next.observation"][warm_up:frames]
    reward = storage["_storage"]["next.reward"][warm_up:frames]
    share = [obs[:, LAYOUT["cube_grasped"]].mean(), obs[:, LAYOUT["cube_lifted"]].mean(), (reward > 0).float().mean()]
    print(
        f"| {run.parent.name}/{run.name} | {frames - warm_up} | " + " | ".join(f"{100 * s:.1f}%" for s in share) + " |"
    )
