"""Grid FourRooms: the classic discrete 13x13 FourRooms of Sutton, Precup & Singh (1999).

A stateless, batched TorchRL environment in pure torch. Cells are ``(row, col)`` with row 0 at
the top; ``#`` is a wall (the outer border included), letters mark the hallways::

        col 0         6         12
    row 0   # # # # # # # # # # # # #
            # . . . . . # . . . . . #
            # . . . . . # . . . . . #
            # . . . . . N . . . . . #      northwest: rows 1-5,  cols 1-5   (25 cells)
            # . . . . . # . . . . . #      northeast: rows 1-6,  cols 7-11  (30 cells)
            # . . . . . # . . . . . #      southwest: rows 7-11, cols 1-5   (25 cells)
        6   # # W # # # # . . . . . #      southeast: rows 8-11, cols 7-11  (20 cells)
            # . . . . . # # # E # # #      hallways N (3, 6), S (10, 6), W (6, 2), E (7, 9)
            # . . . . . # . . . . . #
            # . . . . . # . . . . . #      104 free cells in all
            # . . . . . S . . . . . #
            # . . . . . # . . . . . #
       12   # # # # # # # # # # # # #

Actions (one-hot, :class:`~torchrl.data.OneHot` spec, as TorchRL's discrete losses expect):
``0`` up, ``1`` right, ``2`` down, ``3`` left. A move into a wall leaves the agent where it is.
With probability ``slip`` the chosen action is replaced by one of the other three, uniformly
(``slip=0``, the default, is deterministic; the original paper used ``slip=1/3``).

Episode. The start cell is uniform over the free cells other than the goal (optionally within
one room, ``start_room``). Entering the goal cell gives ``+1`` and ends the episode
(``terminated``, ``success``); any other step gives ``-step_cost``; after ``horizon`` steps
without success the episode is ``truncated``.

Observation (``observation=``):

* ``"onehot"`` (default): a one-hot over the 104 free cells (index :data:`CELL_INDEX`), which
  makes the task tabular for a neural learner;
* ``"coords"``: ``(row, col)`` scaled to ``[-1, 1]`` (``2 c / 12 - 1``).

``observe_goal=True`` appends the goal cell encoded the same way. The integer cell is kept in
the ``"cell"`` entry.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np
import torch
from tensordict import TensorDictBase
from torchrl.data import Bounded, OneHot

from drltg.envs.goal_env import GoalEnv
from drltg.errors import UsageError

LAYOUT = (
    "#############",
    "#.....#.....#",
    "#.....#.....#",
    "#...........#",
    "#.....#.....#",
    "#.....#.....#",
    "##.####.....#",
    "#.....###.###",
    "#.....#.....#",
    "#.....#.....#",
    "#...........#",
    "#.....#.....#",
    "#############",
)

WALLS = torch.tensor([[c == "#" for c in row] for row in LAYOUT])
"""``[13, 13]`` bool mask, ``True`` on walls."""

FREE_CELLS = (~WALLS).nonzero()
"""``[104, 2]`` int64 ``(row, col)`` of the free cells, in row-major order."""

N_CELLS = FREE_CELLS.shape[0]

CELL_INDEX = torch.full(WALLS.shape, -1, dtype=torch.int64)
CELL_INDEX[FREE_CELLS[:, 0], FREE_CELLS[:, 1]] = torch.arange(N_CELLS)
"""``[13, 13]`` index of each free cell into :data:`FREE_CELLS` (``-1`` on walls)."""

MOVES = torch.tensor([[-1, 0], [0, 1], [1, 0], [0, -1]])
"""Cell displacement of each action: up, right, down, left."""

ROOMS = {
    "northwest": (1, 1, 5, 5),
    "northeast": (1, 7, 6, 11),
    "southwest": (7, 1, 11, 5),
    "southeast": (8, 7, 11, 11),
}
"""Each room's cells ``(row_min, col_min, row_max, col_max)``, bounds included."""

HALLWAYS = {"north": (3, 6), "south": (10, 6), "west": (6, 2), "east": (7, 9)}


def next_cell(cell: torch.Tensor, action: torch.Tensor, walls: torch.Tensor = WALLS) -> torch.Tensor:
    """The deterministic successor of ``cell [..., 2]`` under the action index ``action [...]``."""
    moves = MOVES.to(cell.device)
    target = cell + moves[action]
    blocked = walls.to(cell.device)[target[..., 0], target[..., 1]]
    return torch.where(blocked.unsqueeze(-1), cell, target)


