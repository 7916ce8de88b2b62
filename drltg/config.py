"""Run configuration: typed sections (pydantic models), resolved in a fixed order and saved with the run.

    defaults (the models below) <- the task's own overrides (registry) <- a YAML file (--config) <- KEY=VALUE overrides

:func:`resolve` returns a :class:`RunConfig` (``cfg.optim.lr``, ``cfg.transfer.method``); the resolved
config, the task's env settings included, is written to ``<run_dir>/config.yaml`` (:func:`dump`) and
``drltg train --config <run_dir>/config.yaml`` reproduces the run. Every key has a declared type and
range in its section's model (``describe()`` lists them); a typo or a value out of range is one
:class:`~drltg.errors.UsageError` sentence naming the key (pydantic's errors are translated), before
anything is built or written.

Two parts are open-ended: the ``transfer`` section holds, besides ``method``, ``source``,
``allow_incomplete`` and ``source_checkpoint``, the options of every registered transfer method (each
method's options are a model of their own, built when it is registered, :func:`add_method`), and ``env``
is a mapping of the task's keyword arguments, checked against the keywords its factory declares
(:func:`validate`).
"""
from __future__ import annotations

import copy
import difflib
import functools
import math
import re
import types
from pathlib import Path
from typing import Annotated, Any, Iterable, Literal, Optional, Union, get_args, get_origin

import yaml
from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    Strict,
    ValidationError,
    create_model,
    field_validator,
    model_validator,
)
from pydantic.fields import FieldInfo

from drltg import safe_yaml
from drltg.errors import UsageError

__all__ = ["RunConfig", "resolve", "build", "validate", "as_config", "updated", "describe", "dump", "keys", "defaults",
           "config_changes", "refuse_conflicts", "parse_override", "load_yaml", "task_env", "env_defaults",
           "Int", "Float", "Bool", "Str", "Section"]


# ----------------------------------------------------------------------------------------- value types
def _finite_number(value: Any) -> Any:
    # pydantic would also read "1", true and inf as numbers; a config key takes finite numbers only
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ValueError("not a finite number")
    return value


def _integral(value: Any) -> Any:
    value = _finite_number(value)
    return int(value) if isinstance(value, float) and value.is_integer() else value  # 1e3 from -o is 1000


Int = Annotated[int, BeforeValidator(_integral), Strict()]
"""An integer; an integral float (``-o frames=1e4``) becomes ``int``; strings and booleans are refused."""
Float = Annotated[float, BeforeValidator(_finite_number)]
"""A finite number (an integer is read as a float); strings and booleans are refused."""
Bool = Annotated[bool, Strict()]
"""``true`` or ``false`` only (not ``1``, ``"yes"``)."""
Str = Annotated[str, Strict()]
Number = Annotated[Union[int, float], BeforeValidator(_finite_number)]
"""An integer or a float, kept as given (an env keyword whose default is a list of numbers)."""

Probability = Annotated[float, BeforeValidator(_finite_number), Field(ge=0.0, le=1.0)]

MAX_EPISODES = 10_000
"""Most evaluation episodes a run or ``drltg evaluate`` takes (they step as one env batch)."""
MAX_THREADS = 512
"""Most CPU threads a run asks torch for (far more than a machine has is an error, not a request)."""
MAX_SEEDS = 1_000
"""Most seeds of one command (``--seeds``, an experiment's seeds)."""


def _what(text: str = "", noun: str = "") -> dict:
    """``what`` replaces the generated description of the accepted values; ``noun`` names a choice in
    the error message ("unknown algorithm 'ppo'")."""
    return {k: v for k, v in (("what", text), ("noun", noun)) if v}


class Section(BaseModel):
    """A config section: unknown keys are refused, assignments are checked."""

    model_config = ConfigDict(extra="forbid", validate_assignment=True)


# ----------------------------------------------------------------------------------------- the sections
class CollectorConfig(Section):
    num_envs: Int = Field(8, ge=1, description="training envs stepped as one batch")
    frames_per_batch: Int = Field(32, ge=1, description="frames per collector batch, a multiple of num_envs")
    init_random_frames: Int = Field(1024, ge=0, description="random-action warm-up frames")


class BufferConfig(Section):
    size: Int = Field(100_000, ge=1, description="replay capacity (transitions)")
    batch_size: Int = Field(256, ge=1, description="minibatch size")


class OptimConfig(Section):
    lr: Float = Field(3.0e-4, gt=0, description="Adam learning rate")
    updates_per_batch: Int = Field(8, ge=1, description="gradient steps per collected batch")
    # (UTD = updates_per_batch / collector.frames_per_batch)
    gamma: Float = Field(0.99, gt=0, le=1, description="discount")
    tau: Float = Field(0.005, gt=0, le=1, description="target-network smoothing")
    cudagraphs: Bool = Field(False, description="replay each gradient update as a captured CUDA graph "
                                                "(CUDA devices only)")


class NetworkConfig(Section):
    hidden: list[Annotated[Int, Field(ge=1)]] = Field(
        [256, 256], min_length=1, description="MLP widths of actor and critics",
        json_schema_extra=_what("a non-empty list of positive integers (e.g. [64, 64])"))
    layer_norm: Literal["none", "critics", "all"] = Field(
        "none", description="LayerNorm after every hidden layer of the critics, of every network, or none")


class SACConfig(Section):
    alpha_init: Float = Field(1.0, gt=0, description="initial entropy temperature")
    fixed_alpha: Bool = Field(False, description="keep the temperature at alpha_init")
    target_entropy: Union[Literal["auto"], Float] = Field("auto", description="entropy the temperature is tuned to")


