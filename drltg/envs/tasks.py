"""The built-in tasks and pairs: continuous and grid FourRooms, the robosuite manipulation tasks and
Gymnasium's Pendulum, each with the training settings measured to work on it (``train``), its return range
and, where it has one, its shaping potential. Importing :mod:`drltg.envs` registers them; factories and
potentials are named ``"module:attr"`` and the FourRooms tasks declare their options, so registering and
checking a config import neither torch nor a simulator (a manipulation task's options are read from its
factory's signature: checking them imports torch, not robosuite)."""
from __future__ import annotations

import functools
import importlib
import math
from typing import Any

from drltg.envs.registry import register_pair, register_task

# Measured: with SAC's default alpha_init=1.0 the entropy bonus outweighs the sparse goal reward and
# SAC does not learn FourRooms in 200k frames; with alpha_init=0.01 and 2x64 nets the 11 committed
# FourRooms sources (results/sweep-fourrooms-graded/*/sac/source, results/demo/source) succeed 0.34 of the
# time on average at 10k frames, 0.52 at 30k and 0.82 at 40k.
ROOMS_TRAIN = {"sac": {"alpha_init": 0.01}, "network": {"hidden": [64, 64]}}
# Discrete SAC's automatic temperature aims at TorchRL's default entropy, 0.98 log 4 on the grid: the
# policy is kept near uniform and its greedy evaluation collapses to never reaching the goal after
# about 12k frames (measured: return 0.94 at 12k, then -1 from 16k to 40k). A fixed alpha of 0.01 keeps
# 0.94 to 40k frames.
GRID_TRAIN = {**ROOMS_TRAIN, "sac": {**ROOMS_TRAIN["sac"], "fixed_alpha": True}}

# The options of the FourRooms tasks: FourRoomsEnv's and GridFourRoomsEnv's keywords with their defaults,
# declared here (as Gymnasium's EnvSpec holds its kwargs) so that checking a config imports neither the env
# nor torch; tests/test_config.py holds them equal to the classes' signatures.
ROOMS_OPTIONS = {"goal": (8.0, 8.0), "goal_radius": 0.5, "max_step": 0.5, "step_cost": 0.01, "horizon": 100,
                 "start_room": None, "observe_goal": False, "render_size": 200}
GRID_OPTIONS = {"goal": (3, 9), "slip": 0.0, "step_cost": 0.01, "horizon": 100, "start_room": None,
                "observation": "onehot", "observe_goal": False, "cell_pixels": 16}


def _rooms_returns(o: dict) -> tuple[float, float]:
    """FourRooms: -step_cost on every step but the goal's, +1 there: from never reaching it to reaching it at once."""
    return -o["step_cost"] * o["horizon"], 1.0


def _named_potential(entry: str, option: str, options: dict[str, Any]):
    """The potential class (or factory) named ``"module:attr"``, imported on use, of ``options[option]``."""
    module, _, attr = entry.partition(":")
    return getattr(importlib.import_module(module), attr)(options[option])


_rooms_potential = functools.partial(_named_potential, "drltg.envs.fourrooms:FourRoomsPotential", "goal")
_grid_potential = functools.partial(_named_potential, "drltg.envs.gridrooms:GridFourRoomsPotential", "goal")


def _rooms(name: str, goal: tuple[float, float], where: str) -> None:
    """A continuous FourRooms task: its goal disc's centre, the rest as :data:`ROOMS_OPTIONS` declares."""
    description = f"continuous FourRooms, goal disc (r 0.5) at {goal}{where}"
    register_task(name, "drltg.envs.fourrooms:FourRoomsEnv", description, goal=goal, step_cost=0.01,
                  train=ROOMS_TRAIN, returns=_rooms_returns, potential=_rooms_potential, options=ROOMS_OPTIONS)


def _grid(name: str, goal: tuple[int, int], where: str) -> None:
    """A grid FourRooms task: its goal cell (row, column), the rest as :data:`GRID_OPTIONS` declares."""
    description = f"grid FourRooms 13x13, goal cell (row {goal[0]}, col {goal[1]}){where}"
    register_task(name, "drltg.envs.gridrooms:GridFourRoomsEnv", description, goal=goal, step_cost=0.01,
                  train=GRID_TRAIN, returns=_rooms_returns, potential=_grid_potential, options=GRID_OPTIONS)


