"""The tensordict keys drltg's TD losses share: where the TD error goes and what they read of a transition.

Each loss declares its own ``_AcceptedKeys`` (TorchRL's convention, changed with ``.set_keys(...)``) as a
subclass of :class:`TDKeys`, so the keys a prioritized buffer and the collectors rely on are spelled once.
"""
from __future__ import annotations

from dataclasses import dataclass

from tensordict.utils import NestedKey

__all__ = ["TDKeys"]


@dataclass
class TDKeys:
    """Keys every TD loss of drltg reads or writes.

    Attributes:
        priority: where the TD error is written. Defaults to ``"td_error"``.
        done, terminated: as in TorchRL's losses.
        priority_weight: importance weights of a prioritized buffer. Defaults to ``"priority_weight"``.
    """

    priority: NestedKey = "td_error"
    done: NestedKey = "done"
    terminated: NestedKey = "terminated"
    priority_weight: NestedKey = "priority_weight"