class TD3Config(Section):
    exploration_noise: Float = Field(0.1, ge=0, description="std of the exploration noise")
    policy_noise: Float = Field(0.2, ge=0, description="std of the target policy smoothing noise")
    noise_clip: Float = Field(0.5, ge=0, description="clip of the target policy noise")
    policy_delay: Int = Field(2, ge=1, description="critic updates per actor update")


OPTION_POLICIES = ("soft", "egreedy")


class SOCConfig(Section):
    """The soft option-critic (drltg.losses.soc); its action temperature comes from the ``sac`` section."""

    num_options: Int = Field(4, ge=1, description="options of the soft option-critic (--options)")
    option_policy: Literal[OPTION_POLICIES] = Field(
        "soft", description="policy over options", json_schema_extra=_what(noun="option policy"))
    option_alpha_init: Optional[Annotated[Float, Field(gt=0)]] = Field(
        None, description="initial option temperature; null: sac.alpha_init")
    fixed_option_alpha: Bool = Field(False, description="keep the option temperature fixed")
    option_target_entropy: Union[Literal["auto"], Float] = Field(
        "auto", description="entropy over options; auto: 0.5 log(num_options)")
    option_epsilon: Probability = Field(0.1, description="exploration of the egreedy option policy")
    deliberation_cost: Float = Field(0.01, ge=0, description="xi, added to the termination advantage")
    option_entropy_bonus: Bool = Field(False, description="the option choice's entropy enters V_Omega")


class EvalConfig(Section):
    every: Int = Field(5_000, ge=1, description="frames between evaluations")
    episodes: Int = Field(16, ge=1, le=MAX_EPISODES, description="evaluation episodes")


class CheckpointConfig(Section):
    every: Int = Field(10_000, ge=1, description="frames between checkpoints")
    keep_best: Bool = Field(False, description="also keep checkpoints/best.pt, the checkpoint of the best evaluation")
    best_metric: Literal["auto", "success_rate", "lifted_rate", "return_mean"] = Field(
        "auto", description="the evaluation score best.pt maximises; auto: success_rate where the task reports it, "
                            "else return_mean")


class LogConfig(Section):
    tensorboard: Bool = Field(True, description="also log to TensorBoard")
    every: Int = Field(1_000, ge=1, description="frames between logged training scalars")


class TransferConfig(Section):
    """How a run transfers knowledge: a method of drltg.transfer (``none``: the baseline). The options of
    every registered method follow these four keys (the section :func:`transfer_model` builds)."""

    method: Str = Field("none", description="transfer method (`drltg tasks` lists them)",
                        json_schema_extra={"noun": "transfer method", "choices": "registered"})
    source: Optional[Str] = Field(None, description="source run directory, or demonstrator:TASK",
                                  json_schema_extra=_what("a source run directory, demonstrator:TASK"))
    allow_incomplete: Bool = Field(False, description="reuse a source run that did not finish (no summary.json)")
    source_checkpoint: Literal["last", "best"] = Field(
        "last", description="the source run's checkpoint reused: last.pt, or best.pt (kept with checkpoint.keep_best)")

    @field_validator("method")
    @classmethod
    def _registered(cls, value: str) -> str:
        names = method_names()
        for part in value.split("+"):
            if part not in names:
                raise UsageError(f"unknown transfer method {part!r}: config key 'transfer.method' must be one of "
                                f"{', '.join(names)}.")
        return value

    def __reduce__(self):  # a section of methods registered in this process: rebuilt from its values
        return _restore_transfer, (self.model_dump(),)


ALGOS = ("sac", "td3", "soc")
ENV_HELP = "keyword arguments of the task's env factory, checked against its declared defaults"


class RunConfig(Section):
    """One run's configuration. Build it with :func:`resolve` (defaults, task, file, overrides) or
    :func:`build` (a mapping, e.g. a saved ``config.yaml``); :func:`validate` adds the checks that need
    this machine or the task's env (``device``, ``env``, the transfer method's own rules)."""

    task: Str = Field("fourrooms/northeast", description="registered task name (`drltg tasks`)",
                      json_schema_extra=_what("a registered task name"))
    algo: Literal[ALGOS] = Field("sac", description="learner; sac is discrete SAC on discrete tasks",
                                               json_schema_extra=_what(noun="algorithm"))
    seed: Int = Field(0, ge=0, le=2**31 - 1, description="seed of envs, networks and sampling")
    frames: Int = Field(50_000, ge=1, description="environment frames, rounded up to whole collector batches")
    device: Str = Field("cpu", description="torch device",
                        json_schema_extra=_what("a torch device such as cpu, cuda or cuda:0"))
    threads: Int = Field(1, ge=1, le=MAX_THREADS, description="CPU threads per run")  # small nets are overhead-bound
    env: dict[Str, Any] = Field(default_factory=dict, description=ENV_HELP,
                                json_schema_extra=_what("a mapping of the task's keyword arguments (e.g. "
                                                        "env.horizon=200)"))
    collector: CollectorConfig = Field(default_factory=CollectorConfig)
    buffer: BufferConfig = Field(default_factory=BufferConfig)
    optim: OptimConfig = Field(default_factory=OptimConfig)
    network: NetworkConfig = Field(default_factory=NetworkConfig)
    sac: SACConfig = Field(default_factory=SACConfig)
    td3: TD3Config = Field(default_factory=TD3Config)
    soc: SOCConfig = Field(default_factory=SOCConfig)
    eval: EvalConfig = Field(default_factory=EvalConfig)
    checkpoint: CheckpointConfig = Field(default_factory=CheckpointConfig)
    log: LogConfig = Field(default_factory=LogConfig)
    transfer: TransferConfig = Field(default_factory=TransferConfig)

    @field_validator("task")
    @classmethod
    def _known_task(cls, value: str) -> str:
        _task_spec(value)
        return value

    @model_validator(mode="after")
    def _rules(self) -> RunConfig:
        """The rules that tie keys of two sections together."""
        fpb, n = self.collector.frames_per_batch, self.collector.num_envs
        if fpb % n:
            raise UsageError(f"collector.frames_per_batch ({fpb}) must be a multiple of collector.num_envs ({n}).")
        if self.algo == "soc" and self.network.layer_norm != "none":
            raise UsageError("network.layer_norm applies to sac and td3; the soft option-critic's networks have none.")
        return self

    def __reduce__(self):  # pickled as its values: the methods' options are those registered where it is read
        return _restore, (self.model_dump(),)


