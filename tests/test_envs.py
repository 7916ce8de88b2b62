"""Dynamics, episodes, specs, seeding and rendering of the continuous and grid FourRooms."""
import numpy as np
import pytest
import torch
from tensordict import TensorDict
from torchrl.envs import TransformedEnv
from torchrl.envs.utils import step_mdp
from torchrl.record import PixelRenderTransform

from drltg.envs import FourRoomsEnv, GridFourRoomsEnv
from drltg.envs import fourrooms as fr
from drltg.envs import gridrooms as gr
from drltg.errors import UsageError


def _place(env, positions):
    """A root tensordict with the agents at ``positions`` and a fresh episode clock."""
    td = env.reset()
    key = "position" if "position" in td.keys() else "cell"
    td[key] = torch.as_tensor(positions, dtype=td[key].dtype).reshape(td[key].shape)
    td["step_count"].zero_()
    return td


def _walk(env, td, actions):
    """Steps ``env`` through ``actions`` (one per step) and returns the visited ``next`` tds."""
    out = []
    for action in actions:
        td["action"] = torch.as_tensor(action, dtype=env.action_spec.dtype).expand(env.action_spec.shape)
        td = env.step(td)
        out.append(td["next"].clone())
        td = step_mdp(td)
    return out


# ----------------------------------------------------------------------------- geometry
def test_layout_is_consistent():
    for (x, y), _ in fr.DOORWAYS.values():
        assert bool(fr.in_free_space(torch.tensor([x, y])))
        assert x == 5.0 or y == 5.0
    for box in fr.DOOR_PASSAGES:
        assert box[2] - box[0] in (fr.WALL_THICKNESS, fr.DOOR_WIDTH)
        centre = torch.tensor([(box[0] + box[2]) / 2, (box[1] + box[3]) / 2])
        assert bool(fr.in_free_space(centre))
    # a wall box's centre and the four wall junction are blocked; room corners are free
    for box in fr.WALLS:
        assert not bool(fr.in_free_space(torch.tensor([(box[0] + box[2]) / 2, (box[1] + box[3]) / 2])))
    assert not bool(fr.in_free_space(torch.tensor([5.0, 5.0])))
    for name, (x0, y0, x1, y1) in fr.ROOMS.items():
        corners = torch.tensor([[x0, y0], [x1, y1]])
        assert fr.in_free_space(corners).all()
        assert (fr.room_of(corners) == fr.ROOM_NAMES.index(name)).all()
    assert not fr.in_free_space(torch.tensor([[-0.1, 3.0], [3.0, 10.1]])).any()


def test_room_of_quadrants():
    pos = torch.tensor([[1.0, 9.0], [9.0, 9.0], [1.0, 1.0], [9.0, 1.0], [5.1, 2.0], [4.9, 7.5]])
    names = [fr.ROOM_NAMES[i] for i in fr.room_of(pos).tolist()]
    assert names == ["northwest", "northeast", "southwest", "southeast", "southeast", "northwest"]


# ----------------------------------------------------------------------------- continuous dynamics
def test_wall_blocks_and_agent_slides_along_it():
    env = FourRoomsEnv(goal=(8.0, 8.0))
    td = _place(env, [4.0, 3.0])  # south-west room, level with the wall (no doorway at y = 3)
    nxt = _walk(env, td, [[1.0, 0.0]] * 4 + [[1.0, 1.0]] * 2)
    path = [n["position"].tolist() for n in nxt]
    assert path == [[4.5, 3.0], [4.75, 3.0], [4.75, 3.0], [4.75, 3.0], [4.75, 3.5], [4.75, 4.0]]


@pytest.mark.parametrize("max_step", [1.0, 3.0, 50.0])
def test_no_tunnelling_with_any_step_length(max_step):
    env = FourRoomsEnv(goal=(8.0, 8.0), max_step=max_step)
    starts = [[4.0, 3.0], [6.0, 3.0], [3.0, 4.0], [3.0, 6.0], [9.0, 9.0]]
    pushes = [[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0], [1.0, 1.0]]
    stops = [[4.75, 3.0], [5.25, 3.0], [3.0, 4.75], [3.0, 5.25], [10.0, 10.0]]
    for start, push, stop in zip(starts, pushes, stops):
        nxt = _walk(env, _place(env, start), [push])
        assert nxt[0]["position"].tolist() == pytest.approx(stop)


