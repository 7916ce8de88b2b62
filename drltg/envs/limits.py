"""Bounds shared by the tasks and the evaluation that runs them."""

MAX_HORIZON = 100_000
"""The most steps an evaluation runs one episode (:func:`drltg.training.loop.evaluate`), so the longest
horizon a task accepts: an episode is never cut short without being said."""
