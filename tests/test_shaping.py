"""Potential-based reward shaping: arithmetic by hand, specs, resets, dynamic potentials."""
from __future__ import annotations

import pytest
import torch
from tensordict import TensorDict
from tensordict.nn import TensorDictModule
from torch import nn
from torchrl.collectors import Collector
from torchrl.data import Bounded, Categorical, Composite, Unbounded
from torchrl.envs import EnvBase, SerialEnv, TransformedEnv
from torchrl.envs.utils import check_env_specs

from drltg.envs import FourRoomsEnv, GridFourRoomsEnv, fourrooms, gridrooms
from drltg.envs.fourrooms import FourRoomsPotential
from drltg.envs.gridrooms import GridFourRoomsPotential
from drltg.transforms import PotentialShaping, TimeDependentPotential

GAMMA = 0.9


class WalkEnv(EnvBase):
    """A batch of walkers on a line: each step moves ``x`` by +1 and pays 10 on reaching the goal, else 0.

    Env ``i`` starts at ``start[i]``, terminates on reaching ``goal[i]`` and is truncated after
    ``horizon[i]`` steps, so a batch can mix terminal, truncated and ordinary steps.
    """

    def __init__(self, start, goal, horizon):
        super().__init__(batch_size=torch.Size([len(start)]))
        self.start = torch.tensor(start, dtype=torch.float32).unsqueeze(-1)
        self.goal = torch.tensor(goal, dtype=torch.float32).unsqueeze(-1)
        self.horizon = torch.tensor(horizon).unsqueeze(-1)
        n = self.batch_size
        self.observation_spec = Composite(
            observation=Unbounded((*n, 1)),
            step_count=Bounded(0, 1000, (*n, 1), dtype=torch.int64),
            shape=n,
        )
        self.state_spec = self.observation_spec.clone()
        self.action_spec = Bounded(0.0, 1.0, (*n, 1))
        self.reward_spec = Bounded(0.0, 10.0, (*n, 1))
        flag = Categorical(2, (*n, 1), dtype=torch.bool)
        self.done_spec = Composite(done=flag, terminated=flag.clone(), truncated=flag.clone(), shape=n)

    def _reset(self, tensordict=None, **kwargs):
        return TensorDict(
            observation=self.start.clone(),
            step_count=torch.zeros_like(self.horizon),
            batch_size=self.batch_size,
        )

    def _step(self, tensordict):
        x = tensordict["observation"] + 1
        t = tensordict["step_count"] + 1
        terminated = x >= self.goal
        truncated = (t >= self.horizon) & ~terminated
        return TensorDict(
            observation=x,
            step_count=t,
            reward=torch.where(terminated, 10.0, 0.0),
            terminated=terminated,
            truncated=truncated,
            done=terminated | truncated,
            batch_size=self.batch_size,
        )

    def _set_seed(self, seed):
        pass


def phi(x):
    return 2.0 * x + 1.0


def shaped(env, potential=phi, **kwargs):
    kwargs.setdefault("in_keys", ["observation"])
    return TransformedEnv(env, PotentialShaping(potential, gamma=GAMMA, **kwargs))


def ones_action(td):
    return td.set("action", torch.ones(*td.batch_size, 1))


def test_terminal_truncated_and_ordinary_steps_in_one_batch():
    # env 0 terminates, env 1 is truncated, env 2 takes an ordinary step
    env = shaped(WalkEnv(start=[0.0, 3.0, 5.0], goal=[1.0, 99.0, 99.0], horizon=[9, 1, 9]))
    td = env.step(ones_action(env.reset()))["next"]
    assert td["terminated"].squeeze(-1).tolist() == [True, False, False]
    assert td["truncated"].squeeze(-1).tolist() == [False, True, False]
    # r' = r + gamma * Phi(s') * (1 - terminated) - Phi(s), Phi(x) = 2x + 1
    expected = [
        10.0 + GAMMA * 0.0 - 1.0,  # x: 0 -> 1, terminal: Phi(s') = 0
        0.0 + GAMMA * 9.0 - 7.0,  # x: 3 -> 4, truncated: Phi(s') kept
        0.0 + GAMMA * 13.0 - 11.0,  # x: 5 -> 6
    ]
    torch.testing.assert_close(td["reward"].squeeze(-1), torch.tensor(expected))
    assert td["task_reward"].squeeze(-1).tolist() == [10.0, 0.0, 0.0]
    assert td["potential"].squeeze(-1).tolist() == [3.0, 9.0, 13.0]


