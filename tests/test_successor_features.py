"""Successor features and GPI on tabular MDPs solved by hand: psi^pi = (I - gamma P_pi)^-1 Phi exactly, the TD loss
against hand-computed numbers, GPI's value against every source's by exact policy evaluation, and the reward
features and their regression on the FourRooms envs."""
import pytest
import torch
from tensordict import TensorDict
from tensordict.nn import TensorDictModule
from torch import nn
from torchrl.objectives import HardUpdate

from drltg.collectors import GPIPolicy
from drltg.envs.fourrooms import FourRoomsEnv
from drltg.envs.gridrooms import GridFourRoomsEnv
from drltg.errors import UsageError
from drltg.losses import SuccessorFeatureLoss
from drltg.modules import GoalFeatures, make_sf_critic, regress_weights

# ---- a tabular MDP: next[s, a] deterministic, entering a terminal state ends the episode, phi = F[s'] ----


def exact_sf(nxt, terminal, F, pi, gamma):
    """psi^pi [S, A, d] by linear algebra: X = Phi + gamma M X over the (s, a) of non-terminal s, in float64."""
    S, A = nxt.shape
    rows = [(s, a) for s in range(S) if not terminal[s] for a in range(A)]
    at = {sa: i for i, sa in enumerate(rows)}
    M = torch.zeros(len(rows), len(rows), dtype=torch.float64)
    for i, (s, a) in enumerate(rows):
        s2 = int(nxt[s, a])
        if not terminal[s2]:
            M[i, at[(s2, int(pi[s2]))]] = 1.0
    Phi = F[nxt[[s for s, _ in rows], [a for _, a in rows]]].double()
    X = torch.linalg.solve(torch.eye(len(rows), dtype=torch.float64) - gamma * M, Phi)
    psi = torch.zeros(S, A, F.shape[1], dtype=torch.float64)
    for i, (s, a) in enumerate(rows):
        psi[s, a] = X[i]
    return psi


def optimal_policy(nxt, terminal, F, w, gamma, sweeps=600):
    """The greedy policy of Q* for the reward F[s'] . w (value iteration)."""
    r = (F.double() @ w.double())[nxt]
    alive = (~terminal[nxt]).double()
    q = torch.zeros(nxt.shape, dtype=torch.float64)
    for _ in range(sweeps):
        q = r + gamma * alive * q.max(-1).values[nxt]
    return q.argmax(-1)


def table_critic(psi):
    """A discrete SF critic on one-hot states holding exactly the table psi [S, A, d]."""
    S, A, d = psi.shape
    critic = make_sf_critic(S, d, num_actions=A, num_cells=(), bias=False)
    with torch.no_grad():
        critic.module[0].weight.copy_(psi.reshape(S, A * d).T.float())
    return critic


def table_policy(pi, A):
    """A policy module writing the one-hot action pi[s] of one-hot states."""
    lin = nn.Linear(len(pi), A, bias=False)
    with torch.no_grad():
        lin.weight.copy_(nn.functional.one_hot(pi, A).T.float())
    return TensorDictModule(lin, in_keys=["observation"], out_keys=["action"])


def states(S, which=None):
    which = torch.arange(S) if which is None else which
    return TensorDict(observation=nn.functional.one_hot(which, S).float(), batch_size=[len(which)])


def all_transitions(nxt, terminal, F):
    """One transition per (s, a) of every non-terminal s."""
    S, A = nxt.shape
    s, a = (t.reshape(-1) for t in torch.meshgrid(torch.arange(S), torch.arange(A), indexing="ij"))
    keep = ~terminal[s]
    s, a = s[keep], a[keep]
    s2 = nxt[s, a]
    n = len(s)
    return TensorDict(
        observation=nn.functional.one_hot(s, S).float(), action=nn.functional.one_hot(a, A),
        next=TensorDict(observation=nn.functional.one_hot(s2, S).float(), features=F[s2].float(),
                        terminated=terminal[s2].unsqueeze(-1), done=terminal[s2].unsqueeze(-1),
                        truncated=torch.zeros(n, 1, dtype=torch.bool), batch_size=[n]),
        batch_size=[n])


