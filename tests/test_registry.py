"""The task and pair registry, and `drltg tasks`."""
import argparse

import pytest
import torch
from torchrl.envs.utils import check_env_specs

from drltg.cli import tasks as tasks_cmd
from drltg.envs import PAIRS, TASKS, FourRoomsEnv, GridFourRoomsEnv, get_pair, get_task, make_env, registry
from drltg.errors import UsageError

# robosuite tasks take seconds to build; tests/test_robosuite.py checks their specs and workers.
ROOMS = sorted(name for name in TASKS if name.startswith(("fourrooms/", "gridrooms/")))


@pytest.fixture
def scratch_registry(monkeypatch):
    """Registrations made in a test vanish after it."""
    monkeypatch.setattr(registry, "TASKS", dict(registry.TASKS))
    monkeypatch.setattr(registry, "PAIRS", dict(registry.PAIRS))
    return registry


def test_builtin_tasks_and_pairs():
    for family in ("fourrooms", "gridrooms"):
        for goal in ("northeast", "northeast-shifted", "southwest"):
            assert f"{family}/{goal}" in TASKS
        near, far = PAIRS[f"{family}-near"], PAIRS[f"{family}-far"]
        assert near.source == far.source == f"{family}/northeast"
        assert (near.target, far.target) == (f"{family}/northeast-shifted", f"{family}/southwest")
    for pair in PAIRS.values():
        assert pair.source in TASKS and pair.target in TASKS


def test_pair_goals_move_as_described():
    goal = {name: make_env(name).goal.float() for name in ROOMS}
    assert (goal["fourrooms/northeast-shifted"] - goal["fourrooms/northeast"]).norm().item() == 1.0
    assert (goal["gridrooms/northeast-shifted"] - goal["gridrooms/northeast"]).abs().sum().item() == 1.0
    assert torch.equal(goal["fourrooms/southwest"], 10 - goal["fourrooms/northeast"])
    assert torch.equal(goal["gridrooms/southwest"], 12 - goal["gridrooms/northeast"])


@pytest.mark.parametrize("name", ROOMS)
@pytest.mark.parametrize("batch_size", [(), (4,)])
def test_check_env_specs_for_every_task(name, batch_size):
    env = make_env(name, batch_size=batch_size, seed=0)
    assert env.batch_size == batch_size
    check_env_specs(env, seed=0)


def test_make_env_applies_defaults_overrides_and_seed():
    env = make_env("fourrooms/southwest", horizon=7, observe_goal=True)
    assert env.horizon == 7 and env.goal.tolist() == [2.0, 2.0] and env.step_cost == 0.01
    assert env.observation_spec["observation"].shape == (4,)
    a = make_env("gridrooms/northeast", batch_size=(32,), seed=11).reset()["cell"]
    b = make_env("gridrooms/northeast", batch_size=(32,), seed=11).reset()["cell"]
    c = make_env("gridrooms/northeast", batch_size=(32,), seed=12).reset()["cell"]
    assert torch.equal(a, b) and not torch.equal(a, c)


def test_unknown_task_names_it_and_suggests_a_close_name():
    with pytest.raises(UsageError, match=r"unknown task 'fourroom/northeat'.*did you mean 'fourrooms/northeast'"):
        make_env("fourroom/northeat")
    with pytest.raises(UsageError, match=r"unknown task 'zzz'; known tasks: fourrooms/northeast"):
        get_task("zzz")
    with pytest.raises(UsageError, match=r"unknown pair 'fourrooms-nera'.*'fourrooms-near'"):
        get_pair("fourrooms-nera")


def test_unknown_option_is_a_usage_error():
    with pytest.raises(UsageError, match=r"^keyword 'goal_radus' is not an option of task .*goal_radius"):
        make_env("fourrooms/northeast", goal_radus=0.3)
    with pytest.raises(UsageError, match="free space"):
        make_env("fourrooms/northeast", goal=(5.0, 3.0))