def _move_one(x, y, dx, dy):
    """The wall rule for one agent in float32 scalars: each axis moves by its displacement and stops at the
    nearest face, among the walls whose extent along the other axis strictly contains the agent."""
    f = np.float32

    def slide(coord, across, delta, axis):
        upper, lower = f(fr.ARENA_SIZE), f(0.0)
        for wall in fr.WALLS:
            lo, hi, olo, ohi = (f(wall[i]) for i in (axis, axis + 2, 1 - axis, 3 - axis))
            if olo < across < ohi:
                upper = min(upper, lo) if lo >= coord else upper
                lower = max(lower, hi) if hi <= coord else lower
        return min(max(f(coord + delta), lower), upper)

    nx = slide(x, y, dx, 0)
    return nx, slide(y, nx, dy, 1)


def test_batched_move_equals_the_rule_for_one_agent_bit_for_bit():
    gen = torch.Generator().manual_seed(3)
    faces = torch.tensor([0.0, 1.5, 2.5, 4.75, 5.25, 7.0, 8.0, 10.0])
    pos = torch.rand(300, 2, generator=gen) * 10
    pos[:60] = faces[torch.randint(0, 8, (60, 2), generator=gen)]  # on wall faces and doorway edges
    pos = pos[fr.in_free_space(pos)]
    step = (torch.rand(len(pos), 2, generator=gen) * 2 - 1) * 3.0
    moved = fr.move(pos, step)
    expected = [_move_one(*(np.float32(v) for v in (*p, *d))) for p, d in zip(pos.tolist(), step.tolist())]
    assert moved.tolist() == [[float(a), float(b)] for a, b in expected]


def test_random_walk_never_enters_a_wall():
    env = FourRoomsEnv(goal=(8.0, 8.0), max_step=2.0, horizon=10_000, batch_size=(256,), seed=0)
    td = env.reset()
    gen = torch.Generator().manual_seed(0)
    for _ in range(50):
        td["action"] = torch.rand(256, 2, generator=gen) * 2 - 1
        td = step_mdp(env.step(td))
        assert fr.in_free_space(td["position"]).all()


@pytest.mark.parametrize(
    "start, action, end_room",
    [
        ([4.5, 2.0], [1.0, 0.0], "southeast"),  # south doorway, eastwards
        ([5.5, 7.5], [-1.0, 0.0], "northwest"),  # north doorway, westwards
        ([2.0, 4.5], [0.0, 1.0], "northwest"),  # west doorway, northwards
        ([7.5, 5.5], [0.0, -1.0], "southeast"),  # east doorway, southwards
    ],
)
def test_doorways_let_the_agent_through(start, action, end_room):
    env = FourRoomsEnv(goal=(8.0, 8.0), goal_radius=0.1)
    nxt = _walk(env, _place(env, start), [action] * 3)
    pos = nxt[-1]["position"]
    assert fr.ROOM_NAMES[fr.room_of(pos).item()] == end_room
    assert (pos - torch.tensor(start)).abs().sum().item() == pytest.approx(1.5)


def test_goal_terminates_with_reward_one_and_success():
    env = FourRoomsEnv(goal=(8.0, 8.0), goal_radius=0.5, step_cost=0.01)
    nxt = _walk(env, _place(env, [7.0, 8.0]), [[0.2, 0.0], [0.8, 0.0]])
    first, second = nxt
    assert first["reward"].item() == pytest.approx(-0.01)
    assert not first["done"].item() and not first["success"].item()
    assert second["position"].tolist() == pytest.approx([7.5, 8.0])
    assert second["reward"].item() == 1.0
    assert second["terminated"].item() and second["success"].item() and second["done"].item()
    assert not second["truncated"].item()


