"""The config schema: every key has a type and range, and every wrong value is one sentence naming
the key, raised by ``resolve()`` before anything is built or written."""
import dataclasses
import pickle

import pytest
import torch
import yaml
from pydantic import Field

from drltg import config as config_lib
from drltg.cli import main
from drltg.envs import TASKS, register_task
from drltg.errors import UsageError


def _resolve(*overrides, base=None, **explicit):
    return config_lib.resolve(base, list(overrides), **{"task": "fourrooms/northeast", **explicit})


def _refused(key, *overrides, base=None, **explicit):
    with pytest.raises(UsageError) as err:
        _resolve(*overrides, base=base, **explicit)
    message = str(err.value)
    assert f"'{key}'" in message, message
    assert "\n" not in message and message.endswith("."), message
    return message


def _leaves(d, prefix=""):
    for k, v in d.items():
        if isinstance(v, dict) and v:
            yield from _leaves(v, f"{prefix}{k}.")
        else:
            yield f"{prefix}{k}"


@pytest.mark.parametrize(
    "override, key, expected",
    [
        ("network.hidden=abc", "network.hidden", "non-empty list of positive integers"),
        ("network.hidden=[64,", "network.hidden", "non-empty list of positive integers"),
        ("network.hidden=[]", "network.hidden", "non-empty list of positive integers"),
        ("network.hidden=[64, 0]", "network.hidden", "non-empty list of positive integers"),
        ("network.hidden=[64, 1.5]", "network.hidden", "non-empty list of positive integers"),
        ("device=nonsense", "device", "torch device"),
        ("device=5", "device", "torch device"),
        ("device=meta", "device", "cannot train on"),
        ("threads=0", "threads", "integer in [1, 512]"),
        ("seed=-1", "seed", "integer in [0, 2147483647]"),
        ("frames=0", "frames", "integer in [1, 1000000000000]"),
        ("frames=1.5", "frames", "integer in [1, 1000000000000]"),
        ("optim.lr=-1", "optim.lr", "number > 0"),
        ("optim.lr=0", "optim.lr", "number > 0"),
        ("optim.lr=nan", "optim.lr", "number > 0"),
        ("optim.lr=.inf", "optim.lr", "number > 0"),
        ("optim.gamma=2", "optim.gamma", "number in (0, 1]"),
        ("optim.gamma=0", "optim.gamma", "number in (0, 1]"),
        ("optim.tau=0", "optim.tau", "number in (0, 1]"),
        ("optim.tau=1.5", "optim.tau", "number in (0, 1]"),
        ("optim.updates_per_batch=-1", "optim.updates_per_batch", "integer in [1, 100000]"),
        ("optim.updates_per_batch=0", "optim.updates_per_batch", "integer in [1, 100000]"),
        ("buffer.size=0", "buffer.size", "integer >= 1"),
        ("buffer.batch_size=0", "buffer.batch_size", "integer in [1, 1048576]"),
        ("checkpoint.every=0", "checkpoint.every", "integer in [1, 1000000000000]"),
        ("eval.every=0", "eval.every", "integer in [1, 1000000000000]"),
        ("eval.episodes=many", "eval.episodes", "must be an integer"),
        ("collector.init_random_frames=-1", "collector.init_random_frames", "integer in [0, 1000000000000]"),
        ("collector.num_envs=0", "collector.num_envs", "integer in [1, 1048576]"),
        ("log.every=0", "log.every", "integer in [1, 1000000000000]"),
        ("log.tensorboard=1", "log.tensorboard", "true or false"),
        ("algo=ppo", "algo", "unknown algorithm 'ppo'"),
        ("algo=5", "algo", "one of sac, soc, td3"),
        ("sac.alpha_init=0", "sac.alpha_init", "number > 0"),
        ("sac.fixed_alpha=yes please", "sac.fixed_alpha", "true or false"),
        ("sac.target_entropy=high", "sac.target_entropy", "'auto' or a number"),
        ("td3.exploration_noise=-0.1", "td3.exploration_noise", "number >= 0"),
        ("td3.policy_noise=-1", "td3.policy_noise", "number >= 0"),
        ("td3.noise_clip=-1", "td3.noise_clip", "number >= 0"),
        ("td3.policy_delay=0", "td3.policy_delay", "integer in [1, 100000]"),
        ("soc.num_options=0", "soc.num_options", "integer in [1, 256]"),
        ("soc.option_policy=greedy", "soc.option_policy", "unknown option policy 'greedy'"),
        ("soc.option_alpha_init=0", "soc.option_alpha_init", "number > 0 or null"),
        ("soc.fixed_option_alpha=2", "soc.fixed_option_alpha", "true or false"),
        ("soc.option_target_entropy=[1]", "soc.option_target_entropy", "'auto' or a number"),
        ("soc.option_epsilon=1.1", "soc.option_epsilon", "number in [0, 1]"),
        ("soc.deliberation_cost=-0.1", "soc.deliberation_cost", "number >= 0"),
        ("soc.option_entropy_bonus=0", "soc.option_entropy_bonus", "true or false"),
        ("transfer.method=copy", "transfer.method", "unknown transfer method 'copy'"),
        ("transfer.source=[a]", "transfer.source", "source run directory"),
        ("transfer.psi=1.5", "transfer.psi", "number in [0, 1]"),
        ("transfer.upsilon=-0.5", "transfer.upsilon", "number in [0, 1]"),
        ("transfer.psi_end=2", "transfer.psi_end", "number in [0, 1] or null"),
        ("transfer.annealing_frames=-1", "transfer.annealing_frames", "integer >= 0"),
        ("transfer.freeze=actor", "transfer.freeze", "list of parameter-name patterns"),
        ("transfer.freeze=[1]", "transfer.freeze", "list of parameter-name patterns"),
        ("transfer.partial=maybe", "transfer.partial", "true or false"),
        ("transfer.allow_incomplete=1", "transfer.allow_incomplete", "true or false"),
        ("env=5", "env", "mapping of the task's keyword arguments"),
        ("env.horizon=abc", "env.horizon", "integer (task 'fourrooms/northeast' declares horizon=100)"),
        ("env.goal=abc", "env.goal", "list of numbers"),
        ("env.observe_goal=3", "env.observe_goal", "true or false"),
        ("env.foo=1", "env.foo", "not an option of task 'fourrooms/northeast'"),
        ("env.seed=1", "env.seed", "the run sets it from seed"),
        ("env.device=cpu", "env.device", "the run sets it from device"),
        ("env.goal.x=1", "env.goal.x", "too deep"),
        ("optim=5", "optim", "mapping of optim.lr"),
        ("task=[1]", "task", "registered task name"),
        ("transfer.guide_steps=-1", "transfer.guide_steps", "integer >= 0"),
        ("transfer.demo_ratio=2", "transfer.demo_ratio", "number in [0, 1]"),
    ],
)
def test_bad_value_is_one_sentence_naming_the_key(override, key, expected):
    assert expected in _refused(key, override)


