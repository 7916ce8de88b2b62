"""The learned Lift sources as demonstrators on lift-place, under the action noise of ``transfer.demo_noise``.

    python results/manipulation/placement-diagnostics/source_noise.py [--episodes 10]

``source-noise.csv``: for each kept source ``lift-sac-ln-half/seed-<s>`` (its ``best.pt``, the checkpoint
the rows reuse) and sigma in 0, 0.05, 0.1, ``--episodes`` seeded episodes of the full horizon on
``lift-place``, each action run as ``clip(a + sigma N(0, I))`` (``drltg.collectors.demonstrations.perturbed``, as
``collect_demonstrations`` runs it): how often the cube is lifted at the end of the episode. The scripted
demonstrator's counterpart is ``noise.csv`` (``diagnose.py``). Seeded; the same command writes the same file.
"""
from __future__ import annotations

import argparse
import csv
import io
import sys
from pathlib import Path

import torch
from torchrl.envs import ExplorationType, TransformedEnv, set_exploration_type

ROOT = Path(__file__).resolve().parents[3]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from drltg.collectors.demonstrations import perturbed  # noqa: E402
from drltg.envs import make_env  # noqa: E402
from drltg.store.rundir import atomic_write  # noqa: E402
from drltg.transfer.source import load_agent  # noqa: E402

HERE = Path(__file__).resolve().parent
SOURCES = ROOT / "results/manipulation/sources/lift-sac-ln-half"
SEEDS = (0, 100, 200)
SIGMAS = (0.0, 0.05, 0.1)


def lifted_at_end(source: Path, sigma: float, episodes: int) -> int:
    agent = load_agent(source, checkpoint="best")
    env = TransformedEnv(make_env("lift-place"))
    for transform in agent.env_transforms:
        env.append_transform(transform.clone())
    policy = agent.actor
    if sigma > 0:
        policy = perturbed(policy, env.full_action_spec_unbatched["action"], sigma)
    torch.manual_seed(1000)
    lifted = 0
    with set_exploration_type(ExplorationType.DETERMINISTIC), torch.no_grad():
        for k in range(episodes):
            env.set_seed(k)
            td = env.rollout(env.base_env.robosuite_env.horizon, policy, break_when_any_done=False)
            lifted += bool(td["next", "lifted"][-1])
    env.close()
    return lifted


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--episodes", type=int, default=10)
    args = p.parse_args(argv)
    rows = []
    for seed in SEEDS:
        for sigma in SIGMAS:
            lifted = lifted_at_end(SOURCES / f"seed-{seed}", sigma, args.episodes)
            rows.append({"source": f"lift-sac-ln-half/seed-{seed}", "sigma": sigma, "episodes": args.episodes,
                         "lifted": lifted})
            print(rows[-1], flush=True)
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=list(rows[0]))
    writer.writeheader()
    writer.writerows(rows)
    atomic_write(HERE / "source-noise.csv", buf.getvalue())


if __name__ == "__main__":
    main()
