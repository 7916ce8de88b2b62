"""Collector-side policy mixers."""
from drltg.collectors.policy_reuse import PRQL, JumpStart, PiReuse, PolicyReuse, ReuseSchedule

__all__ = ["PolicyReuse", "ReuseSchedule", "PiReuse", "JumpStart", "PRQL"]