def test_action_is_clipped_to_the_box():
    env = FourRoomsEnv(goal=(8.0, 8.0))
    nxt = _walk(env, _place(env, [2.0, 2.0]), [[5.0, -5.0]])
    assert nxt[0]["position"].tolist() == [2.5, 1.5]


@pytest.mark.parametrize("env_cls, kwargs", [(FourRoomsEnv, {}), (GridFourRoomsEnv, {})])
def test_horizon_truncates_exactly(env_cls, kwargs):
    env = env_cls(horizon=5, batch_size=(3,), seed=0, **kwargs)
    td = env.reset()
    assert (td["step_count"] == 0).all()
    still = [0.0, 0.0] if env_cls is FourRoomsEnv else [1, 0, 0, 0]
    if env_cls is GridFourRoomsEnv:  # push up against the top wall so the agent cannot reach the goal
        td["cell"] = torch.tensor([[1, 1], [1, 2], [1, 3]])
    nxt = _walk(env, td, [still] * 5)
    for t, n in enumerate(nxt, start=1):
        assert (n["step_count"] == t).all()
        assert not n["terminated"].any()
        assert (n["truncated"] == (t == 5)).all() and (n["done"] == (t == 5)).all()


def test_reaching_the_goal_on_the_last_step_is_terminal_not_truncated():
    env = FourRoomsEnv(goal=(8.0, 8.0), horizon=2)
    last = _walk(env, _place(env, [7.0, 8.0]), [[0.0, 0.0], [1.0, 0.0]])[-1]
    assert last["terminated"].item() and not last["truncated"].item()


@pytest.mark.parametrize("env_cls", [FourRoomsEnv, GridFourRoomsEnv])
@pytest.mark.parametrize("batch_size", [(), (7,), (2, 3)])
def test_batch_dims(env_cls, batch_size):
    env = env_cls(batch_size=batch_size, seed=0)
    td = env.rollout(4, break_when_any_done=False)
    assert td.batch_size == (*batch_size, 4)
    assert td["next", "reward"].shape == (*batch_size, 4, 1)
    assert td["next", "observation"].dtype == torch.float32
    for key in ("done", "terminated", "truncated", "success"):
        assert td["next", key].shape == (*batch_size, 4, 1) and td["next", key].dtype == torch.bool
    assert td["next", "step_count"].dtype == torch.int64


@pytest.mark.parametrize("env_cls", [FourRoomsEnv, GridFourRoomsEnv])
def test_observe_goal_appends_the_goal(env_cls):
    plain = env_cls(seed=0).reset()["observation"]
    env = env_cls(seed=0, observe_goal=True)
    obs = env.reset()["observation"]
    assert obs.shape[-1] == 2 * plain.shape[-1]
    assert torch.equal(obs[: plain.shape[-1]], plain)


def test_fourrooms_observation_scaling():
    env = FourRoomsEnv(goal=(8.0, 8.0), observe_goal=True)
    nxt = _walk(env, _place(env, [2.0, 7.5]), [[0.0, 0.0]])
    assert nxt[0]["observation"].tolist() == pytest.approx([-0.6, 0.5, 0.6, 0.6])


def test_seeding_gives_identical_episodes():
    def episodes(seed):
        env = FourRoomsEnv(goal=(8.0, 8.0), batch_size=(4,), horizon=3, seed=seed)
        actions = torch.linspace(-1, 1, 8).reshape(4, 2)
        return env.rollout(9, policy=lambda td: td.set("action", actions), break_when_any_done=False)

    a, b, c = episodes(1), episodes(1), episodes(2)
    assert torch.equal(a["position"], b["position"]) and torch.equal(a["next", "position"], b["next", "position"])
    assert not torch.equal(a["position"], c["position"])
    starts = a["position"][:, [0, 3, 6]]  # a new random start after each truncation
    assert not torch.equal(starts[:, 0], starts[:, 1])


def test_set_seed_restarts_the_start_sequence():
    env = GridFourRoomsEnv(batch_size=(16,), slip=0.5)
    env.set_seed(5)
    first = [env.reset()["cell"] for _ in range(3)]
    env.set_seed(5)
    assert all(torch.equal(x, env.reset()["cell"]) for x in first)


