"""A lean ``env.step`` for one fixed-base arm under robosuite's OSC_POSE controller and a gripper.

robosuite's ``env.step`` runs its controller stack at every physics substep (25 per step at 20 Hz):
composite controller, part controllers, site and joint lookups by name, action-limit properties,
history buffers. :class:`LeanStep` computes the same torques from MuJoCo's arrays with the ids,
index arrays and per-step quantities cached, then lets robosuite finish the step (``_post_action``:
reward, task latches). The same floating-point operations run in the same order on arrays of the
same layout, and robosuite's own numba kernels are reused, so the trajectory is bit-identical to
``env.step`` for the same actions. One assumption is checked rather than guaranteed: the few
matrix-vector products robosuite does in NumPy run here inside numba, whose BLAS (SciPy's OpenBLAS)
must round as NumPy's does for these shapes; ``tests/test_robosuite.py`` compares whole trajectories
bit for bit, so a machine where they differ fails it.

Per policy step (the goal, in the arm's base frame ``(p_b, R_b)``, from the achieved pose ``(p, R)``
and the scaled action ``(dp, dr)``):

    p_goal = R_b^T (p - p_b) + dp,        R_goal = exp(dr) R_b^T R,
    x_d = p_b + R_b p_goal,               R_d = R_b R_goal.

Per substep, after ``mj_step1`` (Jacobian ``J = [J_p; J_r]`` of the gripper site, joint-space mass
matrix ``M``, bias forces ``c = qfrc_bias``):

    e_p = x_d - x,  e_r = 1/2 sum_i r_i x r_d,i,      v = J_p qdot,  w = J_r qdot,
    F = kp e_p - kd v,                   T = kp e_r - kd w,
    Lambda_p = pinv(J_p M^-1 J_p^T),     Lambda_r = pinv(J_r M^-1 J_r^T),
    Lambda = pinv(J M^-1 J^T),           N = I - M^-1 J^T Lambda J,
    tau = J^T [Lambda_p F; Lambda_r T] + c + N^T M (k_n (q_0 - q) - 2 sqrt(k_n) qdot),  k_n = 10,

clipped to the actuators' control range (``uncouple_pos_ori=True``: position and orientation are
decoupled by their own task-space inertias). The base of a fixed-base arm does not move, so the
base-velocity terms robosuite subtracts from ``v`` and ``w`` vanish. The gripper command is constant
over a step: ``u = b + w_g a_g`` with the gripper model's formatted action ``a_g``, ``b`` and ``w_g``
the centre and half-width of its actuators' range.

Observables are sampled the way robosuite's ``Observable.update`` samples them (one shared clock,
advanced by the model timestep at each substep), but only those asked for and the ones their
sensors read from the observation cache. What is skipped: robosuite's per-robot history buffers
(``recent_qpos``, ``recent_ee_acc``, ...), which no task reward or observable here reads.
"""
from __future__ import annotations

import functools
from typing import Sequence

import mujoco
import numba
import numpy as np
from robosuite.utils import transform_utils
from robosuite.utils.control_utils import nullspace_torques, opspace_matrices, orientation_error

from drltg.errors import UsageError


class _Recorder(dict):
    """An observation cache that records which keys a sensor looks up."""

    def __init__(self, values):
        super().__init__(values)
        self.read: set[str] = set()

    def __contains__(self, key):
        self.read.add(key)
        return super().__contains__(key)

    def __getitem__(self, key):
        self.read.add(key)
        return super().__getitem__(key)

    def get(self, key, default=None):
        self.read.add(key)
        return super().get(key, default)


def _indexer(indexes: Sequence[int]):
    """A slice when ``indexes`` are consecutive (a view, same values as the fancy-indexed copy)."""
    indexes = [int(i) for i in indexes]
    if indexes == list(range(indexes[0], indexes[0] + len(indexes))):
        return slice(indexes[0], indexes[0] + len(indexes))
    return indexes


