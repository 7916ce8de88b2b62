"""Run configuration: one nested dict, resolved in a fixed order and saved with the run.

    defaults (below) <- the task's own overrides (registry) <- a YAML file (--config) <- KEY=VALUE overrides

The resolved dict, the task's env settings included, is written to ``<run_dir>/config.yaml``;
``drltg train --config <run_dir>/config.yaml`` reproduces the run. Every key has a declared type and range in
``SCHEMA`` (``describe()`` lists them);
``resolve()`` checks them all before anything is built or written, so a typo or a value out of range is
one sentence naming the key, not a silent no-op or a failure deep inside a run.
"""
from __future__ import annotations

import copy
import difflib
import inspect
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable

import yaml

from drltg.errors import UsageError

DEFAULTS: dict[str, Any] = {
    "task": "fourrooms/northeast",
    "algo": "sac",
    "seed": 0,
    "frames": 50_000,
    "device": "cpu",
    "threads": 1,  # small nets are overhead-bound: one thread per run is fastest here
    "env": {},  # keyword overrides passed to drltg.envs.make_env
    "collector": {
        "num_envs": 8,
        "frames_per_batch": 32,
        "init_random_frames": 1024,
    },
    "buffer": {"size": 100_000, "batch_size": 256},
    "optim": {
        "lr": 3.0e-4,
        "updates_per_batch": 8,  # gradient steps per collected batch (UTD = this / frames_per_batch)
        "gamma": 0.99,
        "tau": 0.005,
    },
    "network": {"hidden": [256, 256], "layer_norm": "none"},
    "sac": {"alpha_init": 1.0, "fixed_alpha": False, "target_entropy": "auto"},
    "td3": {"exploration_noise": 0.1, "policy_noise": 0.2, "noise_clip": 0.5, "policy_delay": 2},
    # soft option-critic (drltg.losses.soc); the action temperature comes from "sac"
    "soc": {
        "num_options": 4,
        "option_policy": "soft",  # soft (softmax of Q_Omega / alpha_Omega) | egreedy
        "option_alpha_init": None,  # None: sac.alpha_init
        "fixed_option_alpha": False,
        "option_target_entropy": "auto",  # 0.5 * log(num_options)
        "option_epsilon": 0.1,  # egreedy only
        "deliberation_cost": 0.01,  # xi > 0 keeps options running
        "option_entropy_bonus": False,  # soft policy: the option choice's entropy enters V_Omega
    },
    "eval": {"every": 5_000, "episodes": 16},
    "checkpoint": {"every": 10_000},
    "log": {"tensorboard": True, "every": 1_000},
    # How this run transfers knowledge: a method of drltg.transfer (none: the baseline); each method adds
    # its own transfer.* keys to this section when it is registered
    "transfer": {
        "method": "none",
        "source": None,  # source run directory, or demonstrator:TASK (methods with a source)
        "allow_incomplete": False,  # reuse a source run that did not finish (no summary.json)
    },
}
TRANSFER_KEYS = tuple(DEFAULTS["transfer"])
"""The ``transfer.*`` keys of every method; the others belong to one method (``TransferMethod.options``)."""
METHOD_RULES: dict[str, Any] = {}
"""``transfer.method`` -> the check its configs must pass (``"+"``: the check of every combination
``a+b``), filled with the method's keys (``DEFAULTS``, ``SCHEMA``) by :func:`drltg.transfer.register_method`:
import :mod:`drltg.transfer` (the commands do) before resolving a config that uses a transfer method."""
METHOD_OPTIONS: dict[str, str] = {}
"""``transfer.<key>`` -> the one method whose option it is (filled by ``register_method`` too)."""
BUILTIN_METHOD_OPTIONS: dict[str, dict[str, Any]] = {
    "policy-reuse": {"psi": 1.0, "upsilon": 0.95, "psi_end": None, "annealing_frames": 0},
    "jumpstart": {"guide_steps": 100, "guide_stages": 10, "guide_frames": 20_000},
    "model-reuse": {"freeze": [], "partial": False},
    "value-shaping": {"value_scale": 1.0},
    "demonstrations": {"demo_episodes": 50, "demo_ratio": 0.25, "bc_weight": 10.0, "bc_q_filter": False,
                       "bc_anneal_frames": 0},
}
"""The built-in methods' ``transfer.*`` options at their defaults, as plain data: the method modules
register them from here, and :func:`config_changes` reads them without importing the methods (and torch),
so the analysis of saved runs knows what a key an older config lacks stood for."""


