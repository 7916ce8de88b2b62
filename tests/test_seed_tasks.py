"""The earlier implementation's place reward on drltg's scenes (``lift-place-seed``,
``lift-place-barrier-seed``): hand-computed states, the bound of one per step, the pushing flag."""
from __future__ import annotations

import math

import numpy as np
import pytest
import torch

pytest.importorskip("robosuite")

from torchrl.envs.utils import check_env_specs  # noqa: E402

from drltg.envs import get_pair, make_env  # noqa: E402
from drltg.envs.robosuite import RobosuiteEnv  # noqa: E402
from drltg.envs.robosuite.layout import TABLE_TOP_Z, TARGET_HALF_HEIGHT, TARGET_XY  # noqa: E402

TARGET = np.array([*TARGET_XY, TABLE_TOP_Z + 2 * TARGET_HALF_HEIGHT])


@pytest.fixture(scope="module", params=["lift-place-seed", "lift-place-barrier-seed"])
def env(request):
    env = RobosuiteEnv(request.param, seed=0)
    env.reset()
    yield env
    env.close()


def put_cube(rs, xyz):
    """Place the cube's centre at ``xyz`` (no rotation) and recompute positions and contacts."""
    rs.sim.data.set_joint_qpos(rs.cube.joints[0], np.array([*xyz, 1.0, 0.0, 0.0, 0.0]))
    rs.sim.forward()


def grip_site(rs):
    (gripper,) = rs.robots[0].gripper.values()  # one arm
    return np.array(rs.sim.data.get_site_xpos(gripper.important_sites["grip_site"]))


def expected(gripper, cube, grasped=False):
    """The reward written out by hand from the positions (no contact)."""
    lifted = cube[2] > TABLE_TOP_Z + 0.04
    total = (1 - math.tanh(10 * np.linalg.norm(gripper - cube)) + 0.25 * grasped + 0.5 * lifted
             + 1 - math.tanh(10 * np.linalg.norm(cube - TARGET)))
    return total / 3.25


def test_specs_and_pairs(env):
    check_env_specs(env)
    assert "pushed" in env.observation_spec.keys()
    assert get_pair("lift-dense-to-place-seed").target == "lift-place-seed"
    assert get_pair("lift-dense-to-place-barrier-seed").target == "lift-place-barrier-seed"


def test_reach_and_place_terms_on_the_table(env):
    rs = env.robosuite_env
    cube = np.array([0.05, -0.02, TABLE_TOP_Z + rs.cube.size[2]])
    put_cube(rs, cube)
    assert not rs.cube_on_target() and not rs.cube_grasped()
    assert rs.reward() == pytest.approx(expected(grip_site(rs), cube), abs=1e-9)


def test_a_lifted_cube_earns_the_lift_term(env):
    rs = env.robosuite_env
    cube = np.array([0.0, 0.1, TABLE_TOP_Z + 0.15])  # in the air, away from gripper and target
    put_cube(rs, cube)
    value = rs.reward()
    assert value == pytest.approx(expected(grip_site(rs), cube), abs=1e-9)
    put_cube(rs, cube - [0, 0, 0.12])  # 3 cm above the table: below the lift line
    assert value - rs.reward() > 0.5 / 3.25 - 0.05  # the 0.5 step, less the small change in the distances


def test_a_grasp_adds_a_quarter(env, monkeypatch):
    rs = env.robosuite_env
    cube = np.array([0.02, 0.0, TABLE_TOP_Z + rs.cube.size[2]])
    put_cube(rs, cube)
    without = rs.reward()
    monkeypatch.setattr(rs, "_check_grasp", lambda **_: True)
    assert rs.reward() - without == pytest.approx(0.25 / 3.25, abs=1e-12)
    assert rs.reward() == pytest.approx(expected(grip_site(rs), cube, grasped=True), abs=1e-9)


def test_contact_with_the_target_pays_one_and_pushed_tells_it_from_placing(env):
    rs = env.robosuite_env
    rs._was_lifted = False
    put_cube(rs, [*TARGET_XY, TARGET[2] + rs.cube.size[2] - 5e-4])  # resting on the disc
    assert rs.cube_on_target()
    assert rs.reward() == 1.0
    assert rs.cube_pushed() and not rs._check_success()  # there without a lift: pushed, not placed
    rs._was_lifted = True
    assert rs.reward() == 1.0 and not rs.cube_pushed() and rs._check_success()
    rs._was_lifted = False


def test_a_step_never_pays_more_than_one():
    """Random play (the bound itself: the non-contact terms sum to at most 2.75 < 3.25)."""
    env = make_env("lift-place-seed", seed=3)
    td = env.reset()
    generator = torch.Generator().manual_seed(0)
    rewards = []
    for _ in range(150):
        td = env.step(td.set("action", torch.rand(7, generator=generator) * 2 - 1))["next"]
        rewards.append(td["reward"].item())
    env.close()
    assert 0.0 <= min(rewards) and max(rewards) <= 1.0
    assert 1 + 0.25 + 0.5 + 1 < 3.25
