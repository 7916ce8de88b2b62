"""Bounds shared by the tasks and the evaluation that runs them."""
import os

MAX_HORIZON = 100_000
"""The most steps an evaluation runs one episode (:func:`drltg.training.loop.evaluate`), so the longest
horizon a task accepts: an episode is never cut short without being said."""


def usable_cpus() -> int:
    """The CPU cores this process may run on (its affinity, where the platform has one: a process pinned with
    ``taskset`` sees its own cores, not the machine's)."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