def _restore(data: dict) -> RunConfig:
    """A config from its pickled values, read with the transfer methods of this process: those of
    :mod:`drltg.transfer` (imported by the process, as the workers of drltg.experiments do) and the user's
    plugins (loaded here)."""
    from drltg import plugins

    plugins.load()
    return build(data)


def _restore_transfer(data: dict) -> TransferConfig:
    return transfer_model().model_validate(data)


# ----------------------------------------------------------------------------------------- transfer methods
METHOD_RULES: dict[str, Any] = {}
"""``transfer.method`` -> the check its configs must pass (``"+"``: the check of every combination
``a+b``), filled by :func:`drltg.transfer.register_method` (through :func:`add_method`): import
:mod:`drltg.transfer` (the commands do) before resolving a config that uses a transfer method."""
METHOD_OPTIONS: dict[str, str] = {}
"""``transfer.<key>`` -> the one method whose option it is (filled by :func:`add_method` too)."""
METHOD_MODELS: dict[str, type[Section]] = {}
"""``transfer.method`` -> the model of its options (``transfer.<key>``)."""
TRANSFER_KEYS = tuple(TransferConfig.model_fields)
"""The ``transfer.*`` keys of every method; the others belong to one method (``TransferMethod.options``)."""
BUILTIN_METHOD_OPTIONS: dict[str, dict[str, Any]] = {
    "policy-reuse": {"psi": 1.0, "upsilon": 0.95, "psi_end": None, "annealing_frames": 0},
    "jumpstart": {"guide_steps": 100, "guide_stages": 10, "guide_frames": 20_000},
    "model-reuse": {"freeze": [], "partial": False},
    "value-shaping": {"value_scale": 1.0},
    "demonstrations": {"demo_episodes": 50, "demo_ratio": 0.25, "bc_weight": 10.0, "bc_q_filter": False,
                       "bc_anneal_frames": 0, "demo_noise": 0.0},
}
"""The built-in methods' ``transfer.*`` options at their defaults, as plain data: the method modules
register them from here, and :func:`config_changes` reads them without importing the methods (and torch),
so the analysis of saved runs knows what a key an older config lacks stood for."""


def method_names() -> tuple[str, ...]:
    """The values ``transfer.method`` takes (a combination ``a+b`` joins two of them)."""
    return ("none", *(m for m in METHOD_RULES if m not in ("none", "+")))


def builtin_options(method: str, fields: dict[str, Any]) -> dict[str, tuple[Any, Any]]:
    """``key -> (type, default)`` of a built-in method (the ``options`` of its ``TransferMethod``): the
    types (``Annotated[float, Field(ge=0, description=...)]``) given here, the defaults taken from
    ``BUILTIN_METHOD_OPTIONS``."""
    defaults = BUILTIN_METHOD_OPTIONS[method]
    if set(fields) != set(defaults):
        raise ValueError(f"{method}: options {sorted(fields)} but defaults for {sorted(defaults)}")
    return {key: (annotation, copy.deepcopy(defaults[key])) for key, annotation in fields.items()}


_STRICT = {int: Int, float: Float, bool: Bool, str: Str}


def _strict(annotation: Any) -> Any:
    """``annotation`` with plain ``int``, ``float``, ``bool`` and ``str`` (also inside ``Optional``, ``list``,
    ``Annotated``) read as the built-in keys read them: :data:`Int`, :data:`Float`, :data:`Bool`, :data:`Str`."""
    if isinstance(annotation, type) and annotation in _STRICT:
        return _STRICT[annotation]
    origin, args = get_origin(annotation), get_args(annotation)
    if origin is Annotated:  # one of the types above, or a plain type with constraints
        if any(isinstance(m, (BeforeValidator, Strict)) for m in args[1:]):
            return annotation
        return Annotated[(_strict(args[0]), *args[1:])]
    if origin in (Union, types.UnionType):
        return Union[tuple(_strict(a) for a in args)]
    if origin is list and len(args) == 1:
        return list[_strict(args[0])]
    return annotation


