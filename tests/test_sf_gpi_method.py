"""The sf-gpi method end to end: the source's successor features with the target's exact reward weights, GPI as
the collector's policy, and the one-sentence refusal of pairs that differ in more than the reward."""
import json

import pytest
import torch
from tensordict import TensorDict
from torchrl.envs import ExplorationType, set_exploration_type

from drltg import config as config_lib
from drltg.cli import main
from drltg.collectors import GPIPolicy
from drltg.envs import make_env
from drltg.errors import UsageError
from drltg.learners import make_agent
from drltg.training.loop import AgentLearner
from drltg.training.pretraining import pretrain
from drltg.transfer import get_method
from tests.test_experiment import TINY
from tests.test_methods import _source_run

SF = ["-o", "transfer.sf_frames=512", "-o", "transfer.sf_updates=20"]
REFUSAL = "sf-gpi needs source and target tasks that differ only in reward"


def _build(tmp_path, source_task, target_task, *options):
    run, _ = _source_run(tmp_path / "src", task=source_task)
    cfg = config_lib.resolve({}, ["network.hidden=[8,8]", "collector.num_envs=2", "collector.frames_per_batch=8",
                                  "transfer.method=sf-gpi", f"transfer.source={run}", "transfer.sf_frames=64",
                                  "transfer.sf_updates=2", "transfer.sf_epsilon=0", *options], task=target_task)
    env = make_env(target_task, batch_size=(2,), seed=0)
    agent = make_agent(env, cfg)
    transfer = get_method("sf-gpi").build(cfg, agent, env, resuming=False)
    transfer.summary.update(pretrain(transfer.pretraining))  # psi's TD, as the run does before it trains
    return cfg, agent, env, transfer


def _gpi(transfer):
    (gpi,) = [m for m in transfer.mixer.module if isinstance(m, GPIPolicy)]
    return gpi


def test_grid_targets_weights_are_the_exact_ones_of_its_goal_and_gpi_is_the_collectors_policy(tmp_path):
    cfg, agent, env, transfer = _build(tmp_path, "gridrooms/northeast", "gridrooms/northeast-shifted")
    # phi(s') = [at (3, 9), at (4, 9), 1]; the target pays 1 at (4, 9) and -0.01 elsewhere: w = (0, 1.01, -0.01)
    assert _gpi(transfer).weights.tolist() == pytest.approx([0.0, 1.01, -0.01])
    assert transfer.summary["successor_feature_frames"] == 64
    learner = AgentLearner(agent, None, None, transfer)
    td = learner.policy(env.reset())
    # discrete GPI: the chosen action is the argmax over the source's psi . w and the learner's own Q
    q = _gpi(transfer).action_values(td)
    assert td["gpi_value"].squeeze(-1).tolist() == pytest.approx(q.amax((-2, -1)).tolist())
    assert torch.equal(td["action"].argmax(-1), q.amax(-2).argmax(-1))
    assert torch.equal(td["reused"], td["gpi_index"] == 0)


def test_continuous_gpi_acts_with_the_source_action_or_the_learners_own(tmp_path):
    """GPI over the library {source, learner}: each candidate action valued by the larger of psi_S . w and the
    learner's own min_k Q_k, the better candidate taken."""
    from drltg.modules.critics import min_over_critics

    cfg, agent, env, transfer = _build(tmp_path, "fourrooms/northeast", "fourrooms/northeast-shifted")
    # phi(s') = [in disc (8, 8), in disc (8, 7), 1]
    gpi = _gpi(transfer)
    assert gpi.weights.tolist() == pytest.approx([0.0, 1.01, -0.01])
    torch.manual_seed(0)
    td = env.reset()
    learner_action = agent.policy(td.clone())["action"]
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        source_action = gpi.policies[0](td.clone())["action"]
    torch.manual_seed(0)
    out = AgentLearner(agent, None, None, transfer).policy(td.clone())
    values = []
    for action in (source_action, learner_action):
        pair = TensorDict({"observation": td["observation"], "action": action}, batch_size=[2])
        psi = gpi.critics[0](pair.clone())["successor_features"] @ gpi.weights
        own = min_over_critics(agent.loss.qvalue_network, agent.loss.qvalue_network_params, pair).squeeze(-1)
        values.append(torch.maximum(psi, own))
    source_wins = (values[0] >= values[1]).unsqueeze(-1)
    assert torch.equal(out["reused"], source_wins)
    assert torch.equal(out["action"], torch.where(source_wins, source_action, learner_action))


