"""robosuite manipulation tasks: specs, observation layout, truncation, success checks, demonstrator,
barrier, potentials, parallel workers, rendering and the video command.

One env per task is shared by the whole module (building one takes ~2 s)."""
from __future__ import annotations

import math
import os

import numpy as np
import pytest
import torch

pytest.importorskip("robosuite")

from torchrl.envs import TransformedEnv  # noqa: E402
from torchrl.envs.utils import check_env_specs  # noqa: E402

from drltg.envs import get_task, make_env  # noqa: E402
from drltg.envs.robosuite import (  # noqa: E402
    LAYOUT,
    OBSERVABLES,
    OBSERVATION_SIZE,
    Carry,
    Grasp,
    LiftHeight,
    LiftPotential,
    PickPlaceDemonstrator,
    PlacePotential,
    Reach,
    RobosuiteEnv,
    demonstrator_for,
    make_robosuite_env,
    potential_for,
)
from drltg.envs.robosuite.fast_osc import blas_agrees  # noqa: E402
from drltg.envs.robosuite.layout import LIFT_MARGIN, TABLE_TOP_Z, TARGET_RADIUS, TARGET_XY  # noqa: E402
from drltg.transforms import PotentialShaping  # noqa: E402

TASKS = ("lift", "lift-place", "lift-place-barrier")


@pytest.fixture(scope="module")
def envs():
    built = {task: RobosuiteEnv(task, seed=0) for task in TASKS}
    yield built
    for env in built.values():
        env.close()


def part(td, name):
    return td["observation"][..., LAYOUT[name]]


def drive(env, td, goal, steps, grip=1.0):
    """Move the gripper towards ``goal`` (a position or a function of the TensorDict) for ``steps``."""
    trajectory = []
    for _ in range(steps):
        target = torch.as_tensor(goal(td) if callable(goal) else goal, dtype=torch.float32)
        action = torch.zeros(7)
        action[:3] = ((target - part(td, "robot0_eef_pos")) / 0.05).clamp(-1, 1)
        action[6] = grip
        td = env.step(td.set("action", action))["next"]
        trajectory.append(td.clone())
    return td, trajectory


@pytest.mark.parametrize("task", TASKS)
def test_specs_pass_torchrl_checks(envs, task):
    env = envs[task]
    check_env_specs(env, seed=0)
    assert env.observation_spec["observation"].shape == (OBSERVATION_SIZE,)
    assert env.observation_spec["observation"].dtype == torch.float32
    assert env.action_spec.shape == (7,)
    assert torch.equal(env.action_spec.space.low, -torch.ones(7))
    assert torch.equal(env.action_spec.space.high, torch.ones(7))


@pytest.mark.parametrize("task", TASKS)
def test_observation_holds_each_listed_observable_once(envs, task):
    env = envs[task]
    td = env.reset()
    raw = env.robosuite_env._get_observations(force_update=True)
    assert list(env.layout) == list(OBSERVABLES) and not any(name.endswith("-state") for name in env.layout)
    assert sum(np.size(raw[name]) for name in OBSERVABLES) == OBSERVATION_SIZE == 50
    for name, where in env.layout.items():
        assert td["observation"][where].numpy() == pytest.approx(np.ravel(raw[name]).astype(np.float32), abs=1e-6), name
    cube, target = part(td, "cube_pos"), part(td, "target_pos")
    assert torch.allclose(part(td, "gripper_to_cube_pos"), cube - part(td, "robot0_eef_pos"), atol=1e-6)
    assert torch.allclose(part(td, "cube_to_target_pos"), target - cube, atol=1e-6)
    assert target.tolist() == pytest.approx([*TARGET_XY, TABLE_TOP_Z + 0.002])
    assert part(td, "cube_grasped").item() == 0.0 and part(td, "cube_lifted").item() == 0.0


def test_horizon_is_a_truncation_not_a_termination(envs, monkeypatch):
    env = envs["lift"]
    monkeypatch.setattr(env, "horizon", 4)
    td = env.rollout(10, break_when_any_done=True)
    assert td.shape == (4,)
    assert td["next", "step_count"].squeeze(-1).tolist() == [1, 2, 3, 4]
    assert td["next", "truncated"].squeeze(-1).tolist() == [False, False, False, True]
    assert not td["next", "terminated"].any()
    assert torch.equal(td["next", "done"], td["next", "truncated"])
    assert env.reset()["step_count"].item() == 0