def transition_matrix(slip: float = 0.0) -> torch.Tensor:
    """``P[s, a, s']`` over the free cells (:data:`FREE_CELLS` order), shape ``[104, 4, 104]``."""
    actions = torch.arange(4)
    succ = CELL_INDEX[tuple(next_cell(FREE_CELLS[:, None], actions[None]).unbind(-1))]
    onehot = torch.nn.functional.one_hot(succ, N_CELLS).double()
    others = (onehot.sum(1, keepdim=True) - onehot) / 3
    return (1 - slip) * onehot + slip * others


class GridFourRoomsEnv(GoalEnv):
    """The classic grid FourRooms (see the module docstring for layout, dynamics and rewards).

    With no arguments it is the registered task ``gridrooms/northeast`` (``make_env("gridrooms/northeast")``).

    Args:
        goal: the goal cell ``(row, col)``; must be free.
        slip: probability that the action is replaced by one of the other three.
        step_cost: the cost paid on every step that does not reach the goal.
        horizon: episode length after which the episode is truncated.
        start_room: one of :data:`ROOMS` to start in that room only; ``None`` for anywhere.
        observation: ``"onehot"`` or ``"coords"``.
        observe_goal: append the goal cell, encoded the same way, to the observation.
        cell_pixels: side of one cell in the image returned by :meth:`render`.
        batch_size, device: as for any :class:`~torchrl.envs.EnvBase`.
        seed: seed of the start and slip generator; ``None`` draws one from torch's global RNG.
    """

    state_key = "cell"

    def __init__(
        self,
        goal: Sequence[int] = (3, 9),
        *,
        slip: float = 0.0,
        step_cost: float = 0.01,
        horizon: int = 100,
        start_room: str | None = None,
        observation: str = "onehot",
        observe_goal: bool = False,
        cell_pixels: int = 16,
        batch_size: Sequence[int] | torch.Size = (),
        device: torch.device | str | None = None,
        seed: int | None = None,
    ):
        super().__init__(step_cost=step_cost, horizon=horizon, observe_goal=observe_goal, batch_size=batch_size,
                         device=device)
        goal_t = torch.as_tensor(goal, dtype=torch.int64)
        if goal_t.shape != (2,) or not ((goal_t >= 0) & (goal_t < 13)).all() or WALLS[tuple(goal_t)]:
            raise UsageError(f"goal {tuple(goal)} is not a free cell (row, col) of the 13x13 FourRooms grid.")
        if start_room is not None and start_room not in ROOMS:
            raise UsageError(f"start_room {start_room!r} is not one of {', '.join(ROOMS)}.")
        if observation not in ("onehot", "coords"):
            raise UsageError(f"observation {observation!r} is not 'onehot' or 'coords'.")
        if not 0.0 <= slip <= 1.0:
            raise UsageError(f"slip {slip} is a probability, so it must lie in [0, 1].")
        if not 1 <= cell_pixels <= 256:
            raise UsageError(f"cell_pixels is the side of a rendered cell in pixels, from 1 to 256; got {cell_pixels}.")
        self.slip = float(slip)
        self.start_room = start_room
        self.observation = observation
        self.cell_pixels = int(cell_pixels)
        starts = FREE_CELLS[(FREE_CELLS != goal_t).any(-1)]
        if start_room is not None:
            r0, c0, r1, c1 = ROOMS[start_room]
            rows, cols = starts[:, 0], starts[:, 1]
            starts = starts[(rows >= r0) & (rows <= r1) & (cols >= c0) & (cols <= c1)]
        self._starts = starts
        self.register_buffer("goal", goal_t.to(self.device))
        self.register_buffer("_walls", WALLS.to(self.device))
        self.register_buffer("_cell_index", CELL_INDEX.to(self.device))
        self.register_buffer("_moves", MOVES.to(self.device))
        self._make_spec()
        self._seed_or_draw(seed)

    def _make_spec(self):
        cell_dim = N_CELLS if self.observation == "onehot" else 2
        cell = Bounded(0, 12, (2,), dtype=torch.int64, device=self.device)
        self._state_specs(cell, obs_dim=cell_dim * (2 if self.observe_goal else 1))
        self.action_spec = OneHot(4, (*self.batch_size, 4), device=self.device)

    def _encode(self, cell: torch.Tensor) -> torch.Tensor:
        if self.observation == "onehot":
            index = self._cell_index[cell[..., 0], cell[..., 1]]
            return torch.nn.functional.one_hot(index, N_CELLS).float()
        return cell.float() * (2.0 / 12.0) - 1.0

    def _observe(self, cell: torch.Tensor) -> torch.Tensor:
        obs = self._encode(cell)
        if self.observe_goal:
            obs = torch.cat((obs, self._encode(self.goal).expand_as(obs)), -1)
        return obs

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs) -> TensorDictBase:
        shape = self.batch_size
        if kwargs.get("set_state") and tensordict is not None and "cell" in tensordict.keys():
            cell = tensordict["cell"].clone()
        else:  # a partial reset draws for the whole batch; TorchRL keeps the reset elements' starts
            pick = torch.randint(len(self._starts), (shape.numel(),), generator=self.rng)
            cell = self._starts[pick.reshape(shape)].to(self.device)
        return self._first(cell)

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        action = tensordict["action"].long().argmax(-1)
        if self.slip > 0:
            slipped = torch.rand(action.shape, generator=self.rng) < self.slip
            other = torch.randint(1, 4, action.shape, generator=self.rng)
            action = torch.where(slipped.to(action.device), (action + other.to(action.device)) % 4, action)
        cell = next_cell(tensordict["cell"], action, self._walls)
        step_count = tensordict["step_count"] + 1
        success = (cell == self.goal).all(-1, keepdim=True)
        return self._next(cell, step_count, success)

    def render(self, tensordict: TensorDictBase | None = None) -> np.ndarray:
        """An RGB ``uint8`` image ``[13 * cell_pixels, 13 * cell_pixels, 3]``: walls, goal, agents.

        Every ``"cell"`` in ``tensordict`` is drawn (one state, a batch, or a trajectory).
        """
        grid = np.full((13, 13, 3), 255, dtype=np.uint8)
        grid[WALLS.numpy()] = (60, 60, 60)
        grid[tuple(self.goal.tolist())] = (40, 170, 70)
        if tensordict is not None:
            for row, col in tensordict["cell"].detach().reshape(-1, 2).cpu().tolist():
                grid[row, col] = (215, 40, 40)
        return grid.repeat(self.cell_pixels, 0).repeat(self.cell_pixels, 1)