@pytest.mark.parametrize("source_task, target_task", [("fourrooms/northeast", "fourrooms/northeast-shifted"),
                                                      ("gridrooms/northeast", "gridrooms/northeast-shifted")])
def test_gpi_explores_epsilon_greedily_and_a_random_action_is_not_the_sources(tmp_path, source_task, target_task):
    """sf_epsilon = 1: every action is drawn from the action space in place of GPI's, and counts as reused only
    where it is the source's action GPI chose; sf_epsilon = 0: GPI's action is kept."""
    for epsilon, replaced in ((1.0, True), (0.0, False)):
        cfg, agent, env, transfer = _build(tmp_path / str(epsilon), source_task, target_task,
                                           f"transfer.sf_epsilon={epsilon}")
        td = AgentLearner(agent, None, None, transfer).policy(make_env(target_task, batch_size=(64,), seed=1).reset())
        same = (td["action"] == td["gpi_action"]).all(-1)
        if source_task.startswith("fourrooms"):
            assert td["action"].abs().max() <= 1  # in the action box
        else:
            assert td["action"].sum(-1).eq(1).all()  # one-hot
        # reused: the source's action won GPI and was not replaced by another
        assert torch.equal(td["reused"].squeeze(-1), (td["gpi_index"].squeeze(-1) == 0) & same)
        if replaced and source_task.startswith("fourrooms"):
            assert not same.any()  # a uniform draw in the box is never GPI's action
        elif replaced:
            assert 0 < same.float().mean() < 0.6  # one of 4 actions: GPI's again about a quarter of the time
        else:
            assert same.all()


def test_psi_learns_sf_updates_steps_or_until_its_opt_in_plateau(tmp_path):
    """By default (sf_patience 0) TD takes sf_updates steps; with a plateau rule of one-step blocks that must fall
    99% below the best and patience 1, it stops at its second step."""
    assert config_lib.resolve({}, ["transfer.method=sf-gpi"]).transfer.sf_updates == 20_000
    plateau = ["transfer.sf_updates=50", "transfer.sf_block=1", "transfer.sf_tolerance=0.99"]
    for patience, expected in ((0, (50, "sf_updates")), (1, (2, "plateau"))):
        *_, transfer = _build(tmp_path / str(patience), "gridrooms/northeast", "gridrooms/northeast-shifted",
                              *plateau, f"transfer.sf_patience={patience}")
        td = transfer.summary["successor_feature_td"]
        assert (td["updates"], td["stopped"]) == expected and len(td["block_means"]) == expected[0]


def test_a_seed_groups_members_learn_psi_together_as_each_learns_it_alone(tmp_path, monkeypatch):
    """A group's psi TD is one vmapped update whose members draw their batches as they draw them alone: each
    member's psi is the one it learns alone, up to round-off; members other only in sf_epsilon (a tuning grid's
    settings on one seed) learn it once, and are told the same TD record."""
    from drltg.training import pretraining

    sources = [_source_run(tmp_path / f"src{k}", task="gridrooms/northeast")[0] for k in range(2)]

    def built(source, seed, epsilon):
        cfg = config_lib.resolve({}, ["network.hidden=[8,8]", "collector.num_envs=2", "transfer.method=sf-gpi",
                                      f"transfer.source={source}", "transfer.sf_frames=64", "transfer.sf_updates=7",
                                      f"transfer.sf_epsilon={epsilon}", f"seed={seed}"],
                                 task="gridrooms/northeast-shifted")
        env = make_env(cfg.task, batch_size=(2,), seed=0)
        torch.manual_seed(cfg.seed)  # as a run (and each member of a seed group) starts
        return get_method("sf-gpi").build(cfg, make_agent(env, cfg), env, resuming=False)

    def psi(transfer):
        return TensorDict.from_module(_gpi(transfer).critics[0])

    settings = [(sources[0], 0, 0.1), (sources[1], 1, 0.1), (sources[0], 0, 0.2)]
    alone = [built(*s) for s in settings]
    entries = [pretrain(t.pretraining) for t in alone]
    together = [built(*s) for s in settings]
    monkeypatch.setattr(pretraining, "PRETRAIN_CHUNK", 3)  # 7 steps: batches drawn 3, 3 and 1 at a time
    updates = []
    real = pretraining.SeedGroup.update
    monkeypatch.setattr(pretraining.SeedGroup, "update",
                        lambda self, b, *a: updates.append(b.shape[0]) or real(self, b, *a))
    told = pretraining.pretrain_together([t.pretraining for t in together])
    assert all(e.pop("pretraining_s") > 0 for e in told + entries)  # each summary says how long psi took
    assert told == entries
    assert updates == [2] * 7  # the two distinct problems, seven steps
    for a, t in zip(alone, together):
        torch.testing.assert_close(psi(t), psi(a), rtol=1e-5, atol=1e-6)
    assert (psi(together[0]) == psi(together[2])).all() and not (psi(together[0]) == psi(together[1])).all()