def builtin_options(method: str, fields: dict[str, Any]) -> dict[str, tuple[Any, Any]]:
    """``key -> (default, Field)`` of a built-in method, the defaults taken from ``BUILTIN_METHOD_OPTIONS``."""
    defaults = BUILTIN_METHOD_OPTIONS[method]
    if set(fields) != set(defaults):
        raise ValueError(f"{method}: options {sorted(fields)} but defaults for {sorted(defaults)}")
    return {key: (copy.deepcopy(defaults[key]), field) for key, field in fields.items()}


@dataclass(frozen=True)
class Field:
    """The type and range of one config key.

    ``type`` is ``int``, ``float`` (any finite number), ``bool``, ``str``, ``list`` (of ``item``),
    ``"device"`` (a torch device string usable on this machine) or ``dict`` (``env``, whose keys are
    checked against the keywords the task's factory declares). Bounds are inclusive unless
    ``open_low``; ``nullable`` also accepts null, ``auto`` also accepts the string ``"auto"``.
    ``what`` replaces the generated description of the expected value; ``noun`` names a choice in the
    error message ("unknown algorithm 'ppo'").
    """

    type: Any
    help: str = ""
    low: float | None = None
    high: float | None = None
    open_low: bool = False
    choices: tuple = ()
    item: Any = None
    nonempty: bool = False
    nullable: bool = False
    auto: bool = False
    what: str = ""
    noun: str = ""

    def expected(self) -> str:
        """The accepted values, as the end of "must be ..."."""
        if self.what:
            text = self.what
        elif self.type is bool:
            text = "true or false"
        elif self.choices:
            text = "one of " + ", ".join(self.choices)
        elif self.type in (int, float):
            text = "an integer" if self.type is int else "a number"
            lo, hi = _number_text(self.low), _number_text(self.high)
            if lo is not None and hi is not None:
                text += f" in {'(' if self.open_low else '['}{lo}, {hi}]"
            elif lo is not None:
                text += f" {'>' if self.open_low else '>='} {lo}"
            elif hi is not None:
                text += f" <= {hi}"
        else:
            text = "a string"
        if self.auto:
            text = f"'auto' or {text}"
        if self.nullable:
            text += " or null"
        return text

    def check(self, key: str, value: Any) -> Any:
        """``value`` if it fits (integral floats of an integer key made ``int``); a UsageError otherwise."""
        if (value is None and self.nullable) or (self.auto and value == "auto"):
            return value
        if self.type == "device":
            return _check_device(key, value, self)
        ok, value = self._fit(value)
        if ok:
            return value
        if self.choices and isinstance(value, str):
            raise UsageError(
                f"unknown {self.noun or 'value'} {value!r}: config key '{key}' must be {self.expected()}."
            )
        raise UsageError(f"config key '{key}' must be {self.expected()}, got {_short(value)}.")

    def _fit(self, value: Any) -> tuple[bool, Any]:
        if self.type is bool or self.type is str:
            return isinstance(value, self.type) and (not self.choices or value in self.choices), value
        if self.type is list:
            if not isinstance(value, (list, tuple)) or (self.nonempty and not value):
                return False, value
            items = [self.item._fit(v) for v in value]
            return all(ok for ok, _ in items), [v for _, v in items]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            return False, value
        if self.type is int:
            if isinstance(value, float) and not value.is_integer():
                return False, value
            value = int(value)
        if self.low is not None and (value <= self.low if self.open_low else value < self.low):
            return False, value
        return self.high is None or value <= self.high, value


def _number_text(x: float | None) -> str | None:
    return None if x is None else str(int(x)) if float(x).is_integer() else f"{x:g}"


ALGOS = ("sac", "td3", "soc")
OPTION_POLICIES = ("soft", "egreedy")
_PROB = dict(low=0.0, high=1.0)
_POSITIVE = dict(low=0.0, open_low=True)

