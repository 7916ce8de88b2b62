"""The manipulation tasks: robosuite's Lift and two place tasks built on it.

All three share one table scene and one set of task observables, so a policy trained on ``lift`` sees
the same observation layout in ``lift-place`` (pi-reuse, model reuse):

``target_pos``
    centre of the target disc's top face (world frame, metres). Fixed for a task; in ``LiftWithTarget``
    there is no disc and the same point is reported, so source and target tasks agree.
``cube_to_target_pos``
    ``target_pos - cube_pos``.
``cube_grasped``
    1.0 while both finger pads touch the cube (robosuite's ``_check_grasp``), else 0.0.
``cube_lifted``
    1.0 once the cube centre has been more than ``LIFT_MARGIN`` above the table top in this episode
    (a latch). Success in the place tasks depends on it, so it is part of the Markov state.

Geometry (table top at z = 0.8 m; the cube, of half-size 0.020-0.022 m, is placed within +-0.03 m of
the table centre with a random yaw, as in robosuite's Lift; the robot base sits at x = -0.56 m):

- target disc: green cylinder of radius 0.05 m and height 0.002 m centred at (0, 0.32) on the table;
  a static body (no joint), so it cannot be knocked around; it collides, so the cube rests on it.
- barrier (``LiftPlaceBarrier``): a box 0.30 x 0.04 x 0.07 m (x, y, z) centred at (0, 0.17), standing
  on the table between cube and target; density 25000 kg/m^3 (21 kg), friction 2.0 sliding, 0.005
  torsional, 0.0001 rolling. It is a free body, but too heavy and grippy for the arm: pushing it
  at full force for 300 steps moves it by less than 1 mm (a 1000 kg/m^3 barrier is knocked over). Its
  top is 0.07 m above the table, so the cube must be carried over it; it stands far enough from the
  cube and the target (>= 1.5 cm clearance for the Panda hand) not to block grasping or placing.
"""
from __future__ import annotations

import numpy as np
from robosuite.environments.manipulation.lift import Lift
from robosuite.models.objects import BoxObject, CylinderObject
from robosuite.utils.mjcf_utils import array_to_string
from robosuite.utils.observables import Observable, sensor

from drltg.envs.robosuite.layout import (
    BARRIER_DENSITY,
    BARRIER_FRICTION,
    BARRIER_HALF_SIZE,
    BARRIER_XY,
    LIFT_MARGIN,
    TABLE_TOP_Z,
    TARGET_HALF_HEIGHT,
    TARGET_RADIUS,
    TARGET_XY,
)
from drltg.errors import UsageError

REST_TOLERANCE = 0.005
"""How far above resting height the cube centre may be and still count as resting on the disc."""


class LiftWithTarget(Lift):
    """robosuite's ``Lift`` (its reward and success unchanged) plus the task observables shared with
    the place tasks; the target point is reported but no disc exists."""

    def __init__(self, *args, **kwargs):
        self.target_pos = np.array([*TARGET_XY, TABLE_TOP_Z + 2 * TARGET_HALF_HEIGHT])
        self._was_lifted = False
        super().__init__(*args, **kwargs)

    def _reset_internal(self):
        super()._reset_internal()
        self._was_lifted = False

    def _post_action(self, action):
        self._was_lifted = self._cube_lifted_now() or self._was_lifted
        return super()._post_action(action)

    def _cube_lifted_now(self) -> bool:
        return bool(self.sim.data.body_xpos[self.cube_body_id][2] > TABLE_TOP_Z + LIFT_MARGIN)

    def cube_lifted(self) -> bool:
        """Whether the cube has been lifted since the episode started (including now)."""
        return self._was_lifted or self._cube_lifted_now()

    def cube_grasped(self) -> bool:
        return bool(self._check_grasp(gripper=self.robots[0].gripper, object_geoms=self.cube))

    def _setup_observables(self):
        observables = super()._setup_observables()

        @sensor(modality="object")
        def target_pos(obs_cache):
            return self.target_pos.copy()

        @sensor(modality="object")
        def cube_to_target_pos(obs_cache):
            return self.target_pos - self.sim.data.body_xpos[self.cube_body_id]

        @sensor(modality="object")
        def cube_grasped(obs_cache):
            return np.array([float(self.cube_grasped())])

        @sensor(modality="object")
        def cube_lifted(obs_cache):
            return np.array([float(self.cube_lifted())])

        for s in (target_pos, cube_to_target_pos, cube_grasped, cube_lifted):
            observables[s.__name__] = Observable(name=s.__name__, sensor=s, sampling_rate=self.control_freq)
        return observables


