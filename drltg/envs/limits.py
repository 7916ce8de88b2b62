"""Bounds shared by the tasks and the evaluation that runs them."""
import os

MAX_HORIZON = 100_000
"""The most steps an evaluation runs one episode (:func:`drltg.training.loop.evaluate`), so the longest
horizon a task accepts: an episode is never cut short without being said."""

ROBOSUITE_HORIZON = 500
"""The manipulation tasks' default horizon (25 s at 20 Hz): :class:`~drltg.envs.robosuite.env.RobosuiteEnv`'s
default, and what their return range is read from without importing robosuite."""


def usable_cpus() -> int:
    """The CPU cores this process may run on (its affinity, where the platform has one: a process pinned with
    ``taskset`` sees its own cores, not the machine's)."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