# Graded targets for the source goal (8, 8): shortest free path from the source goal through the
# doorways, 1.0 (northeast-shifted), 2.1 (northeast-inner), 6.1 (southeast, northwest) and 9.9
# (southwest) units.
for _name, _goal, _where in (
    ("fourrooms/northeast", (8.0, 8.0), " in the north-east room, random start"),
    ("fourrooms/northeast-shifted", (8.0, 7.0), ", 1 unit south of fourrooms/northeast"),
    ("fourrooms/southwest", (2.0, 2.0), " in the south-west room, random start"),
    ("fourrooms/northeast-inner", (6.5, 6.5), ", the north-east room's inner corner"),
    ("fourrooms/southeast", (8.0, 2.0), " in the south-east room, random start"),
    ("fourrooms/northwest", (2.0, 8.0), " in the north-west room, random start"),
):
    _rooms(_name, _goal, _where)
for _name, _goal, _where in (
    ("gridrooms/northeast", (3, 9), " in the north-east room, random start"),
    ("gridrooms/northeast-shifted", (4, 9), ", 1 cell below gridrooms/northeast"),
    ("gridrooms/southwest", (9, 3), " in the south-west room, random start"),
):
    _grid(_name, _goal, _where)
register_pair(
    "fourrooms-near",
    "fourrooms/northeast",
    "fourrooms/northeast-shifted",
    "the goal moves 1 unit within the north-east room (transfer should help)",
)
register_pair(
    "fourrooms-far",
    "fourrooms/northeast",
    "fourrooms/southwest",
    "the goal moves to the opposite, south-west room",
)
register_pair(
    "fourrooms-inner",
    "fourrooms/northeast",
    "fourrooms/northeast-inner",
    "the goal moves 2.1 units to the north-east room's inner corner",
)
register_pair(
    "fourrooms-southeast",
    "fourrooms/northeast",
    "fourrooms/southeast",
    "the goal moves to the adjacent south-east room (through the east doorway)",
)
register_pair(
    "fourrooms-northwest",
    "fourrooms/northeast",
    "fourrooms/northwest",
    "the goal moves to the adjacent north-west room (through the north doorway)",
)
register_pair(
    "gridrooms-near",
    "gridrooms/northeast",
    "gridrooms/northeast-shifted",
    "the goal moves 1 cell within the north-east room (transfer should help)",
)
register_pair(
    "gridrooms-far",
    "gridrooms/northeast",
    "gridrooms/southwest",
    "the goal moves to the opposite, south-west room",
)


# robosuite manipulation (drltg.envs.robosuite; robosuite is imported only when a task is built).
# SAC settings known to work on Lift: replay 1e6, batch 256, 2x256 nets, lr 3e-4, one update per frame
# (Stable-Baselines3's SAC defaults; results/README.md's lift-dense study found none better at 30k frames).
def _manipulation_returns(o: dict) -> tuple[float, float]:
    """Every manipulation reward pays between 0 and ``reward_scale`` (1) per step; ``reward_scale`` is robosuite's
    own keyword, which the factory does not declare."""
    return 0.0, o["horizon"] * (1.0 if o.get("reward_scale") is None else o["reward_scale"])


ROBOSUITE_TRAIN = {
    "buffer": {"size": 1_000_000, "batch_size": 256},
    "network": {"hidden": [256, 256]},
    "optim": {"lr": 3.0e-4, "updates_per_batch": 100},
    "collector": {"num_envs": 2, "frames_per_batch": 100, "init_random_frames": 5_000},
    "eval": {"every": 25_000, "episodes": 4},
    "checkpoint": {"every": 50_000},
}


_manipulation_potential = functools.partial(_named_potential, "drltg.envs.robosuite.potentials:potential_for", "task")


def _manipulation(name: str, task: str, description: str, **options) -> None:
    """A robosuite task (:func:`drltg.envs.robosuite.env.robosuite_task`'s ``task``), trained as
    :data:`ROBOSUITE_TRAIN` says."""
    register_task(name, "drltg.envs.robosuite.env:robosuite_task", description, task=task, train=ROBOSUITE_TRAIN,
                  returns=_manipulation_returns, **options)

