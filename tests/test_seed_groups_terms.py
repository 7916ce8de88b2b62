"""Seed groups of methods with loss terms: each seed's term is evaluated inside the group's vmapped loss
with that seed's parameters, teacher and weight, as its run alone evaluates it."""
import copy

import pytest
import torch

from drltg import config as config_lib
from drltg.learners import UpdateStep, make_agent
from drltg.losses import behaviour_cloning, distillation
from drltg.losses.terms import LossTerm
from drltg.training.loop import build_env
from drltg.training.seeds import SeedGroup
from tests.test_seed_groups import SMALL, _agents_and_batches


def _check_each_seed_is_its_own_update(agents, batches, terms, update_actor=True):
    """One grouped update (shared random draws) against each seed's own ``UpdateStep`` with its own term:
    losses, gradients and new parameters to 1e-5. Returns the grouped losses."""
    group = SeedGroup(agents, randomness="same", terms=terms)
    torch.manual_seed(11)
    grouped = group.update(torch.stack(batches), update_actor=update_actor)
    grads = [p.grad for p in group.optimizer.param_groups[0]["params"]]
    for k, (agent, batch, term) in enumerate(zip(agents, batches, terms)):
        torch.manual_seed(11)
        single = UpdateStep(agent, loss_terms=term)(batch, update_actor=update_actor)
        assert sorted(single.keys()) == sorted(grouped.keys())
        for key in single.keys():
            torch.testing.assert_close(grouped[key][k], single[key], atol=1e-5, rtol=1e-5, msg=key)
        for (name, p), g in zip(agent.loss.named_parameters(), grads):
            assert (p.grad is None) == (g is None), name
            if g is not None:
                torch.testing.assert_close(g[k], p.grad, atol=1e-5, rtol=1e-5, msg=name)
        for name, value in agent.loss.state_dict().items():
            torch.testing.assert_close(group.params.get(tuple(name.split(".")))[k], value, atol=1e-5, rtol=1e-5,
                                       msg=name)
    return grouped


@pytest.mark.parametrize("algo", ["sac", "td3", "soc"])
@pytest.mark.parametrize("q_filter", [False, True])
def test_one_grouped_update_with_behaviour_cloning_is_each_seeds_own(algo, q_filter):
    """Seed k clones the first 8 rows of its own batch with its own (scheduled) weight, k + 1."""
    agents, batches = _agents_and_batches("fourrooms/northeast", algo)
    weights = [1.0, 2.0, 3.0]
    terms = [behaviour_cloning(a.loss, 8, lambda w=w: w, q_filter=q_filter) for a, w in zip(agents, weights)]
    grouped = _check_each_seed_is_its_own_update(agents, batches, terms)
    assert (grouped["loss_actor_bc"] > 0).all()


def test_each_seeds_own_bc_alpha_scales_its_cloning_in_a_group():
    """TD3+BC's alpha is a buffer of the term: seeds of one group (a tuning grid's settings) each clone at their
    own mean|Q| / alpha, as alone; a group whose terms differ in form is refused in one sentence."""
    from drltg.errors import UsageError

    agents, batches = _agents_and_batches("fourrooms/northeast", "sac")
    alphas = [1.0, 2.5, 10.0]
    terms = [behaviour_cloning(a.loss, 8, 1.0, alpha=alpha) for a, alpha in zip(agents, alphas)]
    grouped = _check_each_seed_is_its_own_update(agents, batches, terms)
    assert len(set(grouped["bc_scale"].tolist())) == 3
    with pytest.raises(UsageError, match="loss terms of different forms"):
        SeedGroup(agents, terms=[behaviour_cloning(a.loss, 8, 1.0, alpha=alpha) for a, alpha in
                                 zip(agents, [1.0, None, 2.5])])


@pytest.mark.parametrize("task, algo", [("fourrooms/northeast", "sac"), ("gridrooms/northeast", "sac"),
                                        ("fourrooms/northeast", "td3"), ("fourrooms/northeast", "soc")])
