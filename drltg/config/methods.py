"""The built-in transfer methods' options as plain data (readable without importing the methods or
torch), and how a method's declared option types are read."""
from __future__ import annotations

import copy
import types
from typing import Annotated, Any, Union, get_args, get_origin

from pydantic import (
    BeforeValidator,
    Strict,
)

from drltg.config.values import Bool, Float, Int, Str

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