_manipulation("lift", "lift", "robosuite Lift: the Panda lifts the cube 4 cm (reward 1 per lifted step), horizon 500",
              potential=_manipulation_potential)
_manipulation("lift-place", "lift-place",
              "lift the cube and set it down on the green target disc 0.32 m away, horizon 500",
              potential=_manipulation_potential)
_manipulation("lift-place-barrier", "lift-place-barrier",
              "lift-place with a heavy 7 cm wall between cube and target (pushing cannot work), horizon 500",
              potential=_manipulation_potential)
_manipulation("lift-dense", "lift",
              "robosuite Lift with robosuite's dense reward (reach + grasp + lift, at most 1 per step), horizon 500",
              reward_shaping=True)
# The earlier implementation's place reward (drltg.envs.robosuite.tasks.SeedReward) on drltg's scenes: dense
# stages plus a contact bonus that pays pushing like placing; success stays drltg's strict check.
_manipulation("lift-place-seed", "lift-place-seed",
              "lift-place with the earlier implementation's dense reward (reach, grasp, lift, place; contact pays 1), "
              "horizon 500")
_manipulation("lift-place-barrier-seed", "lift-place-barrier-seed",
              "lift-place-barrier with the earlier implementation's dense reward (contact pays 1), horizon 500")
register_pair("lift-to-place", "lift", "lift-place", "lifting skills reused to lift and place")
register_pair("lift-to-place-barrier", "lift", "lift-place-barrier", "lifting reused where pushing cannot work")
register_pair(
    "lift-dense-to-place", "lift-dense", "lift-place", "a Lift policy learned from dense reward reused to place"
)
register_pair(
    "lift-dense-to-place-barrier", "lift-dense", "lift-place-barrier", "a dense-reward Lift policy reused over the wall"
)
register_pair("lift-dense-to-place-seed", "lift-dense", "lift-place-seed",
              "the earlier implementation's pair: dense-reward Lift to its dense place reward")
register_pair("lift-dense-to-place-barrier-seed", "lift-dense", "lift-place-barrier-seed",
              "the earlier implementation's pair over the wall, on its dense place reward")


# Gymnasium's Pendulum with two gravities (drltg.envs.gym.make_gym_env; Gymnasium is imported when one is built).
# SAC as RL Zoo tunes it for Pendulum (lr 1e-3, one update per frame) with 2x64 nets: single-threaded,
# small nets are several times faster and Pendulum needs no more.
PENDULUM_TRAIN = {
    "network": {"hidden": [64, 64]},
    "optim": {"lr": 1.0e-3, "updates_per_batch": 32},
    "collector": {"num_envs": 4, "frames_per_batch": 32, "init_random_frames": 1000},
    "eval": {"every": 1000, "episodes": 5},
    "checkpoint": {"every": 5000},
}

def _pendulum_returns(o: dict) -> tuple[float, float]:
    """Pendulum-v1 costs theta^2 + 0.1 thetadot^2 + 0.001 u^2 per step, at most pi^2 + 0.1 * 8^2 + 0.001 * 2^2."""
    return -(math.pi ** 2 + 6.4 + 0.004) * o.get("max_episode_steps", 200), 0.0


_GYM = "drltg.envs.gym:make_gym_env"  # drltg.envs.gym.register_gym_task's factory
_PENDULUM = {"gym_id": "Pendulum-v1", "info_keys": []}  # drltg.envs.gym.fixed("Pendulum-v1")
register_task("pendulum/g10", _GYM, "Gymnasium Pendulum-v1, gravity g = 10 (its default)",
              fixed=_PENDULUM, g=10.0, train=PENDULUM_TRAIN, returns=_pendulum_returns)
register_task("pendulum/g15", _GYM, "Gymnasium Pendulum-v1, gravity g = 15: a heavier swing-up",
              fixed=_PENDULUM, g=15.0, train=PENDULUM_TRAIN, returns=_pendulum_returns)
register_pair("pendulum-heavier", "pendulum/g10", "pendulum/g15", "Pendulum's gravity rises from 10 to 15")
