"""Gymnasium both ways: Gymnasium envs as drltg tasks (drltg.envs.gym), drltg tasks as Gymnasium envs
(drltg.gymnasium_ids, drltg.envs.gymnasium_env), and the declared Gymnasium range."""
from __future__ import annotations

import math
import subprocess
import sys
import warnings
from importlib.metadata import version
from pathlib import Path

import gymnasium
import numpy as np
import pytest
import tomllib
import torch
from gymnasium.utils.env_checker import check_env
from torchrl.envs import GymWrapper, SerialEnv

import drltg
from drltg import config as config_lib
from drltg.envs import PAIRS, TASKS, FourRoomsEnv, get_task, make_env, register_pair, register_task
from drltg.envs.gym import make_gym_env, register_gym_task
from drltg.envs.gymnasium_env import DrltgEnv, DrltgVectorEnv
from drltg.errors import UsageError
from drltg.gymnasium_ids import pair_ids, register_ids, task_id

ROOT = Path(__file__).resolve().parents[1]
OWN_TASKS = [name for name, spec in TASKS.items() if spec.factory is not make_gym_env and not name.startswith("lift")]
"""drltg's own tasks but the manipulation ones, which have a check of their own (without rendering)."""


# ----------------------------------------------------------------------------- Gymnasium in
@pytest.fixture(autouse=True)
def _registry_as_it_was():
    """Tasks and pairs a test registers (``gym/...`` ones made on use included) are gone after it."""
    tasks, pairs = set(TASKS), set(PAIRS)
    yield
    for name in set(TASKS) - tasks:
        dict.pop(TASKS, name)
    for name in set(PAIRS) - pairs:
        PAIRS.pop(name)


def test_gym_prefix_names_every_gymnasium_id_with_a_batch_of_gym_envs():
    env = make_env("gym/Pendulum-v1", batch_size=(3,), seed=0)
    assert isinstance(env, SerialEnv) and env.batch_size == (3,)
    spec = get_task("gym/Pendulum-v1")  # its options are Pendulum's own keywords and its registered limit
    assert spec.fixed == {"gym_id": "Pendulum-v1", "info_keys": []}
    assert spec.defaults == {"g": 10.0, "max_episode_steps": 200}
    single = make_env("gym/Pendulum-v1")
    assert isinstance(single.base_env, GymWrapper) and single.batch_size == ()
    env.close(), single.close()


def test_unknown_gym_id_is_an_unknown_task():
    with pytest.raises(UsageError, match="unknown task 'gym/NoSuchEnv-v0'"):
        make_env("gym/NoSuchEnv-v0")


def _pendulum_step(obs, u, g, m=1.0, length=1.0, dt=0.05):
    """Gymnasium's Pendulum dynamics by hand: thdot' = thdot + (3g/(2l) sin th + 3u/(m l^2)) dt."""
    th = math.atan2(obs[1], obs[0])
    thdot = float(np.clip(obs[2] + (3 * g / (2 * length) * math.sin(th) + 3.0 / (m * length**2) * u) * dt, -8, 8))
    return np.array([math.cos(th + thdot * dt), math.sin(th + thdot * dt), thdot])


@pytest.mark.parametrize(("task", "g"), [("pendulum/g10", 10.0), ("pendulum/g15", 15.0)])
def test_registered_variant_passes_its_keywords_to_gymnasium_make(task, g):
    env = make_env(task, seed=3)
    td = env.reset()
    td["action"] = torch.tensor([0.5])
    nxt = env.step(td)["next"]
    expected = _pendulum_step(td["observation"].double().numpy(), 0.5, g)
    np.testing.assert_allclose(nxt["observation"].double().numpy(), expected, rtol=1e-5, atol=1e-5)


def test_env_settings_override_gymnasium_keywords():
    cfg = config_lib.resolve({}, ["env.g=12.5"], task="pendulum/g15")
    assert cfg.env == {"g": 12.5}
    assert make_env("pendulum/g15", g=12.5)._env.unwrapped.g == 12.5