def gpi_values(nxt, terminal, F, sources, w, gamma):
    """GPIPolicy's greedy action in every state, the exact Q of that policy and of every source, on w."""
    S, A = nxt.shape
    critics = [table_critic(exact_sf(nxt, terminal, F, pi, gamma)) for pi in sources]
    gpi = GPIPolicy(critics, w)
    out = gpi(states(S))
    pi_gpi = out["action"].argmax(-1)
    q_gpi = exact_sf(nxt, terminal, F, pi_gpi, gamma) @ w.double()
    q_sources = torch.stack([exact_sf(nxt, terminal, F, pi, gamma) @ w.double() for pi in sources])
    return out, gpi, pi_gpi, q_gpi, q_sources


# ---- 1. TD learning drives a tabular psi to (I - gamma P_pi)^-1 Phi ----

def test_td_drives_a_tabular_psi_to_the_exact_successor_features():
    # chain 0-1-2-3, 3 terminal; left/right; pi: right, left, right (0 and 1 bounce back and forth)
    nxt = torch.tensor([[0, 1], [0, 2], [1, 3], [3, 3]])
    terminal = torch.tensor([False, False, False, True])
    F = torch.eye(4)
    pi, gamma = torch.tensor([1, 0, 1, 0]), 0.9
    exact = exact_sf(nxt, terminal, F, pi, gamma)
    # by hand: from (1, right) -> 2, then right -> 3: psi = e_2 + 0.9 e_3
    assert exact[1, 1].tolist() == pytest.approx([0, 0, 1, 0.9])
    critic = make_sf_critic(4, 4, num_actions=2, num_cells=(), bias=False)
    loss = SuccessorFeatureLoss(critic, policy=table_policy(pi, 2), reduction="sum")
    loss.make_value_estimator(gamma=gamma)
    target = HardUpdate(loss, value_network_update_interval=1)  # each step is one exact DP sweep
    optim = torch.optim.SGD(loss.sf_network_params.values(True, True), lr=0.5)
    batch = all_transitions(nxt, terminal, F)
    for _ in range(250):  # 0.9 ** 250 < 1e-11
        optim.zero_grad()
        loss(batch.clone())["loss_sf"].backward()
        optim.step()
        target.step()
    with loss.sf_network_params.to_module(loss.sf_network):
        learnt = loss.sf_network(states(4))["successor_features"]
    assert torch.allclose(learnt[:3].double(), exact[:3], atol=1e-5)


def hand_batch(rows):
    """Transitions (s, a, s', phi, terminated, truncated) on 2 states, 2 actions."""
    s, a, s2, phi, term, trunc = zip(*rows)
    n = len(rows)
    flag = lambda x: torch.tensor(x).unsqueeze(-1)  # noqa: E731
    return TensorDict(
        observation=nn.functional.one_hot(torch.tensor(s), 2).float(),
        action=nn.functional.one_hot(torch.tensor(a), 2),
        next=TensorDict(observation=nn.functional.one_hot(torch.tensor(s2), 2).float(), features=torch.tensor(phi),
                        terminated=flag(term), truncated=flag(trunc), done=flag(term) | flag(trunc), batch_size=[n]),
        batch_size=[n])


HAND_PSI = torch.tensor([[[1.0, 0.0], [0.0, 2.0]], [[3.0, 1.0], [1.0, 1.0]]])  # psi[s, a]


def hand_outputs(rows):
    # greedy on w = (1, -1): at s' = 1, Q = (3 - 1, 1 - 1) = (2, 0), so a' = 0 and psi(s', a') = (3, 1)
    loss = SuccessorFeatureLoss(table_critic(HAND_PSI), weights=torch.tensor([1.0, -1.0]))
    loss.make_value_estimator(gamma=0.5)
    batch = hand_batch(rows)
    return loss(batch), batch


