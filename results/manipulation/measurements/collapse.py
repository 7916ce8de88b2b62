"""What a placing policy does after it collapses: each kept run of a measurement, at ``best.pt`` and at
``last.pt``, on the same seeded episodes.

    python results/manipulation/measurements/collapse.py [NAME] [--episodes 10]

For every ``results/manipulation/measurements/NAME/seed-<s>`` (default NAME: place-reference-ln-half)
and both checkpoints, ``--episodes`` episodes of the deterministic actor (the run's evaluation env,
seeded ``seed + FRESH_SEED_OFFSET`` as ``drltg evaluate`` seeds them) over the full horizon, and per
episode at its last step: placed (the task's success), ever lifted, grasped, the cube's horizontal
distance to the target's centre and its height above it (``cube_pos - target_pos``, m), and the steps
spent placed (the sparse return). An episode that ends early (``env.terminate_on_success``) is read at
its own last step, while the others play on. Writes ``NAME/collapse.csv`` (one row per episode) and prints the means.

And where the demonstrations were: at the states of ``DEMO_EPISODES`` seeded episodes of the task's scripted
demonstrator, the mean absolute gap between the deterministic actor's action and the demonstrator's, and
the smaller twin critic at both (``NAME/demonstrated.csv``, one row per seed and checkpoint). A policy that
still acts as the demonstrator there has collapsed in states the demonstrations do not cover.
"""
from __future__ import annotations

import argparse
import csv
import io
import sys
from pathlib import Path

import torch
from torchrl.envs.utils import ExplorationType, set_exploration_type

ROOT = Path(__file__).resolve().parents[3]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from drltg.collectors.demonstrations import collect_demonstrations  # noqa: E402
from drltg.envs.robosuite import LAYOUT, demonstrator_for  # noqa: E402
from drltg.store.rundir import atomic_write  # noqa: E402
from drltg.training.loop import make_eval_env  # noqa: E402
from drltg.training.reevaluate import FRESH_SEED_OFFSET  # noqa: E402
from drltg.transfer.source import rebuild  # noqa: E402

sys.path.insert(0, str(ROOT / "results" / "manipulation" / "sources"))
from critic_scale import min_q  # noqa: E402

DEMO_EPISODES = 2
DEMONSTRATED = ("seed", "checkpoint", "frames", "action_gap", "q_demonstrated", "q_actor")
FIELDS = ("seed", "checkpoint", "frames", "episode", "placed", "lifted", "grasped", "distance_m", "height_m",
          "steps_placed")


@torch.no_grad()
def episodes_end(agent, cfg, frames: int, checkpoint: str, episodes: int) -> list[dict]:
    """One row per episode: where the cube is at the last step, and how long it rested on the target."""
    env = make_eval_env(cfg, episodes, cfg.seed + FRESH_SEED_OFFSET, agent.env_transforms)
    td = env.reset()
    obs, success = td["observation"].clone(), torch.zeros(episodes, dtype=torch.bool)
    ended = torch.zeros(episodes, dtype=torch.bool)
    lifted = torch.zeros(episodes, dtype=torch.bool)
    placed_steps = torch.zeros(episodes)
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        while not ended.all():
            td = env.step(agent.actor(td))
            nxt, live = td["next"], ~ended
            obs[live] = nxt["observation"][live]
            success[live] = nxt["success"].reshape(-1)[live].bool()
            lifted[live] |= nxt["lifted"].reshape(-1)[live].bool()
            placed_steps[live] += success[live].float()
            ended |= nxt["done"].reshape(-1)
            td = nxt.clone()
    env.close()
    offset = -obs[:, LAYOUT["cube_to_target_pos"]]  # cube_pos - target_pos
    return [{"seed": cfg.seed, "checkpoint": checkpoint, "frames": frames, "episode": i,
             "placed": int(success[i].item()), "lifted": int(lifted[i]),
             "grasped": int(obs[i, LAYOUT["cube_grasped"]].item() > 0.5),
             "distance_m": round(float(offset[i, :2].norm()), 4), "height_m": round(float(offset[i, 2]), 4),
             "steps_placed": int(placed_steps[i])} for i in range(episodes)]


@torch.no_grad()
def demonstrated(agent, cfg, frames: int, checkpoint: str, demo) -> dict:
    """The actor's gap to the demonstrator's actions at its states, and the critics at both actions."""
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        mu = agent.actor(demo.exclude("action").clone())["action"]
    return {"seed": cfg.seed, "checkpoint": checkpoint, "frames": frames,
            "action_gap": round((mu - demo["action"]).abs().mean().item(), 4),
            "q_demonstrated": round(min_q(agent.loss, demo).mean().item(), 2),
            "q_actor": round(min_q(agent.loss, demo.clone().set("action", mu)).mean().item(), 2)}


def write(path: Path, fields: tuple[str, ...], rows: list[dict]) -> None:
    out = io.StringIO()
    writer = csv.DictWriter(out, fields, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    atomic_write(path, out.getvalue())


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("name", nargs="?", default="place-reference-ln-half")
    p.add_argument("--episodes", type=int, default=10)
    args = p.parse_args(argv)
    folder = Path(__file__).resolve().parent / args.name
    rows, gaps, demo = [], [], None
    for run in sorted(folder.glob("seed-*"), key=lambda r: int(r.name.split("-")[1])):
        for checkpoint in ("best", "last"):
            agent, env, cfg, frames = rebuild(run, checkpoint=checkpoint)
            if demo is None:
                torch.manual_seed(0)
                env.set_seed(0)
                demo = collect_demonstrations(env, demonstrator_for(cfg.task), DEMO_EPISODES)
            env.close()
            rows += episodes_end(agent, cfg, frames, checkpoint, args.episodes)
            gaps.append(demonstrated(agent, cfg, frames, checkpoint, demo))
    write(folder / "collapse.csv", FIELDS, rows)
    write(folder / "demonstrated.csv", DEMONSTRATED, gaps)
    for row in gaps:
        print(row)
    for seed in sorted({r["seed"] for r in rows}):
        for checkpoint in ("best", "last"):
            rs = [r for r in rows if r["seed"] == seed and r["checkpoint"] == checkpoint]
            mean = {k: sum(r[k] for r in rs) / len(rs) for k in FIELDS[4:]}
            print(f"seed {seed} {checkpoint}.pt ({rs[0]['frames']} frames): "
                  + ", ".join(f"{k} {v:.3f}" for k, v in mean.items()))


if __name__ == "__main__":
    main()