SCHEMA: dict[str, Field] = {
    "task": Field(str, "registered task name (`drltg tasks`)", what="a registered task name"),
    "algo": Field(str, "learner; sac is discrete SAC on discrete tasks", choices=ALGOS, noun="algorithm"),
    "seed": Field(int, "seed of envs, networks and sampling", low=0, high=2**31 - 1),
    "frames": Field(int, "environment frames, rounded up to whole collector batches", low=1),
    "device": Field("device", "torch device", what="a torch device such as cpu, cuda or cuda:0"),
    "threads": Field(int, "CPU threads per run", low=1),
    "env": Field(dict, "keyword arguments of the task's env factory, checked against its declared defaults",
                 what="a mapping of the task's keyword arguments (e.g. env.horizon=200)"),
    "collector.num_envs": Field(int, "training envs stepped as one batch", low=1),
    "collector.frames_per_batch": Field(int, "frames per collector batch, a multiple of num_envs", low=1),
    "collector.init_random_frames": Field(int, "random-action warm-up frames", low=0),
    "buffer.size": Field(int, "replay capacity (transitions)", low=1),
    "buffer.batch_size": Field(int, "minibatch size", low=1),
    "optim.lr": Field(float, "Adam learning rate", **_POSITIVE),
    "optim.updates_per_batch": Field(int, "gradient steps per collected batch", low=1),
    "optim.gamma": Field(float, "discount", **_PROB, open_low=True),
    "optim.tau": Field(float, "target-network smoothing", **_PROB, open_low=True),
    "network.hidden": Field(list, "MLP widths of actor and critics", item=Field(int, low=1), nonempty=True,
                            what="a non-empty list of positive integers (e.g. [64, 64])"),
    "network.layer_norm": Field(str, "LayerNorm after every hidden layer of the critics, of every network, or none",
                                choices=("none", "critics", "all")),
    "sac.alpha_init": Field(float, "initial entropy temperature", **_POSITIVE),
    "sac.fixed_alpha": Field(bool, "keep the temperature at alpha_init"),
    "sac.target_entropy": Field(float, "entropy the temperature is tuned to", auto=True),
    "td3.exploration_noise": Field(float, "std of the exploration noise", low=0.0),
    "td3.policy_noise": Field(float, "std of the target policy smoothing noise", low=0.0),
    "td3.noise_clip": Field(float, "clip of the target policy noise", low=0.0),
    "td3.policy_delay": Field(int, "critic updates per actor update", low=1),
    "soc.num_options": Field(int, "options of the soft option-critic (--options)", low=1),
    "soc.option_policy": Field(str, "policy over options", choices=OPTION_POLICIES, noun="option policy"),
    "soc.option_alpha_init": Field(float, "initial option temperature; null: sac.alpha_init", **_POSITIVE,
                                   nullable=True),
    "soc.fixed_option_alpha": Field(bool, "keep the option temperature fixed"),
    "soc.option_target_entropy": Field(float, "entropy over options; auto: 0.5 log(num_options)", auto=True),
    "soc.option_epsilon": Field(float, "exploration of the egreedy option policy", **_PROB),
    "soc.deliberation_cost": Field(float, "xi, added to the termination advantage", low=0.0),
    "soc.option_entropy_bonus": Field(bool, "the option choice's entropy enters V_Omega"),
    "eval.every": Field(int, "frames between evaluations", low=1),
    "eval.episodes": Field(int, "evaluation episodes", low=1),
    "checkpoint.every": Field(int, "frames between checkpoints", low=1),
    "log.tensorboard": Field(bool, "also log to TensorBoard"),
    "log.every": Field(int, "frames between logged training scalars", low=1),
    "transfer.method": Field(str, "transfer method (`drltg tasks` lists them)", choices=("none",),
                             noun="transfer method"),
    "transfer.source": Field(str, "source run directory, or demonstrator:TASK", nullable=True,
                             what="a source run directory, demonstrator:TASK"),
    "transfer.allow_incomplete": Field(bool, "reuse a source run that did not finish (no summary.json)"),
}
"""Every config key (dotted) with its type and range; ``validate`` checks a config against it. The
registered transfer methods add their ``transfer.*`` keys (:func:`drltg.transfer.register_method`)."""

_SECTIONS = {k for k, v in DEFAULTS.items() if isinstance(v, dict) and v}
_ENV_RESERVED = {"batch_size": "collector.num_envs and eval.episodes", "device": "device", "seed": "seed"}
# How a batch of envs is stepped (worker processes or this one), not what it steps: the same trajectories
# either way (tests/test_robosuite.py), so two configs that differ only there are the same run.
ENV_EXECUTION_KEYS = ("env.parallel", "env.mp_start_method")


