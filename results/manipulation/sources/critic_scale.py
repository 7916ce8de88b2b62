"""What the kept SAC sources' critics believe at the end of training, against what can be earned.

    python results/manipulation/sources/critic_scale.py [--episodes 2]

Lift pays 1 for every step the cube is lifted and 0 otherwise, so no policy's discounted return exceeds
the ceiling ``1 / (1 - gamma)`` (100 at gamma = 0.99; a run bootstraps through the time limit, so its
critic estimates the unending discounted sum). For every kept SAC source (``lift-sac*/seed-*``, its
``last.pt``) this rolls out ``--episodes`` seeded episodes of the scripted Lift demonstrator (the states
the source was taught at) and writes ``critic_scale.csv``: the smaller of its twin critics at the
demonstrated actions, ``Q(s, a)``, and at its own deterministic action, ``Q(s, mu(s))`` (mean over the
episodes' steps), the demonstrator's mean reward per step, the ceiling, and from the source's
``eval.csv`` its final success rate and the lowest over the second half of training. A critic above the
ceiling has overestimated: it values states above anything the task pays.

The soft option-critic's sources are left out (their critic reads an option as well). Everything is
seeded; the same command writes the same file.
"""
from __future__ import annotations

import argparse
import csv
import io
import sys
from pathlib import Path

import torch

ROOT = Path(__file__).resolve().parents[3]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from torchrl.envs import ExplorationType, set_exploration_type  # noqa: E402

from drltg.collectors.demonstrations import collect_demonstrations  # noqa: E402
from drltg.envs.robosuite import demonstrator_for  # noqa: E402
from drltg.store.rundir import atomic_write  # noqa: E402
from drltg.transfer.source import rebuild  # noqa: E402

HERE = Path(__file__).resolve().parent
COLUMNS = ("source", "seed", "frames", "q_demonstrated", "q_actor", "reward_per_step", "ceiling",
           "final_success", "lowest_success_second_half")


@torch.no_grad()
def min_q(loss, td) -> torch.Tensor:
    """The smaller of ``loss``'s twin critics at ``td``'s (observation, action)."""
    values = []
    for params in loss.qvalue_network_params.unbind(0):
        with params.to_module(loss.qvalue_network):
            values.append(loss.qvalue_network(td.clone(False))["state_action_value"])
    return torch.stack(values).amin(0).squeeze(-1)


def success(run: Path) -> tuple[float, float]:
    """The final success rate of ``run``'s eval.csv and the lowest over its second half."""
    rows = list(csv.DictReader((run / "eval.csv").open()))
    frames = [float(r["frames"]) for r in rows]
    rates = [round(float(r["success_rate"]), 2) for r in rows]
    return rates[-1], min(v for f, v in zip(frames, rates) if f >= frames[-1] / 2)


@torch.no_grad()
def measure(run: Path, episodes: int) -> dict:
    agent, env, cfg, frames = rebuild(run)
    torch.manual_seed(0)
    env.set_seed(0)
    demo = collect_demonstrations(env, demonstrator_for(cfg.task), episodes)
    env.close()
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        mu = agent.actor(demo.exclude("action").clone())["action"]
    final, lowest = success(run)
    return {"source": run.parent.name, "seed": int(run.name.split("-")[1]), "frames": frames,
            "q_demonstrated": round(min_q(agent.loss, demo).mean().item(), 2),
            "q_actor": round(min_q(agent.loss, demo.clone().set("action", mu)).mean().item(), 2),
            "reward_per_step": round(demo["next", "reward"].mean().item(), 4),
            "ceiling": round(1.0 / (1.0 - cfg.optim.gamma), 2), "final_success": final,
            "lowest_success_second_half": lowest}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=2, help="demonstrator episodes (default 2)")
    args = parser.parse_args()
    runs = sorted(HERE.glob("lift-sac*/seed-*"), key=lambda p: (p.parent.name, int(p.name.split("-")[1])))
    out = io.StringIO()
    writer = csv.DictWriter(out, fieldnames=COLUMNS, lineterminator="\n")
    writer.writeheader()
    for run in runs:
        row = measure(run, args.episodes)
        print(row, flush=True)
        writer.writerow(row)
    atomic_write(HERE / "critic_scale.csv", out.getvalue())


if __name__ == "__main__":
    main()
