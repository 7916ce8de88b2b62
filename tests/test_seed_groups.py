"""Seed groups: one vmapped update equals each seed's own update; per-seed env streams; group runs."""
import pytest
import torch
from torchrl.envs import TransformedEnv

from drltg import config as config_lib
from drltg.learners import UpdateStep, make_agent
from drltg.seed_group import SeedGroup
from drltg.training.loop import build_env

SMALL = ["network.hidden=[16,16]"]
LEARNERS = [("gridrooms/northeast", "sac"), ("fourrooms/northeast", "sac"), ("fourrooms/northeast", "td3"),
            ("fourrooms/northeast", "soc")]


def _agents_and_batches(task, algo, seeds=3, batch=32):
    cfg = config_lib.resolve({}, SMALL, task=task, algo=algo)
    probe = build_env(cfg, seed=0)
    agents = []
    for seed in range(seeds):
        torch.manual_seed(seed)
        agents.append(make_agent(probe, cfg))
    env = TransformedEnv(build_env(cfg, batch_size=(16,), seed=1))
    for t in agents[0].env_transforms:
        env.append_transform(t.clone())
    torch.manual_seed(5)
    data = env.rollout(8, break_when_any_done=False).reshape(-1)
    batches = [data[torch.randperm(data.numel())[:batch]] for _ in range(seeds)]
    return agents, batches


@pytest.mark.parametrize("task, algo", LEARNERS)
@pytest.mark.parametrize("update_actor", [True, False])
def test_one_vmapped_update_is_each_seeds_own_update(task, algo, update_actor):
    agents, batches = _agents_and_batches(task, algo)
    group = SeedGroup(agents, randomness="same")  # stacks copies: the agents keep their parameters
    torch.manual_seed(11)
    grouped = group.update(torch.stack(batches), update_actor=update_actor)
    group_grads = [p.grad for p in group._param_list]
    for k, (agent, batch) in enumerate(zip(agents, batches)):
        torch.manual_seed(11)  # the same random draws as the group's shared ("same") draw
        single = UpdateStep(agent)(batch, update_actor=update_actor)
        assert sorted(single.keys()) == sorted(grouped.keys())
        for key in single.keys():
            torch.testing.assert_close(grouped[key][k], single[key], atol=1e-5, rtol=1e-5)
        for (name, p), g in zip(agent.loss.named_parameters(), group_grads):
            assert (p.grad is None) == (g is None), name
            if g is not None:
                torch.testing.assert_close(g[k], p.grad, atol=1e-5, rtol=1e-5)
        after = {name: value for name, value in agent.loss.state_dict().items()}
        for name, value in after.items():
            stacked = group.params.get(tuple(name.split(".")))
            torch.testing.assert_close(stacked[k], value, atol=1e-5, rtol=1e-5, msg=name)