def _random_actions(seed):
    rng = np.random.default_rng(seed)
    return lambda td: torch.as_tensor(rng.uniform(-1.0, 1.0, 7), dtype=torch.float32)


@pytest.mark.parametrize("task", TASKS)
def test_fast_step_reproduces_robosuites_step_exactly(envs, task):
    """The lean step (the default) and robosuite's ``env.step`` (``fast=False``), same seed and actions:
    identical positions, velocities, observations, rewards and success, step for step, over two episodes
    (robosuite rebuilds its controllers at each reset; the first step after a reset uses the state the
    controller saw at reset)."""
    fast, robosuite = envs[task], RobosuiteEnv(task, seed=0, fast=False)
    # where the two BLAS builds round alike (make test pins OpenBLAS's kernel so they do) the lean step runs;
    # elsewhere the env falls back to robosuite's own step, and the trajectories agree all the same
    assert (fast._lean is not None) == blas_agrees() and robosuite._lean is None
    fast.set_seed(1)
    robosuite.set_seed(1)
    demonstrator = demonstrator_for(task)
    grasped = []
    try:
        for policy, steps in ((demonstrator.act, 50), (_random_actions(0), 30)):
            a, b = fast.reset(), robosuite.reset()
            for _ in range(steps):
                action = policy(a["observation"])
                a = fast.step(a.set("action", action))["next"]
                b = robosuite.step(b.set("action", action.clone()))["next"]
                sa, sb = fast.robosuite_env.sim.data, robosuite.robosuite_env.sim.data
                assert np.array_equal(sa.qpos, sb.qpos) and np.array_equal(sa.qvel, sb.qvel)
                for key in ("observation", "reward", "success", "done"):
                    assert torch.equal(a[key], b[key]), key
                grasped.append(part(a, "cube_grasped").item())
    finally:
        robosuite.close()
    assert any(grasped[:50]), "the demonstrator never grasped: the contact-rich part went untested"
    # robosuite's own observation dict, read without an update, holds what the lean step computed
    raw = fast.robosuite_env._get_observations()
    for name, where in fast.layout.items():
        assert np.array_equal(np.ravel(raw[name]).astype(np.float32), a["observation"][where].numpy()), name


def test_fast_step_refuses_a_controller_it_does_not_reproduce():
    from robosuite.controllers.parts.arm.osc import OperationalSpaceController

    from drltg.envs.robosuite.fast_osc import LeanStep, unsupported_reason
    from drltg.errors import UsageError

    env = RobosuiteEnv("lift", seed=0, fast=False)
    try:
        rs = env.robosuite_env
        assert unsupported_reason(rs) is None
        arm = rs.robots[0].composite_controller.part_controllers["right"]
        assert isinstance(arm, OperationalSpaceController)
        arm.impedance_mode = "variable_kp"
        with pytest.raises(UsageError, match="fixed impedance.*fast=False"):
            LeanStep(rs, env.observables)
    finally:
        env.close()


def test_set_seed_reproduces_and_varies_the_initial_state(envs):
    env = envs["lift"]
    env.set_seed(5)
    a = env.rollout(5, demonstrator_for("lift"))["next", "observation"]
    env.set_seed(6)
    c = env.reset()["observation"]
    fresh = make_env("lift", seed=5)  # another env: same scene (cube size), same episode
    b = fresh.rollout(5, demonstrator_for("lift"))["next", "observation"]
    fresh.close()
    assert torch.equal(a, b)
    assert not torch.allclose(a[0, LAYOUT["cube_pos"]], c[LAYOUT["cube_pos"]])


def test_terminate_on_success_ends_the_episode_as_terminated(envs, monkeypatch):
    env = envs["lift"]
    monkeypatch.setattr(env, "terminate_on_success", True)
    env.set_seed(0)
    td = env.rollout(100, demonstrator_for("lift"), break_when_any_done=True)
    assert td["next", "success"][-1].item() and td["next", "terminated"][-1].item()
    assert not td["next", "truncated"].any() and td["next", "success"].sum().item() == 1