class LiftPlace(LiftWithTarget):
    """Lift the cube and set it down on the green target disc.

    Success: the cube has been lifted in this episode, its centre lies within the disc's radius
    (horizontally), it touches the disc, rests on it (centre at most ``REST_TOLERANCE`` above resting
    height) and is not held by the gripper. Pushing the cube along the table onto the disc never lifts
    it, so it does not count. Reward: 1 for every step in success, else 0 (dense shaping comes from
    ``drltg.envs.robosuite.potentials`` through ``PotentialShaping``).
    """

    def __init__(self, *args, reward_shaping: bool = False, **kwargs):
        if reward_shaping:
            raise UsageError(
                "the place tasks have only the sparse success reward; shape it with PotentialShaping "
                "(transfer.method=reward-shaping) and drltg.envs.robosuite.potentials instead."
            )
        super().__init__(*args, **kwargs)

    def _load_model(self):
        super()._load_model()
        self.target = CylinderObject(
            name="target",
            size=[TARGET_RADIUS, TARGET_HALF_HEIGHT],
            rgba=[0.1, 0.8, 0.1, 1.0],
            joints=None,
        )
        self.target.get_obj().set("pos", array_to_string([*TARGET_XY, TABLE_TOP_Z + TARGET_HALF_HEIGHT]))
        self.model.merge_objects([self.target])

    def reward(self, action=None):
        return float(self._check_success()) * (1.0 if self.reward_scale is None else self.reward_scale)

    def cube_on_target(self) -> bool:
        return bool(self.check_contact(self.cube, self.target))

    def cube_pushed(self) -> bool:
        """Whether the cube touches the target without having been lifted in this episode: it got there
        along the table."""
        return self.cube_on_target() and not self.cube_lifted()

    def _check_success(self):
        cube_pos = self.sim.data.body_xpos[self.cube_body_id]
        resting_z = TABLE_TOP_Z + 2 * TARGET_HALF_HEIGHT + self.cube.size[2]
        return (
            self.cube_lifted()
            and np.linalg.norm(cube_pos[:2] - self.target_pos[:2]) < TARGET_RADIUS
            and cube_pos[2] < resting_z + REST_TOLERANCE
            and self.check_contact(self.cube, self.target)
            and not self.cube_grasped()
        )


class LiftPlaceBarrier(LiftPlace):
    """``LiftPlace`` with a heavy, high-friction wall between the cube and the target."""

    def _load_model(self):
        super()._load_model()
        self.barrier = BoxObject(
            name="barrier",
            size=list(BARRIER_HALF_SIZE),
            rgba=[0.45, 0.45, 0.5, 1.0],
            density=BARRIER_DENSITY,
            friction=list(BARRIER_FRICTION),
        )
        self.model.merge_objects([self.barrier])

    def _reset_internal(self):
        super()._reset_internal()
        pose = [*BARRIER_XY, TABLE_TOP_Z + BARRIER_HALF_SIZE[2], 1.0, 0.0, 0.0, 0.0]
        self.sim.data.set_joint_qpos(self.barrier.joints[0], np.array(pose))

    def barrier_pos(self) -> np.ndarray:
        return np.array(self.sim.data.body_xpos[self.sim.model.body_name2id(self.barrier.root_body)])


class SeedReward:
    """The earlier implementation's dense place reward (mixed into a place task), per step:

        r = 3.25                                   if the cube touches the target disc,
        r = reach + grasp + lift + place           otherwise, with
            reach = 1 - tanh(10 * |gripper - cube|),  grasp = 0.25 while grasped,
            lift  = 0.5 while the cube centre is more than 4 cm above the table,
            place = 1 - tanh(10 * |cube - target|);

    returned as ``r / 3.25`` (times ``reward_scale``), so a step pays at most 1 (the non-contact terms sum
    to at most 2.75). Touching the target pays the same whether the cube was carried or pushed there;
    ``success`` stays the strict place check, and ``cube_pushed`` tells the two apart.
    """

    CONTACT = 3.25

    def reward(self, action=None):
        if self.cube_on_target():
            reward = self.CONTACT
        else:
            cube = self.sim.data.body_xpos[self.cube_body_id]
            to_cube = self._gripper_to_target(self.robots[0].gripper, self.cube.root_body, "body", return_distance=True)
            reward = (1 - np.tanh(10.0 * to_cube)
                      + 0.25 * self.cube_grasped()
                      + 0.5 * self._cube_lifted_now()
                      + 1 - np.tanh(10.0 * np.linalg.norm(cube - self.target_pos)))
        return reward / self.CONTACT * (1.0 if self.reward_scale is None else self.reward_scale)


class LiftPlaceSeed(SeedReward, LiftPlace):
    """``LiftPlace``'s scene, observation, action and strict success, with the earlier implementation's
    dense reward (:class:`SeedReward`)."""


class LiftPlaceBarrierSeed(SeedReward, LiftPlaceBarrier):
    """``LiftPlaceBarrier``'s scene, observation, action and strict success, with the earlier
    implementation's dense reward (:class:`SeedReward`)."""
