"""The reward-shaping method: ``PotentialShaping`` with the task's registered potential and the learner's gamma."""
from __future__ import annotations

from drltg.config import RunConfig
from drltg.errors import UsageError
from drltg.transfer.registry import Transfer, TransferMethod


def _check(cfg: RunConfig) -> None:
    from drltg.envs import get_task

    if get_task(cfg.task).potential is None:
        raise UsageError(f"task '{cfg.task}' has no shaping potential registered.")


def _build(cfg: RunConfig, agent, env, *, resuming: bool) -> Transfer:
    """The task's own potential (registered with the task), the learner's gamma."""
    from drltg.envs import get_task
    from drltg.transforms import PotentialShaping

    task = get_task(cfg.task)
    shaping = PotentialShaping(task.potential({**task.defaults, **cfg.env}), gamma=cfg.optim.gamma)
    return Transfer(train_transforms=[shaping])


REWARD_SHAPING = TransferMethod(
    "reward-shaping",
    "adds gamma Phi(s') - Phi(s) to the training reward, Phi the task's registered potential",
    _build,
    grouped=True,
    check=_check,
)