def test_unshaped_reward_is_kept_and_reward_spec_is_honest():
    env = shaped(WalkEnv(start=[0.0, 0.0], goal=[3.0, 5.0], horizon=[9, 9]))
    assert isinstance(env.full_reward_spec["reward"], Unbounded)
    assert env.full_observation_spec["task_reward"] == env.base_env.full_reward_spec["reward"]
    assert env.reward_keys == ["reward"]
    td = env.rollout(6, ones_action, break_when_any_done=False)
    torch.testing.assert_close(
        td["next", "task_reward"], env.base_env.rollout(6, ones_action, break_when_any_done=False)["next", "reward"]
    )
    assert not torch.equal(td["next", "reward"], td["next", "task_reward"])


@pytest.mark.parametrize("break_when_any_done", [True, False])
def test_check_env_specs_passes(break_when_any_done):
    env = shaped(WalkEnv(start=[0.0, 1.0, 2.0], goal=[2.0, 3.0, 9.0], horizon=[9, 1, 9]))
    check_env_specs(env, break_when_any_done=break_when_any_done)


def test_partial_reset_restores_each_envs_start_potential():
    # env 0 terminates every step, env 1 is truncated every 2 steps, env 2 never stops
    env = shaped(WalkEnv(start=[0.0, 10.0, 20.0], goal=[1.0, 99.0, 99.0], horizon=[99, 2, 99]))
    td = env.rollout(4, ones_action, break_when_any_done=False)
    x = td["observation"].squeeze(-1)
    assert x.tolist() == [[0, 0, 0, 0], [10, 11, 10, 11], [20, 21, 22, 23]]
    assert torch.equal(td["potential"], phi(td["observation"]))
    x_next = td["next", "observation"]
    alive = (~td["next", "terminated"]).float()
    torch.testing.assert_close(
        td["next", "reward"],
        td["next", "task_reward"] + GAMMA * phi(x_next) * alive - phi(td["observation"]),
    )


def test_collector_auto_reset_shapes_every_transition():
    env = shaped(WalkEnv(start=[0.0, 10.0, 20.0], goal=[2.0, 99.0, 99.0], horizon=[99, 3, 99]))
    policy = TensorDictModule(lambda x: torch.ones_like(x), in_keys=["observation"], out_keys=["action"])
    collector = Collector(
        env, policy, frames_per_batch=3 * 7, total_frames=3 * 14, auto_register_policy_transforms=False
    )
    for data in collector:
        alive = (~data["next", "terminated"]).float()
        expected = (
            data["next", "task_reward"] + GAMMA * phi(data["next", "observation"]) * alive - phi(data["observation"])
        )
        torch.testing.assert_close(data["next", "reward"], expected)
        assert data["next", "done"].any()
    collector.shutdown()


def test_shaping_inside_batched_env_workers():
    env = SerialEnv(2, lambda: shaped(WalkEnv(start=[0.0, 10.0], goal=[1.0, 99.0], horizon=[99, 2])))
    check_env_specs(env)
    td = env.rollout(4, ones_action, break_when_any_done=False)
    assert td["observation"][0].squeeze(-1).tolist() == [[0, 0, 0, 0], [10, 11, 10, 11]]
    alive = (~td["next", "terminated"]).float()
    expected = td["next", "task_reward"] + GAMMA * phi(td["next", "observation"]) * alive - phi(td["observation"])
    torch.testing.assert_close(td["next", "reward"], expected)