@pytest.mark.parametrize("task", TASKS)
@pytest.mark.parametrize("seed", [0, 1])
def test_demonstrator_solves_the_task_and_reward_is_success(envs, task, seed):
    env = envs[task]
    env.set_seed(seed)
    barrier = env.robosuite_env.barrier_pos() if task == "lift-place-barrier" else None
    td = env.rollout(130, demonstrator_for(task), break_when_any_done=False)
    success = td["next", "success"].squeeze(-1)
    assert success.any(), "no success within 130 steps"
    first = int(success.float().argmax())
    assert success[first:].all(), "success is not kept once reached"
    # sparse reward: 1 exactly on success steps (robosuite's Lift and drltg's place tasks alike)
    assert torch.equal(td["next", "reward"].squeeze(-1), success.float())
    if task != "lift":
        assert (part(td["next"], "cube_grasped")[success] == 0).all(), "a held cube counted as placed"
        assert (part(td["next"], "cube_lifted")[success] == 1).all()
    # the lifted flag is the observation's latch, raised by the first step above the lift margin
    lifted = td["next", "lifted"].squeeze(-1)
    assert torch.equal(lifted.float(), part(td["next"], "cube_lifted").squeeze(-1))
    first_lift = int(lifted.float().argmax())
    above = part(td["next"], "cube_pos")[:, 2] > TABLE_TOP_Z + LIFT_MARGIN
    assert not td["lifted"][0] and lifted[first_lift:].all() and above[first_lift] and not above[:first_lift].any()
    if barrier is not None:
        assert np.abs(env.robosuite_env.barrier_pos() - barrier).max() < 1e-3
    phi = potential_for(task)(td["next", "observation"])
    assert phi[0].item() < 0.2 and phi[-1].item() > 0.9


def test_evaluation_counts_episodes_that_lift_apart_from_those_that_place():
    from drltg.training.loop import evaluate

    env = make_robosuite_env("lift-place", batch_size=(2,), parallel=False, seed=0, horizon=150)
    try:
        lifting_only = evaluate(env, demonstrator_for("lift"))
        placing = evaluate(env, demonstrator_for("lift-place"))
    finally:
        env.close()
    assert lifting_only["success_rate"] == 0.0 and lifting_only["lifted_rate"] == 1.0
    assert lifting_only["return_mean"] == 0.0
    assert placing["success_rate"] == 1.0 and placing["lifted_rate"] == 1.0 and placing["return_mean"] > 0


def test_pushing_the_cube_onto_the_target_is_not_placing(envs):
    env = envs["lift-place"]
    rs = env.robosuite_env
    env.set_seed(0)
    td = env.reset()
    x, y, _ = part(td, "cube_pos").tolist()
    td, _ = drive(env, td, [x, y - 0.08, TABLE_TOP_Z + 0.10], 30)  # above the table, behind the cube
    td, _ = drive(env, td, [x, y - 0.08, TABLE_TOP_Z + 0.025], 25)  # down to the table

    def push(td):  # aim just past the cube's near face, so the closed fingers shove it along +y
        x, y, _ = part(td, "cube_pos").tolist()
        return [x, y - 0.015, TABLE_TOP_Z + 0.025]

    td, pushed = drive(env, td, push, 150)
    back_off = torch.tensor([0.0, -0.05, 0.05])
    td, backed_off = drive(env, td, lambda td: part(td, "robot0_eef_pos") + back_off, 15, grip=-1.0)
    trajectory = pushed + backed_off
    # the cube ended up on the disc: inside its radius, touching it, resting, not held ...
    assert part(td, "cube_to_target_pos")[:2].norm().item() < TARGET_RADIUS
    assert rs.check_contact(rs.cube, rs.target) and not rs.cube_grasped()
    assert part(td, "cube_pos")[2].item() < TABLE_TOP_Z + 0.002 + rs.cube.size[2] + 0.005
    # ... but it was never lifted, so no step counts as a success or earns reward
    assert all(x["observation"][LAYOUT["cube_lifted"]].item() == 0.0 for x in trajectory)
    assert not any(x["success"].item() or x["reward"].item() or x["lifted"].item() for x in trajectory)
    # ... and the episode flag an evaluation counts as pushed_rate says so, from the step the cube touched the disc
    touched = [x["pushed"].item() for x in trajectory]
    assert not touched[0] and touched[-1] and touched.index(True) > 0
    # lifting is the only missing condition
    rs._was_lifted = True
    assert rs._check_success()


