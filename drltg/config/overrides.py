"""Resolving a config: defaults <- the task's settings <- a YAML file <- ``KEY=VALUE`` overrides."""
from __future__ import annotations

import copy
import re
from pathlib import Path
from typing import Any, Iterable

from pydantic import (
    BaseModel,
)

from drltg.config.checks import validate
from drltg.config.env_options import task_env
from drltg.config.run import RunConfig, build, keys, section_models, task_spec, unknown_key
from drltg.config.values import expected
from drltg.errors import UsageError, short


def as_config(cfg: RunConfig | dict) -> RunConfig:
    """``cfg`` itself, or a mapping of config keys resolved as a ``--config`` file is (:func:`resolve`): the
    entry points that take a config (``train``, ``make_agent``) take either."""
    return cfg if isinstance(cfg, RunConfig) else resolve(cfg)


# How a batch of envs is stepped (worker processes or this one), not what it steps: the same trajectories
# either way (tests/test_robosuite.py), so two configs that differ only there are the same run.
ENV_EXECUTION_KEYS = ("env.parallel", "env.mp_start_method")


def flatten(d: dict, prefix: str = "") -> dict[str, Any]:
    out = {}
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict) and v and key != "env":
            out.update(flatten(v, key + "."))
        else:
            out[key] = v
    return out


def _env_expected() -> str:
    return expected(RunConfig.model_fields["env"])


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
            raise UsageError(f"config key 'env' must be {_env_expected()}, got {short(cfg.get('env'))}.")
        cfg["env"][parts[1]] = value
        return
    sections = section_models()
    if dotted in sections:
        if not isinstance(value, dict):
            names = ", ".join(f"{dotted}.{k}" for k in sections[dotted].model_fields)
            raise UsageError(f"config key '{dotted}' must be a mapping of {names}, got {short(value)}.")
        merge(cfg, value, dotted + ".")
        return
    if dotted not in keys():
        raise UsageError(unknown_key(dotted))
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
                raise UsageError(f"config key 'env' must be {_env_expected()}, got {short(v)}.")
            if not isinstance(cfg.get("env"), dict):
                cfg["env"] = {}
            cfg["env"].update(v)
        else:
            set_key(cfg, key, v)


_DECIMAL = re.compile(r"[+-]?(0|[1-9]\d*)")
_NUMBER = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?")

_FRAMES = re.compile(r"\s*(\d+(?:\.\d*)?|\.\d+)(?:[eE]\+?(\d+))?\s*([kKmM]?)\s*")


def frame_count(text: str) -> int:
    """``"50000"``, ``"50k"``, ``"1e4"``, ``"1.5M"`` as a whole number of frames: the argparse ``type`` of every
    ``--frames`` option (an ``argparse.ArgumentTypeError`` names what is wrong)."""
    import argparse

    m = _FRAMES.fullmatch(str(text))
    try:
        value = float(m.group(1)) * 10.0 ** int(m.group(2) or 0) * {"": 1, "k": 1e3, "m": 1e6}[m.group(3).lower()] \
            if m else None
    except OverflowError:  # 1e400
        value = None
    if value is None or not 1 <= value <= 1e12 or value != int(value):
        raise argparse.ArgumentTypeError(f"'{text}' is not a whole number of frames >= 1 (e.g. 50000, 50k, 1e4, 1.5M)")
    return int(value)


def parse_override(text: str) -> tuple[str, Any]:
    """``"optim.lr=1e-3"`` -> ``("optim.lr", 0.001)``; values are parsed as YAML scalars/lists."""
    if "=" not in text:
        raise UsageError(f"override '{text}' must look like KEY=VALUE, e.g. optim.lr=1e-3.")
    key, raw = text.split("=", 1)
    if _DECIMAL.fullmatch(raw.strip()):  # what YAML would read, without loading a YAML parser for a number
        return key.strip(), int(raw)
    from drltg import safe_yaml

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
    from drltg import safe_yaml

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
        raise UsageError(f"a config must be a mapping of config keys, got {short(base)}.")
    base = dict(base or {})
    parsed = [parse_override(text) for text in overrides]
    task = RunConfig.model_fields["task"].default
    for given in (base.get("task"), explicit.get("task"), *(v for k, v in parsed if k == "task")):
        if given is not None:
            task = given
    raw: dict[str, Any] = {}
    merge(raw, copy.deepcopy(task_spec(task).train))
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
    if isinstance(value, dict) and key in section_models():
        return flatten(value, key + ".")
    return {key: value}


def refuse_conflicts(overrides: Iterable[str], where: str = "-o") -> None:
    """Overrides that set one key twice are refused, in any form (``optim.lr=1`` twice, or ``optim={lr: 1}``
    and ``optim.lr=2``): which one was meant would depend on their order. ``overrides`` are a user's ``-o``
    texts, or ``(key, values)`` of a mapping (a sweep spec's ``overrides`` and ``grid``, ``where`` it is)."""
    seen: dict[str, str] = {}
    for item in overrides:
        if isinstance(item, str):
            (key, value), shown = parse_override(item), item.strip()
            leaves = set(_override_leaves(key, value))
        else:
            (key, values), shown = item, item[0]
            leaves = {leaf for value in values for leaf in _override_leaves(key, value)}
        for leaf in leaves:
            if leaf in seen:
                raise UsageError(f"config key '{leaf}' is set twice by {where} ('{seen[leaf]}', then '{shown}'); "
                                 "give it once.")
            seen[leaf] = shown