@numba.njit(cache=True)
def osc_torques(fresh, jacp, jacr, full_mass, site_xpos, site_xmat, qpos, qvel, qfrc_bias, site, dofs, qadr,
                x, R, v, w, J_full, J_pos, J_ori, mass, joint_pos, joint_vel,
                x_d, R_d, kp, kd, initial_joint, low, high):
    """The arm's clipped OSC torque for one substep, built on robosuite's own numba kernels.

    With ``fresh`` the arm state (``x, R, v, w``, the Jacobians, the arm's block of the mass matrix, joint
    positions and velocities) is first read into the given buffers from MuJoCo's arrays; otherwise the
    buffers hold it already. The matrix products run on the same array layouts as robosuite's NumPy
    ones (the mass matrix Fortran-ordered, as robosuite's fancy indexing leaves it; ``J^T`` a transposed
    view), so BLAS takes the same routines (``gemv`` transposed or not) and the torques agree bit for
    bit with robosuite's.
    """
    if fresh:
        for i in range(3):
            x[i] = site_xpos[site, i]
            for j in range(3):
                R[i, j] = site_xmat[site, 3 * i + j]
        v[:] = np.dot(jacp, qvel)
        w[:] = np.dot(jacr, qvel)
        for j in range(dofs.size):
            for i in range(3):
                J_pos[i, j] = jacp[i, dofs[j]]
                J_ori[i, j] = jacr[i, dofs[j]]
                J_full[i, j] = jacp[i, dofs[j]]
                J_full[3 + i, j] = jacr[i, dofs[j]]
            for i in range(dofs.size):
                mass[i, j] = full_mass[dofs[i], dofs[j]]
            joint_pos[j] = qpos[qadr[j]]
            joint_vel[j] = qvel[dofs[j]]
    force = (x_d - x) * kp[0:3] + -v * kd[0:3]
    torque = orientation_error(R_d, R) * kp[3:6] + -w * kd[3:6]
    _, lambda_pos, lambda_ori, nullspace = opspace_matrices(mass, J_full, J_pos, J_ori)
    wrench = np.concatenate((np.dot(lambda_pos, force), np.dot(lambda_ori, torque)))
    tau = np.dot(J_full.T, wrench) + qfrc_bias[dofs]
    tau += nullspace_torques(mass, nullspace, initial_joint, joint_pos, joint_vel)
    return np.clip(tau, low, high)


@numba.njit(cache=True)
def _numba_products(jac, qvel, lam, force, J_full, wrench):
    return np.dot(jac, qvel), np.dot(lam, force), np.dot(J_full.T, wrench)


@functools.cache
def blas_agrees(trials: int = 32) -> bool:
    """Whether numba's matrix-vector products (SciPy's OpenBLAS) round as NumPy's (NumPy's own OpenBLAS) for
    the shapes and layouts of :func:`osc_torques`, on random inputs. The two builds pick their kernels by CPU:
    on some (AVX-512 ones among them) they pick different ones and the sums round differently, so the lean step
    would drift from robosuite's by rounding, then by contacts. Setting ``OPENBLAS_CORETYPE`` (e.g. ``Haswell``)
    before Python starts makes both pick the same kernel."""
    rng = np.random.default_rng(0)
    for _ in range(trials):
        jac, qvel = rng.standard_normal((3, 9)), rng.standard_normal(9)
        lam, force = rng.standard_normal((3, 3)), rng.standard_normal(3)
        J_full, wrench = rng.standard_normal((6, 7)), rng.standard_normal(6)
        ours = _numba_products(jac, qvel, lam, force, J_full, wrench)
        theirs = (np.dot(jac, qvel), np.dot(lam, force), np.dot(J_full.T, wrench))
        if not all(np.array_equal(a, b) for a, b in zip(ours, theirs)):
            return False
    return True