def options_model(method: str, options: dict[str, Any]) -> type[Section]:
    """The model of a method's ``transfer.*`` options, from ``key -> (type, default or Field(...))`` (the
    form of :func:`pydantic.create_model`; plain ``int``, ``float``, ``bool`` and ``str`` are read as the
    built-in keys are, :func:`_strict`); its defaults must pass its own checks."""
    name = "".join(part.capitalize() for part in re.split(r"[^0-9A-Za-z]+", method) if part) + "Options"
    fields = {k: (_strict(v[0]), v[1]) if isinstance(v, tuple) and len(v) == 2 else v for k, v in options.items()}
    try:
        model = create_model(name, __base__=Section, **fields)
    except (TypeError, ValueError) as err:  # pydantic's schema errors are TypeErrors, its usage errors too
        raise UsageError(f"transfer method {method!r}: its options cannot be declared ({err}).") from None
    defaults = {k: f.get_default(call_default_factory=True) for k, f in model.model_fields.items()}
    try:
        model.model_validate(defaults)
    except ValidationError as err:
        raise UsageError(f"transfer method {method!r} declares a default its option refuses: "
                         + _sentence(err, defaults, model, "transfer.")) from None
    return model


def add_method(name: str, options: type[Section] | None, rule) -> None:
    """Make ``name`` a value of ``transfer.method``, its options ``transfer.<key>`` keys (replacing those of
    a method of the same name) and ``rule(cfg)`` the check its configs pass."""
    remove_method(name)
    METHOD_RULES[name] = rule
    if options is not None:
        METHOD_MODELS[name] = options
        for key in options.model_fields:
            METHOD_OPTIONS[key] = name
    _model.cache_clear()


def remove_method(name: str) -> None:
    METHOD_RULES.pop(name, None)
    METHOD_MODELS.pop(name, None)
    for key in [k for k, owner in METHOD_OPTIONS.items() if owner == name]:
        del METHOD_OPTIONS[key]
    _model.cache_clear()


@functools.lru_cache(maxsize=1)
def _model() -> type[RunConfig]:
    """:class:`RunConfig` whose ``transfer`` section holds the options of every registered method."""
    fields = {key: (info.annotation, info) for options in METHOD_MODELS.values()
              for key, info in options.model_fields.items()}
    if not fields:
        return RunConfig
    transfer = create_model("TransferConfig", __base__=TransferConfig, __module__=__name__, **fields)
    return create_model("RunConfig", __base__=RunConfig, __module__=__name__,
                        transfer=(transfer, Field(default_factory=transfer)))


def transfer_model() -> type[TransferConfig]:
    """The ``transfer`` section with the options of the methods registered now."""
    return _model().model_fields["transfer"].annotation


# ----------------------------------------------------------------------------------------- keys
def _section_models(model: type[BaseModel] | None = None) -> dict[str, type[BaseModel]]:
    model = model or _model()
    return {name: info.annotation for name, info in model.model_fields.items()
            if isinstance(info.annotation, type) and issubclass(info.annotation, BaseModel)}


def _fields() -> dict[str, FieldInfo]:
    """Every key (dotted) with its field, in the order of the models."""
    model = _model()
    sections = _section_models(model)
    out = {}
    for name, info in model.model_fields.items():
        if name in sections:
            out.update({f"{name}.{k}": f for k, f in sections[name].model_fields.items()})
        else:
            out[name] = info
    return out


def keys() -> list[str]:
    """Every config key (dotted), in the order ``describe`` and ``dump`` list them."""
    return list(_fields())


def defaults() -> dict[str, Any]:
    """The config of no task at its defaults, as plain data (the layout of ``config.yaml``)."""
    return _model().model_construct().model_dump()


# ----------------------------------------------------------------------------------------- error sentences
def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _number_text(x: float | None) -> str | None:
    return None if x is None else str(int(x)) if float(x).is_integer() else f"{x:g}"


def _unwrap(annotation: Any) -> tuple[Any, list, bool, bool]:
    """``(type, constraints, nullable, auto)`` of a field's annotation: ``Optional[...]`` is nullable, a
    ``Literal["auto"]`` alternative is auto, ``Annotated`` metadata are the constraints."""
    nullable = auto = False
    if get_origin(annotation) in (Union, types.UnionType):
        rest = []
        for arg in get_args(annotation):
            if arg is type(None):
                nullable = True
            elif get_origin(arg) is Literal and get_args(arg) == ("auto",):
                auto = True
            else:
                rest.append(arg)
        annotation = rest[0] if len(rest) == 1 else Union[tuple(rest)]
    metadata: list = []
    while get_origin(annotation) is Annotated:
        annotation, *more = get_args(annotation)
        metadata = more + metadata
    for m in list(metadata):  # Field(...) inside Annotated
        if isinstance(m, FieldInfo):
            metadata += m.metadata
    return annotation, metadata, nullable, auto


def _bound(metadata: list, name: str) -> float | None:
    return next((getattr(m, name) for m in metadata if getattr(m, name, None) is not None), None)


def _expected(info: FieldInfo) -> str:
    """The accepted values of a field, as the end of "must be ..."."""
    extra = info.json_schema_extra if isinstance(info.json_schema_extra, dict) else {}
    annotation, metadata, nullable, auto = _unwrap(info.annotation)
    metadata = list(info.metadata) + metadata
    if "what" in extra:
        text = extra["what"]
    elif extra.get("choices") == "registered":
        text = "one of " + ", ".join(method_names())
    elif get_origin(annotation) is Literal:
        text = "one of " + ", ".join(map(str, get_args(annotation)))
    elif annotation is bool:
        text = "true or false"
    elif annotation in (int, float):
        text = "an integer" if annotation is int else "a number"
        gt, ge = _bound(metadata, "gt"), _bound(metadata, "ge")
        lo, hi = _number_text(gt if gt is not None else ge), _number_text(_bound(metadata, "le"))
        open_low = gt is not None
        if lo is not None and hi is not None:
            text += f" in {'(' if open_low else '['}{lo}, {hi}]"
        elif lo is not None:
            text += f" {'>' if open_low else '>='} {lo}"
        elif hi is not None:
            text += f" <= {hi}"
    elif annotation is str:
        text = "a string"
    elif get_origin(annotation) is list:
        text = "a list"
    elif isinstance(annotation, type) and issubclass(annotation, BaseModel):
        text = "a mapping"
    else:
        text = "a value of type " + getattr(annotation, "__name__", str(annotation))
    if auto:
        text = f"'auto' or {text}"
    if nullable:
        text += " or null"
    return text


