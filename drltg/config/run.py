"""The run config: :class:`RunConfig` with the registered learners' and methods' options
(:mod:`drltg.config.registry`), its keys, and building one from a mapping with every error as one sentence
naming the key."""
from __future__ import annotations

import functools
import re
from typing import Annotated, Any, Literal, Optional

from pydantic import (
    BaseModel,
    Field,
    ValidationError,
    create_model,
    field_validator,
    model_validator,
)
from pydantic.fields import FieldInfo

from drltg.config.methods import _strict
from drltg.config.registry import LEARNER_OPTIONS, LEARNERS, METHODS, method_names
from drltg.config.sections import (
    ENV_HELP,
    BufferConfig,
    CheckpointConfig,
    CollectorConfig,
    EvalConfig,
    LogConfig,
    NetworkConfig,
    OptimConfig,
)
from drltg.config.values import (
    MAX_FRAMES,
    MAX_THREADS,
    Bool,
    Int,
    Section,
    Str,
    _choices,
    _expected,
    _lookup,
    _short,
    _suggest,
    _what,
)
from drltg.errors import UsageError, closest


class TransferConfig(Section):
    """How a run transfers knowledge: a registered method (``none``: the baseline). The options of every
    registered method follow these four keys (the section :func:`transfer_model` builds)."""

    method: Str = Field("none", description="transfer method (`drltg tasks` lists them)",
                        json_schema_extra={"noun": "transfer method", "choices": "methods"})
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
        return restore_transfer, (self.model_dump(),)


TRANSFER_KEYS = tuple(TransferConfig.model_fields)
"""The ``transfer.*`` keys of every method; the others belong to one method (``TransferMethod.options``)."""


class RunConfig(Section):
    """One run's configuration. Build it with :func:`resolve` (defaults, task, file, overrides) or
    :func:`build` (a mapping, e.g. a saved ``config.yaml``); :func:`validate` adds the checks that need
    this machine or the task's env (``device``, ``env``, the transfer method's own rules). The model they
    build adds a section for each registered learner's options (``sac``, ``td3``, ``soc``: :data:`LEARNER_OPTIONS`)
    and every registered method's options to ``transfer``."""

    task: Str = Field("fourrooms/northeast", description="registered task name (`drltg tasks`)",
                      json_schema_extra=_what("a registered task name"))
    algo: Str = Field("sac", description="learner; sac is discrete SAC on discrete tasks",
                      json_schema_extra={"noun": "algorithm", "choices": "learners"})
    seed: Int = Field(0, ge=0, le=2**31 - 1, description="seed of envs, networks and sampling")
    frames: Int = Field(50_000, ge=1, le=MAX_FRAMES,
                        description="environment frames, rounded up to whole collector batches")
    device: Str = Field("cpu", description="torch device",
                        json_schema_extra=_what("a torch device such as cpu, cuda or cuda:0"))
    threads: Int = Field(1, ge=1, le=MAX_THREADS, description="CPU threads per run")  # small nets are overhead-bound
    tuned_on: list[Annotated[Int, Field(ge=0)]] = Field(
        [], description="seeds whose results chose this recipe; a report that reads any of them says so",
        json_schema_extra=_what("a list of seeds (e.g. [0, 100])"))
    env: dict[Str, Any] = Field(default_factory=dict, description=ENV_HELP,
                                json_schema_extra=_what("a mapping of the task's keyword arguments (e.g. "
                                                        "env.horizon=200)"))
    collector: CollectorConfig = Field(default_factory=CollectorConfig)
    buffer: BufferConfig = Field(default_factory=BufferConfig)
    optim: OptimConfig = Field(default_factory=OptimConfig)
    network: NetworkConfig = Field(default_factory=NetworkConfig)
    eval: EvalConfig = Field(default_factory=EvalConfig)
    checkpoint: CheckpointConfig = Field(default_factory=CheckpointConfig)
    log: LogConfig = Field(default_factory=LogConfig)
    transfer: TransferConfig = Field(default_factory=TransferConfig)

    @field_validator("task")
    @classmethod
    def _known_task(cls, value: str) -> str:
        _task_spec(value)
        return value

    @field_validator("algo")
    @classmethod
    def _registered(cls, value: str) -> str:
        if value not in LEARNERS:
            raise UsageError(f"unknown algorithm {value!r}: config key 'algo' must be one of "
                             f"{', '.join(LEARNERS.names())}.")
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
    """A config from its pickled values, read with the transfer methods of this process: the registered
    ones and those of the user's plugins (loaded here)."""
    from drltg import plugins

    plugins.load()
    return build(data)