def test_truncation_is_kept_apart_from_termination():
    env = make_env("pendulum/g10", batch_size=(2,), seed=0)
    td = env.rollout(200, break_when_any_done=False)
    truncated, terminated = td["next", "truncated"].squeeze(-1), td["next", "terminated"].squeeze(-1)
    assert truncated[:, :199].sum() == 0 and truncated[:, 199].all()
    assert not terminated.any()
    # step_count is kept as on drltg's tasks (policy reuse reads it): 1..200 in every element
    assert td["next", "step_count"].squeeze(-1).tolist() == [list(range(1, 201))] * 2
    env.close()


class _Reach(gymnasium.Env):
    """One step: action 1 succeeds (reward 1, info success), action 0 fails."""

    observation_space = gymnasium.spaces.Box(-1.0, 1.0, (1,), np.float32)
    action_space = gymnasium.spaces.Discrete(2)

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        return np.zeros(1, np.float32), {"success": False}

    def step(self, action):
        success = bool(action == 1)
        return np.zeros(1, np.float32), float(success), True, False, {"success": success}


class _Buttons(_Reach):
    action_space = gymnasium.spaces.MultiBinary(3)


gymnasium.register("DrltgTestReach-v0", entry_point=_Reach)
gymnasium.register("DrltgTestButtons-v0", entry_point=_Buttons)


def test_success_in_info_is_evaluated_like_drltg_tasks():
    from drltg.training.loop import evaluate

    register_gym_task("test-gym/reach", "DrltgTestReach-v0", info_keys=["success"], replace=True)
    env = make_env("test-gym/reach", batch_size=(4,), seed=0)
    assert env.action_spec.shape == (4, 2)  # Discrete(2) one-hot, as drltg's discrete learners take it

    def press(index):
        return lambda td: td.set("action", torch.nn.functional.one_hot(torch.full((4,), index), 2))

    assert evaluate(env, press(1)) == {"return_mean": 1.0, "return_std": 0.0, "episodes": 4, "success_rate": 1.0}
    assert evaluate(env, press(0))["success_rate"] == 0.0


def test_other_action_spaces_are_refused_in_one_sentence():
    register_gym_task("test-gym/buttons", "DrltgTestButtons-v0", replace=True)
    with pytest.raises(UsageError, match="MultiBinary action space; drltg's learners take Box or Discrete"):
        make_env("test-gym/buttons")


def test_gym_pair_plans_like_a_drltg_pair_and_a_method_that_cannot_apply_says_so():
    from drltg.experiments.experiment import plan_runs

    runs = plan_runs("pendulum-heavier", "model-reuse", frames=100, seeds=2, out=Path("/tmp/unused"))
    assert [(role, cfg.task, cfg.env["g"]) for role, cfg, _ in runs] == [
        ("source", "pendulum/g10", 10.0), ("baseline", "pendulum/g15", 15.0), ("transfer", "pendulum/g15", 15.0)
    ] * 2
    with pytest.raises(UsageError, match="^task 'pendulum/g15' has no shaping potential registered.$"):
        config_lib.resolve({}, ["transfer.method=reward-shaping"], task="pendulum/g15")


PLUGIN = """
from drltg.envs import register_gym_task, register_pair
register_gym_task("test-plugin/pendulum-light", "Pendulum-v1", g=5.0)
register_gym_task("test-plugin/pendulum-heavy", "Pendulum-v1", "much heavier", g=20.0)
register_pair("test-plugin-pendulum", "test-plugin/pendulum-light", "test-plugin/pendulum-heavy", "g 5 -> 20")
"""