def _flatten(d: dict, prefix: str = "") -> dict[str, Any]:
    out = {}
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict) and v and key != "env":
            out.update(_flatten(v, key + "."))
        else:
            out[key] = v
    return out


def _valid_keys() -> list[str]:
    return sorted(_flatten(DEFAULTS)) + ["env"]


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def set_key(cfg: dict, dotted: str, value: Any) -> None:
    """Set ``cfg[a][b] = value`` for ``dotted = "a.b"``; a mapping given for a section (``optim``)
    is merged into it; keys under ``env.`` are the task's own keyword arguments."""
    parts = dotted.split(".")
    if parts[0] == "env":
        if len(parts) > 2:
            raise UsageError(f"config key '{dotted}' is too deep: env options are one level, e.g. env.horizon=200.")
        if len(parts) == 1:  # a mapping adds to the env options set so far, as env.KEY=VALUE does
            if isinstance(value, dict):
                merge(cfg, {"env": value})
            else:
                cfg["env"] = value
            return
        if not isinstance(cfg.get("env"), dict):
            raise UsageError(f"config key 'env' must be {SCHEMA['env'].expected()}, got {_short(cfg.get('env'))}.")
        cfg["env"][parts[1]] = value
        return
    if dotted in _SECTIONS:
        if not isinstance(value, dict):
            keys = ", ".join(f"{dotted}.{k}" for k in DEFAULTS[dotted])
            raise UsageError(f"config key '{dotted}' must be a mapping of {keys}, got {_short(value)}.")
        merge(cfg, value, dotted + ".")
        return
    if dotted not in _flatten(DEFAULTS):
        hint = difflib.get_close_matches(dotted, _valid_keys(), n=1)
        raise UsageError(
            f"unknown config key '{dotted}'" + (f"; did you mean '{hint[0]}'?" if hint else ".")
        )
    node = cfg
    for p in parts[:-1]:
        node = node.setdefault(p, {})
    node[parts[-1]] = value


def merge(cfg: dict, overrides: dict, prefix: str = "") -> None:
    """Merge a nested dict of overrides into ``cfg``, validating every key."""
    for k, v in overrides.items():
        key = f"{prefix}{k}"
        if key == "env":
            if not isinstance(v, dict):
                raise UsageError(f"config key 'env' must be {SCHEMA['env'].expected()}, got {_short(v)}.")
            if not isinstance(cfg.get("env"), dict):
                cfg["env"] = {}
            cfg["env"].update(v)
        else:
            set_key(cfg, key, v)


_NUMBER = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?")


def parse_override(text: str) -> tuple[str, Any]:
    """``"optim.lr=1e-3"`` -> ``("optim.lr", 0.001)``; values are parsed as YAML scalars/lists."""
    if "=" not in text:
        raise UsageError(f"override '{text}' must look like KEY=VALUE, e.g. optim.lr=1e-3.")
    key, raw = text.split("=", 1)
    try:
        value = yaml.safe_load(raw)
    except yaml.YAMLError:
        value = raw
    if isinstance(value, str) and _NUMBER.fullmatch(value.strip()):  # YAML reads "1e-3" as a string
        value = float(value)
    return key.strip(), value


class UniqueKeyLoader(yaml.SafeLoader):
    """``yaml.SafeLoader`` that refuses a mapping with a key twice (plain YAML keeps the last silently)."""

    def construct_mapping(self, node, deep=False):
        seen = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=True)
            if key in seen:
                raise yaml.constructor.ConstructorError(
                    None, None, f"key {key!r} appears twice (line {key_node.start_mark.line + 1})", key_node.start_mark)
            seen.add(key)
        return super().construct_mapping(node, deep)


