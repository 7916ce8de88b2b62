"""A scripted pick-and-place policy for the three manipulation tasks.

It is a pure function of the observation (no hidden phase): the phase is read from the state itself
(is the cube held, has it been lifted, is it resting on the target), so it acts correctly from any
state, serves any batch size, and can stand in as the "past policy" of a pi-reuse experiment. It
proves the tasks solvable and their rewards and success checks right.

Phases, by priority:

1. the cube has been lifted and rests on (or just above) the target -> open the gripper, then rise
   (release);
2. the cube is held -> carry it: straight up to ``carry_height``, across above the target, down onto
   it (``lift``: only up to ``lift_height``, then hold);
3. the gripper is around the cube -> close it (grasp);
4. above the cube -> descend with the gripper open; elsewhere -> go above the cube (reach).

Position commands are ``clip(gain * (goal - eef) / 0.05, -1, 1)`` for OSC_POSE's 5 cm delta scale.
Rotation commands ``clip(gain * e / 0.5, -1, 1)`` (0.5 rad scale) turn the gripper towards pointing
straight down, ``e = 1/2 sum_i r_i x d_i`` the rotation error between current and desired axes; until
it holds the cube, the desired yaw also turns the fingers square to the nearest pair of cube faces.
The gripper command is -1 (open) or +1 (close).
"""
from __future__ import annotations

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModuleBase

from drltg.envs.robosuite.layout import CUBE_HALF_SIZE, LAYOUT, TABLE_TOP_Z, TARGET_HALF_HEIGHT, TASKS

OSC_POSITION_SCALE = 0.05
OSC_ROTATION_SCALE = 0.5


def rotation_matrix(q: torch.Tensor) -> torch.Tensor:
    """Rotation matrices ``[*, 3, 3]`` of unit quaternions ``[*, 4]`` in robosuite's (x, y, z, w) order."""
    x, y, z, w = q.unbind(-1)
    rows = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ]
    return torch.stack([torch.stack(row, -1) for row in rows], -2)


def downward_gripper(finger_yaw: torch.Tensor) -> torch.Tensor:
    """The Panda gripper frame ``[*, 3, 3]`` pointing down with its finger axis at ``finger_yaw``
    (the gripper frame's y axis is minus the finger axis, its z axis the approach direction)."""
    c, s = finger_yaw.cos(), finger_yaw.sin()
    zero = torch.zeros_like(c)
    columns = [torch.stack([s, -c, zero], -1), torch.stack([-c, -s, zero], -1), torch.stack([zero, zero, zero - 1], -1)]
    return torch.stack(columns, -1)


def _quarter_turn_wrap(angle: torch.Tensor) -> torch.Tensor:
    """``angle`` wrapped into ``[-pi/4, pi/4)``: a cube looks the same every quarter turn."""
    return torch.remainder(angle + torch.pi / 4, torch.pi / 2) - torch.pi / 4


