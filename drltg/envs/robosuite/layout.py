"""The scene constants and the observation layout shared by ``lift``, ``lift-place`` and
``lift-place-barrier`` (no robosuite import, so potentials and the demonstrator stay light).

The flat ``observation`` is the concatenation, in this order, of these robosuite observables, each once
(robosuite's ``robot0_proprio-state`` / ``object-state`` vectors, which repeat them, are not used):

====================  ====  ====================================================================
observable            size  meaning
====================  ====  ====================================================================
robot0_eef_pos           3  gripper site position (world frame, m)
robot0_eef_quat          4  gripper orientation, quaternion (x, y, z, w)
robot0_gripper_qpos      2  finger joint positions (m)
robot0_gripper_qvel      2  finger joint velocities (m/s)
robot0_joint_pos_cos     7  cos of the 7 arm joint angles
robot0_joint_pos_sin     7  sin of the 7 arm joint angles
robot0_joint_vel         7  arm joint velocities (rad/s)
cube_pos                 3  cube centre (world frame, m)
cube_quat                4  cube orientation, quaternion (x, y, z, w)
gripper_to_cube_pos      3  ``cube_pos - robot0_eef_pos``
target_pos               3  centre of the target disc's top face (fixed; reported in ``lift`` too)
cube_to_target_pos       3  ``target_pos - cube_pos``
cube_grasped             1  1.0 while both finger pads touch the cube
cube_lifted              1  1.0 once the cube has been lifted in this episode (a latch)
====================  ====  ====================================================================

50 numbers in all, identical in the three tasks, so source and target policies line up.
"""
from __future__ import annotations

from typing import Mapping

TASKS = ("lift", "lift-place", "lift-place-barrier", "lift-place-seed", "lift-place-barrier-seed")
"""The manipulation tasks sharing this scene and layout."""
TABLE_TOP_Z = 0.8
CUBE_HALF_SIZE = 0.022
"""Largest cube half-size robosuite's Lift samples (0.020-0.022 m)."""
LIFT_MARGIN = 0.04
"""Height of the cube centre above the table top that counts as lifted (robosuite Lift's margin)."""
TARGET_XY = (0.0, 0.32)
TARGET_RADIUS = 0.05
TARGET_HALF_HEIGHT = 0.001
BARRIER_HALF_SIZE = (0.15, 0.02, 0.035)
BARRIER_XY = (0.0, 0.17)
BARRIER_DENSITY = 25000.0
BARRIER_FRICTION = (2.0, 0.005, 0.0001)

OBSERVABLES: dict[str, int] = {
    "robot0_eef_pos": 3,
    "robot0_eef_quat": 4,
    "robot0_gripper_qpos": 2,
    "robot0_gripper_qvel": 2,
    "robot0_joint_pos_cos": 7,
    "robot0_joint_pos_sin": 7,
    "robot0_joint_vel": 7,
    "cube_pos": 3,
    "cube_quat": 4,
    "gripper_to_cube_pos": 3,
    "target_pos": 3,
    "cube_to_target_pos": 3,
    "cube_grasped": 1,
    "cube_lifted": 1,
}


def layout_of(sizes: Mapping[str, int]) -> dict[str, slice]:
    """Where each observable lies in the flat observation: ``{name: slice}`` in the given order."""
    layout, start = {}, 0
    for name, size in sizes.items():
        layout[name] = slice(start, start + size)
        start += size
    return layout


LAYOUT = layout_of(OBSERVABLES)
OBSERVATION_SIZE = sum(OBSERVABLES.values())