def test_tensordict_module_and_plain_callable_potentials_agree():
    base = dict(start=[0.0, 4.0], goal=[2.0, 9.0], horizon=[9, 9])
    module = TensorDictModule(phi, in_keys=["observation"], out_keys=["phi"])
    on_td = shaped(WalkEnv(**base), potential=lambda td: phi(td["observation"]), in_keys=None)
    rewards = [
        env.rollout(5, ones_action, break_when_any_done=False)["next", "reward"]
        for env in (shaped(WalkEnv(**base)), shaped(WalkEnv(**base), potential=module, in_keys=None), on_td)
    ]
    torch.testing.assert_close(rewards[0], rewards[1])
    torch.testing.assert_close(rewards[0], rewards[2])


def test_forward_shapes_stored_transitions_like_the_env():
    env = shaped(WalkEnv(start=[0.0, 4.0], goal=[2.0, 9.0], horizon=[9, 3]))
    td = env.rollout(5, ones_action, break_when_any_done=False)
    stored = td.exclude("potential", ("next", "potential")).clone()
    stored["next", "reward"] = stored["next", "task_reward"]
    torch.testing.assert_close(env.transform(stored)["next", "reward"], td["next", "reward"])


def test_transition_without_stored_potential_recomputes_it():
    env = shaped(WalkEnv(start=[3.0], goal=[9.0], horizon=[9]))
    td = ones_action(env.reset().exclude("potential"))
    torch.testing.assert_close(env.step(td)["next", "reward"], torch.tensor([[GAMMA * 9.0 - 7.0]]))


def test_time_dependent_potential_value_and_shaping():
    # Phi(s, t) = (1 - t / 4) * (2x + 1)
    potential = TimeDependentPotential(phi, lambda t: 1.0 - t / 4)
    x, t = torch.tensor([[3.0], [5.0]]), torch.tensor([[0], [2]])
    torch.testing.assert_close(potential(x, t), torch.tensor([[7.0], [5.5]]))
    env = shaped(
        WalkEnv(start=[3.0], goal=[99.0], horizon=[99]), potential=potential, in_keys=["observation", "step_count"]
    )
    td = env.rollout(2, ones_action)
    # F = gamma * Phi(s', t + 1) - Phi(s, t): steps (x=3,t=0) -> (4,1) -> (5,2)
    expected = [GAMMA * (3 / 4) * 9.0 - 7.0, GAMMA * (2 / 4) * 11.0 - (3 / 4) * 9.0]
    torch.testing.assert_close(td["next", "reward"].flatten(), torch.tensor(expected))


def test_potential_is_evaluated_once_per_state():
    # a potential whose parameter changes between steps (Devlin & Kudenko's dynamic case):
    # Phi(s) must be the value computed when s was reached, not a re-evaluation with the new parameter
    scale = nn.Parameter(torch.tensor(1.0), requires_grad=False)
    env = shaped(WalkEnv(start=[3.0], goal=[99.0], horizon=[99]), potential=lambda x: scale * x)
    td = env.reset()
    scale.fill_(2.0)
    out = env.step(ones_action(td))["next"]
    torch.testing.assert_close(out["reward"], torch.tensor([[GAMMA * 2.0 * 4.0 - 1.0 * 3.0]]))


def test_invalid_gamma_is_refused():
    with pytest.raises(ValueError, match="gamma"):
        PotentialShaping(phi, gamma=1.5, in_keys=["observation"])