def unsupported_reason(env) -> str | None:
    """Why :class:`LeanStep` cannot step ``env`` exactly as robosuite does, or ``None`` if it can."""
    from robosuite import macros
    from robosuite.controllers.parts.arm.osc import OperationalSpaceController
    from robosuite.controllers.parts.gripper.simple_grip import SimpleGripController
    from robosuite.robots.fixed_base_robot import FixedBaseRobot
    from robosuite.utils import observables as rs_obs

    if not macros.ENABLE_NUMBA:
        return "robosuite's numba kernels (robosuite.macros.ENABLE_NUMBA)"
    if len(env.robots) != 1 or not isinstance(env.robots[0], FixedBaseRobot):
        return "one fixed-base robot"
    robot = env.robots[0]
    if not env.lite_physics or env.viewer is not None or env.hard_reset:
        return "lite_physics, no viewer and hard_reset=False (one simulation for the env's lifetime)"
    parts = robot.composite_controller.part_controllers
    if type(robot.composite_controller).__name__ != "CompositeController" or len(robot.arms) != 1:
        return "robosuite's BASIC composite controller on one arm"
    arm_name = robot.arms[0]
    arm = parts.get(arm_name)
    if type(arm) is not OperationalSpaceController:
        return "an OSC arm controller"
    if not (
        arm.use_ori and arm.uncoupling and arm.lite_physics and arm.impedance_mode == "fixed"
        and arm.input_type == "delta" and arm.input_ref_frame == "base" and arm._goal_update_mode == "achieved"
        and arm.interpolator_pos is None and arm.interpolator_ori is None and arm.num_ref_sites == 1
        and arm.position_limits is None and not np.array(arm.orientation_limits).any()
    ):
        return "OSC_POSE with fixed impedance, delta input in the base frame, no interpolation"
    gripper_name = robot.get_gripper_name(arm_name) if robot.has_gripper[arm_name] else None
    if set(parts) != {arm_name, gripper_name} - {None}:
        return "the arm and its gripper as the only controlled parts"
    if gripper_name is not None:
        grip = parts[gripper_name]
        if type(grip) is not SimpleGripController or grip.interpolator is not None or not grip.use_action_scaling:
            return "robosuite's simple gripper controller without interpolation"
    model = env.sim.model._model
    center = model.site(f"{arm.naming_prefix}{arm.part_name}_center").id
    if model.body_weldid[model.site_bodyid[center]] != 0:
        return "an arm base welded to the world"
    for observable in env._observables.values():
        if (
            observable._corrupter is not rs_obs.NO_CORRUPTION or observable._filter is not rs_obs.NO_FILTER
            or observable._delayer is not rs_obs.NO_DELAY or not observable.is_enabled()
            or observable._sampling_timestep != 1.0 / env.control_freq
        ):
            return "observables sampled at the control frequency without corruption, filter or delay"
    return None


