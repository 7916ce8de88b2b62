"""Potentials for ``drltg.transforms.PotentialShaping`` on the manipulation tasks.

The dense rewards of robosuite (reach, grasp, lift) become potentials ``Phi(s)``: shaping with
``F = gamma * Phi(s') - Phi(s)`` keeps the optimal policy of the sparse task (Ng, Harada & Russell
1999) while still telling the learner where to go. Like drltg's other potentials, each is an
``nn.Module`` with ``in_keys = ["observation"]``: called on the flat observation (drltg's manipulation
layout, see ``layout.py``) it returns ``Phi`` of shape ``[*batch, 1]``. Terms lie in ``[0, 1]``:

- ``Reach``: ``1 - tanh(10 * |cube - gripper|)``
- ``Grasp``: ``1`` while both finger pads touch the cube
- ``LiftHeight``: ``clip((z_cube - z_rest) / (height - z_rest), 0, 1)``, heights above the table top
- ``Carry``: ``lifted * (1 - tanh(5 * |xy_target - xy_cube|))``, zero until the cube has been lifted,
  so pushing the cube towards the target earns nothing

and the task potentials combine them:

- ``LiftPotential``: ``(Reach + 0.25 Grasp + LiftHeight) / 2.25`` (robosuite Lift's dense reward
  terms, with its success bonus replaced by lift progress);
- ``PlacePotential``: ``max(0.1 Reach, 0.35 Grasp, Grasp * (0.35 + 0.15 LiftHeight), 0.5 + 0.5 Carry)``
  where the last stage applies once the cube has been lifted: the staged form of robosuite's
  PickPlace reward, so that letting go of the cube on the target keeps ``Phi`` high.
"""
from __future__ import annotations

import torch
from torch import nn

from drltg.envs.robosuite.layout import CUBE_HALF_SIZE, LAYOUT, LIFT_MARGIN, TABLE_TOP_Z


class ObservationPotential(nn.Module):
    """Base: reads named parts of the flat observation through a layout ``{name: slice}``."""

    def __init__(self, layout: dict[str, slice] = LAYOUT, key: str = "observation"):
        super().__init__()
        self.layout = layout
        self.in_keys = [key]

    def part(self, observation: torch.Tensor, name: str) -> torch.Tensor:
        return observation[..., self.layout[name]]


class Reach(ObservationPotential):
    """``1 - tanh(scale * |cube - gripper|)``."""

    def __init__(self, scale: float = 10.0, **kwargs):
        super().__init__(**kwargs)
        self.scale = scale

    def forward(self, obs):
        distance = self.part(obs, "gripper_to_cube_pos").norm(dim=-1, keepdim=True)
        return 1.0 - torch.tanh(self.scale * distance)


class Grasp(ObservationPotential):
    """``1`` while the cube is grasped, else ``0``."""

    def forward(self, obs):
        return self.part(obs, "cube_grasped")


class LiftHeight(ObservationPotential):
    """Lift progress: 0 with the cube resting on the table, 1 with its centre ``height`` above the table."""

    def __init__(self, height: float = LIFT_MARGIN, **kwargs):
        super().__init__(**kwargs)
        if height <= CUBE_HALF_SIZE:
            raise ValueError(f"height must exceed the cube's resting height {CUBE_HALF_SIZE}, got {height}.")
        self.height = height

    def forward(self, obs):
        above_table = self.part(obs, "cube_pos")[..., 2:] - TABLE_TOP_Z
        return ((above_table - CUBE_HALF_SIZE) / (self.height - CUBE_HALF_SIZE)).clamp(0.0, 1.0)


class Carry(ObservationPotential):
    """``lifted * (1 - tanh(scale * horizontal distance from cube to target))``."""

    def __init__(self, scale: float = 5.0, **kwargs):
        super().__init__(**kwargs)
        self.scale = scale

    def forward(self, obs):
        distance = self.part(obs, "cube_to_target_pos")[..., :2].norm(dim=-1, keepdim=True)
        return self.part(obs, "cube_lifted") * (1.0 - torch.tanh(self.scale * distance))


class LiftPotential(ObservationPotential):
    """``(Reach + 0.25 Grasp + LiftHeight) / 2.25``, in ``[0, 1]``."""

    def __init__(self, height: float = LIFT_MARGIN, **kwargs):
        super().__init__(**kwargs)
        self.reach, self.grasp, self.lift = Reach(**kwargs), Grasp(**kwargs), LiftHeight(height, **kwargs)

    def forward(self, obs):
        return (self.reach(obs) + 0.25 * self.grasp(obs) + self.lift(obs)) / 2.25


class PlacePotential(ObservationPotential):
    """``max(0.1 Reach, 0.35 Grasp, Grasp * (0.35 + 0.15 LiftHeight), lifted * (0.5 + 0.5 Carry))``, in ``[0, 1]``."""

    def __init__(self, height: float = LIFT_MARGIN, **kwargs):
        super().__init__(**kwargs)
        self.reach, self.grasp = Reach(**kwargs), Grasp(**kwargs)
        self.lift, self.carry = LiftHeight(height, **kwargs), Carry(**kwargs)

    def forward(self, obs):
        grasped = self.grasp(obs)
        lifted = self.part(obs, "cube_lifted")
        stages = torch.cat(
            [
                0.1 * self.reach(obs),
                0.35 * grasped,
                grasped * (0.35 + 0.15 * self.lift(obs)),
                lifted * (0.5 + 0.5 * self.carry(obs)),
            ],
            dim=-1,
        )
        return stages.amax(dim=-1, keepdim=True)


def potential_for(task: str, **kwargs) -> ObservationPotential:
    """The default shaping potential of a manipulation task name."""
    if task == "lift":
        return LiftPotential(**kwargs)
    if task in ("lift-place", "lift-place-barrier"):
        return PlacePotential(**kwargs)
    raise ValueError(f"No potential for task {task!r}; known: lift, lift-place, lift-place-barrier.")