@pytest.mark.parametrize("update_actor", [True, False])
def test_each_seeds_own_teacher_gives_it_its_own_update_in_a_group(task, algo, update_actor):
    """Two seeds with the same networks and the same batch but different teachers: their grouped updates
    differ, each equal to its run alone's with its own teacher (TD3's delay skips the term with the actor's)."""
    agents, batches = _agents_and_batches(task, algo, seeds=3)
    cfg = config_lib.resolve({}, SMALL, task=task, algo=algo)
    probe = build_env(cfg, seed=0)
    torch.manual_seed(0)  # agent 0's twin, built as _agents_and_batches builds it
    students = [agents[0], make_agent(probe, cfg)]
    for a, b in zip(students[0].loss.state_dict().values(), students[1].loss.state_dict().values()):
        assert torch.equal(a, b)
    if algo == "soc":  # a SAC teacher: the option policy's choice branches on the data, which vmap cannot batch
        agents[1:] = _agents_and_batches(task, "sac", seeds=3)[0][1:]
    teachers = [copy.deepcopy(agents[1].actor), copy.deepcopy(agents[2].actor)]
    terms = [distillation(s.loss, t, 0.5) for s, t in zip(students, teachers)]
    grouped = _check_each_seed_is_its_own_update(students, [batches[0], batches[0]], terms, update_actor)
    gap = grouped["distill_gap"]
    assert gap[0] > 0 and gap[1] > 0 and not torch.isclose(gap[0], gap[1])
    if update_actor:
        a, b = (dict(s.loss.named_parameters()) for s in students)
        assert any(not torch.allclose(a[n], b[n]) for n in a if n.startswith("actor_network_params"))


def test_a_group_refuses_a_plain_function_as_a_grouped_methods_loss_terms():
    from drltg.errors import UsageError
    from drltg.training.seeds import seed_block_transforms
    from drltg.transfer import Transfer

    with pytest.raises(UsageError, match="loss_terms is not a drltg.losses.terms.LossTerm"):
        seed_block_transforms("mine", [Transfer(loss_terms=lambda batch: {})])
    assert isinstance(behaviour_cloning(_agents_and_batches("fourrooms/northeast", "sac", 1)[0][0].loss, 4, 1.0),
                      LossTerm)


def test_combined_terms_give_each_part_its_own_weight():
    """A combination's terms are one LossTerm; each part reads its own weight."""
    from drltg.transfer.registry import Transfer, _join

    agents, batches = _agents_and_batches("fourrooms/northeast", "sac", seeds=2)
    loss = agents[0].loss
    bc, distill = behaviour_cloning(loss, 8, 2.0), distillation(loss, agents[1].actor, 3.0)
    joined = _join([Transfer(loss_terms=bc), Transfer(loss_terms=distill)]).loss_terms
    assert isinstance(joined, LossTerm) and joined.weights().tolist() == [2.0, 3.0]
    together, apart = joined(batches[0]), {**bc(batches[0]), **distill(batches[0])}
    assert together.keys() == apart.keys()
    for key in apart:
        torch.testing.assert_close(together[key], apart[key])


DEMOS = {"transfer.demo_episodes": 1, "env.horizon": 16, "transfer.bc_weight": 10.0}