def test_starts_are_uniform_over_free_space_and_avoid_the_goal():
    env = FourRoomsEnv(goal=(2.0, 2.0), goal_radius=1.0, batch_size=(8192,), seed=0)
    pos = env.reset()["position"]
    assert fr.in_free_space(pos).all()
    assert ((pos - env.goal).norm(dim=-1) > 1.0).all()
    share = torch.bincount(fr.room_of(pos), minlength=4).float() / len(pos)
    quadrant = 4.75**2 + 2 * 0.25  # a room plus half of each of its two doorway passages
    expected = torch.tensor([quadrant, quadrant, quadrant - torch.pi, quadrant]) / (4 * quadrant - torch.pi)
    assert torch.allclose(share, expected, atol=0.02)


def test_start_room_restricts_starts():
    env = FourRoomsEnv(start_room="southeast", batch_size=(512,), seed=0)
    pos = env.reset()["position"]
    assert (fr.room_of(pos) == fr.ROOM_NAMES.index("southeast")).all()
    grid = GridFourRoomsEnv(start_room="southwest", batch_size=(512,), seed=0)
    cells = grid.reset()["cell"]
    assert ((cells[:, 0] >= 7) & (cells[:, 1] <= 5)).all()
    assert len(torch.unique(cells, dim=0)) == 25


def test_partial_reset_keeps_the_other_elements():
    env = FourRoomsEnv(goal=(8.0, 8.0), batch_size=(4,), seed=0)
    td = env.reset()
    td["action"] = torch.full((4, 2), 0.3)
    td = step_mdp(env.step(td))
    td = step_mdp(env.step(td.set("action", torch.full((4, 2), -0.2))))
    before = td.clone()
    mask = torch.tensor([[True], [False], [True], [False]])
    td = env.reset(td.set("_reset", mask), set_state=False)
    assert td["step_count"].squeeze(-1).tolist() == [0, 2, 0, 2]
    assert torch.equal(td["position"][1::2], before["position"][1::2])
    assert not torch.equal(td["position"][0::2], before["position"][0::2])
    assert fr.in_free_space(td["position"]).all()


def test_auto_reset_restarts_only_finished_elements():
    env = FourRoomsEnv(goal=(8.0, 8.0), batch_size=(2,), seed=0)
    td = _place(env, [[7.2, 8.0], [2.0, 2.0]])
    td["action"] = torch.tensor([[1.0, 0.0], [0.0, 0.0]])
    out, td = env.step_and_maybe_reset(td)
    assert out["next", "success"].squeeze(-1).tolist() == [True, False]
    assert td["step_count"].squeeze(-1).tolist() == [0, 1]
    assert td["position"][1].tolist() == [2.0, 2.0]
    assert (td["position"][0] - torch.tensor([7.7, 8.0])).norm() > 1e-3 and not td["done"].any()


def test_reset_with_set_state_honours_the_position():
    env = FourRoomsEnv(goal=(8.0, 8.0), batch_size=(2,))
    state = TensorDict({"position": torch.tensor([[1.0, 1.0], [9.0, 1.0]])}, batch_size=(2,))
    td = env.reset(state, set_state=True)
    assert td["position"].tolist() == [[1.0, 1.0], [9.0, 1.0]]
    assert torch.allclose(td["observation"], torch.tensor([[-0.8, -0.8], [0.8, -0.8]]))


@pytest.mark.parametrize("bad, message", [
    (dict(goal=(5.0, 3.0)), r"goal \(5.0, 3.0\) is not a point"), (dict(goal=(11.0, 1.0)), "goal"),
    (dict(start_room="attic"), "start_room 'attic'"), (dict(goal_radius=0.0), "goal_radius 0.0 must be positive"),
    (dict(max_step=float("nan")), "max_step nan must be positive"), (dict(horizon=0), "horizon 0 must be at least 1")])
def test_fourrooms_rejects_bad_options_naming_them(bad, message):
    with pytest.raises(UsageError, match=message):
        FourRoomsEnv(**bad)


