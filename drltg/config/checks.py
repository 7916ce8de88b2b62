"""The checks beyond types: this machine's device, the task's env keywords, the method's own rules."""
from __future__ import annotations

from drltg.config.env_options import check_env
from drltg.config.registry import get_method
from drltg.config.run import RunConfig
from drltg.config.values import expected
from drltg.errors import UsageError, short


def validate(cfg: RunConfig) -> None:
    """The checks of a built config that need this machine, the task's env or the transfer method:
    ``device`` must be usable here, ``env`` keys must be keywords of the task's factory (their values
    are read with the type of the declared default), the method's own rules must hold; and ``frames``
    is rounded up to whole collector batches, so that the budget is exact."""
    check_device("device", cfg.device)
    if cfg.optim.cudagraphs and not cfg.device.startswith("cuda"):
        raise UsageError(f"config key 'optim.cudagraphs' is true but device is '{cfg.device}'; CUDA graphs "
                         "need device=cuda.")
    cfg.env = check_env(cfg.task, cfg.env)
    get_method(cfg.transfer.method).validate(cfg)
    fpb = cfg.collector.frames_per_batch
    cfg.frames = -(-cfg.frames // fpb) * fpb


_DEVICE = expected(RunConfig.model_fields["device"])


def check_device(key: str, value: str) -> str:
    if value == "cpu":  # always there: no need to import torch to know it
        return value
    import torch

    try:
        device = torch.device(value)
    except (RuntimeError, TypeError, ValueError):
        raise UsageError(f"{_named(key)} must be {_DEVICE}, got {short(value)}.") from None
    backend = getattr(torch, device.type, None)
    available = getattr(backend, "is_available", None)
    if available is None:
        raise UsageError(f"{_named(key)} is '{value}', a device type drltg cannot train on; use cpu or cuda.")
    if not available():
        raise UsageError(
            f"{_named(key)} is '{value}' but no {device.type.upper()} device is available on this "
            "machine; use device=cpu."
        )
    if device.type == "cpu" and device.index not in (None, 0):
        raise UsageError(f"{_named(key)} is '{value}', but the CPU is one device, cpu (or cpu:0).")
    count = getattr(backend, "device_count", None)
    if device.index is not None and device.type != "cpu" and count is not None and device.index >= count():
        raise UsageError(
            f"{_named(key)} is '{value}' but this machine has {count()} {device.type.upper()} "
            f"device(s), numbered from 0."
        )
    return value


def _named(key: str) -> str:
    """A config key as a sentence names it; a command-line option (``--device``) as it is."""
    return key if key.startswith("--") else f"config key '{key}'"
