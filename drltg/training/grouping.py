"""Which runs can train as one seed group (:mod:`drltg.training.seeds`): configs equal but for what each seed
reads alone, a learner and method with a grouped form, and a task whose group steps in this process or in one
worker per seed. A sweep asks it to plan its units of work (:func:`drltg.experiments.executor.seed_groups`)."""
from __future__ import annotations

from drltg.config import RunConfig
from drltg.transfer import get_method

GROUPED_ALGOS = ("sac", "td3", "soc")
"""The learners with a vmapped update over stacked seeds."""


def same_but_seed(a: RunConfig, b: RunConfig) -> bool:
    """Whether two configs differ at most in their seed, their ``transfer.source`` (an experiment's
    transfer run of seed s reads the source run of its own seed) and their method's member options
    (``TransferMethod.member_options``, which each seed's own parts read): their runs can share a seed
    group, each seed transferring from its own source with its own settings."""
    def key(cfg: RunConfig) -> dict:
        dump = cfg.model_dump()
        own = set(get_method(cfg.transfer.method).member_options)
        return {**dump, "seed": 0, "transfer": {k: None if k == "source" or k in own else v
                                                for k, v in dump["transfer"].items()}}

    return key(a) == key(b)


def group_support(cfg: RunConfig) -> str | None:
    """``None`` if the seeds of ``cfg`` can train as one group, else why not (one clause)."""
    if cfg.algo not in GROUPED_ALGOS:
        return f"--algo {cfg.algo} has no grouped update"
    method = get_method(cfg.transfer.method)
    if not method.grouped:
        return f"transfer method {method.name} has no grouped form" + (f": {method.alone}" if method.alone else "")
    if cfg.optim.cudagraphs:
        return "a group's vmapped update is not captured as a CUDA graph (optim.cudagraphs)"
    from drltg.envs import get_task

    get_task(cfg.task)  # an unknown task is one UsageError sentence
    return None


def in_process(cfg: RunConfig) -> bool:
    """Whether a group of the task's runs steps in this process: as one batched env (FourRooms, GridRooms,
    :func:`batched`), or as one env per seed side by side (a Gymnasium task, whose batch is a ``SerialEnv`` of
    single envs anyway); otherwise a group steps one env per seed in worker processes (robosuite)."""
    from drltg.envs import get_task
    from drltg.envs.gym import make_gym_env

    return batched(cfg) or get_task(cfg.task).factory is make_gym_env


def batched(cfg: RunConfig) -> bool:
    """Whether the task's env steps a whole group's batch as one env seeded once (a :class:`GoalEnv`)."""
    from drltg.envs import get_task
    from drltg.envs.goal_env import GoalEnv

    factory = get_task(cfg.task).factory
    return isinstance(factory, type) and issubclass(factory, GoalEnv)
