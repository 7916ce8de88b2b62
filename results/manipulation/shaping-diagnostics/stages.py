"""What the final policies of the ``lift-shaping`` row do on Lift, stage by stage.

    python results/manipulation/shaping-diagnostics/stages.py [RUNS] [--episodes 10]

The row's evaluations count lifts and successes only; shaping with Lift's potential
``Phi = (Reach + 0.25 Grasp + LiftHeight) / 2.25`` (``drltg.envs.robosuite.potentials``, with
``Reach = 1 - tanh(10 d)`` of the gripper's distance ``d`` to the cube) also pays reaching and grasping.
For each run of the row in ``RUNS`` (default ``runs/manipulation``, where ``lift-shaping.sh`` trains them;
their weights are not kept in ``results/``), its last checkpoint acts deterministically for ``--episodes``
seeded episodes of the full horizon on ``lift``; ``stages.csv`` gets per run the mean over episodes of the
gripper's distance to the cube (m) at the start, at its closest and over the episode, and the share of steps
with the cube grasped; and the episodes in which the cube is ever grasped and ever lifted.
Seeded; the same runs give the same file.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import torch
from torchrl.envs import ExplorationType, TransformedEnv, set_exploration_type

ROOT = Path(__file__).resolve().parents[3]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from drltg.analysis.tables import render  # noqa: E402
from drltg.envs import make_env  # noqa: E402
from drltg.envs.robosuite import LAYOUT  # noqa: E402
from drltg.store.rundir import atomic_write  # noqa: E402
from drltg.transfer.source import load_agent  # noqa: E402

HERE = Path(__file__).resolve().parent
SIDES = {"no transfer": "lift/sac/baseline", "reward-shaping": "lift/sac/reward-shaping/transfer"}


def episode_stages(obs: torch.Tensor) -> dict[str, float]:
    """One episode's stage measures from its observations ``[T, obs_dim]`` (drltg's manipulation layout)."""
    distance = obs[..., LAYOUT["gripper_to_cube_pos"]].norm(dim=-1)
    grasped = obs[..., LAYOUT["cube_grasped"]].squeeze(-1) > 0.5
    lifted = obs[..., LAYOUT["cube_lifted"]].squeeze(-1) > 0.5
    return {"start_m": float(distance[0]), "closest_m": float(distance.min()), "mean_m": float(distance.mean()),
            "grasped_share": float(grasped.float().mean()), "grasped": int(grasped.any()),
            "lifted": int(lifted.any())}


def measure(run: Path, episodes: int) -> dict[str, float]:
    agent = load_agent(run)
    env = TransformedEnv(make_env("lift"))
    for transform in agent.env_transforms:
        env.append_transform(transform.clone())
    per_episode = []
    torch.manual_seed(1000)
    with set_exploration_type(ExplorationType.DETERMINISTIC), torch.no_grad():
        for k in range(episodes):
            env.set_seed(k)
            td = env.rollout(env.base_env.robosuite_env.horizon, agent.actor, break_when_any_done=False)
            obs = torch.cat([td["observation"][:1], td["next", "observation"]])
            per_episode.append(episode_stages(obs))
    env.close()
    total = {key: sum(e[key] for e in per_episode) for key in per_episode[0]}
    return {key: v if isinstance(v, int) else v / episodes for key, v in total.items()}  # counts stay counts


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("runs", nargs="?", type=Path, default=Path("runs/manipulation"))
    p.add_argument("--episodes", type=int, default=10)
    args = p.parse_args(argv)
    rows = []
    for side, folder in SIDES.items():
        for run in sorted((args.runs / folder).glob("seed-*"), key=lambda r: int(r.name.split("-")[1])):
            if not (run / "summary.json").is_file():
                continue
            m = measure(run, args.episodes)
            rows.append({"side": side, "seed": run.name.split("-")[1], "episodes": args.episodes,
                         **{k: v if isinstance(v, int) else f"{v:.4f}" if k == "grasped_share" else f"{v:.3f}"
                            for k, v in m.items()}})
            print(rows[-1], flush=True)
    if not rows:
        print(f"error: no finished lift-shaping run in {args.runs} ({', '.join(SIDES.values())}).", file=sys.stderr)
        sys.exit(2)
    atomic_write(HERE / "stages.csv", render([list(rows[0]), *(list(r.values()) for r in rows)], "csv"))


if __name__ == "__main__":
    main()