def test_barrier_stays_put_when_the_arm_drives_into_it(envs):
    env = envs["lift-place-barrier"]
    rs = env.robosuite_env
    env.set_seed(0)
    td = env.reset()
    start = rs.barrier_pos()
    td, _ = drive(env, td, [0.08, 0.12, 0.95], 30)
    td, _ = drive(env, td, [0.08, 0.12, TABLE_TOP_Z + 0.05], 25)
    for _ in range(60):
        td = env.step(td.set("action", torch.tensor([0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0])))["next"]
    sim = rs.sim
    touching = {
        sim.model.geom_id2name(g)
        for c in sim.data.contact[: sim.data.ncon]
        for g in (c.geom1, c.geom2)
        if "barrier" in str(sim.model.geom_id2name(c.geom1)) + str(sim.model.geom_id2name(c.geom2))
    }
    assert any(name.startswith("gripper0") for name in touching), "the arm never reached the barrier"
    assert np.abs(rs.barrier_pos() - start).max() < 2e-3


def test_potential_terms_match_hand_computed_values():
    def approx(values):  # float32 arithmetic
        return pytest.approx(values, abs=1e-5)

    obs = torch.zeros(2, OBSERVATION_SIZE)
    obs[:, LAYOUT["gripper_to_cube_pos"]] = torch.tensor([0.03, 0.04, 0.0])
    obs[0, LAYOUT["cube_pos"]] = torch.tensor([0.0, 0.0, TABLE_TOP_Z + 0.031])
    obs[1, LAYOUT["cube_pos"]] = torch.tensor([0.0, 0.0, TABLE_TOP_Z + 0.010])
    obs[:, LAYOUT["cube_to_target_pos"]] = torch.tensor([0.3, 0.4, -0.5])
    obs[0, LAYOUT["cube_grasped"]] = 1.0
    obs[0, LAYOUT["cube_lifted"]] = 1.0
    reach = 1 - math.tanh(10 * 0.05)
    carry = 1 - math.tanh(5 * 0.5)
    assert Reach()(obs).squeeze(-1).tolist() == approx([reach, reach])
    assert Grasp()(obs).squeeze(-1).tolist() == [1.0, 0.0]
    assert LiftHeight()(obs).squeeze(-1).tolist() == approx([(0.031 - 0.022) / (0.04 - 0.022), 0.0])
    assert Carry()(obs).squeeze(-1).tolist() == approx([carry, 0.0])  # not lifted: no credit
    assert LiftPotential()(obs).squeeze(-1).tolist() == approx([(reach + 0.25 + 0.5) / 2.25, reach / 2.25])
    assert PlacePotential()(obs).squeeze(-1).tolist() == approx([0.5 + 0.5 * carry, 0.1 * reach])
    assert PlacePotential()(obs).shape == (2, 1)


def test_shaped_reward_is_gamma_phi_next_minus_phi(envs):
    env = TransformedEnv(envs["lift"], PotentialShaping(LiftPotential(), gamma=0.9))
    env.set_seed(0)
    td = env.rollout(3, demonstrator_for("lift"))
    phi = LiftPotential()
    expected = 0.9 * phi(td["next", "observation"]) - phi(td["observation"])
    assert torch.allclose(td["next", "reward"] - td["next", "task_reward"], expected, atol=1e-6)
    assert get_task("lift").potential({"task": "lift"}).__class__ is LiftPotential


def test_demonstrator_is_a_function_of_the_observation_batch(envs):
    env = envs["lift-place"]
    env.set_seed(0)
    rows = env.rollout(40, demonstrator_for("lift-place"))["observation"]
    policy = PickPlaceDemonstrator(place=True)
    batched = policy.act(rows)
    assert batched.shape == (40, 7) and batched.abs().max() <= 1.0
    assert torch.equal(batched[17], policy.act(rows[17]))
    assert torch.equal(policy.act(rows.view(4, 10, -1)).view(40, 7), batched)