class GridFourRoomsPotential(torch.nn.Module):
    """``Phi(cell) = -scale * d(cell)``, ``d`` the number of moves to the goal (breadth-first search).

    The task's shaping potential (an exact distance: an upper reference, not transfer). ``d`` is computed once, on the
    env's own layout and move rule, into a ``13 x 13`` lookup table. It reads the ``"cell"`` entry.

    Args:
        goal: the goal cell ``(row, col)``.
        scale: ``Phi`` per move. Default: ``1 / max d``, so ``Phi`` ranges over ``[-1, 0]`` and the
            shaping collected on a shortest path from the farthest cell (``gamma = 1``) equals the goal
            reward of ``+1``.
    """

    in_keys = ["cell"]

    def __init__(self, goal: Sequence[int], scale: float | None = None):
        super().__init__()
        cells = FREE_CELLS
        succ = CELL_INDEX[tuple(next_cell(cells[:, None], torch.arange(4)).unbind(-1))]
        goal_index = CELL_INDEX[tuple(goal)]
        d = torch.full((N_CELLS,), torch.inf)
        d[goal_index] = 0.0
        for _ in range(N_CELLS):
            d_next = torch.minimum(d, 1.0 + d[succ].amin(-1))
            if torch.equal(d_next, d):
                break
            d = d_next
        table = torch.full(WALLS.shape, torch.inf)
        table[cells[:, 0], cells[:, 1]] = d
        if scale is None:
            scale = 1.0 / d.max().item()
        self.scale = float(scale)
        self.register_buffer("table", table)

    def distance(self, cell: torch.Tensor) -> torch.Tensor:
        """Moves ``[...]`` from each cell ``[..., 2]`` to the goal (``inf`` on walls)."""
        return self.table[cell[..., 0], cell[..., 1]]

    def forward(self, cell: torch.Tensor) -> torch.Tensor:
        return -self.scale * self.distance(cell).unsqueeze(-1)
