"""The run config: :class:`RunConfig`, one static model of the keys every run has. The open-ended parts are
validated by the models their owners declare: each registered learner's options are the section of its name
(``sac.alpha_init``), each registered method's options sit in ``transfer`` (``transfer.psi``), so a
parameter is declared, checked and used by its method and the part it configures. Every error is one
sentence naming the key."""
from __future__ import annotations

from typing import Annotated, Any, Literal, Optional

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    ValidationInfo,
    field_validator,
    model_validator,
)
from pydantic.fields import FieldInfo

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
    accepts,
    expected,
    literal_choices,
    lookup,
    suggestion,
)
from drltg.errors import UsageError, closest, short


class TransferConfig(Section):
    """How a run transfers knowledge: a registered method (``none``: the baseline), then the options of every
    registered method (``TransferMethod.model``), each checked by its method's model and held at its default
    where not given, so a ``config.yaml`` lists them all."""

    model_config = ConfigDict(extra="allow", validate_assignment=True)

    method: Str = Field("none", description="transfer method (`drltg tasks` lists them)",
                        json_schema_extra={"noun": "transfer method", "choices": "methods"})
    source: Optional[Str] = Field(None, description="source run directory, or demonstrator:TASK",
                                  json_schema_extra=accepts("a source run directory, demonstrator:TASK"))
    allow_incomplete: Bool = Field(False, description="reuse a source run that did not finish (no summary.json)")
    source_checkpoint: Literal["last", "best"] = Field(
        "last", description="the source run's networks reused: its last, or its best evaluation's (every run keeps "
                            "them)")

    @field_validator("method")
    @classmethod
    def _registered(cls, value: str) -> str:
        names = method_names()
        for part in value.split("+"):
            if part not in names:
                raise UsageError(f"unknown transfer method {part!r}: config key 'transfer.method' must be one of "
                                f"{', '.join(names)}.")
        return value

    @model_validator(mode="after")
    def _options(self, info: ValidationInfo) -> TransferConfig:
        """The methods' options: each given one checked by its method's model, the others at their defaults;
        in a saved config (``build(..., saved=True)``), an option it lacks at its :func:`absent_value`."""
        given = dict(self.__pydantic_extra__ or {})
        owners = option_owners()
        for key in given:
            if key not in owners:
                raise UsageError(unknown_key(f"transfer.{key}"))
        saved = bool(info.context and info.context.get("saved"))
        options = {}
        for method in METHODS.values():
            if method.model is not None:
                mine = {k: v for k, v in given.items() if owners[k] == method.name}
                if saved:
                    mine = {**{k: absent_value(f) for k, f in method.model.model_fields.items()
                               if k not in mine and "absent" in _extra(f)}, **mine}
                try:
                    options.update(method.model.model_validate(mine).model_dump())
                except ValidationError as err:
                    raise UsageError(sentence(err, mine, method.model, "transfer.")) from None
        object.__setattr__(self, "__pydantic_extra__", options)
        return self

    def __setattr__(self, name: str, value: Any) -> None:
        """A method's option is checked by its method's model before it is set, as a declared key is."""
        if name not in type(self).model_fields and not name.startswith("_"):
            owner = option_owners().get(name)
            if owner is None:
                raise UsageError(unknown_key(f"transfer.{name}"))
            model = METHODS[owner].model
            try:
                value = getattr(model.model_validate({name: value}), name)
            except ValidationError as err:
                raise UsageError(sentence(err, {name: value}, model, "transfer.")) from None
        super().__setattr__(name, value)


TRANSFER_KEYS = tuple(TransferConfig.model_fields)
"""The ``transfer.*`` keys of every method; the others belong to one method (``TransferMethod.options``)."""