def test_registered_task_steps_two_parallel_workers():
    env = make_env("lift-place", batch_size=(2,), seed=3, parallel=True, mp_start_method="fork")  # spawn: ~10 s slower
    try:
        from torchrl.envs import ParallelEnv

        assert isinstance(env, ParallelEnv) and env.batch_size == (2,)
        td = env.rollout(3, PickPlaceDemonstrator(place=True))
        assert td.shape == (2, 3) and td["next", "observation"].shape == (2, 3, OBSERVATION_SIZE)
        assert td["next", "step_count"][:, -1].squeeze(-1).tolist() == [3, 3]
        cubes = td["observation"][:, 0, LAYOUT["cube_pos"]]
        assert not torch.allclose(cubes[0], cubes[1]), "both workers got the same seed"
    finally:
        env.close()


def test_a_batch_steps_the_same_in_worker_processes_or_in_this_one(monkeypatch):
    def rollout(**how):
        env = make_env("lift", batch_size=(3,), seed=5, **how)
        try:
            return type(env).__name__, env.rollout(4, PickPlaceDemonstrator(place=False))
        finally:
            env.close()

    monkeypatch.setattr(os, "cpu_count", lambda: 2)  # more envs than cores: they step in this process
    (auto, serial), (kind, parallel) = rollout(), rollout(parallel=True, mp_start_method="fork")
    assert (auto, kind) == ("SerialEnv", "ParallelEnv")
    for key in [("next", "observation"), ("next", "reward"), "action"]:
        assert torch.equal(serial[key], parallel[key]), key


def _renderable_env():
    env = RobosuiteEnv("lift", seed=0, render_size=(64, 64))
    try:
        env.render()
    except Exception as err:  # no GL backend on this host
        env.close()
        pytest.skip(f"no offscreen GL backend for MuJoCo (MUJOCO_GL=egl or osmesa): {err}")
    return env


def test_render_writes_a_non_blank_frame_and_video_writes_files(tmp_path):
    env = _renderable_env()
    frame = env.render(env.reset())
    env.close()
    assert frame.shape == (64, 64, 3) and frame.dtype == np.uint8
    assert frame.std() > 10 and len(np.unique(frame.reshape(-1, 3), axis=0)) > 50

    from drltg.cli import main

    assert main(["video", "demonstrator", "--task", "lift", "--out", str(tmp_path), "--max-steps", "3",
                 "--size", "32", "--format", "gif", "--strip", "2"]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "lift-demonstrator-seed0-ep0-filmstrip.png",
        "lift-demonstrator-seed0-ep0.gif",
    ]
    import imageio.v3 as iio

    assert iio.imread(tmp_path / "lift-demonstrator-seed0-ep0.gif", index=None).shape == (4, 32, 32, 3)


