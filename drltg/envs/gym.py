"""Gymnasium tasks in drltg: any installed Gymnasium env with a Box or Discrete action space is a task.

A Gymnasium env steps one episode at a time, so a batch of ``n`` is ``SerialEnv(n, GymWrapper)``:
TorchRL's :class:`~torchrl.envs.GymWrapper` of ``gymnasium.make(ID, **kwargs)`` per element
(``terminated`` and ``truncated`` kept apart, a Discrete action one-hot as drltg's discrete learners
expect, ``step_count`` kept by a ``StepCounter``), run in this process. ``gym/<ID>`` names every
registered Gymnasium id without registering it first (``drltg train gym/Pendulum-v1``);
:func:`register_gym_task` names a variant with its own ``gymnasium.make`` keywords::

    register_gym_task("pendulum/light", "Pendulum-v1", g=5.0)
    register_pair("pendulum-lighter", "pendulum/g10", "pendulum/light", "gravity 10 -> 5")

Gymnasium itself is imported when an env is built or a ``gym/`` name is looked up.
"""
from __future__ import annotations

import functools
from typing import Any, Callable, Sequence

from drltg.errors import UsageError

PREFIX = "gym/"
"""``gym/<ID>`` is the Gymnasium id ``<ID>`` with its registered defaults, made on first use."""


def make_gym_env(
    gym_id: str,
    *,
    batch_size: Sequence[int] = (),
    device=None,
    info_keys: Sequence[str] = (),
    **make_kwargs,
):
    """``GymWrapper(gymnasium.make(gym_id, **make_kwargs))``, or ``SerialEnv`` of ``batch_size[0]`` of them.

    ``info_keys`` are entries of the env's ``info`` dict read into the tensordict at every step (e.g.
    ``success``, which evaluation reports as ``success_rate``).
    """
    import torch
    from torchrl.envs import SerialEnv

    batch_size = tuple(torch.Size(batch_size))
    if len(batch_size) > 1:
        raise UsageError(f"Gymnasium task {gym_id!r} runs a flat batch of envs; got batch_size {batch_size}.")
    single = functools.partial(_single, gym_id, device, tuple(info_keys), make_kwargs)
    if not batch_size:
        return single()
    return SerialEnv(batch_size[0], single, device=device)


def _single(gym_id: str, device, info_keys: tuple[str, ...], make_kwargs: dict[str, Any]):
    import gymnasium
    import torch
    from torchrl.data import Categorical
    from torchrl.envs import GymWrapper, StepCounter, TransformedEnv
    from torchrl.envs.libs.gym import default_info_dict_reader

    try:
        made = gymnasium.make(gym_id, **{"disable_env_checker": True, **make_kwargs})
    except gymnasium.error.Error as err:
        raise UsageError(f"Gymnasium cannot make {gym_id!r}: {err}") from None
    except TypeError as err:
        cause = str(err).split(" was raised from the environment creator")[0]
        raise UsageError(f"Gymnasium env {gym_id!r} cannot be made with {make_kwargs}: {cause}.") from None
    env = GymWrapper(made, device=device)
    space = env._env.action_space
    if not isinstance(space, (gymnasium.spaces.Box, gymnasium.spaces.Discrete)):
        env.close()
        raise UsageError(
            f"Gymnasium env {gym_id!r} has a {type(space).__name__} action space; drltg's learners take Box or "
            "Discrete actions."
        )
    if info_keys:
        spec = {key: Categorical(2, (1,), dtype=torch.bool) for key in info_keys}
        env.set_info_dict_reader(_flag_reader(default_info_dict_reader)(list(info_keys), spec=spec))
    return TransformedEnv(env, StepCounter())  # step_count, as drltg's tasks keep it (policy reuse reads it)


def _flag_reader(base):
    class FlagReader(base):
        """Reads ``info`` entries as bool flags of shape ``(1,)`` (Gymnasium envs give Python or NumPy
        bools, or numbers); a flag missing from an ``info`` is false."""

        def __call__(self, info_dict, tensordict):
            import numpy as np

            flags = {k: np.asarray(info_dict[k]).astype(bool).reshape(1) for k in self.keys if k in info_dict}
            return super().__call__(flags, tensordict)

    return FlagReader


