"""Why placement is not learned: the scripted demonstrator under action noise, and who earns what on lift-place.

    python results/manipulation/placement-diagnostics/diagnose.py [--episodes 10]

1. ``noise.csv``: the demonstrator of ``lift-place`` and ``lift-place-barrier`` with Gaussian noise
   ``a + N(0, sigma^2)`` (clipped to the action box) for sigma in 0, 0.1, 0.3, 0.5, ``--episodes`` seeded
   episodes of the full horizon (500 steps) each: how often the cube is lifted, placed at the end, and the
   sparse return (steps placed).
2. ``episode.csv``: one noise-free demonstrator episode on ``lift-place`` (seed 0), step by step: the
   task's reward, its stage flags, the registered shaping potential ``Phi`` (``potential_for``) with its
   four stages, and the shaping term ``F = gamma Phi(s') - Phi(s)``.
3. ``summary.json``: the noise table, and for the placing demonstrator and the Lift demonstrator (it lifts
   and holds) acting on ``lift-place``: sparse return, discounted sparse return (gamma = optim.gamma),
   sum of ``F``, ``Phi`` at the end, and the steps at which the cube is first grasped, lifted and placed;
   plus ``Phi`` of the cube held 5 cm above the target's centre against resting on it (the potential's
   stage formula at those two states).

Everything is seeded; the same command writes the same files.
"""
from __future__ import annotations

import argparse
import csv
import json
import math
import sys
from pathlib import Path

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModuleBase

ROOT = Path(__file__).resolve().parents[3]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from drltg.config import OptimConfig  # noqa: E402
from drltg.envs import make_env  # noqa: E402
from drltg.envs.robosuite import LAYOUT, demonstrator_for, potential_for  # noqa: E402
from drltg.store.rundir import atomic_write  # noqa: E402

HERE = Path(__file__).resolve().parent
SIGMAS = (0.0, 0.1, 0.3, 0.5)
TASKS = ("lift-place", "lift-place-barrier")
GAMMA = OptimConfig().gamma


class Noisy(TensorDictModuleBase):
    """``policy``'s action plus ``N(0, sigma^2)`` from its own seeded generator, clipped to [-1, 1]."""

    def __init__(self, policy, sigma: float, seed: int):
        super().__init__()
        self.policy, self.sigma = policy, sigma
        self.in_keys, self.out_keys = policy.in_keys, ["action"]
        self.gen = torch.Generator().manual_seed(seed)

    def forward(self, td: TensorDictBase) -> TensorDictBase:
        td = self.policy(td)
        noise = torch.randn(td["action"].shape, generator=self.gen) * self.sigma
        return td.set("action", (td["action"] + noise).clamp(-1.0, 1.0))


def episode(env, policy, seed: int) -> TensorDictBase:
    env.set_seed(seed)
    return env.rollout(env.robosuite_env.horizon, policy, break_when_any_done=False)


def first(flags: torch.Tensor) -> int | None:
    return int(flags.float().argmax()) + 1 if bool(flags.any()) else None


def noise_table(episodes: int) -> list[dict]:
    rows = []
    for task in TASKS:
        env = make_env(task)
        for sigma in SIGMAS:
            lifted = placed = 0
            returns = []
            for k in range(episodes):
                td = episode(env, Noisy(demonstrator_for(task), sigma, seed=1000 + k), seed=k)
                nxt = td["next"]
                lifted += bool(nxt["lifted"][-1])
                placed += bool(nxt["success"][-1])
                returns.append(float(nxt["reward"].sum()))
            rows.append({"task": task, "sigma": sigma, "episodes": episodes, "lifted": lifted, "placed": placed,
                         "return_mean": round(sum(returns) / episodes, 2)})
            print(rows[-1], flush=True)
        env.close()
    return rows


