"""A sweep spec: the YAML grid ``drltg sweep`` expands (its keys are in :mod:`drltg.experiments.sweep`),
checked before anything is planned; every mistake is one :class:`~drltg.errors.UsageError` sentence."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from drltg.config import refuse_conflicts
from drltg.errors import UsageError, closest
from drltg.experiments.summary import SUMMARY_COLUMNS

__all__ = ["Spec", "parse_spec", "load_spec", "KEYS", "MAX_RUNS", "SET_BY_SWEEP"]

KEYS = ("pairs", "methods", "algos", "seeds", "seed", "frames", "source_frames", "source_success", "overrides", "grid",
        "threshold", "primary_metric", "value_range", "resources")
RESOURCES = ("num_cpus", "num_gpus")
MAX_RUNS = 10_000
"""The most transfer runs one sweep spec may expand to (counted before anything is planned)."""
SET_BY_SWEEP = {"task": "'pairs'", "algo": "'algos'", "seed": "'seed' and 'seeds'",
                "frames": "'frames' or 'source_frames'", "transfer.method": "'methods'",
                "eval.stop_at_success": "'source_success'"}
"""The config keys the sweep sets per run, and the spec key that sets them."""


@dataclass
class Spec:
    pairs: list[str]
    methods: list[str]
    algos: list[str] = field(default_factory=lambda: ["sac"])
    seeds: int = 5
    seed: int = 0
    frames: list[int] = field(default_factory=list)
    source_frames: list[int] | None = None
    source_success: float | None = None
    overrides: dict[str, Any] = field(default_factory=dict)
    grid: dict[str, list] = field(default_factory=dict)
    threshold: float | str | None = None
    primary_metric: str | None = None
    value_range: tuple[float, float] | None = None
    resources: dict[str, float] = field(default_factory=lambda: {"num_cpus": 1, "num_gpus": 0})


def _hint(word: str, choices) -> str:
    close = closest(word, choices)
    return f"; did you mean '{close}'?" if close else f"; choose from: {', '.join(choices)}."


def _axis(data: dict, key: str, kind: type, where: str) -> list:
    """A spec entry as a non-empty list of ``kind`` (a scalar is a one-value list)."""
    value = data[key]
    values = value if isinstance(value, list) else [value]
    if not values:
        raise UsageError(f"{where}: '{key}' is an empty list; give at least one value.")
    for v in values:
        if kind is int and isinstance(v, float) and v.is_integer():
            continue
        if not isinstance(v, kind) or (kind is int and isinstance(v, bool)):
            raise UsageError(f"{where}: '{key}' must hold {kind.__name__} values, got {v!r}.")
    values = [int(v) if kind is int else v for v in values]
    _no_repeats(values, key, where)
    return values


def _no_repeats(values: list, key: str, where: str) -> None:
    seen = []
    for v in values:
        if v in seen:
            raise UsageError(f"{where}: '{key}' lists {v!r} twice; each value is one point of the sweep.")
        seen.append(v)


def _config_keys(mapping, key: str, where: str) -> dict:
    if not isinstance(mapping, dict):
        raise UsageError(f"{where}: '{key}' must be a mapping of config keys like {{eval.every: 1000}}.")
    from drltg.experiments.experiment import refuse_plan_overrides

    listed = {k: vs if key == "grid" and isinstance(vs, list) else [vs] for k, vs in mapping.items()}
    refuse_plan_overrides([(k, v) for k, vs in listed.items() for v in vs], f"{where}: '{key}'", "sweep", SET_BY_SWEEP)
    refuse_conflicts(listed.items(), f"{where}: '{key}'")
    return dict(mapping)


def parse_spec(data: Any, where: str = "sweep spec") -> Spec:
    """Validate a loaded spec; every mistake is one :class:`UsageError` sentence."""

    if not isinstance(data, dict):
        raise UsageError(f"{where} must be a YAML mapping with keys like pairs, methods, seeds, frames.")
    for key in data:
        if key not in KEYS:
            raise UsageError(f"{where}: unknown key '{key}'{_hint(key, KEYS)}")
    for key in ("pairs", "methods", "frames"):
        if key not in data:
            raise UsageError(f"{where}: the key '{key}' is required.")
    spec = Spec(pairs=_axis(data, "pairs", str, where), methods=_axis(data, "methods", str, where),
                frames=_axis(data, "frames", int, where))
    _check_names(spec, data, where)
    for key in ("seeds", "seed"):
        if key in data:
            value = data[key]
            if not isinstance(value, int) or isinstance(value, bool):
                raise UsageError(f"{where}: '{key}' must be an integer, got {value!r}.")
            setattr(spec, key, value)
    if spec.seeds < 1 or min(spec.frames) < 1:
        raise UsageError(f"{where}: 'seeds' and 'frames' must be positive.")
    if data.get("source_frames") is not None:
        spec.source_frames = _axis(data, "source_frames", int, where)
        if min(spec.source_frames) < 1:
            raise UsageError(f"{where}: 'source_frames' must be positive; omit it to give source runs 'frames'.")
    success = data.get("source_success")
    if success is not None:
        if isinstance(success, bool) or not isinstance(success, (int, float)) or not 0 < success <= 1:
            raise UsageError(f"{where}: 'source_success' must be a success rate in (0, 1], got {success!r}.")
        spec.source_success = float(success)
    spec.overrides = _config_keys(data.get("overrides") or {}, "overrides", where)
    spec.grid = _config_keys(data.get("grid") or {}, "grid", where)
    _check_grid(spec.grid, where)
    spec.threshold, primary = _report_keys(data, where)
    spec.primary_metric = primary
    spec.value_range = _value_range(data, where)
    spec.resources.update(_resources(data, where))
    runs = math.prod([len(spec.pairs), len(spec.methods), len(spec.algos), spec.seeds, len(spec.frames),
                      len(spec.source_frames or [None]), *map(len, spec.grid.values())])
    if runs > MAX_RUNS:
        raise UsageError(f"{where} expands to {runs:,} transfer runs (pairs x methods x algos x seeds x frames x grid "
                         f"values), more than the {MAX_RUNS:,} one sweep plans; split it into smaller sweeps.")
    return spec


def _check_names(spec: Spec, data: dict, where: str) -> None:
    """Every pair (or lone target task), method and algo of the spec is registered."""
    from drltg.envs import TASKS, get_pair
    from drltg.learners import ALGOS
    from drltg.transfer import METHODS, get_method

    for pair in spec.pairs:
        try:
            if pair not in TASKS:  # a task alone is a target (methods without a source, or a given one)
                get_pair(pair)
        except UsageError as err:
            raise UsageError(f"{where}: {err}") from None
    for method in spec.methods:
        for part in method.split("+"):
            if part not in METHODS or part == "none":
                raise UsageError(f"{where}: unknown method '{part}'{_hint(part, [m for m in METHODS if m != 'none'])}")
        try:
            get_method(method)
        except UsageError as err:
            raise UsageError(f"{where}: {err}") from None
    if "algos" in data:
        spec.algos = _axis(data, "algos", str, where)
    for algo in spec.algos:
        if algo not in ALGOS:
            raise UsageError(f"{where}: unknown algo '{algo}'{_hint(algo, sorted(ALGOS))}")


def _check_grid(grid: dict, where: str) -> None:
    """Each grid key sweeps a non-empty list of distinct, printable values (they name folders)."""
    for key, values in grid.items():
        if not isinstance(values, list) or not values:
            raise UsageError(f"{where}: grid key '{key}' must be a non-empty list of values.")
        _no_repeats(values, f"grid: {key}", where)
        named = next((v for v in values if any(ord(c) < 32 or c == "\x7f" for c in str(v))), None)
        if named is not None:
            raise UsageError(f"{where}: grid value {named!r} of '{key}' holds a control character; grid values name "
                             "the runs' folders, so give printable values.")


def _value_range(data: dict, where: str) -> tuple[float, float] | None:
    """``value_range: [low, high]``: the range of the runs' returns, for tasks that declare none."""
    from drltg.report.settings import parse_range

    value = data.get("value_range")
    if value is not None and not (isinstance(value, list) and len(value) == 2
                                  and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)):
        raise UsageError(f"{where}: 'value_range' must be [LOW, HIGH], two numbers, got {value!r}.")
    try:
        return parse_range(value)
    except UsageError as err:
        raise UsageError(f"{where}: {err}".replace("--value-range", "value_range")) from None