def _choices(info: FieldInfo) -> tuple | None:
    annotation = _unwrap(info.annotation)[0]
    return get_args(annotation) if get_origin(annotation) is Literal else None


def _lookup(cfg: Any, dotted: str):
    node = cfg
    for part in dotted.split("."):
        if not isinstance(node, dict) or part not in node:
            return KeyError
        node = node[part]
    return node


def _suggest(key: str, known: Iterable[str]) -> str:
    hint = difflib.get_close_matches(key, list(known), n=1)
    return f"; did you mean '{hint[0]}'?" if hint else "."


def _unknown(dotted: str) -> str:
    owners = {f"transfer.{k}": m for m, options in BUILTIN_METHOD_OPTIONS.items() for k in options}
    owner = owners.get(dotted)
    if owner is not None and owner not in METHOD_RULES:  # a built-in method, not imported yet
        return (f"config key '{dotted}' is an option of the transfer method {owner}, which this process has not "
                "registered; import drltg.transfer first.")
    known = _flat_keys(_model(), _section_models())
    section = [k for k in known if k.startswith(dotted.split(".")[0] + ".")]
    if "." in dotted and section and not difflib.get_close_matches(dotted, known, n=1):  # no close key: list them
        return f"unknown config key '{dotted}'; the keys of {dotted.split('.')[0]} are {', '.join(section)}."
    return f"unknown config key '{dotted}'" + _suggest(dotted, known)


def _sentence(err: ValidationError, data: Any, model: type[BaseModel], prefix: str = "") -> str:
    """One sentence for the first error pydantic found in ``data`` (validated by ``model``), naming the key."""
    sections = _section_models(model)
    error = err.errors()[0]
    loc = [str(p) for p in error["loc"]]
    if error["type"] == "value_error" and isinstance(error.get("ctx", {}).get("error"), UsageError):
        return str(error["ctx"]["error"])
    if loc and loc[0] in sections and len(loc) > 1:
        key, info = f"{loc[0]}.{loc[1]}", sections[loc[0]].model_fields.get(loc[1])
    elif loc:
        key, info = loc[0], model.model_fields.get(loc[0])
    else:  # a rule of the whole model
        return f"the config {error['msg'][0].lower()}{error['msg'][1:]}."
    dotted = prefix + key
    if (error["type"] == "extra_forbidden" or info is None) and not prefix:
        return _unknown(dotted)
    if error["type"] == "extra_forbidden" or info is None:
        return f"unknown config key '{dotted}'" + _suggest(dotted, [prefix + k for k in _flat_keys(model, sections)])
    value = _lookup(data, key)
    if isinstance(info.annotation, type) and issubclass(info.annotation, BaseModel):
        names = ", ".join(f"{dotted}.{k}" for k in info.annotation.model_fields)
        return f"config key '{dotted}' must be a mapping of {names}, got {_short(value)}."
    extra = info.json_schema_extra if isinstance(info.json_schema_extra, dict) else {}
    if _choices(info) and isinstance(value, str):
        return f"unknown {extra.get('noun', 'value')} {value!r}: config key '{dotted}' must be {_expected(info)}."
    return f"config key '{dotted}' must be {_expected(info)}, got {_short(value)}."


def _flat_keys(model: type[BaseModel], sections: dict) -> list[str]:
    """The keys of ``model`` and the names of its sections (what a misspelt key may have meant)."""
    out = []
    for name in model.model_fields:
        out += [name, *(f"{name}.{k}" for k in sections[name].model_fields)] if name in sections else [name]
    return out


def build(data: dict | RunConfig) -> RunConfig:
    """A :class:`RunConfig` from a mapping of its keys (missing keys at their defaults), its types and
    ranges checked: a wrong one is one :class:`UsageError` sentence naming the key."""
    if isinstance(data, BaseModel):
        data = data.model_dump()
    if not isinstance(data, dict):
        raise UsageError(f"a config must be a mapping of config keys, got {_short(data)}.")
    model = _model()
    try:
        return model.model_validate(data)
    except ValidationError as err:
        raise UsageError(_sentence(err, data, model)) from None


def as_config(cfg: RunConfig | dict) -> RunConfig:
    """``cfg`` itself, or a mapping of config keys resolved as a ``--config`` file is (:func:`resolve`): the
    entry points that take a config (``train``, ``make_agent``) take either."""
    return cfg if isinstance(cfg, RunConfig) else resolve(cfg)


def updated(cfg: RunConfig, changes: dict[str, Any]) -> RunConfig:
    """A copy of ``cfg`` with the dotted keys of ``changes`` set (``{"transfer.source": path}``), each value
    checked like the key's own."""
    new = cfg.model_copy(deep=True)
    for dotted, value in changes.items():
        *path, last = dotted.split(".")
        if dotted not in keys() and dotted not in _section_models():
            raise UsageError(_unknown(dotted))
        node = new
        for part in path:
            node = getattr(node, part)
        try:
            setattr(node, last, value)
        except ValidationError as err:
            raise UsageError(_sentence(err, {last: value}, type(node), "".join(p + "." for p in path))) from None
    return new