class RunConfig(Section):
    """One run's configuration. Build it with :func:`resolve` (defaults, task, file, overrides) or
    :func:`build` (a mapping, e.g. a saved ``config.yaml``); :func:`validate` adds the checks that need
    this machine or the task's env (``device``, ``env``, the transfer method's own rules). After its keys
    come the registered learners' sections (``sac``, ``td3``, ``soc``: :data:`LEARNER_OPTIONS`), each checked
    by its learner's model and at its defaults where not given."""

    model_config = ConfigDict(extra="allow", validate_assignment=True)

    task: Str = Field("fourrooms/northeast", description="registered task name (`drltg tasks`)",
                      json_schema_extra=accepts("a registered task name"))
    algo: Str = Field("sac", description="learner; sac is discrete SAC on discrete tasks",
                      json_schema_extra={"noun": "algorithm", "choices": "learners"})
    seed: Int = Field(0, ge=0, le=2**31 - 1, description="seed of envs, networks and sampling")
    frames: Int = Field(50_000, ge=1, le=MAX_FRAMES,
                        description="environment frames, rounded up to whole collector batches")
    device: Str = Field("cpu", description="torch device",
                        json_schema_extra=accepts("a torch device such as cpu, cuda or cuda:0"))
    threads: Int = Field(1, ge=1, le=MAX_THREADS, description="CPU threads per run")  # small nets are overhead-bound
    tuned_on: list[Annotated[Int, Field(ge=0)]] = Field(
        [], description="seeds whose results chose this recipe; a report that reads any of them says so",
        json_schema_extra=accepts("a list of seeds (e.g. [0, 100])"))
    env: dict[Str, Any] = Field(default_factory=dict, description=ENV_HELP,
                                json_schema_extra=accepts("a mapping of the task's keyword arguments (e.g. "
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
        task_spec(value)
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
        """The learners' sections, then the rules that tie keys of two sections together."""
        given = dict(self.__pydantic_extra__ or {})
        sections = learner_sections()
        for key in given:
            if key not in sections:
                raise UsageError(unknown_key(key))
        learners = {}
        for name, model in sections.items():
            value = given.get(name, {})
            if isinstance(value, BaseModel):
                value = value.model_dump()
            if not isinstance(value, dict):
                raise UsageError(f"config key '{name}' must be a mapping of "
                                 f"{', '.join(f'{name}.{k}' for k in model.model_fields)}, got {short(value)}.")
            try:
                learners[name] = model.model_validate(value)
            except ValidationError as err:
                raise UsageError(sentence(err, value, model, f"{name}.")) from None
        object.__setattr__(self, "__pydantic_extra__", learners)
        fpb, n = self.collector.frames_per_batch, self.collector.num_envs
        if fpb % n:
            raise UsageError(f"collector.frames_per_batch ({fpb}) must be a multiple of collector.num_envs ({n}).")
        if self.algo == "soc" and self.network.layer_norm != "none":
            raise UsageError("network.layer_norm applies to sac and td3; the soft option-critic's networks have none.")
        return self


def _extra(info: FieldInfo) -> dict:
    return info.json_schema_extra if isinstance(info.json_schema_extra, dict) else {}


def absent_value(info: FieldInfo) -> Any:
    """The value a saved config that lacks the key ran with: the key's ``json_schema_extra["absent"]`` where a
    key came with a new behaviour as its default (runs saved before it behaved as ``absent`` says), else its
    default."""
    extra = _extra(info)
    return extra["absent"] if "absent" in extra else info.get_default(call_default_factory=True)


def absent_values() -> dict[str, Any]:
    """``{dotted key: absent value}`` of the keys that declare one (:func:`absent_value`)."""
    return {key: absent_value(info) for key, info in fields().items() if "absent" in _extra(info)}


def option_owners() -> dict[str, str]:
    """``transfer.<key>`` -> the registered method whose option it is. Two methods declaring one key, or a
    method declaring a key of every method (:data:`TRANSFER_KEYS`), is refused here, the one place that
    sees every method."""
    owners: dict[str, str] = {}
    for method in METHODS.values():
        for key in (method.model.model_fields if method.model is not None else {}):
            if key in owners or key in TRANSFER_KEYS:
                raise UsageError(f"transfer method {method.name!r}: config key 'transfer.{key}' already belongs to "
                                 f"{owners.get(key, 'every method')}; choose another name.")
            owners[key] = method.name
    return owners


def learner_sections() -> dict[str, type[BaseModel]]:
    """The section of each registered learner's options, by the learner's name."""
    sections = {}
    for name in LEARNER_OPTIONS:
        model = LEARNER_OPTIONS[name]
        if not name.isidentifier() or name in RunConfig.model_fields:
            raise UsageError(f"the options of the learner {name!r} cannot be a config section of that name: a "
                             "learner with options is named as a Python identifier that is not a config key.")
        if not (isinstance(model, type) and issubclass(model, BaseModel)):
            raise UsageError(f"the options of the learner {name!r} must be a pydantic model (a subclass of "
                             f"drltg.config.Section), got {short(model)}.")
        try:
            model()
        except ValidationError:
            raise UsageError(f"the options of the learner {name!r} must each have a default.") from None
        sections[name] = model
    return sections


def section_models() -> dict[str, type[BaseModel]]:
    """Every config section by name: the static ones, then the learners'."""
    static = {name: info.annotation for name, info in RunConfig.model_fields.items()
              if isinstance(info.annotation, type) and issubclass(info.annotation, BaseModel)}
    return {**static, **learner_sections()}


def fields() -> dict[str, FieldInfo]:
    """Every key (dotted) with its field, in the order of ``config.yaml``: the static keys and sections, the
    methods' options after ``transfer``'s own keys, the learners' sections last."""
    sections = section_models()
    out = {}
    for name, info in RunConfig.model_fields.items():
        if name not in sections:
            out[name] = info
            continue
        out.update({f"{name}.{k}": f for k, f in sections[name].model_fields.items()})
        if name == "transfer":
            out.update({f"transfer.{k}": f for method in METHODS.values() if method.model is not None
                        for k, f in method.model.model_fields.items()})
    for name, model in learner_sections().items():
        out.update({f"{name}.{k}": f for k, f in model.model_fields.items()})
    return out


def keys() -> list[str]:
    """Every config key (dotted), in the order ``describe`` and ``dump`` list them."""
    return list(fields())


def defaults() -> dict[str, Any]:
    """The config of no task at its defaults, as plain data (the layout of ``config.yaml``)."""
    return RunConfig().model_dump()


def unknown_key(dotted: str) -> str:
    """The sentence for a key no section declares, naming the closest key or the keys of its section."""
    known = [*section_models(), *keys()]
    section = [k for k in keys() if k.startswith(dotted.split(".")[0] + ".")]
    if "." in dotted and section and not closest(dotted, known):  # no close key: list them
        return f"unknown config key '{dotted}'; the keys of {dotted.split('.')[0]} are {', '.join(section)}."
    return f"unknown config key '{dotted}'" + suggestion(dotted, known)


def sentence(err: ValidationError, data: Any, model: type[BaseModel], prefix: str = "") -> str:
    """One sentence for the first error pydantic found in ``data`` (validated by ``model``), naming the key
    (``prefix``: where ``model`` sits in the config, e.g. ``"transfer."``)."""
    sections = {name: info.annotation for name, info in model.model_fields.items()
                if isinstance(info.annotation, type) and issubclass(info.annotation, BaseModel)}
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
    if error["type"] == "extra_forbidden" or info is None:
        return unknown_key(dotted)
    value = lookup(data, key)
    if isinstance(info.annotation, type) and issubclass(info.annotation, BaseModel):
        names = ", ".join(f"{dotted}.{k}" for k in info.annotation.model_fields)
        return f"config key '{dotted}' must be a mapping of {names}, got {short(value)}."
    extra = info.json_schema_extra if isinstance(info.json_schema_extra, dict) else {}
    if literal_choices(info) and isinstance(value, str):
        return f"unknown {extra.get('noun', 'value')} {value!r}: config key '{dotted}' must be {expected(info)}."
    return f"config key '{dotted}' must be {expected(info)}, got {short(value)}."


def build(data: dict | RunConfig, *, saved: bool = False) -> RunConfig:
    """A :class:`RunConfig` from a mapping of its keys (missing keys at their defaults; with ``saved``, a run's
    ``config.yaml``, at the values runs saved without them ran with, :func:`absent_value`), its types and
    ranges checked: a wrong one is one :class:`UsageError` sentence naming the key."""
    if isinstance(data, BaseModel):
        data = data.model_dump()
    if not isinstance(data, dict):
        raise UsageError(f"a config must be a mapping of config keys, got {short(data)}.")
    try:
        return RunConfig.model_validate(data, context={"saved": saved})
    except ValidationError as err:
        raise UsageError(sentence(err, data, RunConfig)) from None


def updated(cfg: RunConfig, changes: dict[str, Any]) -> RunConfig:
    """A copy of ``cfg`` with the dotted keys of ``changes`` set (``{"transfer.source": path}``), each value
    checked like the key's own."""
    data = cfg.model_dump()
    for dotted, value in changes.items():
        if dotted not in keys() and dotted not in section_models():
            raise UsageError(unknown_key(dotted))
        *path, last = dotted.split(".")
        node = data
        for part in path:
            node = node[part]
        node[last] = value.model_dump() if isinstance(value, BaseModel) else value
    return build(data)


def task_spec(task: Any):
    """The registered task ``task`` (:class:`~drltg.envs.TaskSpec`), or one sentence naming the closest."""
    from drltg.envs import TASKS  # registry import is cheap

    if not isinstance(task, str):
        raise UsageError(f"config key 'task' must be a registered task name, got {short(task)}.")
    if task not in TASKS:
        hint = closest(task, TASKS)
        raise UsageError(
            f"unknown task '{task}'" + (f"; did you mean '{hint}'?" if hint else "; see `drltg tasks`.")
        )
    return TASKS[task]