def test_the_plateau_rule_stops_on_a_hand_made_td_sequence():
    """Blocks of 2 steps, tolerance 0.1, patience 2: means 9, 6 (< 0.9 * 9: falls), 5.7 (not < 0.9 * 6 = 5.4),
    5.1 (falls: the count restarts), 4.9 and 4.7 (neither < 0.9 * 5.1 = 4.59): TD stops after 12 steps."""
    from drltg.transfer.sf_gpi import Plateau

    losses = [10, 8, 6, 6, 5.8, 5.6, 5.0, 5.2, 5.0, 4.8, 4.8, 4.6, 1, 1]
    plateau = Plateau(block=2, patience=2, tolerance=0.1)
    stops = [plateau.push(x) for x in losses[:12]]
    assert stops == [False] * 11 + [True]
    assert plateau.means == pytest.approx([9, 6, 5.7, 5.1, 4.9, 4.7])
    assert plateau.best == pytest.approx(5.1)


def test_the_experiment_on_grid_rooms_runs_reports_and_logs_how_often_the_source_won(tmp_path):
    out = tmp_path / "near"
    assert main(["experiment", "gridrooms-near", "--method", "sf-gpi", "--seeds", "1", "--frames", "512",
                 "--out", str(out), "--threshold", "0", "--no-progress", *TINY, *SF, "-o", "log.every=16"]) == 0
    assert json.loads((out / "report" / "transfer_metrics.json").read_text())["metrics"]["n_seeds_transfer"] == 1
    run = out / "transfer" / "seed-0"
    assert json.loads((run / "summary.json").read_text())["successor_feature_frames"] == 512
    (path,) = (run / "logs" / "csv").rglob("reused_fraction.csv")
    rows = [(int(step), float(value)) for step, value in (line.split(",") for line in path.read_text().split())]
    assert [step for step, _ in rows] == list(range(16, 513, 16))
    # random actions until frame 128: GPI does not act there; after it, every batch's choices are in [0, 1]
    assert all(f == 0 for step, f in rows if step <= 128)
    assert all(0 <= f <= 1 for _, f in rows) and any(f > 0 for step, f in rows if step > 128)


