"""What a config may name comes from one registry each (drltg.config.registry): every built-in transfer
method and learner is known first thing in a fresh process, in any import order, a learner added to
``drltg.learners.ALGOS`` is a valid ``--algo``, and its options model is the config section of its name."""
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from drltg import config as config_lib
from drltg.errors import UsageError
from tests.test_reliability import train_args

ROOT = Path(__file__).resolve().parents[1]
BUILTIN = ("none", "reward-shaping", "value-shaping", "policy-reuse", "jumpstart", "model-reuse", "demonstrations",
           "kickstarting", "sf-gpi")

RESOLVE_EVERY_METHOD = """
from drltg.config import resolve
from drltg.errors import UsageError
for method in {methods!r}:
    cfg = resolve(overrides=["transfer.method=" + method])
    assert cfg.transfer.method == method, cfg.transfer.method
assert resolve(overrides=["transfer.method=policy-reuse", "transfer.psi=0.5"]).transfer.psi == 0.5
assert resolve(overrides=["algo=soc", "soc.num_options=2"]).soc.num_options == 2  # a learner's own section
try:
    resolve(overrides=["transfer.method=policy-reuse+jumpstart"])
except UsageError as err:
    print("refused:", err)
print("ok")
"""


def _python(code: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120)


@pytest.mark.parametrize("first", ["", "import drltg.transfer.policy_reuse", "import drltg.learners",
                                   "import drltg.config.registry", "from drltg.transfer import registry"])
def test_every_builtin_method_and_a_combination_resolve_in_a_fresh_process_in_any_import_order(first):
    methods = (*BUILTIN, "model-reuse+demonstrations", "reward-shaping+policy-reuse")
    done = _python(first + "\n" + RESOLVE_EVERY_METHOD.format(methods=methods))
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[-1] == "ok"
    assert lines[-2] == ("refused: transfer.method 'policy-reuse+jumpstart': policy-reuse and jumpstart both set "
                         "the collector's policy; combine at most one of them.")


def test_importing_the_methods_writes_no_config_state():
    """Importing drltg.transfer registers nothing: the registry finds the methods on its first lookup."""
    done = _python("import drltg.transfer, drltg.learners\nfrom drltg.config.registry import METHODS, LEARNERS, "
                   "LEARNER_OPTIONS as O\nprint(METHODS._found, LEARNERS._found, O._found, METHODS._entries, "
                   "LEARNERS._entries, O._entries)")
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["False", "False", "False", "{}", "{}", "{}"]


def test_the_builtin_methods_and_learners_are_the_registrys_entry_points():
    from drltg.learners import ALGOS, make_sac_agent
    from drltg.transfer import METHODS
    from drltg.transfer.policy_reuse import POLICY_REUSE

    assert config_lib.method_names() == ("none", *sorted(BUILTIN[1:]))  # the baseline first, then by name
    assert tuple(ALGOS) == ("sac", "soc", "td3")
    assert METHODS["policy-reuse"] is POLICY_REUSE and ALGOS["sac"] is make_sac_agent
    assert all(METHODS[name].name == name for name in BUILTIN)


@pytest.fixture
def learners():
    registries = (config_lib.LEARNERS, config_lib.LEARNER_OPTIONS)
    saved = [dict(registry) for registry in registries]
    yield config_lib.LEARNERS
    for registry, entries in zip(registries, saved):
        registry.clear()
        registry.update(entries)


def test_a_learner_added_to_algos_is_accepted_by_algo_and_trains(learners, tmp_path, capsys):
    """docs/extending.md's way: a ``make_<algo>_agent`` added to ``drltg.learners.ALGOS``."""
    from drltg.cli import main
    from drltg.learners import ALGOS, make_sac_agent

    built = []

    def make_my_agent(env, cfg):
        built.append(cfg.algo)
        return make_sac_agent(env, cfg)

    with pytest.raises(UsageError, match="^unknown algorithm 'my-sac': config key 'algo' must be one of sac, soc, "
                                         "td3.$"):
        config_lib.resolve(algo="my-sac")
    ALGOS["my-sac"] = make_my_agent
    assert config_lib.resolve(algo="my-sac").algo == "my-sac"
    assert main(train_args(tmp_path / "run", "--algo", "my-sac")) == 0, capsys.readouterr().err
    assert built == ["my-sac"]
    assert yaml.safe_load((tmp_path / "run" / "config.yaml").read_text())["algo"] == "my-sac"
    del ALGOS["my-sac"]
    with pytest.raises(UsageError, match="^unknown algorithm 'my-sac'"):
        config_lib.build({"algo": "my-sac"})


