"""Run configuration: typed sections (pydantic models), resolved in a fixed order and saved with the run.

    defaults (the models below) <- the task's own overrides (registry) <- a YAML file (--config) <- KEY=VALUE overrides

:func:`resolve` returns a :class:`RunConfig` (``cfg.optim.lr``, ``cfg.transfer.method``); the resolved
config, the task's env settings included, is written to ``<run_dir>/config.yaml`` (:func:`dump`) and
``drltg train --config <run_dir>/config.yaml`` reproduces the run. Every key has a declared type and
range in its section's model (``describe()`` lists them); a typo or a value out of range is one
:class:`~drltg.errors.UsageError` sentence naming the key (pydantic's errors are translated), before
anything is built or written.

:class:`RunConfig` is one static model. Four parts are open-ended, each checked by what its owner declares:
``algo`` names a registered learner; each registered learner's options are the section of its name (``sac``,
``td3``, ``soc``: the model in :data:`LEARNER_OPTIONS`); the ``transfer`` section holds, besides ``method``,
``source``, ``allow_incomplete`` and ``source_checkpoint``, the options of every registered transfer method,
each validated by the model its method declares in its own module (``TransferMethod.model``); all are found in
the registries of :mod:`drltg.config.registry` (:data:`LEARNERS`, :data:`LEARNER_OPTIONS`, :data:`METHODS`),
which load drltg's own and the installed plugins' on first lookup. ``env`` is a mapping of the task's keyword
arguments, checked against the options the task declares (:func:`validate`).
"""
from drltg.config import sections
from drltg.config.checks import check_device, validate
from drltg.config.diff import config_changes, describe, dump, env_keys_set_once
from drltg.config.env_options import env_defaults, task_env
from drltg.config.overrides import (
    ENV_EXECUTION_KEYS,
    as_config,
    frame_count,
    load_yaml,
    merge,
    parse_override,
    refuse_conflicts,
    resolve,
    set_key,
)
from drltg.config.registry import LEARNER_OPTIONS, LEARNERS, METHODS, Registry, get_method, method_names
from drltg.config.run import (
    TRANSFER_KEYS,
    RunConfig,
    TransferConfig,
    build,
    defaults,
    keys,
    option_owners,
    sentence,
    updated,
)
from drltg.config.sections import *  # noqa: F403 (the section models, listed in sections.__all__)
from drltg.config.values import (
    DEMO_SEED_OFFSET,
    EVAL_SEED_OFFSET,
    FRESH_SEED_OFFSET,
    MAX_EPISODES,
    MAX_SEEDS,
    MAX_THREADS,
    SEED_STRIDE,
    Bool,
    Float,
    Int,
    Number,
    Probability,
    Section,
    Str,
    run_seeds,
    source_seed,
)

__all__ = [
    "RunConfig", "resolve", "build", "validate", "as_config", "updated", "describe", "dump", "keys", "defaults",
    "config_changes", "env_keys_set_once", "refuse_conflicts", "parse_override", "frame_count", "load_yaml",
    "merge", "set_key", "task_env", "env_defaults", "check_device",
    "Int", "Float", "Bool", "Str", "Number", "Probability", "Section", "MAX_EPISODES", "MAX_SEEDS", "MAX_THREADS",
    "SEED_STRIDE", "run_seeds", "source_seed", "EVAL_SEED_OFFSET", "DEMO_SEED_OFFSET", "FRESH_SEED_OFFSET",
    *sections.__all__, "TransferConfig",
    "METHODS", "LEARNERS", "LEARNER_OPTIONS", "Registry", "TRANSFER_KEYS", "ENV_EXECUTION_KEYS",
    "method_names", "get_method", "option_owners", "sentence",
]