# ----------------------------------------------------------------------------------------- overrides
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


def _env_expected() -> str:
    return _expected(RunConfig.model_fields["env"])


def set_key(cfg: dict, dotted: str, value: Any) -> None:
    """Set ``cfg[a][b] = value`` in a mapping of config values for ``dotted = "a.b"``; a mapping given for
    a section (``optim``) is merged into it; keys under ``env.`` are the task's own keyword arguments."""
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
        if not isinstance(cfg.setdefault("env", {}), dict):
            raise UsageError(f"config key 'env' must be {_env_expected()}, got {_short(cfg.get('env'))}.")
        cfg["env"][parts[1]] = value
        return
    sections = _section_models()
    if dotted in sections:
        if not isinstance(value, dict):
            names = ", ".join(f"{dotted}.{k}" for k in sections[dotted].model_fields)
            raise UsageError(f"config key '{dotted}' must be a mapping of {names}, got {_short(value)}.")
        merge(cfg, value, dotted + ".")
        return
    if dotted not in keys():
        raise UsageError(_unknown(dotted))
    node = cfg
    for p in parts[:-1]:
        node = node.setdefault(p, {})
    node[parts[-1]] = value


def merge(cfg: dict, overrides: dict, prefix: str = "") -> None:
    """Merge a nested mapping of overrides into the mapping ``cfg``, checking every key's name."""
    for k, v in overrides.items():
        key = f"{prefix}{k}"
        if key == "env":
            if not isinstance(v, dict):
                raise UsageError(f"config key 'env' must be {_env_expected()}, got {_short(v)}.")
            if not isinstance(cfg.get("env"), dict):
                cfg["env"] = {}
            cfg["env"].update(v)
        else:
            set_key(cfg, key, v)


_NUMBER = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?")


_FRAMES = re.compile(r"\s*(\d+(?:\.\d*)?|\.\d+)(?:[eE]\+?(\d+))?\s*([kKmM]?)\s*")


def frame_count(text: str) -> int:
    """``"50000"``, ``"50k"``, ``"1e4"``, ``"1.5M"`` as a whole number of frames: the argparse ``type`` of every
    ``--frames`` option (an ``argparse.ArgumentTypeError`` names what is wrong)."""
    import argparse

    m = _FRAMES.fullmatch(str(text))
    value = float(m.group(1)) * 10 ** int(m.group(2) or 0) * {"": 1, "k": 1e3, "m": 1e6}[m.group(3).lower()] if m \
        else None
    if value is None or not 1 <= value <= 1e12 or value != int(value):
        raise argparse.ArgumentTypeError(f"'{text}' is not a whole number of frames >= 1 (e.g. 50000, 50k, 1e4, 1.5M)")
    return int(value)


def parse_override(text: str) -> tuple[str, Any]:
    """``"optim.lr=1e-3"`` -> ``("optim.lr", 0.001)``; values are parsed as YAML scalars/lists."""
    if "=" not in text:
        raise UsageError(f"override '{text}' must look like KEY=VALUE, e.g. optim.lr=1e-3.")
    key, raw = text.split("=", 1)
    try:
        value = safe_yaml.load(raw, f"the value of override '{key.strip()}'")
    except UsageError as err:
        if "not valid YAML" not in str(err):
            raise
        value = raw
    if isinstance(value, str) and _NUMBER.fullmatch(value.strip()):  # YAML reads "1e-3" as a string
        value = float(value)
    return key.strip(), value


def load_yaml(path: str | Path, what: str = "config file") -> dict:
    """A YAML mapping from ``path``; a missing file, a duplicate key, bad YAML or a file that is not
    UTF-8 text is one :class:`UsageError` sentence."""
    path = Path(path)
    if not path.is_file():
        raise UsageError(f"{what} '{path}' does not exist.")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as err:
        raise UsageError(f"{what} '{path}' is not UTF-8 text (byte {err.start}).") from None
    data = safe_yaml.load(text, f"{what} '{path}'") or {}
    if not isinstance(data, dict):
        raise UsageError(f"{what} '{path}' must hold a mapping of keys.")
    return data


def resolve(
    base: dict | RunConfig | None = None,
    overrides: Iterable[str] = (),
    **explicit: Any,
) -> RunConfig:
    """Build a full config: defaults <- task overrides <- ``base`` (e.g. a YAML file) <- ``explicit``
    keyword values (e.g. ``seed=3``, ``**{"soc.num_options": 2}``) <- ``KEY=VALUE`` ``overrides``; then
    check it (:func:`build`, :func:`validate`), so that nothing is built or written from a config with a
    wrong key, type or range. The ``env`` section ends up holding every env setting of the task."""
    if isinstance(base, BaseModel):
        base = base.model_dump()
    if base is not None and not isinstance(base, dict):
        raise UsageError(f"a config must be a mapping of config keys, got {_short(base)}.")
    base = dict(base or {})
    parsed = [parse_override(text) for text in overrides]
    task = RunConfig.model_fields["task"].default
    for given in (base.get("task"), explicit.get("task"), *(v for k, v in parsed if k == "task")):
        if given is not None:
            task = given
    raw: dict[str, Any] = {}
    merge(raw, copy.deepcopy(_task_spec(task).train))
    merge(raw, base)
    for key, value in explicit.items():
        if value is not None:
            set_key(raw, key, value)
    for key, value in parsed:
        set_key(raw, key, value)
    cfg = build(raw)
    validate(cfg)
    cfg.env = {**task_env(cfg.task), **cfg.env}
    return cfg