def test_a_learner_s_options_model_is_the_config_section_of_its_name(learners, tmp_path, capsys):
    """docs/extending.md's way: a :class:`Section` in ``LEARNER_OPTIONS`` under the learner's name gives it
    typed keys that ``-o`` sets, that are checked like every key, saved in config.yaml and read by the learner."""
    from pydantic import Field

    from drltg.cli import main
    from drltg.learners import ALGOS, make_sac_agent

    class MySACOptions(config_lib.Section):
        temperature: config_lib.Float = Field(0.2, gt=0, description="my_sac: SAC's temperature, kept fixed")

    def make_my_agent(env, cfg):
        return make_sac_agent(env, config_lib.updated(cfg, {"sac.alpha_init": cfg.my_sac.temperature,
                                                             "sac.fixed_alpha": True}))

    ALGOS["my_sac"], config_lib.LEARNER_OPTIONS["my_sac"] = make_my_agent, MySACOptions
    assert config_lib.resolve(algo="my_sac").my_sac.temperature == 0.2
    assert "my_sac.temperature" in config_lib.keys() and "my_sac.temperature" in config_lib.describe()
    with pytest.raises(UsageError, match=r"^config key 'my_sac.temperature' must be a number > 0, got -1.$"):
        config_lib.resolve(overrides=["algo=my_sac", "my_sac.temperature=-1"])
    args = train_args(tmp_path / "run", "--algo", "my_sac", "-o", "my_sac.temperature=0.5")
    assert main(args) == 0, capsys.readouterr().err
    saved = yaml.safe_load((tmp_path / "run" / "config.yaml").read_text())
    assert saved["my_sac"] == {"temperature": 0.5}
    from drltg.store.networks import load

    state, _ = load(tmp_path / "run", "last")
    assert state["log_alpha"].exp().item() == pytest.approx(0.5)  # the learner read its own key
    del config_lib.LEARNER_OPTIONS["my_sac"]
    with pytest.raises(UsageError, match="^unknown config key 'my_sac'"):
        config_lib.build(saved)
    config_lib.LEARNER_OPTIONS["my-sac"] = MySACOptions
    with pytest.raises(UsageError, match="^the options of the learner 'my-sac' cannot be a config section of that "
                                         "name: a learner with options is named as a Python identifier"):
        config_lib.keys()


def test_a_registry_reads_its_group_s_entry_points_and_says_when_drltg_s_own_are_missing(monkeypatch):
    from importlib.metadata import EntryPoint

    from drltg.config import registry

    group = "drltg.test-methods"
    points = [EntryPoint("jumpstart", "drltg.transfer.policy_reuse:JUMPSTART", group),
              EntryPoint("none", "drltg.transfer.registry:NONE", group),
              EntryPoint("reuse", "drltg.transfer.policy_reuse:POLICY_REUSE", group)]
    monkeypatch.setattr(registry, "entry_points", lambda group: [p for p in points if p.group == group])
    methods = registry.Registry(group, "transfer method", builtin="none")
    assert methods.names() == ("none", "jumpstart", "reuse")  # found, none loaded yet
    assert methods["jumpstart"].name == "jumpstart"
    with pytest.raises(UsageError, match="^the entry point 'reuse' .* names the transfer method 'policy-reuse'; "):
        methods["reuse"]
    with pytest.raises(UsageError, match="^drltg's learners are entry points of its installed distribution \\(group "
                                         "drltg.nothing\\) and none was found: .*reinstall drltg"):
        "sac" in registry.Registry("drltg.nothing", "learner", builtin="sac")