def test_register_a_user_task_and_pair(scratch_registry):
    def factory(batch_size=(), device=None, **kwargs):
        return FourRoomsEnv(batch_size=batch_size, device=device, **kwargs)

    spec = scratch_registry.register_task(
        "mine/west", factory, "goal by the west door", goal=(2.0, 4.0), train={"frames": 10}
    )
    assert spec.train == {"frames": 10} and scratch_registry.TASKS["mine/west"] is spec
    assert scratch_registry.make_env("mine/west", batch_size=(3,)).goal.tolist() == [2.0, 4.0]
    scratch_registry.register_pair("mine", "fourrooms/northeast", "mine/west", "to the west door")
    assert scratch_registry.get_pair("mine").target == "mine/west"
    with pytest.raises(UsageError, match="already registered; pass replace=True"):
        scratch_registry.register_task("mine/west", factory, "again")
    again = scratch_registry.register_task("mine/west", factory, "goal moved", goal=(2.0, 3.0), replace=True)
    assert scratch_registry.TASKS["mine/west"] is again
    assert scratch_registry.make_env("mine/west").goal.tolist() == [2.0, 3.0]
    with pytest.raises(UsageError, match="pair 'mine' is already registered"):
        scratch_registry.register_pair("mine", "fourrooms/northeast", "mine/west", "again")
    scratch_registry.register_pair("mine", "mine/west", "fourrooms/northeast", "reversed", replace=True)
    assert scratch_registry.get_pair("mine").source == "mine/west"
    with pytest.raises(UsageError, match="unknown task 'mine/east'"):
        scratch_registry.register_pair("bad", "fourrooms/northeast", "mine/east", "no such target")
    assert "bad" not in scratch_registry.PAIRS


def test_tasks_command_lists_every_task_and_pair(capsys):
    parser = argparse.ArgumentParser()
    tasks_cmd.add_arguments(parser)
    assert tasks_cmd.run(parser.parse_args([])) == 0
    lines = capsys.readouterr().out.splitlines()
    for task in TASKS.values():
        assert any(line.split()[0] == task.name and task.description in line for line in lines)
    for pair in PAIRS.values():
        assert any(line.split()[0] == pair.name and f"{pair.source} -> {pair.target}" in line for line in lines)
    assert tasks_cmd.run(parser.parse_args(["grid"])) == 0
    names = [line.split()[0] for line in capsys.readouterr().out.splitlines() if line.startswith("  ")]
    assert names and all("grid" in name for name in names)


def test_graded_fourrooms_targets_lie_in_their_rooms_at_growing_distances():
    from drltg.envs.fourrooms import ROOM_NAMES, in_free_space, room_of

    graded = ["fourrooms-near", "fourrooms-inner", "fourrooms-southeast", "fourrooms-northwest", "fourrooms-far"]
    rooms = ["northeast", "northeast", "southeast", "northwest", "southwest"]
    source = make_env("fourrooms/northeast").goal.float()
    straight = []
    for pair, room in zip(graded, rooms):
        goal = make_env(PAIRS[pair].target).goal.float()
        assert PAIRS[pair].source == "fourrooms/northeast"
        assert bool(in_free_space(goal)) and ROOM_NAMES[room_of(goal)] == room
        straight.append((goal - source).norm().item())
    assert straight[0] < straight[1] < min(straight[2:4]) and max(straight[2:4]) < straight[4]


@pytest.mark.parametrize(
    "cls, task", [(FourRoomsEnv, "fourrooms/northeast"), (GridFourRoomsEnv, "gridrooms/northeast")]
)
def test_an_env_class_without_arguments_is_its_registered_default_task(cls, task):
    plain, registered = cls(batch_size=(4,), seed=3), make_env(task, batch_size=(4,), seed=3)
    assert plain.full_observation_spec == registered.full_observation_spec
    assert plain.full_action_spec == registered.full_action_spec
    assert plain.full_reward_spec == registered.full_reward_spec and plain.full_done_spec == registered.full_done_spec
    for option, value in get_task(task).defaults.items():
        assert torch.equal(torch.as_tensor(getattr(plain, option)), torch.as_tensor(getattr(registered, option)))
    assert plain.step_cost == 0.01
    torch.manual_seed(0)
    a = plain.rollout(60, break_when_any_done=False)
    torch.manual_seed(0)
    b = registered.rollout(60, break_when_any_done=False)
    assert (a == b).all()
    assert (a["next", "reward"] == -0.01).any()


def test_a_factory_named_module_attr_is_imported_when_the_task_is_built(scratch_registry):
    spec = scratch_registry.register_task("mine/grid", "drltg.envs.gridrooms:GridFourRoomsEnv", "grid", goal=(9, 3))
    assert spec.factory is GridFourRoomsEnv
    assert scratch_registry.make_env("mine/grid").goal.tolist() == [9, 3]
    with pytest.raises(UsageError, match=r"^task 'bad': .* is 'module:attr', got 'nowhere'\.$"):
        scratch_registry.register_task("bad", "nowhere", "no colon")
    scratch_registry.register_task("lost", "drltg.envs.nowhere:Env", "a module that does not exist")
    with pytest.raises(UsageError, match=r"^task 'lost': its factory 'drltg.envs.nowhere:Env' cannot be imported"):
        scratch_registry.make_env("lost")