@pytest.mark.parametrize(
    "overrides, key, expected",
    [
        (["transfer.method=policy-reuse", "transfer.psi_end=0.1"], "transfer.psi_end", "annealing_frames > 0"),
        (["transfer.method=value-shaping", "algo=soc"], "transfer.method", "which works with algo sac or td3"),
    ],
)
def test_a_methods_own_rules_hold_when_it_is_chosen(overrides, key, expected):
    assert expected in _refused(key, *overrides)
    assert config_lib.resolve(overrides=overrides[1:])  # another method does not read them


@pytest.fixture
def registries():
    """The method and learner registries as they are, restored after the test (which registers its own)."""
    saved = [(table, dict(table)) for table in (config_lib.METHODS, config_lib.LEARNERS)]
    yield
    for table, before in saved:
        table.clear()
        table.update(before)


def test_a_registered_method_brings_its_keys(registries):
    from drltg.transfer import Transfer, TransferMethod, register_method

    method = TransferMethod("test-scale", "scales nothing", lambda *a, **k: Transfer(),
                            options={"scale": (float, Field(2.0, ge=0.0, description="how much"))})
    register_method(method)
    cfg = config_lib.resolve(overrides=["transfer.method=test-scale"])
    assert cfg.transfer.scale == 2.0 and list(cfg.model_dump()["transfer"])[-1] == "scale"
    assert "must be a number >= 0" in _refused("transfer.scale", "transfer.scale=-1")
    assert "| `transfer.scale` | 2.0 | a number >= 0 | how much |" in config_lib.describe()
    with pytest.raises(UsageError, match="already registered; pass replace=True"):
        register_method(method)
    with pytest.raises(UsageError, match="'transfer.psi' already belongs to policy-reuse"):
        register_method(TransferMethod("test-psi", "", method.build, options={"psi": (float, 1.0)}))
    with pytest.raises(UsageError, match="test-bad.*config key 'transfer.level' must be an integer >= 1, got 0"):
        register_method(TransferMethod("test-bad", "", method.build, options={"level": (int, Field(0, ge=1))}))
    register_method(TransferMethod("test-scale", "", method.build, options={"gain": (int, 3)}), replace=True)
    assert "scale" not in config_lib.keys() and config_lib.resolve().transfer.gain == 3
    with pytest.raises(UsageError, match="unknown config key 'transfer.scale'"):
        _resolve("transfer.scale=1")


@pytest.mark.parametrize(
    "base, key, expected",
    [
        ({"network": {"hidden": 64}}, "network.hidden", "got 64"),
        ({"optim": {"lr": {"a": 1}}}, "optim.lr", "number > 0"),
        ({"optim": 5}, "optim", "mapping"),
        ({"sac": None}, "sac", "mapping"),
        ({"transfer": ["none"]}, "transfer", "mapping"),
        ({"env": [1]}, "env", "mapping"),
        ({"env": {"horizon": {"x": 1}}}, "env.horizon", "integer"),
        ({"collector": {"frames_per_batch": [32]}}, "collector.frames_per_batch", "integer"),
        ({"seed": "zero"}, "seed", "integer"),
    ],
)
def test_yaml_value_of_the_wrong_shape_is_refused(base, key, expected):
    assert expected in _refused(key, base=base)