# ------------------------------------------------------------------ FourRooms potentials
def test_fourrooms_potential_is_minus_the_path_through_the_doorways():
    potential = FourRoomsPotential(goal=(8.0, 8.0), scale=1.0)  # northeast room
    door_n, door_w, door_s, door_e = (5.0, 7.5), (2.0, 5.0), (5.0, 2.0), (7.5, 5.0)

    def dist(*points):
        return sum(((a - c) ** 2 + (b - d) ** 2) ** 0.5 for (a, b), (c, d) in zip(points, points[1:]))

    positions = [(8.0, 8.0), (6.0, 9.0), (2.0, 8.0), (2.0, 2.0), (8.0, 2.0), (4.0, 3.0)]
    expected = [
        0.0,
        dist((6.0, 9.0), (8.0, 8.0)),  # same room: straight line
        dist((2.0, 8.0), door_n, (8.0, 8.0)),  # northwest: through the north doorway
        min(dist((2.0, 2.0), door_w, door_n, (8.0, 8.0)), dist((2.0, 2.0), door_s, door_e, (8.0, 8.0))),
        dist((8.0, 2.0), door_e, (8.0, 8.0)),
        dist((4.0, 3.0), door_s, door_e, (8.0, 8.0)),  # southwest, nearer the south doorway
    ]
    torch.testing.assert_close(potential(torch.tensor(positions)), -torch.tensor(expected).unsqueeze(-1))


def test_default_scales_put_potentials_in_minus_one_to_zero():
    grid = torch.cartesian_prod(torch.linspace(0, 10, 101), torch.linspace(0, 10, 101))
    phi_cont = FourRoomsPotential(goal=(2.0, 2.0))(grid[fourrooms.in_free_space(grid)])
    phi_grid = GridFourRoomsPotential(goal=(10, 2))(gridrooms.FREE_CELLS)
    for values in (phi_cont, phi_grid):
        assert values.max() == 0.0 and -1.0 <= values.min() < -0.95


def test_grid_potential_is_minus_the_number_of_moves():
    potential = GridFourRoomsPotential(goal=(3, 9), scale=1.0)
    cells = torch.tensor([[3, 9], [3, 8], [3, 5], [7, 9], [6, 2], [11, 1]])
    # (3,5) -> north hallway (3,6) -> (3,9): 4 moves; (11,1) -> west hallway (6,2) (6 moves) -> (3,9) (10 more)
    assert potential(cells).squeeze(-1).tolist() == [0.0, -1.0, -4.0, -4.0, -10.0, -16.0]


@pytest.mark.parametrize("task", ["fourrooms", "gridrooms"])
def test_shaped_task_envs_pass_check_env_specs(task):
    if task == "fourrooms":
        base = FourRoomsEnv(goal=(8.0, 8.0), horizon=5, batch_size=(4,), seed=0)
        potential, in_keys = FourRoomsPotential(goal=(8.0, 8.0)), ["position"]
    else:
        base = GridFourRoomsEnv(goal=(3, 9), horizon=5, batch_size=(4,), seed=0)
        potential, in_keys = GridFourRoomsPotential(goal=(3, 9)), ["cell"]
    fade = TimeDependentPotential(potential, lambda t: 1.0 - t / 10)
    for phi_, keys in ((potential, None), (fade, None), (fade, [*in_keys, "step_count"])):
        env = TransformedEnv(base, PotentialShaping(phi_, gamma=0.99, in_keys=keys))
        check_env_specs(env, break_when_any_done="both", seed=0)
        td = env.rollout(12, break_when_any_done=False)  # horizon 5: truncations and resets inside
        assert td["next", "truncated"].any()
        shaping = env.transform
        alive = ~td["next", "terminated"]
        expected = (
            td["next", "task_reward"] + 0.99 * shaping.potential_of(td["next"]) * alive - shaping.potential_of(td)
        )
        torch.testing.assert_close(td["next", "reward"], expected)


