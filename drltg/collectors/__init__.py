"""Collector-side parts: the policy-reuse mixer and its schedules, and demonstration episodes.

    PolicyReuse(source, spec, schedule)   after the learner's policy: the source acts with prob. psi_h;
                                          its primer() carries the episode's choice in the env
    PiReuse, JumpStart, PRQL              schedules: psi * upsilon^h; the guide's first H steps; a library
    collect_demonstrations, demonstration_buffer, mixed_batches   a policy's episodes, in a buffer of
                                          their own, a fixed share of every minibatch
    GPIPolicy(critics, w)                 acts by argmax_a max_i psi_i(s, a) . w over source policies'
                                          successor features (generalised policy improvement)
"""
from drltg.collectors.demonstrations import collect_demonstrations, demonstration_buffer, mixed_batches
from drltg.collectors.gpi import GPIPolicy
from drltg.collectors.policy_reuse import PRQL, JumpStart, PiReuse, PolicyReuse, ReuseSchedule

__all__ = [
    "PolicyReuse", "ReuseSchedule", "PiReuse", "JumpStart", "PRQL",
    "collect_demonstrations", "demonstration_buffer", "mixed_batches",
    "GPIPolicy",
]