def test_config_file_with_a_scalar_hidden_is_refused(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text("task: fourrooms/northeast\nnetwork:\n  hidden: 64\n")
    _refused("network.hidden", base=config_lib.load_yaml(path))


def test_explicit_seed_is_checked():
    _refused("seed", seed=-1)
    _refused("frames", frames=0)


def test_cuda_when_unavailable_is_one_sentence(monkeypatch):
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    assert "no CUDA device is available" in _refused("device", "device=cuda")


def test_cuda_graphs_on_the_cpu_are_one_sentence(monkeypatch):
    assert "need device=cuda" in _refused("optim.cudagraphs", "optim.cudagraphs=true")
    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    monkeypatch.setattr(torch.cuda, "device_count", lambda: 1)
    assert _resolve("optim.cudagraphs=true", "device=cuda").optim.cudagraphs is True


def test_cuda_index_beyond_the_devices_is_one_sentence(monkeypatch):
    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    monkeypatch.setattr(torch.cuda, "device_count", lambda: 1)
    assert "has 1 CUDA device(s)" in _refused("device", "device=cuda:3")
    assert _resolve("device=cuda:0").device == "cuda:0"


def test_valid_edge_values_pass():
    cfg = _resolve(
        "optim.gamma=1", "optim.tau=1", "optim.updates_per_batch=1", "network.hidden=[8]",
        "collector.init_random_frames=0", "transfer.psi=0", "transfer.upsilon=1", "soc.option_epsilon=0",
        "soc.deliberation_cost=0", "sac.target_entropy=-2", "soc.option_alpha_init=null", "device=cpu",
        "transfer.freeze=[actor_network_params]", "transfer.source=runs/src", "buffer.size=1",
        "transfer.partial=true", "transfer.allow_incomplete=true", seed=0,
    )
    assert cfg.optim.model_dump() == {"lr": 3e-4, "updates_per_batch": 1, "gamma": 1, "tau": 1, "cudagraphs": False}
    assert cfg.network.hidden == [8]
    assert cfg.sac.target_entropy == -2
    assert cfg.transfer.partial is True and cfg.transfer.allow_incomplete is True


@pytest.mark.parametrize("frames, every", [(20_000, 1000), (30_000, 1000), (40_000, 2000), (99_000, 2000),
                                           (100_000, 5000), (1_000_000, 50_000), (2_500_000, 100_000), (19, 1)])
def test_eval_every_auto_gives_at_least_20_evaluations_at_round_frames(frames, every):
    cfg = config_lib.resolve(None, [], task="fourrooms/northeast")
    assert cfg.eval.every == "auto" and cfg.eval.interval(frames) == every
    assert 20 <= frames // every <= 50 or every == 1
    assert _resolve("eval.every=3000").eval.interval(frames) == 3000  # a number is kept as given


def test_override_parsing_is_unchanged_for_valid_values():
    cfg = _resolve("optim.lr=1e-3", "frames=1e4", "env.horizon=1e3", "env.goal=[8, 7]", "eval.every=2000.0")
    assert cfg.optim.lr == 0.001
    assert cfg.frames == 10_016 and isinstance(cfg.frames, int)  # rounded up to whole batches
    assert cfg.env == {**config_lib.task_env("fourrooms/northeast"), "horizon": 1000, "goal": [8, 7]}
    assert isinstance(cfg.env["horizon"], int)
    assert cfg.eval.every == 2000 and isinstance(cfg.eval.every, int)
    assert config_lib.parse_override("transfer.source=runs/a=b") == ("transfer.source", "runs/a=b")
    assert config_lib.parse_override("sac.target_entropy=auto") == ("sac.target_entropy", "auto")


@pytest.mark.parametrize("raw", ["0", "7", "-3", "+4", "1000", " 12 ", "007", "0x1f", "1_000", "0o17", "1.", "1e3",
                                 "-0", "yes", "~", "12345678901234567890"])
def test_an_override_value_reads_as_yaml_reads_it(raw):
    """Plain decimals skip the YAML parser (a refused key is answered without loading it): same value, same type."""
    import yaml

    key, value = config_lib.parse_override(f"a.b={raw}")
    expected = yaml.safe_load(raw)
    if raw == "1e3":
        expected = 1000.0  # YAML 1.1 reads a string, drltg a number
    assert key == "a.b" and value == expected and type(value) is type(expected)


def test_a_mapping_for_a_section_is_merged():
    cfg = _resolve("optim={lr: 0.1}")
    assert cfg.optim.lr == 0.1 and cfg.optim.gamma == 0.99


def test_task_given_as_override_brings_its_own_settings():
    cfg = config_lib.resolve({}, ["task=gridrooms/northeast"])
    assert cfg.task == "gridrooms/northeast" and cfg.sac.fixed_alpha is True


def test_every_default_key_has_a_field_and_every_default_fits():
    assert config_lib.keys() == list(_leaves(config_lib.defaults()))
    for task in TASKS:
        config_lib.resolve({}, [], task=task)
    table = config_lib.describe()
    assert [line.split("`")[1] for line in table.splitlines()[2:]] == config_lib.keys()


def test_choices_match_the_implementations():
    from drltg.learners import ALGOS
    from drltg.losses.soc import OPTION_POLICIES
    from drltg.transfer import METHODS

    assert ALGOS is config_lib.LEARNERS and METHODS is config_lib.METHODS  # one registry each
    assert set(ALGOS) == {"sac", "td3", "soc"}
    assert set(config_lib.method_names()) == set(METHODS)
    assert set(config_lib.OPTION_POLICIES) == set(OPTION_POLICIES)


def test_env_keys_of_an_open_factory_are_only_those_the_task_declares(monkeypatch):
    def factory(*, batch_size=(), device=None, size: int = 3, **rest):
        raise AssertionError("resolve must not build the env")

    spec = register_task("test/open-factory", factory, "a factory taking any keyword", colour="red",
                         fixed={"kind": "box"})
    monkeypatch.setitem(TASKS, spec.name, TASKS.pop(spec.name))
    assert _resolve("env.colour=blue", "env.size=4", task=spec.name).env == {"colour": "blue", "size": 4}
    assert "declares size=3" in _refused("env.size", "env.size=abc", task=spec.name)
    assert _refused("env.anything", "env.anything=[1, 2]", task=spec.name) == (
        "config key 'env.anything' is not an option of task 'test/open-factory'; its options are: colour, size.")
    assert _refused("env.kind", "env.kind=sphere", task=spec.name) == (
        "config key 'env.kind' cannot be set: it is part of the task 'test/open-factory' as registered (kind='box'), "
        "not an option, got 'sphere'.")
    assert _resolve("env.kind=box", task=spec.name).env == {"colour": "red", "size": 3}  # as older configs said it


def test_build_fills_defaults_and_checks_types_like_resolve():
    cfg = config_lib.build({"optim": {"lr": 1}, "frames": 1e3, "soc": {"option_alpha_init": None}})
    assert isinstance(cfg, config_lib.RunConfig)
    assert (cfg.optim.lr, type(cfg.optim.lr), cfg.frames, type(cfg.frames)) == (1.0, float, 1000, int)
    assert cfg.soc.option_alpha_init is None and cfg.optim.gamma == 0.99 and cfg.transfer.psi == 1.0
    for data, message in [
        ({"frames": 2.5}, "config key 'frames' must be an integer in [1, 1000000000000], got 2.5."),
        ({"frames": "7"}, "config key 'frames' must be an integer in [1, 1000000000000], got '7'."),
        ({"optim": {"lr": True}}, "config key 'optim.lr' must be a number > 0, got True."),
        ({"optim": {"gamma": 1.5}}, "config key 'optim.gamma' must be a number in (0, 1], got 1.5."),
        ({"log": {"tensorboard": "yes"}}, "config key 'log.tensorboard' must be true or false, got 'yes'."),
        ({"optim": {"lrr": 1}}, "unknown config key 'optim.lrr'; did you mean 'optim.lr'?"),
        ({"optimm": {}}, "unknown config key 'optimm'; did you mean 'optim'?"),
        ({"transfer": {"psy": 0.5}}, "unknown config key 'transfer.psy'; did you mean 'transfer.psi'?"),
        ({"collector": {"num_envs": 3}},
         "collector.frames_per_batch (32) must be a multiple of collector.num_envs (3)."),
        ({"algo": "ppo"}, "unknown algorithm 'ppo': config key 'algo' must be one of sac, soc, td3."),
        ({"buffer": 3}, "config key 'buffer' must be a mapping of buffer.size, buffer.batch_size, got 3."),
    ]:
        with pytest.raises(UsageError) as err:
            config_lib.build(data)
        assert str(err.value) == message


def test_overrides_are_coerced_as_before():
    cfg = _resolve("seed=7.0", "optim.lr=1", "soc.option_alpha_init=null", "network.hidden=[32, 16.0]",
                   "sac.target_entropy=-1", "transfer.freeze=[a, b]", "transfer.psi_end=0")
    assert (cfg.seed, type(cfg.seed)) == (7, int)
    assert (cfg.optim.lr, type(cfg.optim.lr)) == (1.0, float)
    assert cfg.soc.option_alpha_init is None and cfg.sac.target_entropy == -1.0
    assert cfg.network.hidden == [32, 16] and all(type(w) is int for w in cfg.network.hidden)
    assert cfg.transfer.freeze == ["a", "b"] and cfg.transfer.psi_end == 0.0


def test_a_config_is_checked_on_assignment_and_by_updated():
    cfg = _resolve()
    cfg.optim.lr = 0.5
    assert cfg.optim.lr == 0.5
    with pytest.raises(ValueError):
        cfg.optim.lr = -1
    other = config_lib.updated(cfg, {"seed": 3, "transfer.source": "runs/a"})
    assert (other.seed, other.transfer.source, cfg.seed, cfg.transfer.source) == (3, "runs/a", 0, None)
    with pytest.raises(UsageError, match=r"^config key 'optim.gamma' must be a number in \(0, 1\], got 0.$"):
        config_lib.updated(cfg, {"optim.gamma": 0})
    with pytest.raises(UsageError, match=r"^unknown config key .optim.lrr.; did you mean .optim.lr.\?$"):
        config_lib.updated(cfg, {"optim.lrr": 1})


def test_dump_then_load_gives_the_same_config(tmp_path):
    cfg = _resolve("transfer.method=policy-reuse", "transfer.source=runs/src", "env.horizon=60", "optim.lr=1e-3")
    path = tmp_path / "config.yaml"
    path.write_text(config_lib.dump(cfg))
    again = config_lib.resolve(config_lib.load_yaml(path))
    assert again == cfg and config_lib.dump(again) == config_lib.dump(cfg)
    assert config_lib.build(yaml.safe_load(config_lib.dump(cfg))) == cfg
    assert list(yaml.safe_load(config_lib.dump(cfg))) == ["task", "algo", "seed", "frames", "device", "threads",
                                                          "tuned_on", "env",
                                                          "collector", "buffer", "optim", "network", "eval",
                                                          "checkpoint", "log", "transfer", "sac", "soc", "td3"]
    assert pickle.loads(pickle.dumps(cfg)) == cfg  # a config goes to worker processes as its values


def test_a_config_file_that_is_not_a_mapping_is_one_sentence():
    with pytest.raises(UsageError, match=r"^a config must be a mapping of config keys, got \[1\]\.$"):
        config_lib.resolve([1])


@pytest.mark.parametrize(
    "args, key",
    [
        (["-o", "network.hidden=abc"], "network.hidden"),
        (["-o", "device=nonsense"], "device"),
        (["--seed", "-1"], "seed"),
        (["-o", "buffer.size=0"], "buffer.size"),
        (["-o", "env=5"], "env"),
    ],
)
def test_cli_refuses_in_one_line_with_exit_2_and_writes_nothing(args, key, tmp_path, capsys):
    run_dir = tmp_path / "run"
    code = main(["train", "fourrooms/northeast", "--no-progress", "--run-dir", str(run_dir), *args])
    err = capsys.readouterr().err
    assert code == 2
    assert len(err.strip().splitlines()) == 1 and f"'{key}'" in err and "Traceback" not in err
    assert not run_dir.exists()


def test_cli_refuses_a_config_file_with_a_scalar_hidden(tmp_path, capsys):
    path = tmp_path / "bad.yaml"
    path.write_text("task: fourrooms/northeast\nnetwork:\n  hidden: 64\n")
    run_dir = tmp_path / "run"
    code = main(["train", "--config", str(path), "--run-dir", str(run_dir)])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and "'network.hidden'" in err
    assert not run_dir.exists()


def test_manipulation_env_keys_are_checked_against_robosuite_env_defaults():
    with pytest.raises(UsageError, match=r"config key 'env.horizon' must be an integer .*horizon=500"):
        config_lib.resolve(task="lift", overrides=["env.horizon=abc"])
    assert config_lib.resolve(task="lift", overrides=["env.horizon=100"]).env["horizon"] == 100
    dense = config_lib.resolve(task="lift-dense").env
    assert dense["task"] == "lift" and dense["reward_shaping"] is True and dense["horizon"] == 500


def test_the_config_holds_every_env_setting_of_its_task(monkeypatch):
    cfg = _resolve("env.horizon=50")
    assert cfg.env == {"goal": [8.0, 8.0], "goal_radius": 0.5, "max_step": 0.5, "step_cost": 0.01, "horizon": 50,
                          "start_room": None, "observe_goal": False, "render_size": 200}
    assert yaml.safe_load(config_lib.dump(cfg)) == cfg.model_dump()  # plain YAML, no tuples


def test_an_option_of_a_method_the_run_does_not_use_is_not_a_change():
    from drltg.config import config_changes

    baseline = config_lib.resolve(None, [], task="fourrooms/northeast", algo="sac")
    other = config_lib.resolve(None, ["transfer.demo_episodes=3"], task="fourrooms/northeast", algo="sac")
    assert config_changes(baseline, other) == []
    demos = ["transfer.method=demonstrations", "transfer.source=demonstrator:x"]
    a = config_lib.resolve(None, demos, task="fourrooms/northeast", algo="sac")
    b = config_lib.resolve(None, [*demos, "transfer.demo_episodes=3"], task="fourrooms/northeast", algo="sac")
    assert config_changes(a, b) == ["transfer.demo_episodes"]
    parallel = {**b.model_dump(), "env": {**b.env, "parallel": True}}  # how envs are stepped, not what they step
    assert config_changes(b, parallel) == []
    best = config_lib.resolve(None, ["transfer.source_checkpoint=best"], task="fourrooms/northeast", algo="sac")
    assert config_changes(baseline, best) == []  # the checkpoint of a source neither run reads
    assert config_changes(a, {**a.model_dump(), "transfer": {**a.transfer.model_dump(), "source_checkpoint": "best"}}
                          ) == ["transfer.source_checkpoint"]


def test_a_changed_env_default_is_a_changed_run(monkeypatch):
    from drltg.config import config_changes
    from drltg.envs import registry

    saved = _resolve()
    old_style = {**saved.model_dump(), "env": {}}  # saved before env settings were written in full
    assert config_changes(old_style, _resolve()) == [] and config_changes(saved, _resolve()) == []
    spec = registry.TASKS["fourrooms/northeast"]
    monkeypatch.setitem(registry.TASKS, spec.name, dataclasses.replace(spec, defaults={**spec.defaults, "horizon": 60}))
    assert config_changes(saved, _resolve()) == ["env.horizon"]


def test_each_builtin_method_owns_its_options_model_and_the_config_holds_them_all():
    from drltg.transfer import METHODS

    defaults = config_lib.defaults()["transfer"]
    owners = config_lib.option_owners()
    for method in METHODS.values():
        own = method.model().model_dump() if method.model is not None else {}
        assert own == {k: defaults[k] for k, owner in owners.items() if owner == method.name}
    assert set(owners) == {k for m in METHODS.values() for k in m.options}
    assert owners["psi"] == "policy-reuse" and defaults["psi"] == 1.0 and defaults["freeze"] == []


def test_the_run_config_is_one_static_model_whose_open_parts_their_owners_check():
    """No model is assembled at run time: every config is a RunConfig, pickled as its values and read back
    without the registries; a method's option is checked by its method's model, on build and on assignment,
    and a refused assignment leaves the config as it was."""
    import pickle

    from drltg.config import run as config_run

    cfg = config_lib.resolve(overrides=["transfer.method=policy-reuse", "transfer.psi=0.5"])
    assert type(cfg) is config_lib.RunConfig and type(cfg.transfer) is config_lib.TransferConfig
    assert not hasattr(config_lib, "_model") and not hasattr(config_run, "_model_at")
    assert pickle.loads(pickle.dumps(cfg)) == cfg
    cfg.transfer.psi = 0.25
    with pytest.raises(UsageError, match=r"^config key 'transfer.psi' must be a number in \[0, 1\], got 3\.$"):
        cfg.transfer.psi = 3
    with pytest.raises(UsageError, match=r"^unknown config key 'transfer.psy'; did you mean 'transfer.psi'\?$"):
        cfg.transfer.psy = 0.1
    assert cfg.transfer.psi == 0.25 and "psy" not in cfg.model_dump()["transfer"]
    assert config_lib.updated(cfg, {"transfer.upsilon": 0.5}).transfer.upsilon == 0.5


def test_pi_reuse_s_annealing_rule_is_the_schedule_s_said_as_config_keys():
    """The rule lives in PiReuse (the part); the method says the part's sentence in config keys."""
    from drltg.collectors import PiReuse
    from drltg.errors import ArgumentError

    with pytest.raises(ArgumentError, match=r"^psi_end needs annealing_frames > 0") as raised:
        PiReuse(1.0, 0.9, psi_end=0.1)
    assert raised.value.argument == "psi_end"
    with pytest.raises(UsageError, match=r"^config key 'transfer.psi_end' needs annealing_frames > 0, the frames over "
                                         r"which psi decays\.$"):
        config_lib.resolve(overrides=["transfer.method=policy-reuse", "transfer.psi_end=0.1"])
    assert config_lib.resolve(overrides=["transfer.method=policy-reuse", "transfer.psi_end=0.1",
                                         "transfer.annealing_frames=100"]).transfer.psi_end == 0.1


def test_a_key_that_came_with_a_new_default_reads_as_the_old_behaviour_where_a_saved_config_lacks_it():
    """jumpstart's guide_curriculum came with JSRL's return-driven curriculum as its default; a run saved before
    the key existed ran on the clock: its config reads back as ``frames``, and comparing it with today's
    default says the key differs (a resume is refused, a report's pairing names it) instead of passing it."""
    from drltg.config import config_changes

    new = config_lib.resolve(overrides=["transfer.method=jumpstart"]).model_dump()
    old = {**new, "transfer": {k: v for k, v in new["transfer"].items()
                               if k not in ("guide_curriculum", "bc_alpha", "sf_epsilon")}}
    assert config_lib.build(old, saved=True).transfer.guide_curriculum == "frames"
    assert config_lib.build(old).transfer.guide_curriculum == "return"  # a file a user writes: today's default
    assert config_lib.build(old, saved=True).transfer.bc_alpha is None
    assert config_changes(old, new) == ["transfer.guide_curriculum"]  # bc_alpha, sf_epsilon: methods not used
    clock = config_lib.resolve(overrides=["transfer.method=jumpstart", "transfer.guide_curriculum=frames"])
    assert config_changes(old, clock) == []


def test_config_changes_without_the_task_registry():
    """env_defaults=False (the analysis): an env key only one config sets is not compared, one both set is;
    a built-in method's option an older config lacks stands for its default."""
    from drltg.config import config_changes, env_keys_set_once

    demos = ["transfer.method=demonstrations", "transfer.source=demonstrator:x"]
    full = config_lib.resolve(None, demos, task="fourrooms/northeast", algo="sac").model_dump()
    old = {**full, "env": {}, "transfer": {k: v for k, v in full["transfer"].items() if k != "bc_weight"}}
    assert config_changes(old, full, env_defaults=False) == []
    assert env_keys_set_once(old, full) == sorted(f"env.{k}" for k in full["env"])
    assert config_changes({k: v for k, v in full.items() if k != "env"}, full, env_defaults=False) == []
    changed = {**full, "env": {**full["env"], "horizon": 60},
               "transfer": {**full["transfer"], "bc_weight": 3.0}}
    assert config_changes(full, changed, env_defaults=False) == ["env.horizon", "transfer.bc_weight"]
    assert config_changes({**old, "transfer": {**old["transfer"]}}, {**old, "transfer": {
        **old["transfer"], "bc_weight": 3.0}}, env_defaults=False) == ["transfer.bc_weight"]


ORDERS = [("optim.lr=0.5", "optim={lr: 0.1}", "optim.lr"), ("env.horizon=50", "env={horizon: 60}", "env.horizon")]


@pytest.mark.parametrize("first, second, key", ORDERS)
@pytest.mark.parametrize("command", ["train", "experiment"])
def test_overrides_that_set_one_key_twice_are_refused_in_either_order(first, second, key, command, tmp_path,
                                                                      capsys):
    for a, b in ((first, second), (second, first)):
        args = (["train", "fourrooms/northeast", "--run-dir", str(tmp_path / "run")] if command == "train"
                else ["experiment", "fourrooms-near", "--method", "reward-shaping", "--frames", "64",
                      "--out", str(tmp_path / "exp")])
        assert main([*args, "-o", a, "-o", b]) == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and f"config key '{key}' is set twice by -o" in err, err
        assert not (tmp_path / "run").exists() and not (tmp_path / "exp").exists()


def test_an_env_mapping_and_an_env_key_give_the_same_config_in_either_order():
    a = config_lib.resolve({}, ["env.horizon=50", "env={step_cost: 0.5}"], task="fourrooms/northeast")
    b = config_lib.resolve({}, ["env={step_cost: 0.5}", "env.horizon=50"], task="fourrooms/northeast")
    assert a == b and (a.env["horizon"], a.env["step_cost"]) == (50, 0.5)


@pytest.mark.parametrize("overrides, key", [
    (["optim.lr=1e-3", "optim.lr=3e-4"], "optim.lr"),
    (["optim.lr=1e-3", "optim.lr=1e-3"], "optim.lr"),
    (["env.horizon=50", "seed=1", "env.horizon=60"], "env.horizon"),
    (["optim={gamma: 0.9}", "optim.gamma=0.9"], "optim.gamma"),
])
def test_the_same_override_key_given_twice_is_refused(overrides, key):
    with pytest.raises(UsageError) as err:
        config_lib.refuse_conflicts(overrides)
    first, second = overrides[0], overrides[-1]
    assert str(err.value) == f"config key '{key}' is set twice by -o ('{first}', then '{second}'); give it once."
    config_lib.refuse_conflicts(["optim.lr=0.5", "optim={gamma: 0.9}", "env.horizon=5", "env={step_cost: 0}"])


def test_cli_refuses_the_same_override_twice_with_exit_2(tmp_path, capsys):
    run_dir = tmp_path / "run"
    assert main(["train", "fourrooms/northeast", "--run-dir", str(run_dir), "-o", "optim.lr=1e-3",
                 "-o", "optim.lr=3e-4"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.endswith("config key 'optim.lr' is set twice by -o ('optim.lr=1e-3', then 'optim.lr=3e-4'); give it "
                        "once.") and len(err.splitlines()) == 1
    assert not run_dir.exists()


def test_declared_env_options_are_those_of_the_imported_signature():
    """A task that declares its options at register_task (so a config is checked without importing the env)
    declares the keywords and defaults of its factory's signature, and no others."""
    from drltg.envs import registry

    declared = [spec for spec in TASKS.values() if spec.options is not None]
    assert {spec.entry for spec in declared} >= {"drltg.envs.fourrooms:FourRoomsEnv",
                                                 "drltg.envs.gridrooms:GridFourRoomsEnv"}
    for spec in declared:
        signature = {k: v for k, v in registry._signature_keywords(spec.factory).items()
                     if k not in registry.BUILD_KEYWORDS}
        assert spec.options == signature, spec.name


def test_the_entry_points_take_a_mapping_resolved_as_a_config_file():
    from drltg.envs import make_env
    from drltg.learners import make_agent

    agent = make_agent(make_env("fourrooms/northeast"), {"task": "fourrooms/northeast", "network": {"hidden": [8]}})
    assert [m.out_features for m in agent.actor.modules() if isinstance(m, torch.nn.Linear)] == [8, 4]
    assert config_lib.as_config({"algo": "td3"}) == config_lib.resolve(None, ["algo=td3"])
    with pytest.raises(UsageError, match=r"^config key 'network.hidden' must be a non-empty list"):
        make_agent(make_env("fourrooms/northeast"), {"network": {"hidden": []}})


def test_every_committed_run_config_loads_as_it_was_written():
    """The config.yaml of every run kept in the repository reads as a typed config with the same values."""
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    paths = [p for folder in ("results", "tests/data") for p in sorted((root / folder).rglob("config.yaml"))]
    assert len(paths) > 100
    for path in paths:
        saved = config_lib.load_yaml(path)
        assert config_lib.config_changes(saved, config_lib.build(saved, saved=True), env_defaults=False) == [], path


def test_a_methods_plain_types_read_values_as_the_builtin_keys(registries):
    from typing import Optional

    from drltg.transfer import Transfer, TransferMethod, register_method

    register_method(TransferMethod("test-plain", "", lambda *a, **k: Transfer(), options={
        "count": (int, Field(2, ge=0)), "gain": (Optional[float], None), "names": (list[str], []),
        "on": (bool, False)}))
    cfg = _resolve("transfer.count=1e1", "transfer.gain=1", "transfer.names=[a]", "transfer.on=true")
    assert (cfg.transfer.count, cfg.transfer.gain, cfg.transfer.names, cfg.transfer.on) == (10, 1.0, ["a"], True)
    assert (type(cfg.transfer.count), type(cfg.transfer.gain)) == (int, float)
    for override, message in [
        ("transfer.count=three", "config key 'transfer.count' must be an integer >= 0, got 'three'."),
        ("transfer.count=true", "config key 'transfer.count' must be an integer >= 0, got True."),
        ("transfer.gain=x", "config key 'transfer.gain' must be a number or null, got 'x'."),
        ("transfer.on=1", "config key 'transfer.on' must be true or false, got 1."),
        ("transfer.names=[1]", "config key 'transfer.names' must be a list, got [1]."),
    ]:
        with pytest.raises(UsageError) as err:
            _resolve(override)
        assert str(err.value) == message


@pytest.mark.parametrize("text, frames", [("50000", 50000), ("50k", 50000), ("1e4", 10000), ("1.5M", 1500000),
                                          ("2K", 2000), (" 64 ", 64)])
def test_frame_counts_read_as_every_command_writes_them(text, frames):
    assert config_lib.frame_count(text) == frames


@pytest.mark.parametrize("text", ["0", "-5", "2.5", "1.5k7", "abc", "1e13", "nan", ""])
def test_a_frame_count_that_is_not_a_whole_positive_number_is_refused(text, capsys):
    from drltg.cli import main

    assert main(["train", "fourrooms/northeast", "--frames", text, "--run-dir", "/nonexistent/never"]) == 2  # no exit
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "is not a whole number of frames >= 1" in err, err


def test_an_unknown_key_of_a_known_section_is_answered_with_its_keys(capsys):
    from drltg.cli import main

    with pytest.raises(UsageError, match=r"^unknown config key 'optim.learning_rate'; the keys of optim are optim.lr, "
                                         r"optim.updates_per_batch, .*optim.cudagraphs.$"):
        config_lib.resolve(None, ["optim.learning_rate=1e-3"])
    assert main(["train", "fourrooms/northeast", "-o", "optim.lr", "1e-3"]) == 2
    assert capsys.readouterr().err == ("drltg: error: unrecognized arguments: 1e-3; -o takes KEY=VALUE as one "
                                       "argument, e.g. -o optim.lr=VALUE\n")


def test_a_learner_section_one_run_does_not_read_is_not_a_change():
    """``soc.*`` never reaches a SAC learner (``ALGO_SECTIONS``): a SAC run resumed with another option count is
    the same run; between two SOC runs it is a change, and between SAC and SOC ``algo`` says it."""
    from drltg.config import config_changes

    def cfg(algo, *overrides):
        return config_lib.resolve(None, list(overrides), task="fourrooms/northeast", algo=algo)

    assert config_changes(cfg("sac"), cfg("sac", "soc.num_options=2")) == []
    assert config_changes(cfg("soc"), cfg("soc", "soc.num_options=2")) == ["soc.num_options"]
    assert config_changes(cfg("sac"), cfg("soc", "soc.num_options=2")) == ["algo"]
    assert config_changes(cfg("sac"), cfg("soc", "sac.alpha_init=0.5")) == ["algo", "sac.alpha_init"]  # both read it
    assert config_changes(cfg("td3"), cfg("td3", "sac.alpha_init=0.5")) == []


@pytest.mark.parametrize("word, choices, hint", [
    ("optim.lrr", ["optim.lr", "optim.batch_size"], "optim.lr"),  # a near spelling
    ("gpus", ["num_cpus", "num_gpus"], "num_gpus"),  # a choice that holds the word
    ("lift-place-seed", ["lift-place-seed-barrier", "lift"], "lift-place-seed-barrier"),
    ("name", ["pairs", "frames", "seeds"], None),  # 'ame' alone: similarity 0.6, no suggestion
    ("zzz", ["pairs"], None),
])
def test_a_suggestion_is_a_near_spelling_or_a_containing_choice(word, choices, hint):
    from drltg.errors import closest

    assert closest(word, choices) == hint