def test_a_plugin_registers_gym_variants_that_a_sweep_and_gymnasium_take(tmp_path, monkeypatch):
    from drltg import plugins
    from drltg.experiments.spec import parse_spec

    (tmp_path / "drltg_test_gym_plugin.py").write_text(PLUGIN)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv("DRLTG_IMPORT", "")  # plugins.load exports its modules here: undone after the test
    assert "drltg_test_gym_plugin" in plugins.load(["drltg_test_gym_plugin"])
    spec = parse_spec({"pairs": ["test-plugin-pendulum", "pendulum-heavier"], "methods": ["model-reuse"],
                       "frames": 100})
    assert spec.pairs == ["test-plugin-pendulum", "pendulum-heavier"]
    assert make_env("test-plugin/pendulum-light")._env.unwrapped.g == 5.0
    source, target = pair_ids("test-plugin-pendulum")
    assert target == "drltg/test-plugin-pendulum-heavy-v0"
    assert gymnasium.make(target).unwrapped._env._env.unwrapped.g == 20.0  # Gymnasium -> drltg -> Gymnasium
    with pytest.raises(UsageError, match=r"^keyword 'l' is not an option of task 'test-plugin/pendulum-heavy'; its "
                       r"options are: g.$"):  # a variant's options are the keywords it was registered with
        make_env("test-plugin/pendulum-heavy", l=1.5)


# ----------------------------------------------------------------------------- Gymnasium out
@pytest.mark.parametrize("task", OWN_TASKS)
def test_every_task_passes_gymnasiums_env_checker_without_a_warning(task):
    env = gymnasium.make(task_id(task))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped)
    env.close()


@pytest.mark.parametrize("task, flags", [("lift", {"success", "lifted"}),
                                         ("lift-place-barrier-seed", {"success", "lifted", "pushed"})])
def test_a_manipulation_task_passes_the_env_checker(task, flags):
    pytest.importorskip("robosuite")
    env = gymnasium.make(task_id(task))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        # rendering needs an offscreen GL backend; the close check builds a second simulation
        check_env(env.unwrapped, skip_render_check=True, skip_close_check=True)
    assert env.unwrapped.observation_space.shape == env.unwrapped._env.observation_spec["observation"].shape
    assert set(env.reset(seed=0)[1]) == flags
    env.close()


def test_the_agent_sees_the_observation_scalars_and_flags_in_info():
    env = gymnasium.make("drltg/fourrooms-northeast-v0", horizon=2)
    obs, info = env.reset(seed=7)
    assert obs.shape == (2,) and obs.dtype == np.float32 and info == {"success": False}
    position = (obs + 1.0) * 5.0  # observation = 2 p / 10 - 1
    step_right = np.array([1.0, 0.0], np.float32) if position[0] < 4.0 or position[0] > 5.5 else None
    if step_right is None:  # next to the middle wall: step left instead
        step_right = np.array([-1.0, 0.0], np.float32)
    obs2, reward, terminated, truncated, info = env.step(step_right)
    np.testing.assert_allclose((obs2 - obs) * 5.0, 0.5 * step_right, atol=1e-5)  # max_step 0.5, no wall in reach
    assert reward == pytest.approx(-0.01) and isinstance(reward, float)
    assert (terminated, truncated, info) == (False, False, {"success": False})
    assert env.step(step_right)[3] is True  # horizon 2
    # the same seed gives the same start: the task's generator is seeded from np_random
    assert np.array_equal(env.reset(seed=7)[0], obs) and not np.array_equal(env.reset(seed=8)[0], obs)


def test_reaching_the_goal_terminates_with_success_in_info():
    env = gymnasium.make("drltg/gridrooms-northeast-v0")
    env.reset(seed=0)
    goal = get_task("gridrooms/northeast").defaults["goal"]
    env.unwrapped._td["cell"] = torch.tensor([goal[0], goal[1] - 1])  # left of the goal
    _, reward, terminated, truncated, info = env.step(1)  # right
    assert (reward, terminated, truncated, info) == (1.0, True, False, {"success": True})


