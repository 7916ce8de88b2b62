"""Continuous FourRooms: a point agent in four rooms joined by four doorways.

The classic FourRooms layout (Sutton, Precup & Singh 1999) made continuous, as a stateless,
batched TorchRL environment in pure torch (any ``batch_size``, any device).

Geometry (arena units; ``x`` to the right, ``y`` up)::

    y
    10 +-------------------+--------------------+
       |                   |                    |
       |    northwest      N     northeast      |      N doorway: x in [4.75, 5.25], y in [7.0, 8.0]
       |                   |                    |      S doorway: x in [4.75, 5.25], y in [1.5, 2.5]
     5 +----W----+---------+---------E---+------+      W doorway: x in [1.5, 2.5], y in [4.75, 5.25]
       |                   |                    |      E doorway: x in [7.0, 8.0], y in [4.75, 5.25]
       |    southwest      S     southeast      |
       |                   |                    |
     0 +-------------------+--------------------+  x
       0                   5                    10

* The arena is the square ``[0, 10]^2``; its border is a wall.
* Two inner walls of thickness 0.5 lie along the middle lines ``x = 5`` and ``y = 5``
  (the boxes ``[4.75, 5.25] x [0, 10]`` and ``[0, 10] x [4.75, 5.25]``), each cut by two
  doorways of width 1.0 placed off-centre like the classic layout (see :data:`DOORWAYS`).
* The four rooms are the ``4.75 x 4.75`` squares left between the walls (see :data:`ROOMS`).
  :func:`room_of` assigns every point (doorway passages included) to the quadrant it lies in.

Dynamics. The action ``a`` lies in ``[-1, 1]^2`` and asks for the displacement ``max_step * a``.
Motion is axis-separated: the ``x`` displacement is applied first and stops at the first wall
face on the way, then the ``y`` displacement likewise. A wall stops the agent however long the
step, so the agent never tunnels through a wall; moving along a wall face is free. The agent is
a point; free space is the arena minus the open interiors of the walls.

Episode. The start position is uniform over free space minus the goal disc (optionally over one
room, ``start_room``), drawn from the environment's own generator, seeded by :meth:`set_seed`.
Reaching the goal disc (``||p' - goal|| <= goal_radius``, tested at the end of each move) gives
reward ``+1`` and ends the episode (``terminated``, ``success``); any other step gives
``-step_cost``. After ``horizon`` steps without success the episode is ``truncated``.

Observation. The position scaled to ``[-1, 1]^2`` (``2 p / 10 - 1``), float32; with
``observe_goal=True`` the goal, scaled the same way, is appended. The raw position (arena units)
is kept in the ``"position"`` entry.
"""
from __future__ import annotations

from typing import NamedTuple, Sequence

import numpy as np
import torch
from tensordict import TensorDictBase
from torchrl.data import Bounded

from drltg.envs.goal_env import GoalEnv
from drltg.errors import UsageError

ARENA_SIZE = 10.0
WALL_THICKNESS = 0.5
DOOR_WIDTH = 1.0

_LO, _HI = 5.0 - WALL_THICKNESS / 2, 5.0 + WALL_THICKNESS / 2

ROOM_NAMES = ("northwest", "northeast", "southwest", "southeast")
"""Room names in the order of the indices returned by :func:`room_of`."""

ROOMS = {
    "northwest": (0.0, _HI, _LO, ARENA_SIZE),
    "northeast": (_HI, _HI, ARENA_SIZE, ARENA_SIZE),
    "southwest": (0.0, 0.0, _LO, _LO),
    "southeast": (_HI, 0.0, ARENA_SIZE, _LO),
}
"""Each room's free rectangle ``(xmin, ymin, xmax, ymax)``."""


class Doorway(NamedTuple):
    center: tuple[float, float]
    rooms: tuple[str, str]


DOORWAYS = {
    "north": Doorway((5.0, 7.5), ("northwest", "northeast")),
    "south": Doorway((5.0, 2.0), ("southwest", "southeast")),
    "west": Doorway((2.0, 5.0), ("northwest", "southwest")),
    "east": Doorway((7.5, 5.0), ("northeast", "southeast")),
}
"""Doorway centres (on a middle line) and the two rooms each one joins."""


