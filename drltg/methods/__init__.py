"""Transfer methods, one module each, registered by name (``transfer.method``).

    none             plain learning on the task: the baseline
    reward-shaping   PotentialShaping(the task's potential) on the training env     (reward_shaping)
    policy-reuse     PolicyReuse(source policy, PiReuse(psi, upsilon)) after the policy   (policy_reuse)
    jumpstart        PolicyReuse(source policy, JumpStart(H)): the guide acts first  (policy_reuse)
    model-reuse      the learner starts from the source run's weights                 (model_reuse)
    value-shaping    PotentialShaping(Phi = the source run's value V(s))              (value_shaping)
    demonstrations   source-policy episodes in their own buffer, a share of every batch,
                     behaviour cloning on them                                        (demonstrations)

:mod:`drltg.methods.registry` defines what a method is (:class:`TransferMethod`) and what it adds to a
run (:class:`Transfer`); :mod:`drltg.methods.source` reads ``transfer.source``.
"""
from drltg.methods.registry import METHODS, Transfer, TransferMethod, get_method, register_method

register_method(TransferMethod("none", "plain learning on the task: the baseline", lambda *a, **k: Transfer()))

from drltg.methods import reward_shaping, policy_reuse, model_reuse, demonstrations, value_shaping  # noqa: E402,I001
from drltg.methods.demonstrations import (  # noqa: E402
    behaviour_cloning,
    collect_demonstrations,
    demonstration_buffer,
    mixed_batches,
)
from drltg.methods.model_reuse import LoadReport, freeze_parameters, load_from_run, load_weights  # noqa: E402
from drltg.methods.policy_reuse import PRQL, JumpStart, PiReuse, PolicyReuse, ReuseSchedule  # noqa: E402
from drltg.methods.reward_shaping import PotentialShaping, TimeDependentPotential  # noqa: E402
from drltg.methods.value_shaping import SourceValue  # noqa: E402

__all__ = [
    "METHODS", "Transfer", "TransferMethod", "get_method", "register_method",
    "PotentialShaping", "TimeDependentPotential", "SourceValue",
    "PolicyReuse", "ReuseSchedule", "PiReuse", "JumpStart", "PRQL",
    "LoadReport", "load_weights", "load_from_run", "freeze_parameters",
    "collect_demonstrations", "demonstration_buffer", "mixed_batches", "behaviour_cloning",
    "reward_shaping", "policy_reuse", "model_reuse", "demonstrations", "value_shaping",
]
