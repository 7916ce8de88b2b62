"""The value types of config keys (strict ints, finite floats, ...), the bounds, the section base, and the
words an error sentence uses to say what a key takes."""
from __future__ import annotations

import math
import types
from typing import Annotated, Any, Iterable, Literal, Union, get_args, get_origin

from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    Strict,
)
from pydantic.fields import FieldInfo

from drltg.config.registry import LEARNERS, method_names
from drltg.errors import closest


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

SEED_STRIDE = 100
"""Run i of a set of seeds uses ``seed + 100 i`` and lives in ``seed-<that>/``: ``drltg train --seeds``, an
experiment's or sweep's baseline and transfer runs alike, so runs of one seed pair up wherever they were
trained; a source run of run i uses ``seed + 100 i + 50`` (:func:`source_seed`), no target run's seed."""


EVAL_SEED_OFFSET = 10_000
DEMO_SEED_OFFSET = 20_000
FRESH_SEED_OFFSET = 30_000
"""The envs of run ``seed`` are seeded apart: training ``seed``, its evaluations ``seed + EVAL_SEED_OFFSET``,
a transfer's demonstrations ``seed + DEMO_SEED_OFFSET``, ``drltg evaluate`` by default
``seed + FRESH_SEED_OFFSET``."""


def run_seeds(first: int, count: int) -> list[int]:
    """The seeds of ``count`` runs from ``first``: ``first + 100 i``."""
    return [first + SEED_STRIDE * i for i in range(count)]


def source_seed(seed: int) -> int:
    """The seed of the source run that a target run of ``seed`` transfers from."""
    return seed + SEED_STRIDE // 2

MAX_FRAMES = 10**12
"""Most frames of a run or of any interval counted in frames (``--frames`` takes as many)."""

MAX_BATCH = 2**20
"""Most envs, frames or transitions in one batch (``collector.*``, ``buffer.batch_size``)."""

MAX_OPTIONS = 256
"""Most options of the soft option-critic (its heads are allocated per option)."""

MAX_REPEATS = 100_000
"""Most repeated steps asked for in one go (``optim.updates_per_batch``, ``td3.policy_delay``)."""


def accepts(text: str = "", noun: str = "") -> dict:
    """``what`` replaces the generated description of the accepted values; ``noun`` names a choice in
    the error message ("unknown algorithm 'ppo'")."""
    return {k: v for k, v in (("what", text), ("noun", noun)) if v}


class Section(BaseModel):
    """A config section: unknown keys are refused, assignments are checked."""

    model_config = ConfigDict(extra="forbid", validate_assignment=True)


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


def expected(info: FieldInfo) -> str:
    """The accepted values of a field, as the end of "must be ..."."""
    extra = info.json_schema_extra if isinstance(info.json_schema_extra, dict) else {}
    annotation, metadata, nullable, auto = _unwrap(info.annotation)
    metadata = list(info.metadata) + metadata
    if "what" in extra:
        text = extra["what"]
    elif extra.get("choices") in ("methods", "learners"):
        text = "one of " + ", ".join(method_names() if extra["choices"] == "methods" else LEARNERS.names())
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


def literal_choices(info: FieldInfo) -> tuple | None:
    annotation = _unwrap(info.annotation)[0]
    return get_args(annotation) if get_origin(annotation) is Literal else None


def lookup(cfg: Any, dotted: str):
    node = cfg
    for part in dotted.split("."):
        if not isinstance(node, dict) or part not in node:
            return KeyError
        node = node[part]
    return node


def suggestion(key: str, known: Iterable[str]) -> str:
    hint = closest(key, known)
    return f"; did you mean '{hint}'?" if hint else "."