WALLS = (
    (_LO, 0.0, _HI, 1.5),
    (_LO, 2.5, _HI, 7.0),
    (_LO, 8.0, _HI, ARENA_SIZE),
    (0.0, _LO, 1.5, _HI),
    (2.5, _LO, 7.0, _HI),
    (8.0, _LO, ARENA_SIZE, _HI),
)
"""Inner wall boxes ``(xmin, ymin, xmax, ymax)``: the two middle walls cut by the doorways."""

DOOR_PASSAGES = (
    (_LO, 7.0, _HI, 8.0),
    (_LO, 1.5, _HI, 2.5),
    (1.5, _LO, 2.5, _HI),
    (7.0, _LO, 8.0, _HI),
)
"""The free rectangles through the walls, one per doorway, in :data:`DOORWAYS` order."""


def room_of(pos: torch.Tensor) -> torch.Tensor:
    """Index into :data:`ROOM_NAMES` of the quadrant holding each position ``[..., 2]`` (int64)."""
    x, y = pos[..., 0], pos[..., 1]
    return 2 * (y < 5.0).long() + (x >= 5.0).long()


def in_free_space(pos: torch.Tensor) -> torch.Tensor:
    """Whether each position ``[..., 2]`` lies in the arena and outside every wall's interior."""
    walls = torch.as_tensor(WALLS, dtype=pos.dtype, device=pos.device)
    x, y = pos[..., 0:1], pos[..., 1:2]
    inside = (walls[:, 0] < x) & (x < walls[:, 2]) & (walls[:, 1] < y) & (y < walls[:, 3])
    in_arena = ((pos >= 0) & (pos <= ARENA_SIZE)).all(-1)
    return in_arena & ~inside.any(-1)


def _slide(coord, across, delta, walls, axis):
    """Moves ``coord`` by ``delta`` along ``axis``, stopping at the first wall face on the way.

    Only walls whose extent along the other axis strictly contains ``across`` are in the way. The
    comparisons are laid out ``[walls, *batch]`` so that every elementwise kernel runs along the batch
    (contiguous, vectorised) rather than along the six walls.
    """
    shape = (-1,) + (1,) * coord.dim()
    lo, hi = walls[:, axis].reshape(shape), walls[:, axis + 2].reshape(shape)
    olo, ohi = walls[:, 1 - axis].reshape(shape), walls[:, 3 - axis].reshape(shape)
    in_the_way = (olo < across) & (across < ohi)
    upper = torch.where(in_the_way & (lo >= coord), lo, ARENA_SIZE).amin(0)
    lower = torch.where(in_the_way & (hi <= coord), hi, 0.0).amax(0)
    return torch.minimum(torch.maximum(coord + delta, lower), upper)


def move(pos: torch.Tensor, displacement: torch.Tensor, walls: torch.Tensor | None = None) -> torch.Tensor:
    """Applies ``displacement [..., 2]`` to ``pos [..., 2]`` with the axis-separated wall rule."""
    if walls is None:
        walls = torch.as_tensor(WALLS, dtype=pos.dtype, device=pos.device)
    x = _slide(pos[..., 0], pos[..., 1], displacement[..., 0], walls, 0)
    y = _slide(pos[..., 1], x, displacement[..., 1], walls, 1)
    return torch.stack((x, y), -1)