def test_fourrooms_render():
    env = FourRoomsEnv(goal=(8.0, 8.0), render_size=100, batch_size=(2,), seed=0)
    empty = env.render()
    td = _place(env, [[2.0, 2.0], [7.0, 2.0]])
    img = env.render(td)
    assert img.shape == (100, 100, 3) and img.dtype == np.uint8
    assert tuple(img[50, 50]) == (60, 60, 60)  # the wall junction
    assert tuple(img[20, 80]) == (40, 170, 70)  # goal (8, 8): row 100 - 80, col 80
    assert tuple(img[80, 20]) == tuple(img[80, 70]) == (215, 40, 40)  # the two agents
    assert tuple(empty[80, 20]) == (255, 255, 255)


@pytest.mark.parametrize("env_cls", [FourRoomsEnv, GridFourRoomsEnv])
def test_render_through_torchrl_pixel_transform(env_cls):
    env = TransformedEnv(env_cls(seed=0), PixelRenderTransform(out_keys=["pixels"], pass_tensordict=True))
    td = env.rollout(3, break_when_any_done=False)
    side = env.base_env.render().shape[0]
    assert td["next", "pixels"].shape == (3, side, side, 3) and td["next", "pixels"].dtype == torch.uint8
    assert not torch.equal(td["next", "pixels"][0], torch.as_tensor(env.base_env.render()))  # the agent is drawn


# ----------------------------------------------------------------------------- grid
def test_grid_layout():
    assert gr.WALLS.shape == (13, 13) and gr.N_CELLS == 104
    assert gr.WALLS[0].all() and gr.WALLS[-1].all() and gr.WALLS[:, 0].all() and gr.WALLS[:, -1].all()
    for cell in gr.HALLWAYS.values():
        assert not gr.WALLS[cell]
    sizes = {name: int((~gr.WALLS[r0 : r1 + 1, c0 : c1 + 1]).sum()) for name, (r0, c0, r1, c1) in gr.ROOMS.items()}
    assert sizes == {"northwest": 25, "northeast": 30, "southwest": 25, "southeast": 20}
    assert sum(sizes.values()) + len(gr.HALLWAYS) == 104


def test_grid_walls_block_and_hallways_pass():
    up, right, down, left = torch.arange(4)
    cell = torch.tensor
    assert gr.next_cell(cell([1, 1]), up).tolist() == [1, 1]
    assert gr.next_cell(cell([1, 1]), left).tolist() == [1, 1]
    assert gr.next_cell(cell([2, 5]), right).tolist() == [2, 5]  # the wall at column 6
    assert gr.next_cell(cell([3, 5]), right).tolist() == [3, 6]  # north hallway
    assert gr.next_cell(cell([3, 6]), right).tolist() == [3, 7]
    assert gr.next_cell(cell([3, 6]), up).tolist() == [3, 6]
    assert gr.next_cell(cell([5, 2]), down).tolist() == [6, 2]  # west hallway
    assert gr.next_cell(cell([6, 9]), down).tolist() == [7, 9]  # east hallway
    assert gr.next_cell(cell([6, 8]), down).tolist() == [6, 8]


def test_grid_env_matches_next_cell_and_is_deterministic():
    env = GridFourRoomsEnv(goal=(9, 3), batch_size=(104, 4), seed=0)
    td = env.reset()
    td["cell"] = gr.FREE_CELLS[:, None].expand(104, 4, 2).clone()
    td["action"] = torch.eye(4, dtype=torch.bool).expand(104, 4, 4)
    out = env.step(td)["next"]
    assert torch.equal(out["cell"], gr.next_cell(td["cell"], torch.arange(4).expand(104, 4)))
    p = gr.transition_matrix(0.0)
    index = gr.CELL_INDEX[out["cell"][..., 0], out["cell"][..., 1]]
    assert torch.equal(p.argmax(-1), index) and (p.max(-1).values == 1).all()


