"""Potentials for :class:`~drltg.transforms.PotentialShaping`.

Each potential is an ``nn.Module`` from observation tensors to ``Phi`` of shape ``[*batch, 1]``; its
``in_keys`` attribute names the TensorDict entries it reads, in argument order, and the shaping
transform uses them unless told otherwise.
"""
from __future__ import annotations

from typing import Callable, Sequence

import torch
from torch import nn

from drltg.envs import fourrooms, gridrooms


class TimeDependentPotential(nn.Module):
    """A dynamic potential ``Phi(s, t) = schedule(t) * Phi(s)`` (Devlin & Kudenko 2012).

    ``t`` is the step within the episode (``step_count``, 0 after a reset), so the shaping term is
    ``F = gamma * schedule(t + 1) * Phi(s') - schedule(t) * Phi(s)``. Along any episode the discounted
    sum of ``F`` telescopes to ``-Phi(s_0, 0)`` (plus ``gamma^N Phi(s_N, N)`` at a truncation, which the
    learner's bootstrap absorbs), the same for every policy, so the ranking of policies is unchanged.
    Use it, e.g., to fade a heuristic out as the episode goes on.

    Args:
        potential: the static potential, a callable on the observation tensors.
        schedule: maps ``step_count`` (int64, ``[*batch, 1]``) to a weight of the same shape.
        step_count_key: the entry holding ``t``, read last; ``in_keys`` are the static potential's
            ``in_keys`` (if it has them) followed by this key.

    Examples:
        >>> fade = TimeDependentPotential(FourRoomsPotential(goal), lambda t: (1 - t / 100).clamp_min(0))
        >>> PotentialShaping(fade, gamma=0.99)  # reads "position" and "step_count"
    """

    def __init__(
        self,
        potential: Callable[..., torch.Tensor],
        schedule: Callable[[torch.Tensor], torch.Tensor],
        *,
        step_count_key: str = "step_count",
    ):
        super().__init__()
        self.potential = potential
        self.schedule = schedule
        if hasattr(potential, "in_keys"):
            self.in_keys = [*potential.in_keys, step_count_key]

    def forward(self, *observation_and_step_count: torch.Tensor) -> torch.Tensor:
        *observation, step_count = observation_and_step_count
        return self.schedule(step_count) * self.potential(*observation)


class FourRoomsPotential(nn.Module):
    """``Phi(p) = -scale * d(p)``, ``d`` the shortest path to the goal through the doorway centres.

    For continuous FourRooms (:mod:`drltg.envs.fourrooms`): within the goal's room ``d`` is the
    straight-line distance; from another room it is the shortest route from ``p`` to a doorway of its
    room, then from doorway centre to doorway centre (Dijkstra on the four doorways), then to the goal.
    It reads the ``"position"`` entry (arena units).

    Args:
        goal: the goal ``(x, y)`` in arena units.
        scale: ``Phi`` per arena unit. Default: ``1 / max d`` over free space, so ``Phi`` ranges over
            ``[-1, 0]`` and the shaping collected on a path from the farthest point to the goal
            (``gamma = 1``) equals the goal reward of ``+1``.
    """

    in_keys = ["position"]

    def __init__(self, goal: Sequence[float], scale: float | None = None):
        super().__init__()
        goal = torch.as_tensor(goal, dtype=torch.float32)
        centres = torch.tensor([door.center for door in fourrooms.DOORWAYS.values()])
        joins = torch.tensor([[room in door.rooms for door in fourrooms.DOORWAYS.values()] for room in fourrooms.ROOM_NAMES])
        goal_room = fourrooms.room_of(goal)
        to_goal = torch.where(joins[goal_room], (centres - goal).norm(dim=-1), torch.inf)
        share_room = (joins.T.float() @ joins.float()) > 0
        hops = torch.cdist(centres, centres).masked_fill(~share_room, torch.inf)
        for _ in range(len(centres)):
            to_goal = torch.minimum(to_goal, (hops + to_goal).amin(-1))
        self.register_buffer("goal", goal)
        self.register_buffer("goal_room", goal_room)
        self.register_buffer("doors", centres)
        self.register_buffer("door_to_goal", to_goal)
        self.register_buffer("room_doors", joins)
        if scale is None:
            grid = torch.linspace(0.0, fourrooms.ARENA_SIZE, 201)
            points = torch.cartesian_prod(grid, grid)
            scale = 1.0 / self.distance(points[fourrooms.in_free_space(points)]).max().item()
        self.scale = float(scale)

    def distance(self, position: torch.Tensor) -> torch.Tensor:
        """Shortest path length ``[...]`` from each position ``[..., 2]`` to the goal."""
        room = fourrooms.room_of(position)
        via_door = (position.unsqueeze(-2) - self.doors).norm(dim=-1) + self.door_to_goal
        via_door = via_door.masked_fill(~self.room_doors[room], torch.inf).amin(-1)
        direct = (position - self.goal).norm(dim=-1).masked_fill(room != self.goal_room, torch.inf)
        return torch.minimum(direct, via_door)

    def forward(self, position: torch.Tensor) -> torch.Tensor:
        return -self.scale * self.distance(position).unsqueeze(-1)


class GridFourRoomsPotential(nn.Module):
    """``Phi(cell) = -scale * d(cell)``, ``d`` the number of moves to the goal (breadth-first search).

    For grid FourRooms (:mod:`drltg.envs.gridrooms`): ``d`` is computed once, on the env's own layout
    and move rule, into a ``13 x 13`` lookup table. It reads the ``"cell"`` entry.

    Args:
        goal: the goal cell ``(row, col)``.
        scale: ``Phi`` per move. Default: ``1 / max d``, so ``Phi`` ranges over ``[-1, 0]`` and the
            shaping collected on a shortest path from the farthest cell (``gamma = 1``) equals the goal
            reward of ``+1``.
    """

    in_keys = ["cell"]

    def __init__(self, goal: Sequence[int], scale: float | None = None):
        super().__init__()
        cells = gridrooms.FREE_CELLS
        succ = gridrooms.CELL_INDEX[tuple(gridrooms.next_cell(cells[:, None], torch.arange(4)).unbind(-1))]
        goal_index = gridrooms.CELL_INDEX[tuple(goal)]
        d = torch.full((gridrooms.N_CELLS,), torch.inf)
        d[goal_index] = 0.0
        for _ in range(gridrooms.N_CELLS):
            d_next = torch.minimum(d, 1.0 + d[succ].amin(-1))
            if torch.equal(d_next, d):
                break
            d = d_next
        table = torch.full(gridrooms.WALLS.shape, torch.inf)
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