def test_a_groups_minibatches_are_each_seeds_own_transfer_batches(tmp_path):
    """Seed k's block of a grouped minibatch is the batch seed k's demonstrations transfer draws from seed k's
    buffer; the seeds' demonstrations come from their own sources, so they differ."""
    from torchrl.data import LazyTensorStorage, ReplayBuffer

    from drltg.training import loop, seeds
    from drltg.transfer import get_method
    from tests.test_seed_groups import tiny_cfg

    sources = seeds.train_seeds(tiny_cfg(task="fourrooms/southwest", frames=64, seed=50), tmp_path / "src", 2,
                                progress=False)
    cfgs = [tiny_cfg(seed=3 + k, **{"transfer.method": "demonstrations", "transfer.source": str(s), **DEMOS})
            for k, s in enumerate(sources)]
    agents, transfers, drawn = [], [], []
    for c in cfgs:
        torch.manual_seed(c.seed)
        probe, agent = loop.check_config(c)
        agents.append(agent)
        transfers.append(get_method("demonstrations").build(c, agent, probe, resuming=False))
    buffers = []
    for k, t in enumerate(transfers):
        buffer = ReplayBuffer(storage=LazyTensorStorage(100), batch_size=32)
        data = loop.build_env(cfgs[k], batch_size=(4,), seed=k).rollout(10, break_when_any_done=False).reshape(-1)
        buffer.extend(data.select(*agents[k].loss.in_keys))
        buffers.append(buffer)

        def recorded(own, n, make=t.batches, k=k):
            for batch in make(own, n):
                drawn.append((k, own, batch))
                yield batch
        t.batches = recorded
    learner = seeds.GroupLearner(SeedGroup(agents, terms=[t.loss_terms for t in transfers]), buffers, None,
                                 transfers)
    stacked = list(learner.batches(2))
    assert [k for k, _, _ in drawn] == [0, 1, 0, 1]
    for i, (k, own, batch) in enumerate(drawn):
        assert own is buffers[k]
        assert torch.equal(stacked[i // 2][k]["observation"], batch["observation"])
    demos = [stacked[0][k]["observation"][:8] for k in range(2)]  # demo_ratio 0.25 of 32
    assert not torch.equal(demos[0], demos[1])
    losses = learner.update(stacked[0], True)
    assert losses["loss_actor_bc"].shape == (2,) and (losses["loss_actor_bc"] > 0).all()


@pytest.mark.parametrize("algo", ["td3", "soc"])
def test_demonstrations_train_their_seeds_as_one_group(algo, tmp_path, capsys):
    import json

    from drltg.training import seeds
    from tests.test_seed_groups import tiny_cfg

    source = seeds.train_seeds(tiny_cfg(frames=64, algo=algo), tmp_path / "src", 1, progress=False)[0]
    cfg = tiny_cfg(frames=192, algo=algo, **{"transfer.method": "demonstrations", "transfer.source": str(source),
                                            "transfer.bc_anneal_frames": 1000, **DEMOS})
    dirs = seeds.train_seeds(cfg, tmp_path / "runs", 2, progress=False)
    assert "note:" not in capsys.readouterr().err
    for d in dirs:
        summary = json.loads((d / "summary.json").read_text())
        assert summary["seed_group"] == {"seeds": [3, 103]} and summary["demonstration_frames"] > 0


def test_an_experiment_with_demonstrations_trains_its_transfer_runs_as_one_seed_group(tmp_path):
    """From a user's side: the transfer runs' logs say they trained in one seed group."""
    import drltg
    from tests.test_seed_groups import TINY

    out = tmp_path / "near"
    tiny = [o for o in TINY if not o.startswith("eval.every")]
    drltg.experiment("fourrooms-near", "demonstrations", seeds=2, frames=128, out=out, threshold=0, progress=False,
                     overrides=[*tiny, "eval.every=64", "transfer.demo_episodes=1", "env.horizon=16"])
    first, second = (out / "logs" / "transfer" / f"seed-{s}.log" for s in (0, 100))
    assert f"start seed group {out / 'transfer' / 'seed-0'}, {out / 'transfer' / 'seed-100'}" in first.read_text()
    assert "trains in a seed group" in second.read_text()


def test_a_soc_groups_demonstrations_are_labelled_with_each_seeds_current_networks(tmp_path):
    """The option labels' pi_Omega(.|s) in seed k's block are seed k's policy over options with the group's
    current (stacked) parameters, not with the networks seed k started from."""
    from torchrl.data import LazyTensorStorage, ReplayBuffer
    from torchrl.envs import TransformedEnv

    from drltg.losses.behaviour_cloning import OPTION_PROBS
    from drltg.training import loop, seeds
    from drltg.transfer import get_method
    from tests.test_seed_groups import tiny_cfg

    options = {"algo": "soc", "soc.num_options": 3}
    source = seeds.train_seeds(tiny_cfg(frames=64, **options), tmp_path / "src", 1, progress=False)[0]
    cfgs = [tiny_cfg(seed=s, **options, **{"transfer.method": "demonstrations", "transfer.source": str(source),
                                           **DEMOS}) for s in (3, 4)]
    agents, transfers, buffers = [], [], []
    for c in cfgs:
        torch.manual_seed(c.seed)
        probe, agent = loop.check_config(c)
        agents.append(agent)
        transfers.append(get_method("demonstrations").build(c, agent, probe, resuming=False))
        buffer = ReplayBuffer(storage=LazyTensorStorage(100), batch_size=32)
        env = TransformedEnv(loop.build_env(c, batch_size=(4,), seed=c.seed))
        for t in agent.env_transforms:  # the option the loss reads
            env.append_transform(t.clone())
        buffer.extend(env.rollout(10, break_when_any_done=False).reshape(-1).select(*agent.loss.in_keys))
        buffers.append(buffer)
    seen = []
    for k, agent in enumerate(agents):  # what the labels' pi_Omega(.|s) reads, seed by seed
        def recorded(td, *a, loss=agent.loss, k=k, real=agent.loss.option_values, **kw):
            seen.append((k, loss.actor_network_params.detach().clone(), loss.qvalue_network_params.detach().clone()))
            return real(td, *a, **kw)
        agent.loss.option_values = recorded
    group = SeedGroup(agents, terms=[t.loss_terms for t in transfers])
    with torch.no_grad():  # the group's networks move away from the ones the seeds started from
        for value in group.params.values(True, True):
            value.add_(0.3 * torch.randn_like(value))
    batch = next(iter(seeds.GroupLearner(group, buffers, None, transfers).batches(1)))
    assert batch[OPTION_PROBS].shape == (2, 32, 3) and [k for k, _, _ in seen] == [0, 1]
    for k, actor, qvalue in seen:
        assert (actor == group.params[k]["actor_network_params"]).all()
        assert (qvalue == group.params[k]["qvalue_network_params"]).all()
        assert not (actor == agents[k].loss.actor_network_params).all()