def test_options_declared_at_registration_are_the_task_s_and_nothing_is_read_from_source(scratch_registry):
    """``options=`` declares a factory's keywords, as Gymnasium's EnvSpec holds its kwargs: a config is checked
    against them without importing the factory; without them the imported factory's signature says them
    (its defaults as objects, not read from its module's source)."""
    import sys

    spec = scratch_registry.register_task("mine/far", "drltg_test_no_such_module:Env", "never built",
                                          options={"horizon": 100, "goal": (1.0, 2.0)}, goal=(3.0, 4.0))
    assert spec.keywords() == {"horizon": 100, "goal": (3.0, 4.0)}  # the registered default over the declared
    assert spec.check({"horizon": 1e2}) == {"horizon": 100}
    with pytest.raises(UsageError, match=r"^keyword 'slip' is not an option of task 'mine/far'; its options are: "
                                         r"goal, horizon\.$"):
        spec.check({"slip": 0.1})
    assert "drltg_test_no_such_module" not in sys.modules
    with pytest.raises(UsageError, match=r"^task 'mine/far': its factory .* cannot be imported"):
        scratch_registry.make_env("mine/far")
    sentinel = object()  # a default no source text could hold

    def factory(batch_size=(), device=None, seed=None, *, level=sentinel, **kwargs):
        return FourRoomsEnv(batch_size=batch_size, device=device)

    assert scratch_registry.register_task("mine/signature", factory, "read").keywords() == {"level": sentinel}
    with pytest.raises(UsageError, match=r"^task 'mine/x': 'horizon' is declared as an option, but it is a "
                                         r"registration field\.$"):
        scratch_registry.register_task("mine/x", factory, "x", options={"horizon": 1}, fixed={"horizon": 2})
    with pytest.raises(UsageError, match=r"^task 'mine/x': 'seed' is declared as an option, but it is make_env's"):
        scratch_registry.register_task("mine/x", factory, "x", options={"seed": 0})
    assert not hasattr(registry, "_read_keywords") and "ast" not in vars(registry)


def test_options_are_checked_once_by_the_task_for_make_env_and_the_config():
    """One rule reads an option as the type of its declared default (an int from an integral number, a float
    from any finite number, a list from a sequence of numbers); make_env and a config say the same sentence,
    naming the keyword or the config key."""
    from drltg import config as config_lib

    spec = get_task("fourrooms/northeast")
    checked = spec.check({"horizon": 1e2, "step_cost": 1, "goal": (2, 4.5), "observe_goal": True})
    assert checked == {"horizon": 100, "step_cost": 1.0, "goal": [2, 4.5], "observe_goal": True}
    assert (type(checked["horizon"]), type(checked["step_cost"]), type(checked["goal"])) == (int, float, list)
    assert make_env("fourrooms/northeast", horizon=7.0).horizon == 7
    declares = "(task 'fourrooms/northeast' declares {}), got {}."
    for key, value, words in [("horizon", 2.5, "an integer"), ("horizon", "7", "an integer"),
                              ("horizon", True, "an integer"), ("step_cost", float("inf"), "a number"),
                              ("step_cost", None, "a number"), ("observe_goal", 1, "true or false"),
                              ("goal", [], "a list of numbers"), ("goal", [1.0, "x"], "a list of numbers")]:
        default = f"{key}={spec.keywords()[key]!r}"
        with pytest.raises(UsageError) as err:
            make_env("fourrooms/northeast", **{key: value})
        assert str(err.value) == f"keyword '{key}' must be {words} " + declares.format(default, repr(value))
        with pytest.raises(UsageError) as err:
            config_lib.resolve({"env": {key: value}}, [], task="fourrooms/northeast")
        assert str(err.value) == f"config key 'env.{key}' must be {words} " + declares.format(default, repr(value))
    with pytest.raises(UsageError, match=r"^keyword 'colour' is not an option of task 'fourrooms/northeast'; its "
                                         r"options are: goal, goal_radius, horizon, "):
        make_env("fourrooms/northeast", colour="red")