def test_video_names_a_missing_gl_library_in_one_sentence(tmp_path, monkeypatch, capsys):
    import ctypes.util

    from drltg.cli import main

    monkeypatch.setenv("MUJOCO_GL", "osmesa")
    monkeypatch.setattr(ctypes.util, "find_library", lambda name: None)
    assert main(["video", "demonstrator", "--task", "lift", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "MUJOCO_GL=osmesa needs the OSMesa library" in err and "libosmesa6" in err
    assert list(tmp_path.iterdir()) == []


def _config(task, *overrides):
    from drltg import config

    return config.resolve({}, list(overrides), task=task, frames=1000, seed=0)


def test_demonstrator_as_past_policy_acts_through_the_reuse_mixer(envs):
    from tensordict.nn import TensorDictSequential
    from torchrl.envs.utils import ExplorationType, set_exploration_type

    from drltg.learners import make_agent
    from drltg.transfer import get_method, source

    cfg = _config("lift-place", "transfer.method=policy-reuse", "transfer.source=demonstrator:lift",
                  "transfer.upsilon=1.0", "network.hidden=[8,8]")
    source.check(cfg)  # no run directory needed
    past = source.source_actor(cfg)
    assert isinstance(past, PickPlaceDemonstrator) and not past.place  # lift's skill: reach, grasp, lift
    env = envs["lift-place"]
    env.set_seed(0)
    agent = make_agent(env, cfg)
    transfer = get_method("policy-reuse").build(cfg, agent, env, resuming=False)
    (primer,) = transfer.train_transforms  # declares the episode's choice of past policy, "reuse_index"
    td, policy = primer(env.reset()), TensorDictSequential(agent.policy, transfer.mixer)
    with torch.no_grad(), set_exploration_type(ExplorationType.RANDOM):
        out = policy(td.clone())
    assert out["reused"].item()  # psi_h = 1 * 1^h: the demonstrator always acts
    assert torch.equal(out["action"], past.act(td["observation"]))
    with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
        assert not policy(td.clone())["reused"].item()  # evaluation measures the learner


@pytest.mark.parametrize(
    "task, overrides, message",
    [
        ("lift-place", ["transfer.method=model-reuse", "transfer.source=demonstrator:lift"], "no weights"),
        ("lift-place", ["transfer.method=policy-reuse", "transfer.source=demonstrator:stack"], "solves lift"),
        ("fourrooms/northeast", ["transfer.method=policy-reuse", "transfer.source=demonstrator:lift"], "solves"),
    ],
)
def test_demonstrator_source_misuse_is_one_sentence(task, overrides, message):
    from drltg.errors import UsageError
    from drltg.transfer import source

    with pytest.raises(UsageError, match=message):
        source.check(_config(task, *overrides))


def test_lift_sparse_vs_shaped_uses_the_lift_potential_on_the_sparse_task():
    from drltg.transfer import get_method

    cfg = _config("lift", "transfer.method=reward-shaping")
    (shaping,) = get_method("reward-shaping").build(cfg, None, None, resuming=False).train_transforms
    assert isinstance(shaping.potential, LiftPotential) and shaping.gamma == cfg.optim.gamma
    assert get_task("lift").defaults == {"task": "lift"}  # the baseline learns from Lift's sparse reward


def test_lift_to_place_experiment_plans_sources_or_reuses_the_demonstrator(tmp_path):
    from drltg.experiments.experiment import plan_runs

    trained = plan_runs("lift-to-place", "policy-reuse", frames=100, seeds=2, out=tmp_path)
    assert [(role, cfg.task) for role, cfg, _ in trained] == [
        ("source", "lift"), ("baseline", "lift-place"), ("transfer", "lift-place")] * 2
    assert trained[2][1].transfer.source == str(trained[0][2])

    given = plan_runs("lift-to-place", "policy-reuse", frames=100, seeds=2, out=tmp_path,
                      overrides=["transfer.source=demonstrator:lift"])
    assert [(role, cfg.task, cfg.seed) for role, cfg, _ in given] == [
        ("baseline", "lift-place", 0), ("transfer", "lift-place", 0),
        ("baseline", "lift-place", 100), ("transfer", "lift-place", 100)]
    assert [cfg.transfer.source for _, cfg, _ in given] == [None, "demonstrator:lift"] * 2  # transfer runs only
    assert [cfg.transfer.method for _, cfg, _ in given] == ["none", "policy-reuse"] * 2

    shaping = plan_runs("lift", "reward-shaping", frames=100, seeds=1, out=tmp_path)
    assert [(role, cfg.task, cfg.transfer.method) for role, cfg, _ in shaping] == [
        ("baseline", "lift", "none"), ("transfer", "lift", "reward-shaping")]


def test_an_experiment_on_a_task_alone_needs_a_given_source(tmp_path):
    from drltg.errors import UsageError
    from drltg.experiments.experiment import plan_runs

    demos = plan_runs("lift", "demonstrations", frames=100, seeds=2, out=tmp_path,
                      overrides=["transfer.source=demonstrator:lift"])
    assert [(role, cfg.task, cfg.transfer.method) for role, cfg, _ in demos] == [
        ("baseline", "lift", "none"), ("transfer", "lift", "demonstrations")] * 2
    with pytest.raises(UsageError, match="'lift' is a task, not a pair: policy-reuse on it needs"):
        plan_runs("lift", "policy-reuse", frames=100, seeds=1, out=tmp_path)


def test_the_blas_probe_tells_apart_products_that_round_differently():
    """The probe compares numba's products with NumPy's on random inputs; the lean step is used exactly
    where it says they agree, and a process started with OPENBLAS_CORETYPE=Haswell agrees on any x86 CPU
    this suite runs on (both builds then take the same kernel)."""
    import os
    import subprocess
    import sys

    code = "from drltg.envs.robosuite.fast_osc import blas_agrees; print(blas_agrees())"
    pinned = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300,
                            env={**os.environ, "OPENBLAS_CORETYPE": "Haswell"})
    assert pinned.stdout.strip() == "True", pinned.stderr[-2000:]
    assert (RobosuiteEnv("lift", seed=0)._lean is not None) == blas_agrees()
