"""How a transfer method's declared option types are read: as the built-in keys read theirs."""
from __future__ import annotations

import types
from typing import Annotated, Any, Union, get_args, get_origin

from pydantic import (
    BeforeValidator,
    Strict,
)

from drltg.config.values import Bool, Float, Int, Str

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