class FourRoomsEnv(GoalEnv):
    """Continuous FourRooms (see the module docstring for geometry, dynamics and rewards).

    With no arguments it is the registered task ``fourrooms/northeast`` (``make_env("fourrooms/northeast")``).

    Args:
        goal: the goal centre ``(x, y)`` in arena units; must lie in free space.
        goal_radius: radius of the goal disc.
        max_step: the displacement per unit of action along each axis.
        step_cost: the cost paid on every step that does not reach the goal.
        horizon: episode length after which the episode is truncated.
        start_room: one of :data:`ROOM_NAMES` to start in that room only; ``None`` for anywhere.
        observe_goal: append the scaled goal to the observation.
        render_size: side of the square image returned by :meth:`render`, in pixels.
        batch_size, device: as for any :class:`~torchrl.envs.EnvBase`.
        seed: seed of the start-position generator; ``None`` draws one from torch's global RNG.

    Examples:
        >>> env = FourRoomsEnv(goal=(8.0, 8.0), batch_size=(16,), seed=0)
        >>> td = env.rollout(100, break_when_any_done=False)
        >>> td["next", "success"].shape
        torch.Size([16, 100, 1])
    """

    state_key = "position"

    def __init__(
        self,
        goal: Sequence[float] = (8.0, 8.0),
        *,
        goal_radius: float = 0.5,
        max_step: float = 0.5,
        step_cost: float = 0.01,
        horizon: int = 100,
        start_room: str | None = None,
        observe_goal: bool = False,
        render_size: int = 200,
        batch_size: Sequence[int] | torch.Size = (),
        device: torch.device | str | None = None,
        seed: int | None = None,
    ):
        super().__init__(step_cost=step_cost, horizon=horizon, observe_goal=observe_goal, batch_size=batch_size,
                         device=device)
        goal_t = torch.as_tensor(goal, dtype=torch.float32)
        if goal_t.shape != (2,) or not bool(in_free_space(goal_t)):
            raise UsageError(f"goal {tuple(goal)} is not a point (x, y) in the free space of the 10x10 arena.")
        if start_room is not None and start_room not in ROOMS:
            raise UsageError(f"start_room {start_room!r} is not one of {', '.join(ROOM_NAMES)}.")
        for name, value in (("goal_radius", goal_radius), ("max_step", max_step)):
            if not value > 0:
                raise UsageError(f"{name} {value} must be positive.")
        if not 16 <= render_size <= 4096:
            raise UsageError(f"render_size is the side of a rendered frame in pixels, from 16 to 4096; got "
                             f"{render_size}.")
        self.goal_radius = float(goal_radius)
        self.max_step = float(max_step)
        self.start_room = start_room
        self.render_size = int(render_size)
        regions = [ROOMS[start_room]] if start_room else list(ROOMS.values()) + list(DOOR_PASSAGES)
        self.register_buffer("goal", goal_t.to(self.device))
        self.register_buffer("_walls", torch.tensor(WALLS, device=self.device))
        regions = torch.tensor(regions)
        self._region_low, self._region_size = regions[:, :2], regions[:, 2:] - regions[:, :2]
        self._region_areas = self._region_size.prod(-1)
        self._make_spec()
        self._seed_or_draw(seed)

    def _make_spec(self):
        position = Bounded(0.0, ARENA_SIZE, (2,), dtype=torch.float32, device=self.device)
        self._state_specs(position, obs_dim=4 if self.observe_goal else 2)
        self.action_spec = Bounded(-1.0, 1.0, (*self.batch_size, 2), dtype=torch.float32, device=self.device)

    def _observe(self, position: torch.Tensor) -> torch.Tensor:
        obs = position * (2.0 / ARENA_SIZE) - 1.0
        if self.observe_goal:
            obs = torch.cat((obs, (self.goal * (2.0 / ARENA_SIZE) - 1.0).expand_as(obs)), -1)
        return obs

    def _starts(self, mask: torch.Tensor) -> torch.Tensor:
        """``mask.sum()`` positions (the flat batch elements where ``mask`` is true, in order) uniform over
        the start regions (weighted by area) minus the goal disc.

        Draws on the CPU generator, so a seed gives the same starts on every device.
        """
        rng, n = self.rng, int(mask.sum())
        goal = self.goal.cpu()
        pos = torch.empty(n, 2)
        todo = torch.arange(n)
        while todo.numel():
            box = torch.multinomial(self._region_areas, todo.numel(), replacement=True, generator=rng)
            pos[todo] = self._region_low[box] + torch.rand(todo.numel(), 2, generator=rng) * self._region_size[box]
            todo = todo[(pos[todo] - goal).norm(dim=-1) <= self.goal_radius]
        return pos.to(self.device)

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs) -> TensorDictBase:
        shape = self.batch_size
        reset = None if tensordict is None else tensordict.get("_reset", None)
        if kwargs.get("set_state") and tensordict is not None and "position" in tensordict.keys():
            position = tensordict["position"].clone()
        elif reset is None:
            position = self._starts(torch.ones(shape.numel(), dtype=torch.bool)).reshape(*shape, 2)
        else:  # a partial reset: only the reset elements need a start (the others are kept)
            mask = reset.squeeze(-1)
            position = torch.zeros((*shape, 2), device=self.device)
            position[mask] = self._starts(mask.reshape(-1).cpu())
        return self._first(position)

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        action = tensordict["action"].clamp(-1.0, 1.0)
        position = move(tensordict["position"], action * self.max_step, self._walls)
        step_count = tensordict["step_count"] + 1
        success = (position - self.goal).norm(dim=-1, keepdim=True) <= self.goal_radius
        return self._next(position, step_count, success)

    def render(self, tensordict: TensorDictBase | None = None) -> np.ndarray:
        """An RGB ``uint8`` image ``[render_size, render_size, 3]``: walls, goal disc and agents.

        Every ``"position"`` in ``tensordict`` is drawn (one state, a batch, or a trajectory);
        pass ``td[0]`` to draw only the first environment of a batch.
        """
        size = self.render_size
        scale = ARENA_SIZE / size
        centres = (np.arange(size) + 0.5) * scale
        x, y = np.meshgrid(centres, centres[::-1])
        img = np.full((size, size, 3), 255, dtype=np.uint8)
        for x0, y0, x1, y1 in WALLS:
            img[(x0 <= x) & (x <= x1) & (y0 <= y) & (y <= y1)] = (60, 60, 60)
        edge = max(1, size // 100)
        img[:edge] = img[-edge:] = img[:, :edge] = img[:, -edge:] = (60, 60, 60)
        gx, gy = self.goal.tolist()
        img[(x - gx) ** 2 + (y - gy) ** 2 <= self.goal_radius**2] = (40, 170, 70)
        if tensordict is not None:
            agent_radius = max(0.12, 2.5 * scale)
            for px, py in tensordict["position"].detach().reshape(-1, 2).cpu().tolist():
                img[(x - px) ** 2 + (y - py) ** 2 <= agent_radius**2] = (215, 40, 40)
        return img


class FourRoomsPotential(torch.nn.Module):
    """``Phi(p) = -scale * d(p)``, ``d`` the shortest path to the goal through the doorway centres.

    The task's shaping potential, an exact distance to the goal: an upper reference for what shaping can
    give, not knowledge transferred from a source. Within the goal's room ``d`` is the
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
        centres = torch.tensor([door.center for door in DOORWAYS.values()])
        joins = torch.tensor([[room in door.rooms for door in DOORWAYS.values()] for room in ROOM_NAMES])
        goal_room = room_of(goal)
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
            grid = torch.linspace(0.0, ARENA_SIZE, 201)
            points = torch.cartesian_prod(grid, grid)
            scale = 1.0 / self.distance(points[in_free_space(points)]).max().item()
        self.scale = float(scale)

    def distance(self, position: torch.Tensor) -> torch.Tensor:
        """Shortest path length ``[...]`` from each position ``[..., 2]`` to the goal."""
        room = room_of(position)
        via_door = (position.unsqueeze(-2) - self.doors).norm(dim=-1) + self.door_to_goal
        via_door = via_door.masked_fill(~self.room_doors[room], torch.inf).amin(-1)
        direct = (position - self.goal).norm(dim=-1).masked_fill(room != self.goal_room, torch.inf)
        return torch.minimum(direct, via_door)

    def forward(self, position: torch.Tensor) -> torch.Tensor:
        return -self.scale * self.distance(position).unsqueeze(-1)