class PickPlaceDemonstrator(TensorDictModuleBase):
    """Scripted policy: reads ``observation`` (drltg's manipulation layout), writes ``action``.

    Args:
        place: carry the cube to the target and release it (``lift-place*``); ``False`` for ``lift``.
        lift_height: cube-centre height above the table to lift to (``lift``).
        carry_height: cube-centre height above the table to carry at (clears the 0.07 m barrier).
        hover: gripper height above the cube before descending onto it.
        release_height: the cube is let go this far (m) above its resting height on the target.
        tolerance: position error (m) under which a phase counts as reached.
        gain: proportional gain on the position error.
    """

    def __init__(
        self,
        place: bool = True,
        *,
        lift_height: float = 0.10,
        carry_height: float = 0.13,
        hover: float = 0.06,
        release_height: float = 0.015,
        tolerance: float = 0.01,
        gain: float = 1.0,
        layout: dict[str, slice] = LAYOUT,
        observation_key: str = "observation",
        action_key: str = "action",
    ):
        super().__init__()
        self.in_keys = [observation_key]
        self.out_keys = [action_key]
        self.place = place
        self.lift_height = lift_height
        self.carry_height = carry_height
        self.hover = hover
        self.release_height = release_height
        self.tolerance = tolerance
        self.gain = gain
        self.layout = layout

    def act(self, obs: torch.Tensor) -> torch.Tensor:
        """The action for a batch of flat observations ``[*, n]`` -> ``[*, 7]``."""
        part = {name: obs[..., where] for name, where in self.layout.items()}
        eef, cube, target = part["robot0_eef_pos"], part["cube_pos"], part["target_pos"]
        held = part["cube_grasped"] > 0.5
        lifted = part["cube_lifted"] > 0.5
        up = torch.zeros_like(eef)
        up[..., 2] = 1.0
        tol = self.tolerance

        # 4. reach / descend (gripper open)
        above_cube = cube + self.hover * up
        over_cube = (cube - eef)[..., :2].norm(dim=-1, keepdim=True) < tol
        goal = torch.where(over_cube, cube, above_cube)
        close = torch.zeros_like(held)

        # 3. grasp
        at_cube = (cube - eef).norm(dim=-1, keepdim=True) < tol
        goal = torch.where(at_cube, eef, goal)
        close = close | at_cube

        # 2. carry (cube goals converted to gripper goals: the gripper moves with the cube it holds)
        table = torch.full_like(cube[..., 2:], TABLE_TOP_Z)
        if self.place:
            high = table + self.carry_height
            resting = table + 2 * TARGET_HALF_HEIGHT + CUBE_HALF_SIZE
            over_target = (target - cube)[..., :2].norm(dim=-1, keepdim=True) < tol
            raised = cube[..., 2:] > high - tol
            cube_goal = torch.where(
                over_target,
                torch.cat([target[..., :2], resting], -1),
                torch.where(raised, torch.cat([target[..., :2], high], -1), torch.cat([cube[..., :2], high], -1)),
            )
        else:
            cube_goal = torch.cat([cube[..., :2], table + self.lift_height], -1)
        goal = torch.where(held, eef + cube_goal - cube, goal)
        close = close | held

        # 1. release
        if self.place:
            on_target = (
                lifted
                & ((target - cube)[..., :2].norm(dim=-1, keepdim=True) < 2 * tol)
                & (cube[..., 2:] < resting + self.release_height)
            )
            retreat = torch.cat([eef[..., :2], high + self.hover], -1)
            goal = torch.where(on_target, torch.where(held, eef, retreat), goal)
            close = close & ~on_target

        move = (self.gain * (goal - eef) / OSC_POSITION_SCALE).clamp(-1.0, 1.0)
        turn = (self.gain * self._rotation_error(part["robot0_eef_quat"], part["cube_quat"], held)).clamp(-1.0, 1.0)
        grip = torch.where(close, 1.0, -1.0).to(obs.dtype)
        return torch.cat([move, turn, grip], -1)

    def _rotation_error(self, eef_quat: torch.Tensor, cube_quat: torch.Tensor, held: torch.Tensor) -> torch.Tensor:
        current = rotation_matrix(eef_quat)
        finger_yaw = torch.atan2(-current[..., 1, 1], -current[..., 0, 1])
        cube = rotation_matrix(cube_quat)
        cube_yaw = torch.atan2(cube[..., 1, 0], cube[..., 0, 0])
        square = _quarter_turn_wrap(cube_yaw - finger_yaw).masked_fill(held.squeeze(-1), 0.0)
        desired = downward_gripper(finger_yaw + square)
        error = 0.5 * torch.linalg.cross(current, desired, dim=-2).sum(-1)
        return error / OSC_ROTATION_SCALE

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        tensordict.set(self.out_keys[0], self.act(tensordict.get(self.in_keys[0])))
        return tensordict


def demonstrator_for(task: str, **kwargs) -> PickPlaceDemonstrator:
    """The demonstrator for a manipulation task name: lift and hold for ``lift``, place otherwise."""
    if task not in TASKS:
        raise ValueError(f"No demonstrator for task {task!r}; known: {', '.join(TASKS)}.")
    return PickPlaceDemonstrator(place=task != "lift", **kwargs)