def register_gym_task(
    name: str,
    gym_id: str,
    description: str | None = None,
    *,
    info_keys: Sequence[str] = (),
    train: dict[str, Any] | None = None,
    potential: Callable[[dict[str, Any]], Callable] | None = None,
    returns: Callable[[dict[str, Any]], tuple[float, float]] | tuple[float, float] | None = None,
    replace: bool = False,
    **make_kwargs,
):
    """Registers the Gymnasium env ``gym_id`` made with ``make_kwargs`` as the drltg task ``name``.

    The task is batched like drltg's own (``SerialEnv`` of ``GymWrapper``), so ``register_pair``,
    ``drltg experiment`` and sweeps take it as any other; ``make_kwargs`` become its ``env.*`` settings,
    its only options. ``gym_id`` and ``info_keys`` are what the task is (:attr:`~drltg.envs.TaskSpec.fixed`):
    no config sets them, so a run directory cannot name the module ``gymnasium.make`` would import for an
    id ``"module:Env-v0"``.
    ``potential(env_options)`` builds its reward-shaping potential, as for :func:`~drltg.envs.register_task`
    (``--method reward-shaping``). ``returns`` is the range every episode's return lies in, as
    ``(low, high)`` or ``returns(env_options)`` (:attr:`~drltg.envs.TaskSpec.returns`): the report's
    interval over the declared range and its normalised scores read it. Gymnasium is not imported here: a
    plugin registering tasks stays cheap to import.
    """
    from drltg.envs.registry import register_task

    if not isinstance(gym_id, str) or not gym_id:
        raise UsageError(f"register_gym_task({name!r}, ...): gym_id must be a Gymnasium id such as 'Pendulum-v1'.")
    options = ", ".join(f"{k}={v!r}" for k, v in make_kwargs.items())
    description = description or f"Gymnasium {gym_id}" + (f" with {options}" if options else "")
    if isinstance(returns, (tuple, list)):
        returns = _Range(*returns)
    return register_task(name, make_gym_env, description, train=train, potential=potential, returns=returns,
                         replace=replace, fixed=fixed(gym_id, info_keys), **make_kwargs)


class _Range:
    """A fixed return range as a task's ``returns(options)`` (a class, not a lambda: worker processes
    receive registered tasks pickled)."""

    def __init__(self, low: float, high: float):
        self.low, self.high = float(low), float(high)

    def __call__(self, options) -> tuple[float, float]:
        return self.low, self.high


def fixed(gym_id: str, info_keys: Sequence[str] = ()) -> dict[str, Any]:
    """The registration fields of a Gymnasium task (``register_task(..., fixed=...)``)."""
    return {"gym_id": gym_id, "info_keys": list(info_keys)}


def declared_options(gym_id: str) -> dict[str, Any]:
    """What a Gymnasium id's ``make`` takes as keywords with their defaults: its env's constructor
    keywords (``render_mode`` aside: drltg renders through its own path), the keywords it is registered
    with over them, and ``max_episode_steps``. The entry point is the one a registered id already names."""
    import inspect

    import gymnasium
    from gymnasium.envs.registration import load_env_creator

    spec = gymnasium.spec(gym_id)
    creator = spec.entry_point if callable(spec.entry_point) else load_env_creator(spec.entry_point)
    try:
        params = inspect.signature(creator).parameters.values()
    except (TypeError, ValueError):
        params = ()
    declared = {p.name: p.default for p in params if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)
                and p.default is not p.empty and p.name not in ("self", "render_mode")}
    return {**declared, **spec.kwargs, "max_episode_steps": spec.max_episode_steps}


def resolve(name: str) -> bool:
    """Registers ``gym/<ID>`` when ``<ID>`` is a registered Gymnasium id; whether it did."""
    if not name.startswith(PREFIX):
        return False
    try:
        import gymnasium
    except ImportError:
        return False
    gym_id = name[len(PREFIX):]
    if ":" in gym_id or gym_id not in gymnasium.registry:  # "module:Env-v0" would make Gymnasium import module
        return False
    register_gym_task(name, gym_id, f"Gymnasium {gym_id} with its registered defaults", **declared_options(gym_id))
    return True