def restore_transfer(data: dict) -> TransferConfig:
    """A ``transfer`` section from its pickled values, with the methods registered where it is read."""
    return transfer_model().model_validate(data)


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


def option_owners() -> dict[str, str]:
    """``transfer.<key>`` -> the registered method whose option it is."""
    return {key: method.name for method in METHODS.values() if method.model is not None
            for key in method.model.model_fields}


def _model() -> type[RunConfig]:
    """:class:`RunConfig` with a section of each registered learner's options and, in ``transfer``, the
    options of every registered method."""
    METHODS.names(), LEARNER_OPTIONS.names()  # found now: the versions read next are those the model holds
    return _model_at(METHODS.version, LEARNER_OPTIONS.version)


@functools.lru_cache(maxsize=4)
def _model_at(methods_version: int, learners_version: int) -> type[RunConfig]:
    fields: dict[str, Any] = {name: (model, Field(default_factory=model))
                              for name, model in _learner_sections().items()}
    options: dict[str, Any] = {}
    owners: dict[str, str] = {}
    for method in METHODS.values():
        for key, info in (method.model.model_fields if method.model is not None else {}).items():
            if key in owners or key in TRANSFER_KEYS:
                raise UsageError(f"transfer method {method.name!r}: config key 'transfer.{key}' already belongs to "
                                 f"{owners.get(key, 'every method')}; choose another name.")
            owners[key] = method.name
            options[key] = (info.annotation, info)
    if options:
        transfer = create_model("TransferConfig", __base__=TransferConfig, __module__=__name__, **options)
        fields["transfer"] = (transfer, Field(default_factory=transfer))
    return create_model("RunConfig", __base__=RunConfig, __module__=__name__, **fields) if fields else RunConfig


def _learner_sections() -> dict[str, type[BaseModel]]:
    """The section of each registered learner's options, by the learner's name."""
    sections = {}
    for name in LEARNER_OPTIONS:
        model = LEARNER_OPTIONS[name]
        if not name.isidentifier() or name in RunConfig.model_fields:
            raise UsageError(f"the options of the learner {name!r} cannot be a config section of that name: a "
                             "learner with options is named as a Python identifier that is not a config key.")
        if not (isinstance(model, type) and issubclass(model, BaseModel)):
            raise UsageError(f"the options of the learner {name!r} must be a pydantic model (a subclass of "
                             f"drltg.config.Section), got {_short(model)}.")
        try:
            model()
        except ValidationError:
            raise UsageError(f"the options of the learner {name!r} must each have a default.") from None
        sections[name] = model
    return sections


def transfer_model() -> type[TransferConfig]:
    """The ``transfer`` section with the options of the methods registered now."""
    return _model().model_fields["transfer"].annotation


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


def _unknown(dotted: str) -> str:
    known = _flat_keys(_model(), _section_models())
    section = [k for k in known if k.startswith(dotted.split(".")[0] + ".")]
    if "." in dotted and section and not closest(dotted, known):  # no close key: list them
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


def _task_spec(task: Any):
    from drltg.envs import TASKS  # registry import is cheap

    if not isinstance(task, str):
        raise UsageError(f"config key 'task' must be a registered task name, got {_short(task)}.")
    if task not in TASKS:
        hint = closest(task, TASKS)
        raise UsageError(
            f"unknown task '{task}'" + (f"; did you mean '{hint}'?" if hint else "; see `drltg tasks`.")
        )
    return TASKS[task]
