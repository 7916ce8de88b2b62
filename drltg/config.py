"""Run configuration: one nested dict, resolved in a fixed order and saved with the run.

    defaults (below) <- the task's own overrides (registry) <- a YAML file (--config) <- KEY=VALUE overrides

The resolved dict is written to ``<run_dir>/config.yaml``; ``drltg train --config <run_dir>/config.yaml``
reproduces the run. Keys are validated against the defaults, so a typo is an error, not a silent no-op.
"""
from __future__ import annotations

import copy
import difflib
from pathlib import Path
from typing import Any, Iterable

import yaml

from drltg.errors import UsageError

DEFAULTS: dict[str, Any] = {
    "task": "fourrooms/northeast",
    "algo": "sac",
    "seed": 0,
    "frames": 50_000,
    "device": "cpu",
    "threads": 1,  # small nets are overhead-bound: one thread per run is fastest here
    "env": {},  # keyword overrides passed to drltg.envs.make_env
    "collector": {
        "num_envs": 8,
        "frames_per_batch": 32,
        "init_random_frames": 1024,
    },
    "buffer": {"size": 100_000, "batch_size": 256},
    "optim": {
        "lr": 3.0e-4,
        "updates_per_batch": 8,  # gradient steps per collected batch (UTD = this / frames_per_batch)
        "gamma": 0.99,
        "tau": 0.005,
    },
    "network": {"hidden": [256, 256]},
    "sac": {"alpha_init": 1.0, "fixed_alpha": False, "target_entropy": "auto"},
    "td3": {"exploration_noise": 0.1, "policy_noise": 0.2, "noise_clip": 0.5, "policy_delay": 2},
    # soft option-critic (drltg.losses.soc); the action temperature comes from "sac"
    "soc": {
        "num_options": 4,
        "option_policy": "soft",  # soft (softmax of Q_Omega / alpha_Omega) | egreedy
        "option_alpha_init": None,  # None: sac.alpha_init
        "fixed_option_alpha": False,
        "option_target_entropy": "auto",  # 0.5 * log(num_options)
        "option_epsilon": 0.1,  # egreedy only
        "deliberation_cost": 0.01,  # xi > 0 keeps options running
        "option_entropy_bonus": False,  # soft policy: the option choice's entropy enters V_Omega
    },
    "eval": {"every": 5_000, "episodes": 16},
    "checkpoint": {"every": 10_000},
    "log": {"tensorboard": True, "every": 1_000},
    # How this run transfers knowledge (drltg.transfer): none | reward-shaping | policy-reuse | model-reuse
    "transfer": {
        "method": "none",
        "source": None,  # source run directory (policy-reuse, model-reuse)
        "psi": 1.0,  # pi-reuse: probability of reusing at an episode's first step ...
        "upsilon": 0.95,  # ... decaying as psi * upsilon^h within the episode
        "psi_end": None,  # optional decay of psi across training, reached after annealing_frames
        "annealing_frames": 0,
        "freeze": [],  # model reuse: parameter name patterns to keep fixed
    },
}


def _flatten(d: dict, prefix: str = "") -> dict[str, Any]:
    out = {}
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict) and v and key != "env":
            out.update(_flatten(v, key + "."))
        else:
            out[key] = v
    return out


def _valid_keys() -> list[str]:
    return sorted(_flatten(DEFAULTS)) + ["env"]


def set_key(cfg: dict, dotted: str, value: Any) -> None:
    """Set ``cfg[a][b][c] = value`` for ``dotted = "a.b.c"``; keys under ``env.`` are free-form."""
    parts = dotted.split(".")
    if parts[0] != "env" and dotted not in _flatten(DEFAULTS):
        hint = difflib.get_close_matches(dotted, _valid_keys(), n=1)
        raise UsageError(
            f"unknown config key '{dotted}'" + (f"; did you mean '{hint[0]}'?" if hint else ".")
        )
    node = cfg
    for p in parts[:-1]:
        node = node.setdefault(p, {})
    node[parts[-1]] = value