def load_yaml(path: str | Path, what: str = "config file") -> dict:
    """A YAML mapping from ``path``; a missing file, a duplicate key, bad YAML or a file that is not
    UTF-8 text is one :class:`UsageError` sentence."""
    path = Path(path)
    if not path.is_file():
        raise UsageError(f"{what} '{path}' does not exist.")
    try:
        data = yaml.load(path.read_text(encoding="utf-8"), Loader=UniqueKeyLoader) or {}
    except UnicodeDecodeError as err:
        raise UsageError(f"{what} '{path}' is not UTF-8 text (byte {err.start}).") from None
    except yaml.constructor.ConstructorError as err:
        if "appears twice" in str(err.problem):
            raise UsageError(f"{what} '{path}': {err.problem}; give each key once.") from None
        raise UsageError(f"{what} '{path}' is not valid YAML ({err.__class__.__name__}).") from None
    except yaml.YAMLError as err:
        raise UsageError(f"{what} '{path}' is not valid YAML ({err.__class__.__name__}).") from None
    if not isinstance(data, dict):
        raise UsageError(f"{what} '{path}' must hold a mapping of keys.")
    return data


def resolve(
    base: dict | None = None,
    overrides: Iterable[str] = (),
    **explicit: Any,
) -> dict:
    """Build a full config: defaults <- task overrides <- ``base`` (e.g. a YAML file) <- ``explicit``
    keyword values (e.g. ``--seed``) <- ``KEY=VALUE`` ``overrides``; then ``validate`` it, so that
    nothing is built or written from a config with a wrong key, type or range."""
    if base is not None and not isinstance(base, dict):
        raise UsageError(f"a config must be a mapping of config keys, got {_short(base)}.")
    base = dict(base or {})
    parsed = [parse_override(text) for text in overrides]
    cfg = copy.deepcopy(DEFAULTS)
    task = cfg["task"]
    for given in (base.get("task"), explicit.get("task"), *(v for k, v in parsed if k == "task")):
        if given is not None:
            task = given
    merge(cfg, copy.deepcopy(_task_spec(task).train))
    merge(cfg, base)
    for key, value in explicit.items():
        if value is not None:
            set_key(cfg, key, value)
    for key, value in parsed:
        set_key(cfg, key, value)
    validate(cfg)
    cfg["env"] = {**task_env(cfg["task"]), **cfg["env"]}
    return cfg


def _override_leaves(key: str, value: Any) -> dict[str, Any]:
    """The single keys an override sets: ``optim={lr: 1}`` sets ``optim.lr``, ``env={horizon: 5}`` ``env.horizon``."""
    if isinstance(value, dict) and key == "env":
        return {f"env.{k}": v for k, v in value.items()}
    if isinstance(value, dict) and key in _SECTIONS:
        return _flatten(value, key + ".")
    return {key: value}


def refuse_conflicts(overrides: Iterable[str]) -> None:
    """A user's ``-o`` overrides that set one key to two values in two forms (``optim={lr: 1}`` and
    ``optim.lr=2``) are refused: which one wins would depend on their order. The same ``KEY=`` given twice
    is plainly a replacement (the last wins), as :func:`resolve` applies overrides in order."""
    seen: dict[str, tuple[str, Any]] = {}
    for key, value in map(parse_override, overrides):
        for leaf, v in _override_leaves(key, value).items():
            if leaf in seen and seen[leaf][0] != key and seen[leaf][1] != v:
                raise UsageError(f"config key '{leaf}' is set twice by -o, to {_short(seen[leaf][1])} (by "
                                 f"'{seen[leaf][0]}') and to {_short(v)} (by '{key}'); give it once.")
            seen[leaf] = (key, v)


def task_env(task: str) -> dict[str, Any]:
    """Every env setting of ``task`` at its default (the factory's declared keywords, the task's
    registered values over them), as plain YAML values: ``resolve`` writes them all into the config,
    so a run's ``config.yaml`` says exactly which env it trained on and a changed default is a
    changed config."""
    declared, _ = env_defaults(task)
    return {k: _plain(v) for k, v in declared.items() if k not in _ENV_RESERVED}