def test_make_vec_is_one_batched_torch_env_that_resets_finished_elements_in_the_same_step():
    vec = gymnasium.make_vec("drltg/fourrooms-northeast-v0", num_envs=5, horizon=3)
    assert isinstance(vec, DrltgVectorEnv) and isinstance(vec._env, FourRoomsEnv) and vec._env.batch_size == (5,)
    obs, info = vec.reset(seed=1)
    assert obs.shape == (5, 2) and info["success"].shape == (5,)
    away = np.zeros((5, 2), np.float32)
    for _ in range(2):
        obs, reward, terminated, truncated, info = vec.step(away)
        assert "final_obs" not in info and not truncated.any()
    obs3, reward, terminated, truncated, info = vec.step(away)
    assert truncated.all() and not terminated.any() and np.allclose(reward, -0.01)
    assert info["_final_obs"].all() and np.stack(info["final_obs"]).tolist() == obs.tolist()  # zero moves: stayed
    assert vec._env.reset is not None and (vec._td["step_count"] == 0).all()  # reset in the same step
    vec.close()


def test_vector_env_of_one_follows_the_single_env():
    single, vec = DrltgEnv("fourrooms/northeast"), DrltgVectorEnv("fourrooms/northeast", num_envs=1)
    actions = np.random.default_rng(0).uniform(-1, 1, (20, 2)).astype(np.float32)
    a, _ = single.reset(seed=4)
    b, _ = vec.reset(seed=4)
    assert np.array_equal(a, b[0])
    for action in actions:
        a = single.step(action)[0]
        b = vec.step(action[None])[0]
        assert np.array_equal(a, b[0])


def test_pair_ids_and_plugin_tasks_get_ids():
    assert pair_ids("fourrooms-near") == ("drltg/fourrooms-northeast-v0", "drltg/fourrooms-northeast-shifted-v0")
    assert pair_ids("pendulum-heavier") == ("drltg/pendulum-g10-v0", "drltg/pendulum-g15-v0")
    register_task("test-plugin/far-goal", FourRoomsEnv, "a plugin's task", goal=(2.0, 2.0), replace=True)
    register_pair("test-plugin-pair", "fourrooms/northeast", "test-plugin/far-goal", "a plugin's pair", replace=True)
    assert pair_ids("test-plugin-pair")[1] == "drltg/test-plugin-far-goal-v0"
    env = gymnasium.make("drltg/test-plugin-far-goal-v0")
    assert env.unwrapped._env.goal.tolist() == [2.0, 2.0]
    assert register_ids() == []  # every task has its id already
    with pytest.raises(UsageError, match="unknown pair"):
        pair_ids("no-such-pair")


FRESH = """
import sys
finders = list(sys.meta_path)
import drltg
assert sys.meta_path == finders, "import drltg changed sys.meta_path"
assert "torch" not in sys.modules, "import drltg is not cheap"
import gymnasium
assert "drltg/fourrooms-northeast-v0" in gymnasium.registry and "torch" not in sys.modules, "ids not cheap"
gymnasium.register_envs(drltg)  # Gymnasium's idiom for a package that registers its ids when imported
env = gymnasium.make("drltg/fourrooms-northeast-v0")
print(env.reset(seed=0)[0].shape)
"""