def stages(obs: torch.Tensor, potential) -> dict[str, torch.Tensor]:
    grasped = obs[..., LAYOUT["cube_grasped"]]
    lifted = obs[..., LAYOUT["cube_lifted"]]
    return {"reach": 0.1 * potential.reach(obs), "grasp": 0.35 * grasped,
            "grasp_lift": grasped * (0.35 + 0.15 * potential.lift(obs)),
            "carry": lifted * (0.5 + 0.5 * potential.carry(obs))}


def account(td: TensorDictBase, potential) -> dict:
    """What one episode earns on the sparse reward and on the shaping term."""
    reward = td["next", "reward"].squeeze(-1)
    phi, phi_next = potential(td["observation"]).squeeze(-1), potential(td["next", "observation"]).squeeze(-1)
    shaping = GAMMA * phi_next - phi
    discount = GAMMA ** torch.arange(len(reward), dtype=torch.float32)
    grasped = td["next", "observation"][..., LAYOUT["cube_grasped"]].squeeze(-1) > 0.5
    return {"return": float(reward.sum()), "discounted_return": round(float((discount * reward).sum()), 3),
            "shaping_sum": round(float(shaping.sum()), 3), "phi_start": round(float(phi[0]), 3),
            "phi_end": round(float(phi_next[-1]), 3), "first_grasped": first(grasped),
            "first_lifted": first(td["next", "lifted"].squeeze(-1)),
            "first_placed": first(td["next", "success"].squeeze(-1))}


def held_versus_placed(potential) -> dict:
    """Phi with the cube lifted and centred over the target, held 5 cm above it or resting on it, released."""
    obs = torch.zeros(2, LAYOUT["cube_lifted"].stop)
    obs[:, LAYOUT["cube_lifted"]] = 1.0
    obs[0, LAYOUT["cube_grasped"]] = 1.0  # held above the target
    obs[:, LAYOUT["cube_to_target_pos"]] = torch.tensor([[0.0, 0.0, -0.05], [0.0, 0.0, -0.02]])
    phi = potential(obs).squeeze(-1)
    return {"held_above_target": round(float(phi[0]), 3), "resting_on_target": round(float(phi[1]), 3)}


def decomposition() -> tuple[list[dict], dict]:
    potential = potential_for("lift-place")
    env = make_env("lift-place")
    place = episode(env, demonstrator_for("lift-place"), seed=0)
    hold = episode(env, demonstrator_for("lift"), seed=0)
    env.close()
    obs = place["next", "observation"]
    terms = stages(obs, potential)
    phi = potential(place["observation"]).squeeze(-1)
    phi_next = potential(obs).squeeze(-1)
    rows = []
    for t in range(len(phi)):
        rows.append({"step": t + 1, "reward": float(place["next", "reward"][t]),
                     "placed": int(place["next", "success"][t]), "lifted": int(place["next", "lifted"][t]),
                     "grasped": int(obs[t, LAYOUT["cube_grasped"]]),
                     **{f"phi_{k}": round(float(v[t]), 4) for k, v in terms.items()},
                     "phi": round(float(phi_next[t]), 4), "shaping": round(float(GAMMA * phi_next[t] - phi[t]), 4)})
    summary = {"gamma": GAMMA, "place_demonstrator": account(place, potential),
               "lift_demonstrator_on_lift_place": account(hold, potential),
               "phi_states": held_versus_placed(potential)}
    return rows, summary


def write_csv(path: Path, rows: list[dict]) -> None:
    import io

    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=list(rows[0]))
    writer.writeheader()
    writer.writerows(rows)
    atomic_write(path, buf.getvalue())


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--episodes", type=int, default=10)
    args = p.parse_args(argv)
    torch.manual_seed(0)
    rows, summary = decomposition()
    write_csv(HERE / "episode.csv", rows)
    print(json.dumps(summary, indent=1), flush=True)
    noise = noise_table(args.episodes)
    write_csv(HERE / "noise.csv", noise)
    summary["noise"] = noise
    atomic_write(HERE / "summary.json", json.dumps(summary, indent=1) + "\n")
    assert not math.isnan(summary["place_demonstrator"]["return"])


if __name__ == "__main__":
    main()
