"""The ``env`` section: the task factory's declared keywords, read with the type of their defaults."""
from __future__ import annotations

from typing import Annotated, Any

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    create_model,
)

from drltg.config.run import _task_spec
from drltg.config.values import Bool, Float, Int, Number, Str, _expected, _short, _what
from drltg.errors import UsageError

_ENV_RESERVED = {"batch_size": "collector.num_envs and eval.episodes", "device": "device", "seed": "seed"}


def env_defaults(task: str) -> dict[str, Any]:
    """The options of task ``task``: its factory's declared keywords (its registered defaults win), less
    its registration fields; read without importing the env where the registry can
    (:meth:`drltg.envs.TaskSpec.keywords`)."""
    return _task_spec(task).keywords()


def task_env(task: str) -> dict[str, Any]:
    """Every env setting of ``task`` at its default (the factory's declared keywords, the task's
    registered values over them), as plain YAML values: ``resolve`` writes them all into the config,
    so a run's ``config.yaml`` says exactly which env it trained on and a changed default is a
    changed config."""
    declared = env_defaults(task)
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
    """The model of task ``task``'s ``env`` section: one optional field per option the task declares,
    typed by the declared default; other keys are refused."""
    fields = {}
    for name, ref in env_defaults(task).items():
        kind = _env_type(ref)
        fields[name] = (Any if kind is None else kind, None)
    return create_model("EnvOptions", __config__=ConfigDict(extra="forbid"), **fields)


def _check_env(task: str, env: dict) -> dict:
    """``env`` with its values read as the types of the task's declared defaults; an unknown or reserved
    key, or a value of another type, is one sentence naming the key. A registration field of the task
    (:attr:`drltg.envs.TaskSpec.fixed`, e.g. a Gymnasium id) is no option: stated with the task's own value
    (as configs saved before the distinction did) it is dropped, with any other value refused."""
    spec = _task_spec(task)
    env = spec.without_registration(env)
    declared = env_defaults(task)
    for name in env:
        if name in _ENV_RESERVED:
            raise UsageError(f"config key 'env.{name}' cannot be set: the run sets it from {_ENV_RESERVED[name]}.")
        if name in spec.fixed:
            raise UsageError(f"config key 'env.{name}' cannot be set: it is part of the task '{task}' as registered "
                             f"({name}={spec.fixed[name]!r}), not an option, got {_short(env[name])}.")
        if name not in declared:
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