def test_import_drltg_registers_the_ids_and_leaves_the_import_system_as_it_found_it():
    """No import hook: ``import drltg`` registers every id itself, as a Gymnasium 1.x package does, so
    ``import drltg`` then ``import gymnasium`` (isort's order) finds them, and ``sys.meta_path`` is untouched."""
    out = subprocess.run([sys.executable, "-c", FRESH], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "(2,)"


def test_gymnasium_make_imports_drltg_in_a_fresh_process():
    code = 'import gymnasium; print(gymnasium.make("drltg:drltg/gridrooms-northeast-v0").reset(seed=0)[0].sum())'
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "1.0"  # a one-hot cell


# ----------------------------------------------------------------------------- declared range
def test_declared_gymnasium_range_is_the_one_torchrl_accepts():
    deps = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["dependencies"]
    assert [d for d in deps if d.startswith("gymnasium")] == ["gymnasium>=1.1,<2"]  # torchrl 0.14 refuses 1.0.x
    installed = tuple(int(p) for p in version("gymnasium").split(".")[:2])
    assert (1, 1) <= installed < (2, 0)


def test_drltg_exports_the_id_functions():
    assert drltg.gymnasium_ids.task_id("lift") == "drltg/lift-v0"
    with pytest.raises(ValueError, match="has no Gymnasium id"):
        task_id("bad name")


# ----------------------------------------------------------------------------- the Pendulum study
STUDY = ROOT / "results" / "bench" / "v1" / "quick" / "pendulum" / "pendulum-heavier" / "sac"


def _rounded(value):
    """Floats to 12 significant digits (numpy's sums may differ in the last bits on another CPU)."""
    if isinstance(value, float):
        return float(f"{value:.12g}")
    if isinstance(value, dict):
        return {k: _rounded(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_rounded(v) for v in value]
    return value


def test_the_pendulum_rows_are_reproduced_from_their_committed_curves(tmp_path):
    import json

    from drltg.report import transfer_report

    assert len(list(STUDY.glob("source/seed-*/checkpoints/last.safetensors"))) == 10
    assert len(list(STUDY.glob("baseline/seed-*/summary.json"))) == 10
    committed = json.loads((STUDY / "model-reuse" / "report" / "transfer_metrics.json").read_text())
    settings = committed["settings"]
    assert settings["paired"] is True and committed["metrics"]["n_seeds_transfer"] == 10
    result = transfer_report(STUDY / "baseline", STUDY / "model-reuse" / "transfer", tmp_path,
                             threshold=settings["threshold"], baseline_label=settings["baseline_label"],
                             transfer_label=settings["transfer_label"])
    assert _rounded(result["metrics"]) == _rounded(committed["metrics"])


def _upright(options):
    """Phi = -(1 - cos(theta)): 0 upright, -2 hanging (Pendulum's observation is cos, sin, velocity)."""
    from tensordict.nn import TensorDictModule

    return TensorDictModule(lambda obs: obs[..., :1] - 1.0, in_keys=["observation"], out_keys=["potential"])


def test_a_gymnasium_task_takes_a_shaping_potential():
    """register_gym_task(..., potential=) makes reward shaping work on a Gymnasium task, as on drltg's own."""
    register_gym_task("pend/shaped", "Pendulum-v1", potential=_upright, replace=True)
    try:
        cfg = config_lib.resolve(task="pend/shaped", overrides=["transfer.method=reward-shaping"])
        env = make_env("pend/shaped", batch_size=(2,), seed=0)
        td = env.reset()
        phi = get_task("pend/shaped").potential(cfg.env)(td)["potential"]
        assert torch.allclose(phi, td["observation"][..., :1] - 1.0)
        with pytest.raises(UsageError, match="no shaping potential"):
            register_gym_task("pend/plain", "Pendulum-v1", replace=True)
            config_lib.resolve(task="pend/plain", overrides=["transfer.method=reward-shaping"])
    finally:
        TASKS.pop("pend/shaped", None), TASKS.pop("pend/plain", None)


def test_drltg_tasks_names_the_gymnasium_id_a_slashed_id_misses(capsys):
    """``gymnasium.make("drltg/fourrooms/northeast-v0")`` is refused by Gymnasium's own id parser before
    drltg sees it; ``drltg tasks`` says how ids are formed, and the id it shows makes the env."""
    from drltg.cli import main

    with pytest.raises(gymnasium.error.Error, match="Malformed"):
        gymnasium.make("drltg/fourrooms/northeast-v0")
    assert main(["tasks", "fourrooms/northeast"]) == 0
    line = capsys.readouterr().out.strip().splitlines()[-1]
    shown = line.split('gymnasium.make("', 1)[1].split('"', 1)[0]
    assert shown == "drltg/fourrooms-northeast-v0" and "'/' as '-'" in line
    env = gymnasium.make(shown)
    assert env.reset(seed=0)[0].shape == (2,)
    env.close()