def _report_keys(data: dict, where: str) -> tuple:
    """``threshold`` and ``primary_metric`` (``None`` where not given), checked as ``drltg report`` checks them."""
    from drltg.report import check_metric, parse_threshold

    threshold = data.get("threshold")
    if threshold is not None and (isinstance(threshold, bool) or not isinstance(threshold, (int, float, str))):
        raise UsageError(f"{where}: 'threshold' must be a number or a percentage like \"80%\".")
    try:
        parse_threshold(threshold)
    except UsageError as err:
        raise UsageError(f"{where}: {err}".replace("--threshold", "threshold")) from None
    primary = data.get("primary_metric")
    if primary is not None:
        try:
            check_metric(str(primary), "primary_metric")
        except UsageError as err:
            raise UsageError(f"{where}: {err}") from None
        if primary not in SUMMARY_COLUMNS or primary.startswith("time_to"):
            raise UsageError(f"{where}: primary_metric '{primary}' is not a comparison the summary holds; choose "
                             f"one of {', '.join(c for c in SUMMARY_COLUMNS if not c.startswith('time_to'))}.")
    return threshold, primary


def _resources(data: dict, where: str) -> dict:
    """What each run asks of a Ray cluster (``num_cpus``, ``num_gpus``), non-negative numbers."""
    resources = data.get("resources") or {}
    if not isinstance(resources, dict):
        raise UsageError(f"{where}: 'resources' must be a mapping like {{num_cpus: 1, num_gpus: 0}}.")
    for key, value in resources.items():
        if key not in RESOURCES:
            raise UsageError(f"{where}: unknown resource '{key}'{_hint(key, RESOURCES)}")
        if isinstance(value, bool) or not isinstance(value, (int, float)) or value < 0:
            raise UsageError(f"{where}: resource '{key}' must be a non-negative number, got {value!r}.")
    return resources


def load_spec(path: str | Path) -> Spec:
    from drltg.config import load_yaml

    return parse_spec(load_yaml(path, "sweep spec"), where=f"sweep spec '{path}'")
