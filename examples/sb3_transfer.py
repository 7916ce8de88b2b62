"""A Stable-Baselines3 agent on a drltg task pair through Gymnasium, then drltg's transfer report.

    pip install "drltg[bench]"          # Stable-Baselines3
    python examples/sb3_transfer.py     # FRAMES=20000 SEEDS=5 OUT=sb3 by default
    drltg report --baseline sb3/baseline --transfer sb3/transfer --threshold 0.5

Per seed: SAC learns the source task, then the target task from scratch (baseline) and from the
source agent's weights (transfer: SB3's own model reuse); each target run logs its evaluations to
``OUT/<side>/seed-<s>/progress.csv``, which ``drltg report`` reads as it reads drltg runs.
"""
import os

import gymnasium
from stable_baselines3 import SAC
from stable_baselines3.common.callbacks import EvalCallback
from stable_baselines3.common.logger import configure

import drltg  # registers every drltg task with Gymnasium as drltg/<task>-v0

FRAMES, SEEDS = int(os.environ.get("FRAMES", 20_000)), int(os.environ.get("SEEDS", 5))
OUT = os.environ.get("OUT", "sb3")
source, target = drltg.gymnasium_ids.pair_ids("fourrooms-near")  # drltg/fourrooms-northeast(-shifted)-v0
for seed in range(SEEDS):
    SAC("MlpPolicy", gymnasium.make(source), seed=seed).learn(FRAMES).save(f"{OUT}/source-{seed}")
    for side in ("baseline", "transfer"):
        env = gymnasium.make(target)
        if side == "transfer":
            agent = SAC.load(f"{OUT}/source-{seed}", env, seed=seed)
        else:
            agent = SAC("MlpPolicy", env, seed=seed)
        agent.set_logger(configure(f"{OUT}/{side}/seed-{seed}", ["csv"]))
        evaluation = EvalCallback(gymnasium.make(target), eval_freq=FRAMES // 20, n_eval_episodes=10, verbose=0)
        agent.learn(FRAMES, callback=evaluation)
