"""The transfer methods registered in this process: each method's check, the keys it owns and the
model of its options (filled by :func:`drltg.config.run.add_method`)."""
from __future__ import annotations

from typing import Any

from pydantic import (
    BaseModel,
)

METHOD_RULES: dict[str, Any] = {}
"""``transfer.method`` -> the check its configs must pass (``"+"``: the check of every combination
``a+b``), filled by :func:`drltg.transfer.register_method` (through :func:`add_method`): import
:mod:`drltg.transfer` (the commands do) before resolving a config that uses a transfer method."""

METHOD_OPTIONS: dict[str, str] = {}
"""``transfer.<key>`` -> the one method whose option it is (filled by :func:`~drltg.config.run.add_method` too)."""

METHOD_MODELS: dict[str, type[BaseModel]] = {}
"""``transfer.method`` -> the model of its options (``transfer.<key>``)."""


def method_names() -> tuple[str, ...]:
    """The values ``transfer.method`` takes (a combination ``a+b`` joins two of them)."""
    return ("none", *(m for m in METHOD_RULES if m not in ("none", "+")))