def config_changes(saved: dict, cfg: dict, *, env_defaults: bool = True) -> list[str]:
    """The keys in which two configs of one task differ (``cfg`` gives the task). A key one of them
    lacks counts only when the other sets it to something else than its default, for ``env.*`` the
    task's: runs saved before the key existed, or before env settings were saved in full, stay the
    same run (resumable, and comparable in one report). Options of a transfer method that neither
    config uses do not count (a baseline is the same run whatever another method's defaults are), nor
    do ``ENV_EXECUTION_KEYS``.

    ``env_defaults=False`` leaves the task registry (and torch with it) unimported: an ``env.*`` key
    only one config sets is then not compared, its default being unknown (:func:`env_keys_set_once`
    names them)."""
    env = {}
    if env_defaults:
        try:
            env = task_env(cfg["task"])
        except (KeyError, UsageError):  # a task this process does not know: no env defaults to fill in
            pass
    builtin = {k: v for options in BUILTIN_METHOD_OPTIONS.values() for k, v in options.items()}
    defaults = {**DEFAULTS, "env": env, "transfer": {**builtin, **DEFAULTS["transfer"]}}
    owners = {**{k: m for m, options in BUILTIN_METHOD_OPTIONS.items() for k in options}, **METHOD_OPTIONS}
    methods = {part for c in (saved, cfg) if isinstance(m := _lookup(c, "transfer.method"), str)
               for part in m.split("+")}
    unknown = set() if env_defaults else set(env_keys_set_once(saved, cfg))
    if not env_defaults and (_lookup(saved, "env") is KeyError) != (_lookup(cfg, "env") is KeyError):
        unknown.add("env")

    def missing_as_default(a, b, key):
        return _lookup(a, key) is KeyError and _lookup(b, key) == _lookup(defaults, key)

    def unused(key):  # an option of a method neither run uses changes nothing they do
        owner = owners.get(key.removeprefix("transfer.")) if key.startswith("transfer.") else None
        return owner is not None and owner not in methods

    return sorted(key for key in _diff_keys(saved, cfg)
                  if not (missing_as_default(saved, cfg, key) or missing_as_default(cfg, saved, key) or unused(key)
                          or key in ENV_EXECUTION_KEYS or key in unknown))


def env_keys_set_once(a: dict, b: dict) -> list[str]:
    """The ``env.*`` keys exactly one of two configs sets (one saved before env settings were saved in full)."""
    ea, eb = (c.get("env") if isinstance(c.get("env"), dict) else {} for c in (a, b))
    return sorted(f"env.{k}" for k in set(ea) ^ set(eb))


def _lookup(cfg: dict, dotted: str):
    node = cfg
    for part in dotted.split("."):
        if not isinstance(node, dict) or part not in node:
            return KeyError
        node = node[part]
    return node


def _diff_keys(a, b, prefix=""):
    if isinstance(a, dict) and isinstance(b, dict):
        for k in set(a) | set(b):
            yield from _diff_keys(a.get(k, KeyError), b.get(k, KeyError), f"{prefix}{k}.")
    elif a != b:
        yield prefix.rstrip(".")


def _plain(value: Any) -> Any:
    return [_plain(v) for v in value] if isinstance(value, (list, tuple)) else value