def hand_loss(rows):
    out, batch = hand_outputs(rows)
    return out["loss_sf"].item(), batch["td_error"].squeeze(-1).tolist()


HAND_ROWS = [
    (0, 1, 1, [0.5, 1.0], False, False),  # target (0.5, 1) + 0.5 (3, 1) = (2, 1.5); psi (0, 2): 4 + 0.25
    (1, 0, 0, [1.0, 0.0], True, False),  # terminated: target (1, 0); psi (3, 1): 4 + 1
]


def test_one_td_step_equals_the_hand_computed_loss():
    value, errors = hand_loss(HAND_ROWS)
    assert errors == pytest.approx([4.25, 5.0])
    assert value == pytest.approx(4.625)
    out, _ = hand_outputs(HAND_ROWS)  # the targets' mean squared norm, (2^2 + 1.5^2 + 1^2) / 2, for the relative error
    assert out["sf_target_sq"].item() == pytest.approx(3.625)


def test_a_truncated_transition_still_bootstraps():
    # truncated (done) but not terminated: target (0, 1) + 0.5 (3, 1) = (1.5, 1.5); psi(1, 1) = (1, 1): 0.25 + 0.25
    value, _ = hand_loss([(1, 1, 1, [0.0, 1.0], False, True)])
    assert value == pytest.approx(0.5)  # 1.0 had it stopped at done: target (0, 1)
    value, _ = hand_loss([(1, 1, 1, [0.0, 1.0], True, False)])
    assert value == pytest.approx(1.0)


def test_a_continuous_critic_bootstraps_on_the_policys_action():
    critic = make_sf_critic(1, 1, action_dim=1, num_cells=(), bias=False)  # psi(o, a) = 2 o + 3 a
    policy = TensorDictModule(nn.Linear(1, 1), in_keys=["observation"], out_keys=["action"])  # a' = 0.5
    with torch.no_grad():
        critic.module[0].weight.copy_(torch.tensor([[2.0, 3.0]]))
        policy.module.weight.zero_()
        policy.module.bias.fill_(0.5)
    loss = SuccessorFeatureLoss(critic, policy=policy)
    loss.make_value_estimator(gamma=0.5)
    batch = TensorDict(observation=torch.tensor([[1.0]]), action=torch.tensor([[-1.0]]),
                       next=TensorDict(observation=torch.tensor([[2.0]]), features=torch.tensor([[1.0]]),
                                       terminated=torch.tensor([[False]]), batch_size=[1]), batch_size=[1])
    # psi = 2 - 3 = -1; target = 1 + 0.5 (4 + 1.5) = 3.75; (3.75 + 1)^2
    assert loss(batch)["loss_sf"].item() == pytest.approx(4.75 ** 2)


def test_the_loss_needs_the_policy_it_evaluates():
    with pytest.raises(ValueError, match="policy"):
        SuccessorFeatureLoss(make_sf_critic(2, 2, action_dim=1))


# ---- 2. GPI is at least as good as every source policy, and can beat all of them ----

