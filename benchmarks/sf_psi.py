"""``python -m benchmarks.sf_psi [SOURCE_RUN ...] [--pair fourrooms-near] [--steps 30000]``: how well sf-gpi's
psi values its source policy after a number of TD steps, and where its opt-in plateau rule would stop TD.

For each source run (default: the committed fourrooms-near bench sources of seeds 50, 150, 250 and 350), psi of the
source's deterministic policy, on the features of the pair's two goals, is learnt as the sf-gpi method learns it
(``sf_frames`` = 10,000 frames of its exploration policy on the source task, the ``SuccessorFeatureLoss`` TD, Adam
at ``optim.lr``, a soft target at ``optim.tau``) for ``--steps`` steps. Every 500 steps it records the plain TD
loss, the relative TD error (``loss_sf / sf_target_sq``, the quantity the rule reads) and how psi's value at 512
start states, ``psi(s, pi(s)) . w_source``, agrees with the policy's Monte Carlo discounted return from them
(Pearson correlation, mean absolute error). It reports the step at which the plateau rule (``Plateau(500, 3,
0.01)`` on the relative TD error: ``transfer.sf_patience=3``) would stop, and the agreement there, at 2,000 steps
(the method's former fixed count), at 20,000 (its default now) and at the last step.

Prints one JSON object and writes it to ``benchmarks/sf_psi_result.json`` (minutes; not a test).
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SOURCES = [REPO / f"results/bench/v1/quick/fourrooms/fourrooms-near/sac/source/seed-{s}" for s in (50, 150, 250, 350)]
BLOCK = 500


def _monte_carlo(source, episodes: int = 512, seed: int = 7):
    """Start states of the source task, the source's deterministic action there and its discounted return."""
    import torch
    from torchrl.envs import ExplorationType, set_exploration_type

    from drltg.envs import make_env

    cfg = source.cfg
    env = make_env(cfg.task, batch_size=(episodes,), seed=seed, **cfg.env)
    td = env.reset()
    start = td.select("observation").clone()
    ret, alive, discount = torch.zeros(episodes), torch.ones(episodes, dtype=torch.bool), 1.0
    with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
        action = source.agent.actor(start.clone())["action"]
        for _ in range(10_000):
            td = env.step(source.agent.actor(td))
            ret += discount * td["next", "reward"].squeeze(-1) * alive
            alive &= ~td["next", "done"].squeeze(-1)
            discount *= cfg.optim.gamma
            if not alive.any():
                break
            td = td["next"].clone()
    return start.set("action", action), ret


def measure(run: Path, pair: str, steps: int) -> dict:
    import torch
    from torchrl.data import LazyTensorStorage, ReplayBuffer
    from torchrl.envs import TransformedEnv
    from torchrl.objectives import SoftUpdate

    from drltg.envs import get_pair, make_env
    from drltg.losses import SuccessorFeatureLoss
    from drltg.modules import GoalFeatures, make_sf_critic
    from drltg.transfer.sf_gpi import Plateau
    from drltg.transfer.source import rebuild

    torch.manual_seed(0)
    source = rebuild(run, "cpu")
    cfg, goal = source.cfg, source.env.goal.tolist()
    target_goal = make_env(get_pair(pair).target).goal.tolist()
    features = GoalFeatures.for_env(source.env, [goal] + ([target_goal] if target_goal != goal else []))
    n = cfg.collector.num_envs
    env = TransformedEnv(make_env(cfg.task, batch_size=(n,), seed=cfg.seed + 30_000, **cfg.env))
    with torch.no_grad():
        data = features(env.rollout(-(-10_000 // n), source.agent.policy, break_when_any_done=False).reshape(-1))
    critic = make_sf_critic(data["observation"].shape[-1], features.num_features, num_cells=cfg.network.hidden,
                            action_dim=data["action"].shape[-1])
    loss = SuccessorFeatureLoss(critic, policy=source.agent.actor)
    loss.make_value_estimator(gamma=cfg.optim.gamma)
    buffer = ReplayBuffer(storage=LazyTensorStorage(data.numel()), batch_size=cfg.buffer.batch_size)
    buffer.extend(data.select(*loss.in_keys))
    target, optimizer = SoftUpdate(loss, tau=cfg.optim.tau), torch.optim.Adam(loss.parameters(), lr=cfg.optim.lr)
    w = features.task_weights(goal, source.env.step_cost)
    start, returns = _monte_carlo(source)
    rule, stop, rows, plain, relative = Plateau(BLOCK, 3, 0.01), None, [], 0.0, 0.0
    for step in range(1, steps + 1):
        optimizer.zero_grad(set_to_none=True)
        out = loss(buffer.sample())
        out["loss_sf"].backward()
        optimizer.step()
        target.step()
        ratio = (out["loss_sf"] / out["sf_target_sq"].clamp_min(1e-12)).item()
        plain, relative = plain + out["loss_sf"].item(), relative + ratio
        if rule.push(ratio) and stop is None:
            stop = step
        if step % BLOCK == 0:
            with torch.no_grad():
                value = critic(start.clone())["successor_features"] @ w
            rows.append({"step": step, "td_loss": round(plain / BLOCK, 6),
                         "relative_td": float(f"{relative / BLOCK:.4g}"),
                         "corr": round(torch.corrcoef(torch.stack([value, returns]))[0, 1].item(), 3),
                         "mae": round((value - returns).abs().mean().item(), 3)})
            plain = relative = 0.0
    at = {r["step"]: r for r in rows}
    return {"source": str(run.relative_to(REPO)) if run.is_relative_to(REPO) else str(run), "rule_stops_at": stop,
            "at_stop": at.get(stop), "at_2000": at.get(2000), "at_20000": at.get(20_000), "at_last": rows[-1],
            "every_500": rows}


def main(argv=None) -> int:
    import torch

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("sources", nargs="*", type=Path, default=SOURCES)
    parser.add_argument("--pair", default="fourrooms-near")
    parser.add_argument("--steps", type=int, default=30_000)
    parser.add_argument("--result", type=Path, default=REPO / "benchmarks" / "sf_psi_result.json")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    result = {"steps": args.steps, "rule": "Plateau(block=500, patience=3, tolerance=0.01) on loss_sf / sf_target_sq",
              "runs": [measure(run.resolve(), args.pair, args.steps) for run in args.sources]}
    text = json.dumps(result, indent=1)
    args.result.write_text(text + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