def _override_leaves(key: str, value: Any) -> dict[str, Any]:
    """The single keys an override sets: ``optim={lr: 1}`` sets ``optim.lr``, ``env={horizon: 5}`` ``env.horizon``."""
    if isinstance(value, dict) and key == "env":
        return {f"env.{k}": v for k, v in value.items()}
    if isinstance(value, dict) and key in _section_models():
        return _flatten(value, key + ".")
    return {key: value}


def refuse_conflicts(overrides: Iterable[str]) -> None:
    """A user's ``-o`` overrides that set one key twice are refused, in any form (``optim.lr=1`` twice, or
    ``optim={lr: 1}`` and ``optim.lr=2``): which one was meant would depend on their order."""
    seen: dict[str, str] = {}
    for text in overrides:
        key, value = parse_override(text)
        for leaf in _override_leaves(key, value):
            if leaf in seen:
                raise UsageError(f"config key '{leaf}' is set twice by -o ('{seen[leaf]}', then '{text.strip()}'); "
                                 "give it once.")
            seen[leaf] = text.strip()


# ----------------------------------------------------------------------------------------- checks beyond types
def validate(cfg: RunConfig) -> None:
    """The checks of a built config that need this machine, the task's env or the transfer method:
    ``device`` must be usable here, ``env`` keys must be keywords of the task's factory (their values
    are read with the type of the declared default), the method's own rules must hold; and ``frames``
    is rounded up to whole collector batches, so that the budget is exact."""
    check_device("device", cfg.device)
    if cfg.optim.cudagraphs and not cfg.device.startswith("cuda"):
        raise UsageError(f"config key 'optim.cudagraphs' is true but device is '{cfg.device}'; CUDA graphs "
                         "need device=cuda.")
    cfg.env = _check_env(cfg.task, cfg.env)
    method = cfg.transfer.method
    rule = METHOD_RULES.get(method) or (METHOD_RULES.get("+") if "+" in method else None)
    if rule is not None:
        rule(cfg)
    fpb = cfg.collector.frames_per_batch
    cfg.frames = -(-cfg.frames // fpb) * fpb


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


_DEVICE = _expected(RunConfig.model_fields["device"])


def check_device(key: str, value: str) -> str:
    if value == "cpu":  # always there: no need to import torch to know it
        return value
    import torch

    try:
        device = torch.device(value)
    except (RuntimeError, TypeError, ValueError):
        raise UsageError(f"{_named(key)} must be {_DEVICE}, got {_short(value)}.") from None
    backend = getattr(torch, device.type, None)
    available = getattr(backend, "is_available", None)
    if available is None:
        raise UsageError(f"{_named(key)} is '{value}', a device type drltg cannot train on; use cpu or cuda.")
    if not available():
        raise UsageError(
            f"{_named(key)} is '{value}' but no {device.type.upper()} device is available on this "
            "machine; use device=cpu."
        )
    count = getattr(backend, "device_count", None)
    if device.index is not None and device.type != "cpu" and count is not None and device.index >= count():
        raise UsageError(
            f"{_named(key)} is '{value}' but this machine has {count()} {device.type.upper()} "
            f"device(s), numbered from 0."
        )
    return value


def _named(key: str) -> str:
    """A config key as a sentence names it; a command-line option (``--device``) as it is."""
    return key if key.startswith("--") else f"config key '{key}'"


# ----------------------------------------------------------------------------------------- env options
def env_defaults(task: str) -> tuple[dict[str, Any], bool]:
    """The keyword arguments task ``task``'s factory declares with a default (its registered defaults
    win), and whether it also takes other keywords (``**kwargs``); read without importing the env where
    the registry can (:meth:`drltg.envs.TaskSpec.keywords`)."""
    spec = _task_spec(task)
    declared, open_ended = spec.keywords()
    return {**declared, **spec.defaults}, open_ended


def task_env(task: str) -> dict[str, Any]:
    """Every env setting of ``task`` at its default (the factory's declared keywords, the task's
    registered values over them), as plain YAML values: ``resolve`` writes them all into the config,
    so a run's ``config.yaml`` says exactly which env it trained on and a changed default is a
    changed config."""
    declared, _ = env_defaults(task)
    return {k: _plain(v) for k, v in declared.items() if k not in _ENV_RESERVED}


def _plain(value: Any) -> Any:
    return [_plain(v) for v in value] if isinstance(value, (list, tuple)) else value


def _env_type(ref: Any) -> Any:
    """The type an env keyword's declared default implies (no range: the env checks that); ``None``: any."""
    if isinstance(ref, bool):
        return Bool
    if isinstance(ref, int):
        return Int
    if isinstance(ref, float):
        return Float
    if isinstance(ref, str):
        return Str
    if isinstance(ref, (list, tuple)) and ref:
        if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in ref):
            return Annotated[list[Number], Field(min_length=1, json_schema_extra=_what("a list of numbers"))]
        if all(isinstance(v, str) for v in ref):
            return Annotated[list[Str], Field(json_schema_extra=_what("a list of strings"))]
    return None