@pytest.mark.parametrize("pair", ["pendulum-heavier", "lift-to-place"])
def test_a_pair_without_goal_features_is_refused_in_one_sentence_before_training(pair, tmp_path, capsys):
    assert main(["experiment", pair, "--method", "sf-gpi", "--frames", "256", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert REFUSAL in err and "has no goal" in err and "Traceback" not in err
    assert not (tmp_path / "x").exists()


def test_a_source_of_other_dynamics_is_refused_at_config_time(tmp_path):
    run, _ = _source_run(tmp_path / "src", task="gridrooms/northeast")
    with pytest.raises(UsageError, match=f"{REFUSAL}.*are different environments"):
        config_lib.resolve({}, ["transfer.method=sf-gpi", f"transfer.source={run}"], task="fourrooms/northeast")
    longer = config_lib.resolve({}, ["env.horizon=50"], task="fourrooms/northeast")
    (run / "config.yaml").write_text(config_lib.dump(longer))
    with pytest.raises(UsageError, match=f"{REFUSAL}.*differ in env.horizon"):
        config_lib.resolve({}, ["transfer.method=sf-gpi", f"transfer.source={run}"], task="fourrooms/southwest")
    same = config_lib.resolve({}, ["transfer.method=sf-gpi", f"transfer.source={run}", "env.horizon=50"],
                              task="fourrooms/southwest")
    assert same.transfer.source == str(run)


def test_sf_gpi_trains_a_sac_learner_only():
    with pytest.raises(UsageError, match="sf-gpi, which works with algo sac"):
        config_lib.resolve({}, ["transfer.method=sf-gpi"], task="fourrooms/northeast-shifted", algo="td3")


def test_the_mixer_reads_the_learners_live_critics(tmp_path):
    """Discrete: the learner's own values are min_k Q_k(s, .) of its current parameters, not a copy."""
    cfg, agent, env, transfer = _build(tmp_path, "gridrooms/northeast", "gridrooms/northeast-shifted")
    own = transfer.mixer.module[0]
    obs = env.reset()["observation"]
    before = own(TensorDict({"observation": obs}, batch_size=[2]))["learner_action_value"]
    with torch.no_grad():
        for p in agent.loss.qvalue_network_params.values(True, True):
            p.add_(1.0)
    after = own(TensorDict({"observation": obs}, batch_size=[2]))["learner_action_value"]
    assert not torch.allclose(before, after)


@pytest.mark.parametrize("source_task, target_task", [("gridrooms/northeast", "gridrooms/northeast-shifted"),
                                                      ("fourrooms/northeast", "fourrooms/northeast-shifted")])
def test_in_a_seed_group_each_seeds_gpi_reads_its_own_live_critics(tmp_path, source_task, target_task):
    """Block k of a group's batch acts by seed k's GPI, valued with seed k's current (stacked) critics: after seed
    1's critics move, block 1's actions are those of GPI over seed 1's new critics, block 0's stay."""
    from drltg.training.seeds import GroupLearner, SeedGroup

    built = [_build(tmp_path / str(k), source_task, target_task) for k in range(2)]
    agents, transfers = [b[1] for b in built], [b[3] for b in built]
    group = SeedGroup(agents)
    learner = GroupLearner(group, [None, None], None, transfers)
    td = make_env(target_task, batch_size=(4,), seed=1).reset()

    def gpi_of_each_seed():
        """Block k through seed k's own mixer, seed k's stacked critics copied into its own loss."""
        group.sync()
        blocks = []
        for k, (agent, transfer) in enumerate(zip(agents, transfers)):
            block = td[2 * k:2 * k + 2].clone()
            torch.manual_seed(0)
            block.update(agent.policy(block.clone()).select("action"))
            blocks.append(transfer.mixer(block))
        return torch.cat(blocks)

    def grouped():
        torch.manual_seed(0)
        return learner.policy(td.clone())

    key = "learner_action_value" if source_task.startswith("gridrooms") else "gpi_value"
    before = grouped()
    torch.testing.assert_close(before[key], gpi_of_each_seed()[key])
    with torch.no_grad():
        for p in group.params[1]["qvalue_network_params"].values(True, True):
            p.add_(torch.randn_like(p))
    after = grouped()
    assert torch.equal(after[key][:2], before[key][:2]) and not torch.allclose(after[key][2:], before[key][2:])
    torch.testing.assert_close(after[key][2:], gpi_of_each_seed()[key][2:])


def test_a_sweep_runs_both_new_methods_on_one_source_and_baseline(tmp_path):
    import yaml

    from tests.test_sweep import TINY as SWEEP_TINY

    spec = tmp_path / "sweep.yaml"
    spec.write_text(yaml.safe_dump({"pairs": ["gridrooms-near"], "methods": ["kickstarting", "sf-gpi"], "seeds": 1,
                                    "frames": 256, "threshold": 0,
                                    "overrides": {**SWEEP_TINY, "transfer.sf_frames": 256, "transfer.sf_updates": 10,
                                                  "transfer.kick_frames": 128}}))
    out = tmp_path / "out"
    assert main(["sweep", str(spec), "--out", str(out)]) == 0
    group = out / "gridrooms-near" / "sac"
    assert [p.name for p in (group / "source").iterdir()] == ["seed-50"]
    assert [p.name for p in (group / "baseline").iterdir()] == ["seed-0"]
    for method in ("kickstarting", "sf-gpi"):
        assert (group / method / "report" / "transfer_metrics.json").is_file()
    summary = json.loads((group / "sf-gpi" / "transfer" / "seed-0" / "summary.json").read_text())
    assert summary["successor_feature_frames"] == 256
