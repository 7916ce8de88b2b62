"""A plugin as docs/extending.md shows one: two Gymnasium tasks, a pair and a method, registered without
``replace=True``, as a user writes them. ``PENDPLUG_FAIL_IN_WORKER=1`` makes its import fail in a worker
process only (the parent imports it fine), to check what the parent says of such a worker."""
import multiprocessing
import os

from drltg.envs import register_gym_task, register_pair
from drltg.transfer import Transfer, TransferMethod, load_from_run, register_method

if os.environ.get("PENDPLUG_FAIL_IN_WORKER") and multiprocessing.current_process().name != "MainProcess":
    raise RuntimeError("pendplug refuses to load in a worker")

register_gym_task("pend/light", "Pendulum-v1", g=10.0, returns=(-1700.0, 0.0))
register_gym_task("pend/heavy", "Pendulum-v1", g=12.0, returns=(-1700.0, 0.0))
register_pair("pend-lh", "pend/light", "pend/heavy", "Pendulum's gravity rises from 10 to 12")


def reuse_all(cfg, agent, env, *, resuming):
    """Every network starts from the source run's (model reuse, as a plugin of its own)."""
    if not resuming:
        load_from_run(agent.loss, cfg.transfer.source, checkpoint=cfg.transfer.source_checkpoint)
    return Transfer()


register_method(TransferMethod("pend-reuse", "every network starts from the source run's", reuse_all, source="run"))