# ------------------------------------------------------------------ policy invariance
def value_iteration(P, R, terminal, gamma):
    """Q*[s, a] of the MDP with transitions P[s, a, s'], rewards R[s, s'] and terminal states s'."""
    V = torch.zeros(P.shape[0], dtype=P.dtype)
    expected_reward = torch.einsum("sat,st->sa", P, R)
    for _ in range(100_000):
        Q = expected_reward + gamma * torch.einsum("sat,t->sa", P, V.masked_fill(terminal, 0.0))
        V_new = Q.amax(-1)
        if (V_new - V).abs().max() < 1e-13:
            return Q
        V = V_new
    raise AssertionError("value iteration did not converge")


def greedy_sets(Q, tol=1e-9):
    return (Q >= Q.amax(-1, keepdim=True) - tol).tolist()


def grid_mdp(goal, slip, step_cost):
    """The grid task as tables, and its (s, s') transitions as a TensorDict the transform can shape."""
    cells = gridrooms.FREE_CELLS
    goal_index = gridrooms.CELL_INDEX[goal].item()
    terminal = torch.arange(gridrooms.N_CELLS) == goal_index
    R = torch.where(terminal, 1.0, -step_cost).double().expand(gridrooms.N_CELLS, -1)
    n = gridrooms.N_CELLS
    transitions = TensorDict(
        cell=cells[:, None].expand(n, n, 2),
        next=TensorDict(
            cell=cells[None].expand(n, n, 2),
            reward=R.unsqueeze(-1).clone(),
            terminated=terminal[None, :, None].expand(n, n, 1),
            batch_size=(n, n),
        ),
        batch_size=(n, n),
    )
    return gridrooms.transition_matrix(slip), R, terminal, transitions, goal_index


@pytest.mark.parametrize(
    "goal, gamma, slip, step_cost",
    [
        ((3, 9), 0.9, 0.0, 0.0),
        ((3, 9), 0.99, 0.0, 0.0),
        ((10, 2), 0.95, 0.0, 0.01),
        ((7, 9), 0.99, 1 / 3, 0.0),
        ((11, 1), 0.9, 1 / 3, 0.01),
    ],
)
def test_shaping_preserves_the_optimal_policy_and_a_plain_bonus_does_not(goal, gamma, slip, step_cost):
    P, R, terminal, transitions, goal_index = grid_mdp(goal, slip, step_cost)
    potential = GridFourRoomsPotential(goal)
    shaping = PotentialShaping(potential, gamma=gamma, in_keys=["cell"])
    R_shaped = shaping(transitions)["next", "reward"].squeeze(-1)
    acting = ~terminal  # the goal state is never acted from

    Q = value_iteration(P, R, terminal, gamma)[acting]
    Q_shaped = value_iteration(P, R_shaped, terminal, gamma)[acting]
    assert greedy_sets(Q_shaped) == greedy_sets(Q)
    phi = potential(gridrooms.FREE_CELLS).squeeze(-1).double()[acting]
    torch.testing.assert_close(Q_shaped, Q - phi.unsqueeze(-1), rtol=0, atol=1e-9)  # Ng et al., Thm 1

    # a bonus as large as the biggest shaping term, for entering one far cell, is not potential-based
    possible = P.sum(1) > 0
    bonus = (R_shaped - R)[possible].abs().max()
    far_index = int(potential.distance(gridrooms.FREE_CELLS).argmax())
    R_bonus = R.clone()
    R_bonus[:, far_index] += bonus
    Q_bonus = value_iteration(P, R_bonus, terminal, gamma)[acting]
    assert greedy_sets(Q_bonus) != greedy_sets(Q)


def test_value_iteration_matches_the_breadth_first_distances():
    # undiscounted moves d(s) to the goal and the optimal values of the +1 task: V*(s) = gamma^(d(s) - 1)
    P, R, terminal, _, _ = grid_mdp((3, 9), 0.0, 0.0)
    d = GridFourRoomsPotential((3, 9), scale=1.0).distance(gridrooms.FREE_CELLS).double()
    V = value_iteration(P, R, terminal, 0.9).amax(-1)
    torch.testing.assert_close(V[~terminal], 0.9 ** (d[~terminal] - 1), rtol=0, atol=1e-10)
