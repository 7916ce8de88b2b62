"""Transfer methods: thin compositions of drltg's parts, registered by name (``transfer.method``).

    none             plain learning on the task: the baseline
    reward-shaping   transforms.PotentialShaping(the task's potential) on the training env  (reward_shaping)
    value-shaping    transforms.PotentialShaping(transforms.SourceValue(source run))        (value_shaping)
    policy-reuse     collectors.PolicyReuse(source policy, PiReuse(psi, upsilon))           (policy_reuse)
    jumpstart        collectors.PolicyReuse(source policy, JumpStart(H))                     (policy_reuse)
    model-reuse      modules.load_weights(source run's checkpoint -> the learner)           (model_reuse)
    demonstrations   collectors.collect_demonstrations + mixed_batches, losses.behaviour_cloning
                                                                                            (demonstrations)
    kickstarting     losses.distillation(source actor, KickstartingWeight)                  (kickstarting)
    sf-gpi           modules.GoalFeatures, losses.SuccessorFeatureLoss, collectors.GPIPolicy (sf_gpi)

A trained run as a source, in one call each (they print nothing): ``load_actor(run_dir)`` (the past
policy of policy reuse), ``load_critic(run_dir)`` (its value V(s), the potential of value shaping),
``load_agent(run_dir)`` (the whole learner) and ``load_from_run(module, run_dir)`` (its weights into
another network, model reuse); each reads the run's networks file ``checkpoints/last.safetensors``, or with
``checkpoint="best"`` its ``best.safetensors`` (``transfer.source_checkpoint`` for the methods), never the
training checkpoint with its replay buffer.

:mod:`drltg.transfer.registry` defines what a method is (:class:`TransferMethod`) and what it adds to a
run (:class:`Transfer`); :mod:`drltg.transfer.source` reads ``transfer.source``. The built-in methods are
the entry points of the group ``drltg.methods`` (``pyproject.toml``), found by the config's registry
(:data:`drltg.config.METHODS`, here ``METHODS``) on its first lookup: importing this package registers
nothing (``a+b`` names a combination, :func:`combine`); each trains its seeds as one seed group
(``TransferMethod.grouped``, :mod:`drltg.training.seeds`); the parts themselves
(``drltg.transforms``, ``drltg.collectors``, ``drltg.losses``, ``drltg.modules``) register nothing.
"""
from drltg.transfer import (  # noqa: I001
    demonstrations,
    kickstarting,
    model_reuse,
    policy_reuse,
    reward_shaping,
    sf_gpi,
    value_shaping,
)
from drltg.transfer.model_reuse import load_from_run
from drltg.transfer.registry import (
    METHODS,
    TUNING_BUDGET,
    Pretraining,
    Transfer,
    TransferMethod,
    combine,
    get_method,
    register_method,
)
from drltg.transfer.source import load_actor, load_agent, load_critic

__all__ = [
    "METHODS", "TUNING_BUDGET", "Transfer", "Pretraining", "TransferMethod", "combine", "get_method", "register_method",
    "load_actor", "load_critic", "load_agent", "load_from_run",
    "reward_shaping", "value_shaping", "policy_reuse", "model_reuse", "demonstrations", "kickstarting", "sf_gpi",
]