def test_gpi_beats_both_sources_where_it_combines_them():
    # 0 -a0-> 1 -a1-> 2 (goal, +1); every other move falls into 3 (pit, 0); 2 and 3 terminal
    nxt = torch.tensor([[1, 3], [3, 2], [2, 2], [3, 3]])
    terminal = torch.tensor([False, False, True, True])
    F = torch.tensor([[0.0, 0.0], [0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])  # phi: (at goal, at pit)
    pi1, pi2 = torch.tensor([0, 0, 0, 0]), torch.tensor([1, 1, 0, 0])  # pi1: to 1 then the pit; pi2: the pit
    gamma, w = 0.9, torch.tensor([1.0, 0.0])
    out, _, pi_gpi, q_gpi, q_sources = gpi_values(nxt, terminal, F, [pi1, pi2], w, gamma)
    assert pi_gpi[:2].tolist() == [0, 1]  # pi1's first action (valued by psi_2), then pi2's
    assert out["gpi_index"][0].item() == 1  # at 1 both value a1 at 1 (the episode ends): a tie, the first wins
    v_gpi = q_gpi[0, pi_gpi[0]].item()
    assert v_gpi == pytest.approx(0.9)
    assert q_sources[0, 0, pi1[0]].item() == 0.0 and q_sources[1, 0, pi2[0]].item() == 0.0


@pytest.mark.parametrize("seed", range(5))
def test_gpi_is_at_least_every_source_on_a_random_mdp(seed):
    g = torch.Generator().manual_seed(seed)
    S, A, d, gamma = 9, 3, 3, 0.9
    nxt = torch.randint(0, S, (S, A), generator=g)
    terminal = torch.zeros(S, dtype=torch.bool)
    terminal[-2:] = True
    F = torch.randn(S, d, generator=g)
    sources = [torch.randint(0, A, (S,), generator=g) for _ in range(3)]
    w = torch.randn(d, generator=g)
    _, _, _, q_gpi, q_sources = gpi_values(nxt, terminal, F, sources, w, gamma)
    live = ~terminal
    assert (q_gpi[live] >= q_sources.amax(0)[live] - 1e-5).all()  # Q^GPI >= max_i Q^pi_i at every (s, a)


# ---- 3. with w = a source task's weights, GPI is that (optimal) source ----

def test_gpi_on_a_source_tasks_weights_recovers_that_source():
    g = torch.Generator().manual_seed(7)
    S, A, d, gamma = 9, 3, 3, 0.9
    nxt = torch.randint(0, S, (S, A), generator=g)
    terminal = torch.zeros(S, dtype=torch.bool)
    terminal[-2:] = True
    F = torch.randn(S, d, generator=g)
    w1, w2 = torch.randn(d, generator=g), torch.randn(d, generator=g)
    pi1, pi2 = optimal_policy(nxt, terminal, F, w1, gamma), optimal_policy(nxt, terminal, F, w2, gamma)
    out, gpi, pi_gpi, q_gpi, q_sources = gpi_values(nxt, terminal, F, [pi1, pi2], w1, gamma)
    live = ~terminal
    q = gpi.action_values(states(S)).double()  # [S, 2, A]
    assert torch.allclose(q.amax(1)[live], q_sources[0][live], atol=1e-5)  # max_i Q_i = Q_1 = Q*
    assert torch.equal(pi_gpi[live], pi1[live])
    strictly = (q_sources[0] - q_sources[1])[torch.arange(S), pi1] > 1e-4
    assert strictly[live].any()
    assert (out["gpi_index"].squeeze(-1)[live & strictly] == 0).all()


def test_discrete_gpi_weighs_the_learners_own_values():
    psi = torch.zeros(2, 2, 1)
    psi[:, 1] = 1.0  # the source values action 1 at 1
    gpi = GPIPolicy([table_critic(psi)], torch.tensor([1.0]), own_value_key="action_value")
    td = states(2)
    td["action_value"] = torch.tensor([[2.0, 0.0], [0.0, 0.5]])  # the learner: 2 for action 0 in state 0
    out = gpi(td)
    assert out["action"].argmax(-1).tolist() == [0, 1]
    assert out["gpi_index"].squeeze(-1).tolist() == [1, 0]  # the learner's own (index 1), then the source
    assert out["gpi_value"].squeeze(-1).tolist() == [2.0, 1.0]


def test_continuous_gpi_chooses_the_best_candidate_per_element():
    def critic(weights):  # psi(o, a) = W [o, a]
        c = make_sf_critic(1, 2, action_dim=1, num_cells=(), bias=False)
        with torch.no_grad():
            c.module[0].weight.copy_(torch.tensor(weights))
        return c

    def constant(a):
        p = TensorDictModule(nn.Linear(1, 1), in_keys=["observation"], out_keys=["action"])
        with torch.no_grad():
            p.module.weight.zero_()
            p.module.bias.fill_(a)
        return p

    # w = (1, 1): Q_1(s, a) = a, Q_2(s, a) = -a, so max_i Q_i = |a|
    critics = [critic([[0.0, 1.0], [0.0, 0.0]]), critic([[0.0, 0.0], [0.0, -1.0]])]
    gpi = GPIPolicy(critics, torch.tensor([1.0, 1.0]), policies=[constant(0.3), constant(-0.8)], include_action=True)
    td = TensorDict(observation=torch.zeros(2, 1), action=torch.tensor([[0.5], [0.9]]), batch_size=[2])
    out = gpi(td.clone())
    assert out["action"].squeeze(-1).tolist() == pytest.approx([-0.8, 0.9])
    assert out["gpi_index"].squeeze(-1).tolist() == [1, 2]  # pi_2's action; the learner's own
    assert out["gpi_value"].squeeze(-1).tolist() == pytest.approx([0.8, 0.9])

    # the learner's own values join the library: Q_L(s, a) = 2a, so max_i Q_i(a_j) = max(|a_j|, 2 a_j) over the
    # candidates (0.3, -0.8, 0.5) is (0.6, 0.8, 1.0) and over (0.3, -0.8, 0.9) is (0.6, 0.8, 1.8)
    with_own = GPIPolicy(critics, torch.tensor([1.0, 1.0]), policies=[constant(0.3), constant(-0.8)],
                         include_action=True, own_values=lambda td, candidates: 2 * candidates.squeeze(-1))
    out = with_own(td.clone())
    assert out["action"].squeeze(-1).tolist() == pytest.approx([0.5, 0.9])
    assert out["gpi_index"].squeeze(-1).tolist() == [2, 2]
    assert out["gpi_value"].squeeze(-1).tolist() == pytest.approx([1.0, 1.8])


# ---- 4. the FourRooms reward features are exact, and the regression recovers w ----

def rollout(env, features, steps=100):
    td = env.rollout(steps, break_when_any_done=False)
    return features(td.reshape(-1))


def test_grid_goal_features_give_the_reward_and_the_regression_recovers_w():
    goals = [(3, 9), (10, 9), (7, 9)]
    env = GridFourRoomsEnv(goal=(3, 9), start_room="northeast", batch_size=(64,), seed=0)
    features = GoalFeatures.for_env(env, goals)
    td = rollout(env, features)
    phi, reward = td["next", "features"], td["next", "reward"]
    assert td["next", "success"].sum() > 0  # the goal is in the data
    w = features.task_weights((3, 9), env.step_cost)
    assert w.tolist() == pytest.approx([1.01, 0.0, 0.0, -0.01])
    assert torch.allclose(phi @ w, reward.squeeze(-1), atol=1e-6)
    assert torch.allclose(regress_weights(phi, reward), w, atol=1e-5)


def test_continuous_goal_discs_give_the_reward():
    env = FourRoomsEnv(goal=(8.0, 8.0), start_room="northeast", batch_size=(64,), seed=0)
    features = GoalFeatures.for_env(env, [(2.0, 2.0), (8.0, 8.0)])
    td = rollout(env, features)
    assert td["next", "success"].sum() > 0
    w = features.task_weights((8.0, 8.0), env.step_cost)
    assert torch.allclose(td["next", "features"] @ w, td["next", "reward"].squeeze(-1), atol=1e-6)
    assert torch.allclose(regress_weights(td["next", "features"], td["next", "reward"]), w, atol=1e-5)


def test_bad_goal_and_regression_inputs_are_refused_in_one_sentence():
    features = GoalFeatures([(3, 9)])
    with pytest.raises(UsageError, match="not one of the candidate goals"):
        features.task_weights((1, 1), 0.01)
    with pytest.raises(UsageError, match="one reward per feature row"):
        regress_weights(torch.ones(3, 2), torch.ones(2))