def merge(cfg: dict, overrides: dict, prefix: str = "") -> None:
    """Merge a nested dict of overrides into ``cfg``, validating every key."""
    for k, v in overrides.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict) and key != "env" and isinstance(_flatten(DEFAULTS).get(key, {}), dict):
            merge(cfg, v, key + ".")
        elif key == "env":
            if not isinstance(v, dict):
                raise UsageError("config key 'env' must be a mapping of environment keyword arguments.")
            cfg["env"].update(v)
        else:
            set_key(cfg, key, v)


def parse_override(text: str) -> tuple[str, Any]:
    """``"optim.lr=1e-3"`` -> ``("optim.lr", 0.001)``; values are parsed as YAML scalars/lists."""
    if "=" not in text:
        raise UsageError(f"override '{text}' must look like KEY=VALUE, e.g. optim.lr=1e-3.")
    key, raw = text.split("=", 1)
    try:
        value = yaml.safe_load(raw)
    except yaml.YAMLError:
        value = raw
    if isinstance(value, str):  # YAML reads "1e-3" as a string
        try:
            value = float(value)
        except ValueError:
            pass
    return key.strip(), value


def load_yaml(path: str | Path) -> dict:
    path = Path(path)
    if not path.is_file():
        raise UsageError(f"config file '{path}' does not exist.")
    try:
        data = yaml.safe_load(path.read_text()) or {}
    except yaml.YAMLError as err:
        raise UsageError(f"config file '{path}' is not valid YAML ({err.__class__.__name__}).") from None
    if not isinstance(data, dict):
        raise UsageError(f"config file '{path}' must hold a mapping of config keys.")
    return data


def resolve(
    base: dict | None = None,
    overrides: Iterable[str] = (),
    **explicit: Any,
) -> dict:
    """Build a full config: defaults <- task overrides <- ``base`` (e.g. a YAML file) <- ``explicit``
    keyword values (e.g. ``--seed``) <- ``KEY=VALUE`` ``overrides``."""
    from drltg.envs import TASKS  # registry import is cheap

    base = dict(base or {})
    cfg = copy.deepcopy(DEFAULTS)
    task = explicit.get("task") or base.get("task") or cfg["task"]
    if task not in TASKS:
        hint = difflib.get_close_matches(str(task), list(TASKS), n=1)
        raise UsageError(
            f"unknown task '{task}'" + (f"; did you mean '{hint[0]}'?" if hint else "; see `drltg tasks`.")
        )
    merge(cfg, copy.deepcopy(TASKS[task].train))
    merge(cfg, base)
    for key, value in explicit.items():
        if value is not None:
            set_key(cfg, key, value)
    for text in overrides:
        set_key(cfg, *parse_override(text))
    _check_types(cfg)
    return cfg


def _check_types(cfg: dict) -> None:
    flat_default = _flatten(DEFAULTS)
    for key, value in _flatten(cfg).items():
        if key == "env" or key.startswith("env."):
            continue
        ref = flat_default.get(key)
        if isinstance(ref, bool) and not isinstance(value, bool):
            raise UsageError(f"config key '{key}' must be true or false, got {value!r}.")
        if isinstance(ref, int) and not isinstance(ref, bool):
            if isinstance(value, float) and value.is_integer():
                set_key(cfg, key, int(value))
            elif not isinstance(value, int) or isinstance(value, bool):
                raise UsageError(f"config key '{key}' must be an integer, got {value!r}.")
        if isinstance(ref, float) and not isinstance(value, (int, float)):
            raise UsageError(f"config key '{key}' must be a number, got {value!r}.")
    for key in ("frames", "collector.num_envs", "collector.frames_per_batch", "buffer.batch_size",
                "eval.every", "eval.episodes"):
        if _get(cfg, key) <= 0:
            raise UsageError(f"config key '{key}' must be positive, got {_get(cfg, key)}.")
    fpb, n = cfg["collector"]["frames_per_batch"], cfg["collector"]["num_envs"]
    if fpb % n:
        raise UsageError(
            f"collector.frames_per_batch ({fpb}) must be a multiple of collector.num_envs ({n})."
        )
    cfg["frames"] = -(-cfg["frames"] // fpb) * fpb  # whole collector batches: the budget is exact


def _get(cfg: dict, dotted: str) -> Any:
    node = cfg
    for p in dotted.split("."):
        node = node[p]
    return node


def dump(cfg: dict) -> str:
    return yaml.safe_dump(cfg, sort_keys=False)