class LeanStep:
    """``env.step(action)`` of a robosuite environment, the same physics with less Python per substep.

    Args:
        env: a robosuite environment (``lite_physics``, one fixed-base arm, OSC_POSE and a simple
            gripper controller; :func:`unsupported_reason` says what is missing otherwise).
        observables: the observable names whose values :meth:`step` refreshes (with those their
            sensors read from the observation cache).

    :meth:`step` returns the reward; :attr:`values` holds each listed observable's value after the
    step, as ``env.step`` would return it. Reset through robosuite (``env.reset()``): this class
    keeps no episode state, it reads the controller's nullspace posture and gains at every step.
    """

    def __init__(self, env, observables: Sequence[str]):
        reason = unsupported_reason(env)
        if reason is not None:
            raise UsageError(f"the lean robosuite step needs {reason}; build the env with fast=False.")
        self.env = env
        robot = env.robots[0]
        arm_name = robot.arms[0]
        composite = robot.composite_controller
        # robosuite builds new controllers at every reset: they are looked up at every step.
        self._robot, self._arm_name = robot, arm_name
        arm = composite.part_controllers[arm_name]
        self._arm_actions = slice(*composite._action_split_indexes[arm_name])
        self._gripper_name = gripper_name = robot.get_gripper_name(arm_name) if robot.has_gripper[arm_name] else None
        if gripper_name is not None:
            self._gripper_model = robot.gripper[arm_name]
            self._grip_actions = slice(*composite._action_split_indexes[gripper_name])
            grip_actuators = robot._ref_actuators_indexes_dict[gripper_name]
            self._grip_ctrl = _indexer(grip_actuators)
            self._grip_range = env.sim.model.actuator_ctrlrange[grip_actuators].T.copy()
        self._model = model = env.sim.model._model
        self._data = env.sim.data._data
        self._substeps = int(env.control_timestep / env.model_timestep)

        self._site = model.site(arm.ref_name).id
        self._center = model.site(f"{arm.naming_prefix}{arm.part_name}_center").id
        self._dofs = np.asarray(arm.qvel_index, dtype=np.int64)
        self._qadr = np.asarray(arm.qpos_index, dtype=np.int64)
        arm_actuators = robot._ref_actuators_indexes_dict[arm_name]
        self._arm_ctrl = _indexer(arm_actuators)
        self._arm_range = env.sim.model.actuator_ctrlrange[arm_actuators].T.copy()
        n = len(self._dofs)
        self._jacp, self._jacr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
        self._full_mass = np.zeros((model.nv, model.nv))
        # x, R, v, w, J, J_p, J_r, M (Fortran-ordered, as robosuite's fancy indexing leaves it), q, qdot
        self._state = (
            np.zeros(3), np.zeros((3, 3)), np.zeros(3), np.zeros(3), np.zeros((6, n)), np.zeros((3, n)),
            np.zeros((3, n)), np.zeros((n, n), order="F"), np.zeros(n), np.zeros(n),
        )
        self._set_observables(observables)

    def _set_observables(self, names: Sequence[str]) -> None:
        """The observables to refresh: ``names`` and, transitively, the cache entries their sensors read."""
        env = self.env
        current = {name: np.array(observable.obs) for name, observable in env._observables.items()}
        reads = {}
        for name, observable in env._observables.items():
            cache = _Recorder({**current, **env._obs_cache})
            observable._sensor(cache)
            reads[name] = cache.read & set(env._observables)
        needed, todo = set(), list(names)
        while todo:
            name = todo.pop()
            if name not in needed:
                needed.add(name)
                todo.extend(reads[name])
        self._observables = [(name, obs) for name, obs in env._observables.items() if name in needed]
        self._all_observables = list(env._observables.values())
        self.values = {name: obs.obs for name, obs in self._observables}

    def _sample(self) -> None:
        """What ``Observable.update`` stores when it samples: the sensor value, a scalar if it has one entry."""
        cache = self.env._obs_cache
        values = self.values
        for name, observable in self._observables:
            obs = np.array(observable._sensor(cache))
            value = obs[0] if len(obs.shape) == 1 and obs.shape[0] == 1 else obs
            cache[name] = np.array(value)
            values[name] = value

    def _goal(self, arm, delta: np.ndarray, ref_pos: np.ndarray, ref_ori: np.ndarray):
        """The step's goal in the world frame, ``(x_d, R_d)``, from the achieved pose and the scaled action,
        computed with robosuite's own transforms."""
        T, data = transform_utils, self._data
        origin_pos = np.array(data.site_xpos[self._center])
        origin_ori = np.array(data.site_xmat[self._center].reshape([3, 3]))
        origin_inv = T.pose_inv(T.make_pose(origin_pos, origin_ori))
        world = np.eye(4)
        world[:3, 3] = ref_pos
        goal_pos = T.pose_in_A_to_pose_in_B(world, origin_inv)[:3, 3] + delta[0:3]
        eef_in_origin = T.pose_in_A_to_pose_in_B(T.make_pose(ref_pos, ref_ori), origin_inv)[:3, :3]
        goal_ori = np.dot(T.quat2mat(T.axisangle2quat(delta[3:6])), eef_in_origin)
        arm.goal_pos, arm.goal_ori = goal_pos, goal_ori
        return origin_pos + np.dot(origin_ori, goal_pos), np.dot(origin_ori, goal_ori)

    def _gripper_command(self, grip, action: np.ndarray) -> np.ndarray:
        goal = grip.scale_action(self._gripper_model.format_action(action))
        grip.goal_qvel = goal
        ctrl_range = np.stack([grip.actuator_min, grip.actuator_max], axis=-1)
        bias = 0.5 * (ctrl_range[:, 1] + ctrl_range[:, 0])
        weight = 0.5 * (ctrl_range[:, 1] - ctrl_range[:, 0])
        return np.clip(bias + weight * np.array(goal), *self._grip_range)

    def step(self, action: np.ndarray) -> float:
        """One policy step: ``env.step(action)``'s physics, clock, reward and observables; returns the reward."""
        env = self.env
        if env.done:
            raise ValueError("executing action in terminated episode")
        if len(action) != env.action_dim:
            raise ValueError(f"expected an action of size {env.action_dim}, got {len(action)}")
        env.timestep += 1
        model, data = self._model, self._data
        parts = self._robot.composite_controller.part_controllers
        arm = parts[self._arm_name]
        step1, step2, jac_site, full_m = mujoco.mj_step1, mujoco.mj_step2, mujoco.mj_jacSite, mujoco.mj_fullM
        site, jacp, jacr, full_mass = self._site, self._jacp, self._jacr, self._full_mass
        dofs, qadr = self._dofs, self._qadr
        site_xpos, site_xmat, qpos, qvel, qfrc_bias, qM, ctrl = (
            data.site_xpos, data.site_xmat, data.qpos, data.qvel, data.qfrc_bias, data.qM, data.ctrl,
        )
        kp, kd, initial_joint = arm.kp, arm.kd, arm.initial_joint
        (low, high), arm_ctrl = self._arm_range, self._arm_ctrl
        # robosuite's controller skips its state update until it has run once since its last update (at
        # reset, before the gripper was posed): then the first substep uses that older state.
        stale = not arm.new_update
        clock = self._all_observables[0]
        elapsed, sampled, period = clock._time_since_last_sample, clock._sampled, clock._sampling_timestep
        dt = env.model_timestep

        for substep in range(self._substeps):
            step1(model, data)
            if substep == 0:
                if stale:
                    state = (arm.ref_pos, arm.ref_ori_mat, arm.ref_pos_vel, arm.ref_ori_vel, arm.J_full, arm.J_pos,
                             arm.J_ori, arm.mass_matrix, arm.joint_pos, arm.joint_vel)
                    ref_pos, ref_ori = arm.ref_pos, arm.ref_ori_mat
                else:
                    state = self._state
                    ref_pos = np.array(site_xpos[site])
                    ref_ori = np.array(site_xmat[site].reshape([3, 3]))
                x_d, R_d = self._goal(arm, arm.scale_action(action[self._arm_actions]), ref_pos, ref_ori)
                if self._gripper_name is not None:
                    grip = parts[self._gripper_name]
                    ctrl[self._grip_ctrl] = self._gripper_command(grip, action[self._grip_actions])
                fresh = not stale
            else:
                state, fresh = self._state, True
            if fresh:
                jac_site(model, data, jacp, jacr, site)
                full_m(model, full_mass, qM)
            ctrl[arm_ctrl] = osc_torques(
                fresh, jacp, jacr, full_mass, site_xpos, site_xmat, qpos, qvel, qfrc_bias, site, dofs, qadr,
                *state, x_d, R_d, kp, kd, initial_joint, low, high,
            )
            step2(model, data)

            elapsed += dt
            if not sampled and period >= elapsed:
                self._sample()
                sampled = True
            if elapsed >= period:
                if not sampled:
                    self._sample()
                elapsed %= period
                sampled = False

        arm.new_update = True
        for observable in self._all_observables:
            observable._time_since_last_sample = elapsed
            observable._sampled = sampled
        for name, observable in self._observables:
            observable._current_observed_value = self.values[name]
        env.cur_time += env.control_timestep
        reward, _, _ = env._post_action(action)
        return reward