def validate(cfg: dict) -> None:
    """Check every key of a full config against ``SCHEMA`` and the rules that tie keys together;
    integral floats of integer keys become ``int`` and ``frames`` is rounded up to whole batches. The keys
    whose check imports torch or the task's module (``device``, ``env``) come last, so that any other
    mistake is reported at once."""
    for key, field in sorted(SCHEMA.items(), key=lambda item: item[0] in ("device", "env")):
        try:
            value = _get(cfg, key)
        except (KeyError, TypeError):
            raise UsageError(f"the config has no key '{key}'; resolve() fills in every key.") from None
        if key == "env":
            _check_env(cfg["task"], value)
        elif key == "transfer.method" and isinstance(value, str) and "+" in value:
            for part in value.split("+"):
                field.check(key, part)
        else:
            checked = field.check(key, value)
            if checked is not value:
                set_key(cfg, key, checked)
    fpb, n = cfg["collector"]["frames_per_batch"], cfg["collector"]["num_envs"]
    if fpb % n:
        raise UsageError(
            f"collector.frames_per_batch ({fpb}) must be a multiple of collector.num_envs ({n})."
        )
    if cfg["algo"] == "soc" and cfg["network"]["layer_norm"] != "none":
        raise UsageError("network.layer_norm applies to sac and td3; the soft option-critic's networks have none.")
    method = cfg["transfer"]["method"]
    rule = METHOD_RULES.get(method) or (METHOD_RULES.get("+") if "+" in method else None)
    if rule is not None:
        rule(cfg)
    cfg["frames"] = -(-cfg["frames"] // fpb) * fpb  # whole collector batches: the budget is exact


def _get(cfg: dict, dotted: str) -> Any:
    node = cfg
    for p in dotted.split("."):
        node = node[p]
    return node


def _task_spec(task: Any):
    from drltg.envs import TASKS  # registry import is cheap

    if not isinstance(task, str):
        raise UsageError(f"config key 'task' must be a registered task name, got {_short(task)}.")
    if task not in TASKS:
        hint = difflib.get_close_matches(task, list(TASKS), n=1)
        raise UsageError(
            f"unknown task '{task}'" + (f"; did you mean '{hint[0]}'?" if hint else "; see `drltg tasks`.")
        )
    return TASKS[task]


def _check_device(key: str, value: Any, field: Field) -> str:
    import torch

    try:
        if not isinstance(value, str):
            raise TypeError(value)
        device = torch.device(value)
    except (RuntimeError, TypeError, ValueError):
        raise UsageError(f"config key '{key}' must be {field.expected()}, got {_short(value)}.") from None
    backend = getattr(torch, device.type, None)
    available = getattr(backend, "is_available", None)
    if available is None:
        raise UsageError(f"config key '{key}' is '{value}', a device type drltg cannot train on; use cpu or cuda.")
    if not available():
        raise UsageError(
            f"config key '{key}' is '{value}' but no {device.type.upper()} device is available on this "
            "machine; use device=cpu."
        )
    count = getattr(backend, "device_count", None)
    if device.index is not None and device.type != "cpu" and count is not None and device.index >= count():
        raise UsageError(
            f"config key '{key}' is '{value}' but this machine has {count()} {device.type.upper()} "
            f"device(s), numbered from 0."
        )
    return value


def env_defaults(task: str) -> tuple[dict[str, Any], bool]:
    """The keyword arguments task ``task``'s factory declares with a default (its registered defaults
    win), and whether it also takes other keywords (``**kwargs``)."""
    spec = _task_spec(task)
    factory = spec.factory
    params = inspect.signature(factory.__init__ if inspect.isclass(factory) else factory).parameters
    declared = {
        name: p.default
        for name, p in params.items()
        if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY) and name != "self"
    }
    declared.update(spec.defaults)
    return declared, any(p.kind is p.VAR_KEYWORD for p in params.values())


def _check_env(task: str, env: Any) -> None:
    if not isinstance(env, dict):
        raise UsageError(f"config key 'env' must be {SCHEMA['env'].expected()}, got {_short(env)}.")
    declared, open_ended = env_defaults(task)
    for name, value in list(env.items()):
        key = f"env.{name}"
        if name in _ENV_RESERVED:
            raise UsageError(f"config key '{key}' cannot be set: the run sets it from {_ENV_RESERVED[name]}.")
        if name not in declared:
            if open_ended:
                continue
            known = ", ".join(sorted(set(declared) - set(_ENV_RESERVED)))
            raise UsageError(f"config key '{key}' is not an option of task '{task}'; its options are: {known}.")
        ref = declared[name]
        field = _field_like(ref)
        if field is None:
            continue
        try:
            env[name] = field.check(key, value)
        except UsageError:
            raise UsageError(
                f"config key '{key}' must be {field.expected()} (task '{task}' declares {name}={ref!r}), "
                f"got {_short(value)}."
            ) from None


def _field_like(ref: Any) -> Field | None:
    """The field an env keyword's declared default implies: its type, no range (the env checks that)."""
    if isinstance(ref, bool):
        return Field(bool)
    if isinstance(ref, int):
        return Field(int)
    if isinstance(ref, float):
        return Field(float)
    if isinstance(ref, str):
        return Field(str)
    if isinstance(ref, (list, tuple)) and ref:
        if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in ref):
            return Field(list, item=Field(float), nonempty=True, what="a list of numbers")
        if all(isinstance(v, str) for v in ref):
            return Field(list, item=Field(str), what="a list of strings")
    return None


def describe() -> str:
    """Every config key with its default, accepted values and meaning, as a Markdown table."""
    flat = _flatten(DEFAULTS)
    rows = ["| key | default | accepted values | meaning |", "|---|---|---|---|"]
    for key, field in SCHEMA.items():
        default = yaml.safe_dump(flat[key], default_flow_style=True).strip().removesuffix("...").strip()
        rows.append(f"| `{key}` | {default} | {field.expected()} | {field.help} |")
    return "\n".join(rows)


def dump(cfg: dict) -> str:
    return yaml.safe_dump(cfg, sort_keys=False)