def test_grid_slip():
    env = GridFourRoomsEnv(slip=1.0, batch_size=(300,), seed=0)
    td = _place(env, [[9, 3]] * 300)
    nxt = _walk(env, td, [[0, 1, 0, 0]])[0]  # "right" from an open cell, always replaced
    moves = nxt["cell"] - torch.tensor([9, 3])
    assert not (moves == torch.tensor([0, 1])).all(-1).any()
    assert len(torch.unique(moves, dim=0)) == 3
    p = gr.transition_matrix(1 / 3)
    assert torch.allclose(p.sum(-1), torch.ones(104, 4, dtype=torch.float64))
    s = gr.CELL_INDEX[9, 3]
    for (row, col), prob in {(9, 4): 2 / 3, (8, 3): 1 / 9, (10, 3): 1 / 9, (9, 2): 1 / 9}.items():
        assert p[s, 1, gr.CELL_INDEX[row, col]].item() == pytest.approx(prob)
    corner = gr.CELL_INDEX[1, 1]  # up and left stay put: staying has (1/3) * (1/3 + 1/3)
    assert p[corner, 1, corner].item() == pytest.approx(2 / 9)


def test_grid_goal_terminates():
    env = GridFourRoomsEnv(goal=(3, 9), step_cost=0.05)
    nxt = _walk(env, _place(env, [3, 7]), [[0, 1, 0, 0]] * 2)
    assert nxt[0]["reward"].item() == pytest.approx(-0.05) and not nxt[0]["done"].item()
    assert nxt[1]["cell"].tolist() == [3, 9] and nxt[1]["reward"].item() == 1.0
    assert nxt[1]["terminated"].item() and nxt[1]["success"].item() and not nxt[1]["truncated"].item()


def test_grid_observations():
    onehot = GridFourRoomsEnv(observe_goal=True)
    obs = onehot._observe(torch.tensor([3, 6]))
    assert obs.shape == (208,) and obs.sum().item() == 2
    assert obs[gr.CELL_INDEX[3, 6]].item() == 1 and obs[104 + gr.CELL_INDEX[3, 9]].item() == 1
    coords = GridFourRoomsEnv(observation="coords")
    assert coords._observe(torch.tensor([0, 12])).tolist() == [-1.0, 1.0]
    assert coords._observe(torch.tensor([6, 3])).tolist() == [0.0, -0.5]


@pytest.mark.parametrize("bad, message", [
    (dict(goal=(0, 0)), r"goal \(0, 0\) is not a free cell"), (dict(goal=(6, 6)), "goal"),
    (dict(observation="pixels"), "observation 'pixels'"), (dict(slip=1.5), r"slip 1.5 .* \[0, 1\]"),
    (dict(horizon=0), "horizon 0 must be at least 1")])
def test_grid_rejects_bad_options_naming_them(bad, message):
    with pytest.raises(UsageError, match=message):
        GridFourRoomsEnv(**bad)


def test_grid_render():
    env = GridFourRoomsEnv(goal=(3, 9), cell_pixels=4)
    img = env.render(_place(env, [9, 3]))
    assert img.shape == (52, 52, 3) and img.dtype == np.uint8
    assert tuple(img[0, 0]) == (60, 60, 60)
    assert tuple(img[3 * 4 + 1, 9 * 4 + 1]) == (40, 170, 70)
    assert tuple(img[9 * 4 + 1, 3 * 4 + 1]) == (215, 40, 40)
    assert tuple(img[1 * 4 + 1, 1 * 4 + 1]) == (255, 255, 255)


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
@pytest.mark.parametrize("env_cls", [FourRoomsEnv, GridFourRoomsEnv])
def test_runs_on_cuda_with_the_same_starts(env_cls):
    cpu = env_cls(batch_size=(8,), seed=3).rollout(5, break_when_any_done=False)
    cuda = env_cls(batch_size=(8,), seed=3, device="cuda").rollout(5, break_when_any_done=False)
    assert cuda.device.type == "cuda"
    key = "position" if env_cls is FourRoomsEnv else "cell"
    assert torch.equal(cpu[key][:, 0], cuda[key][:, 0].cpu())