def env_model(task: str) -> type[BaseModel]:
    """The model of task ``task``'s ``env`` section: one optional field per keyword its factory declares,
    typed by the declared default; other keys are refused unless the factory takes ``**kwargs``."""
    declared, open_ended = env_defaults(task)
    fields = {}
    for name, ref in declared.items():
        kind = _env_type(ref)
        fields[name] = (Any if kind is None else kind, None)
    return create_model("EnvOptions", __config__=ConfigDict(extra="allow" if open_ended else "forbid"), **fields)


def _check_env(task: str, env: dict) -> dict:
    """``env`` with its values read as the types of the task's declared defaults; an unknown or reserved
    key, or a value of another type, is one sentence naming the key."""
    declared, open_ended = env_defaults(task)
    for name in env:
        if name in _ENV_RESERVED:
            raise UsageError(f"config key 'env.{name}' cannot be set: the run sets it from {_ENV_RESERVED[name]}.")
        if name not in declared and not open_ended:
            known = ", ".join(sorted(set(declared) - set(_ENV_RESERVED)))
            raise UsageError(f"config key 'env.{name}' is not an option of task '{task}'; its options are: {known}.")
    model = env_model(task)
    try:
        checked = model.model_validate(env)
    except ValidationError as err:
        name = str(err.errors()[0]["loc"][0])
        raise UsageError(f"config key 'env.{name}' must be {_expected(model.model_fields[name])} (task '{task}' "
                         f"declares {name}={declared[name]!r}), got {_short(env[name])}.") from None
    values = checked.model_dump(exclude_unset=True)
    return {name: values.get(name, env[name]) for name in env}


# ----------------------------------------------------------------------------------------- comparing, printing
def config_changes(saved: dict | RunConfig, cfg: dict | RunConfig, *, env_defaults: bool = True) -> list[str]:
    """The keys in which two configs of one task differ (``cfg`` gives the task). A key one of them
    lacks counts only when the other sets it to something else than its default, for ``env.*`` the
    task's: runs saved before the key existed, or before env settings were saved in full, stay the
    same run (resumable, and comparable in one report). Options of a transfer method that neither
    config uses do not count (a baseline is the same run whatever another method's defaults are), nor
    does ``transfer.source_checkpoint`` where neither has a source, nor do ``ENV_EXECUTION_KEYS``.

    ``env_defaults=False`` leaves the task registry (and torch with it) unimported: an ``env.*`` key
    only one config sets is then not compared, its default being unknown (:func:`env_keys_set_once`
    names them)."""
    saved, cfg = (c.model_dump() if isinstance(c, BaseModel) else c for c in (saved, cfg))
    env = {}
    if env_defaults:
        try:
            env = task_env(cfg["task"])
        except (KeyError, UsageError, ValueError):  # a task this process does not know: no env defaults to fill in
            pass
    builtin = {k: v for options in BUILTIN_METHOD_OPTIONS.values() for k, v in options.items()}
    plain = defaults()
    base = {**plain, "env": env, "transfer": {**builtin, **plain["transfer"]}}
    owners = {**{k: m for m, options in BUILTIN_METHOD_OPTIONS.items() for k in options}, **METHOD_OPTIONS}
    methods = {part for c in (saved, cfg) if isinstance(m := _lookup(c, "transfer.method"), str)
               for part in m.split("+")}
    unknown = set() if env_defaults else set(env_keys_set_once(saved, cfg))
    if not env_defaults and (_lookup(saved, "env") is KeyError) != (_lookup(cfg, "env") is KeyError):
        unknown.add("env")

    def missing_as_default(a, b, key):
        return _lookup(a, key) is KeyError and _lookup(b, key) == _lookup(base, key)

    sourceless = all(_lookup(c, "transfer.source") in (None, KeyError) for c in (saved, cfg))

    def unused(key):  # an option of a method neither run uses changes nothing they do, nor does the
        if key == "transfer.source_checkpoint":  # checkpoint of a source neither of them reads
            return sourceless
        owner = owners.get(key.removeprefix("transfer.")) if key.startswith("transfer.") else None
        return owner is not None and owner not in methods

    return sorted(key for key in _diff_keys(saved, cfg)
                  if not (missing_as_default(saved, cfg, key) or missing_as_default(cfg, saved, key) or unused(key)
                          or key in ENV_EXECUTION_KEYS or key in unknown))


def env_keys_set_once(a: dict, b: dict) -> list[str]:
    """The ``env.*`` keys exactly one of two configs sets (one saved before env settings were saved in full)."""
    ea, eb = (c.get("env") if isinstance(c.get("env"), dict) else {} for c in (a, b))
    return sorted(f"env.{k}" for k in set(ea) ^ set(eb))


def _diff_keys(a, b, prefix=""):
    if isinstance(a, dict) and isinstance(b, dict):
        for k in set(a) | set(b):
            yield from _diff_keys(a.get(k, KeyError), b.get(k, KeyError), f"{prefix}{k}.")
    elif a != b:
        yield prefix.rstrip(".")


def describe() -> str:
    """Every config key with its default, accepted values and meaning, as a Markdown table."""
    flat = _flatten(defaults())
    rows = ["| key | default | accepted values | meaning |", "|---|---|---|---|"]
    for key, info in _fields().items():
        default = yaml.safe_dump(flat[key], default_flow_style=True).strip().removesuffix("...").strip()
        rows.append(f"| `{key}` | {default} | {_expected(info)} | {info.description or ''} |")
    return "\n".join(rows)


def dump(cfg: RunConfig | dict) -> str:
    """``cfg`` as the YAML of ``config.yaml``: its sections in order, plain values."""
    return yaml.safe_dump(cfg.model_dump() if isinstance(cfg, BaseModel) else cfg, sort_keys=False)
