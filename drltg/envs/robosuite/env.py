"""A robosuite manipulation task as a TorchRL ``EnvBase``.

robosuite runs with ``ignore_done=True`` and this env counts steps itself: the horizon is reported as
``truncated`` (bootstrapping continues through it), never as ``terminated``. ``terminated`` is set only
by a true task end, which these tasks do not have unless ``terminate_on_success=True``.

Steps go through :class:`~drltg.envs.robosuite.fast_osc.LeanStep` by default: robosuite's physics,
controller arithmetic, rewards and success checks with its per-substep Python bookkeeping cut out,
bit-identical to robosuite's ``env.step`` (``fast=False`` steps through robosuite itself).
"""
from __future__ import annotations

import functools
import inspect
import logging
from typing import Sequence

import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Bounded, Categorical, Composite, Unbounded
from torchrl.envs import EnvBase

from drltg.envs.limits import MAX_HORIZON, usable_cpus
from drltg.envs.robosuite.layout import OBSERVABLES, layout_of
from drltg.errors import UsageError

TASK_CLASSES = {
    "lift": "LiftWithTarget",
    "lift-place": "LiftPlace",
    "lift-place-barrier": "LiftPlaceBarrier",
    "lift-place-seed": "LiftPlaceSeed",
    "lift-place-barrier-seed": "LiftPlaceBarrierSeed",
}


def _task_class(task):
    """A drltg task name, a robosuite environment name, or a robosuite environment class."""
    if not isinstance(task, str):
        return task
    if task in TASK_CLASSES:
        from drltg.envs.robosuite import tasks

        return getattr(tasks, TASK_CLASSES[task])
    from robosuite.environments.base import REGISTERED_ENVS

    if task not in REGISTERED_ENVS:
        known = ", ".join([*TASK_CLASSES, *sorted(REGISTERED_ENVS)])
        raise UsageError(f"unknown robosuite task {task!r}; known: {known}.")
    return REGISTERED_ENVS[task]


def _quiet_import_robosuite():
    """Import robosuite without its start-up warnings (private macro file, optional robot models)."""
    logging.disable(logging.WARNING)
    try:
        import robosuite  # noqa: F401
    finally:
        logging.disable(logging.NOTSET)
    logging.getLogger("robosuite_logs").setLevel(logging.ERROR)


@functools.cache
def _warn_slow_step() -> None:
    """Said once a process: the lean step is off where its products would not round as robosuite's."""
    logging.getLogger("drltg").warning(
        "robosuite tasks step through robosuite's own env.step here (several times slower than drltg's lean step): "
        "on this CPU NumPy's and numba's BLAS round matrix-vector products differently, so the lean step would not "
        "be robosuite's step bit for bit; OPENBLAS_CORETYPE=Haswell, set before Python starts, makes them agree.")


def osc_pose_config(robot: str = "Panda") -> dict:
    """robosuite 1.5's default composite controller (OSC_POSE arm + gripper), reduced to one arm."""
    from robosuite.controllers import load_composite_controller_config

    config = load_composite_controller_config(controller="BASIC", robot=robot)
    config["body_parts"] = {"right": config["body_parts"]["right"]}
    return config


class RobosuiteEnv(EnvBase):
    """One robosuite environment (Panda, OSC_POSE, object observations, no cameras) as an ``EnvBase``.

    Keys: ``observation`` (float32, the listed ``observables`` concatenated, each once), ``action``
    (the controller's box, ``[-1, 1]^7``: OSC position/rotation deltas and the gripper), ``reward``,
    ``success`` (the task's own success check after the step), ``lifted`` (the cube has been lifted in
    this episode; drltg's tasks only: the first stage of every task, so an evaluation can tell a policy
    that lifts but never places from one that does nothing), ``pushed`` (the place tasks: the cube touches
    the target without having been lifted in this episode), ``step_count``, ``done`` /
    ``terminated`` / ``truncated``. One env steps one simulation; use ``ParallelEnv`` for several.

    Args:
        task: ``"lift"``, ``"lift-place"``, ``"lift-place-barrier"``, another robosuite environment
            name (e.g. ``"Stack"``, with ``observables`` it provides), or a robosuite environment class.
        observables: robosuite observable names, in observation order (default: ``layout.OBSERVABLES``).
        horizon: steps until ``truncated``.
        control_freq: policy steps per simulated second.
        terminate_on_success: end the episode (``terminated``) when the task succeeds.
        render_camera: the robosuite camera :meth:`render` uses by default (``frontview``,
            ``sideview``, ``agentview``, ``birdview``, ...).
        render_size: ``(height, width)`` of rendered frames.
        seed: seeds the episodes (cube placement and yaw, joint noise); ``None`` draws fresh entropy.
            The scene itself is always built with seed 0, so the cube's size (robosuite samples it
            once per model, 0.020-0.022 m) is the same in every env and worker.
        fast: step with :class:`~drltg.envs.robosuite.fast_osc.LeanStep` (the same trajectories as
            robosuite's ``env.step``, several times faster) where its BLAS rounds as NumPy's
            (:func:`~drltg.envs.robosuite.fast_osc.blas_agrees`; else robosuite's, with one warning);
            ``False`` calls robosuite's ``env.step``.
        reward_shaping: robosuite's dense staged reward instead of the task's sparse one (``lift-dense``).
        reward_scale: robosuite's scale of the reward (``None``: unscaled).
        **task_kwargs: passed to the robosuite environment as they are (from code only: a config's ``env``
            keys are the keywords above, :meth:`drltg.envs.TaskSpec.keywords`).
    """

    def __init__(
        self,
        task="lift",
        *,
        observables: Sequence[str] = tuple(OBSERVABLES),
        horizon: int = 500,
        control_freq: int = 20,
        robot: str = "Panda",
        terminate_on_success: bool = False,
        render_camera: str = "frontview",
        render_size: tuple[int, int] = (256, 256),
        seed: int | None = None,
        fast: bool = True,
        reward_shaping: bool = False,
        reward_scale: float | None = 1.0,
        device=None,
        **task_kwargs,
    ):
        super().__init__(device=device, batch_size=torch.Size([]))
        if not 1 <= horizon <= MAX_HORIZON:
            raise UsageError(f"horizon {horizon} must be between 1 and {MAX_HORIZON:,}, the steps an evaluation runs "
                             "an episode.")
        _quiet_import_robosuite()
        self.task = task
        self.horizon = int(horizon)
        self.terminate_on_success = bool(terminate_on_success)
        self.render_camera = render_camera
        self.render_size = tuple(render_size)
        self._env = _task_class(task)(
            robots=robot,
            controller_configs=osc_pose_config(robot),
            use_camera_obs=False,
            use_object_obs=True,
            has_renderer=False,
            has_offscreen_renderer=False,
            control_freq=control_freq,
            horizon=self.horizon,
            ignore_done=True,
            hard_reset=False,
            seed=0,
            reward_shaping=reward_shaping,
            reward_scale=reward_scale,
            **task_kwargs,
        )
        self.observables = tuple(observables)
        raw = self._env.reset()
        missing = [name for name in self.observables if name not in raw]
        if missing:
            raise UsageError(f"task {task!r} has no observables {missing}; it has {', '.join(sorted(raw))}.")
        self.layout = layout_of({name: np.size(raw[name]) for name in self.observables})
        self._lean = None
        if fast:
            from drltg.envs.robosuite.fast_osc import LeanStep, blas_agrees

            if blas_agrees():
                self._lean = LeanStep(self._env, self.observables)
            else:
                _warn_slow_step()
        self._step_count = 0
        self._has_lifted = hasattr(self._env, "cube_lifted")
        self._has_pushed = hasattr(self._env, "cube_pushed")
        self._make_specs(sum(s.stop - s.start for s in self.layout.values()))
        self._set_seed(seed)

    @property
    def robosuite_env(self):
        """The wrapped robosuite environment (for its sim, success check, rendering)."""
        return self._env

    def _make_specs(self, obs_size: int) -> None:
        low, high = self._env.action_spec
        self.observation_spec = Composite(
            observation=Unbounded((obs_size,), dtype=torch.float32, device=self.device),
            success=Categorical(2, (1,), dtype=torch.bool, device=self.device),
            **({"lifted": Categorical(2, (1,), dtype=torch.bool, device=self.device)} if self._has_lifted else {}),
            **({"pushed": Categorical(2, (1,), dtype=torch.bool, device=self.device)} if self._has_pushed else {}),
            step_count=Unbounded((1,), dtype=torch.int64, device=self.device),
        )
        self.action_spec = Bounded(
            low=torch.as_tensor(low, dtype=torch.float32),
            high=torch.as_tensor(high, dtype=torch.float32),
            shape=(len(low),),
            dtype=torch.float32,
            device=self.device,
        )
        self.reward_spec = Unbounded((1,), dtype=torch.float32, device=self.device)
        flag = Categorical(2, (1,), dtype=torch.bool, device=self.device)
        self.done_spec = Composite(done=flag.clone(), terminated=flag.clone(), truncated=flag.clone())

    def _observation(self, raw: dict) -> torch.Tensor:
        flat = np.concatenate([np.asarray(raw[name], dtype=np.float32).ravel() for name in self.observables])
        return torch.from_numpy(flat).to(self.device)

    def _flag(self, value: bool) -> torch.Tensor:
        return torch.tensor([bool(value)], device=self.device)

    def _stage_flags(self) -> dict:
        flags = {"lifted": self._flag(self._env.cube_lifted())} if self._has_lifted else {}
        if self._has_pushed:
            flags["pushed"] = self._flag(self._env.cube_pushed())
        return flags

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs) -> TensorDictBase:
        raw = self._env.reset()
        self._step_count = 0
        return TensorDict(
            {
                "observation": self._observation(raw),
                "success": self._flag(self._env._check_success()),
                **self._stage_flags(),
                "step_count": torch.zeros(1, dtype=torch.int64, device=self.device),
                "done": self._flag(False),
                "terminated": self._flag(False),
                "truncated": self._flag(False),
            },
            batch_size=(),
            device=self.device,
        )

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        action = tensordict.get("action").detach().cpu().numpy().astype(np.float64)
        if self._lean is not None:
            reward, raw = self._lean.step(action), self._lean.values
        else:
            raw, reward, _, _ = self._env.step(action)
        self._step_count += 1
        success = bool(self._env._check_success())
        terminated = self.terminate_on_success and success
        truncated = self._step_count >= self.horizon
        return TensorDict(
            {
                "observation": self._observation(raw),
                "reward": torch.tensor([reward], dtype=torch.float32, device=self.device),
                "success": self._flag(success),
                **self._stage_flags(),
                "step_count": torch.tensor([self._step_count], dtype=torch.int64, device=self.device),
                "done": self._flag(terminated or truncated),
                "terminated": self._flag(terminated),
                "truncated": self._flag(truncated),
            },
            batch_size=(),
            device=self.device,
        )

    def _set_seed(self, seed: int | None) -> None:
        # robosuite's placement sampler and robot noise share the env's Generator object: reseed it in place.
        self._env.rng.bit_generator.state = np.random.default_rng(seed).bit_generator.state

    def render(
        self,
        tensordict: TensorDictBase | None = None,
        *,
        camera: str | None = None,
        size: tuple[int, int] | None = None,
    ) -> np.ndarray:
        """The current scene as an ``(height, width, 3)`` uint8 image. The simulation holds the state,
        so ``tensordict`` is not needed (it is accepted so every drltg env renders as ``env.render(td)``).
        The offscreen context is created on first use (``MUJOCO_GL=egl`` or ``osmesa`` on a headless host)."""
        sim = self._env.sim
        if sim._render_context_offscreen is None:
            from robosuite.utils.binding_utils import MjRenderContextOffscreen

            context = MjRenderContextOffscreen(sim, device_id=-1)
            context.vopt.geomgroup[0] = 0  # collision geoms hidden, visual geoms shown (robosuite's default)
            context.vopt.geomgroup[1] = 1
        height, width = size or self.render_size
        image = sim.render(camera_name=camera or self.render_camera, height=height, width=width)
        return np.ascontiguousarray(image[::-1])

    def close(self, *, raise_if_closed: bool = True):
        env = getattr(self, "_env", None)
        if env is not None:
            env.close()
            self._env = None
        super().close(raise_if_closed=raise_if_closed)


def make_robosuite_env(
    task: str = "lift",
    *,
    batch_size: Sequence[int] | torch.Size = (),
    device=None,
    parallel: bool | None = None,
    mp_start_method: str | None = None,
    **options,
) -> EnvBase:
    """One :class:`RobosuiteEnv` for ``batch_size=()``; for ``(n,)``, ``n`` of them stepped together,
    each in its own worker process (``ParallelEnv``, started by ``mp_start_method``, TorchRL's default
    ``spawn`` if ``None``) or, with ``parallel=False``, in this one (``SerialEnv``). ``parallel=None``
    starts processes only when this process may use a CPU core for each env (its affinity: a run pinned to
    one core with ``taskset`` steps its envs here): a worker holds its own simulation and interpreter (about
    1 GB), so on 2 cores the 10 envs of an evaluation step in this process instead.
    Both step the same simulations from the same seeds: ``set_seed(s)`` on the batch seeds its members
    with distinct seeds derived from ``s``, in order, either way."""
    from torchrl.envs import ParallelEnv, SerialEnv

    batch_size = torch.Size(batch_size)
    if len(batch_size) == 0:
        return RobosuiteEnv(task, device=device, **options)
    if len(batch_size) != 1:
        raise ValueError(f"robosuite tasks batch along one dimension, got batch_size={tuple(batch_size)}.")
    n = batch_size[0]
    if parallel is None:
        parallel = n <= usable_cpus()
    make = functools.partial(RobosuiteEnv, task, device=device, **options)
    if parallel and n > 1:
        return ParallelEnv(n, make, mp_start_method=mp_start_method)
    return SerialEnv(n, make)


def robosuite_task(**options) -> EnvBase:
    """The task registry's factory of the manipulation tasks: :func:`make_robosuite_env`, with a signature
    that also lists :class:`RobosuiteEnv`'s keywords."""
    return make_robosuite_env(**options)


def _robosuite_signature() -> inspect.Signature:
    """``make_robosuite_env``'s keywords and ``RobosuiteEnv``'s, so configs can check their types."""
    outer = [p for p in inspect.signature(make_robosuite_env).parameters.values() if p.kind is not p.VAR_KEYWORD]
    names = {p.name for p in outer}
    inner = [
        p if p.kind is p.VAR_KEYWORD else p.replace(kind=p.KEYWORD_ONLY)
        for p in inspect.signature(RobosuiteEnv.__init__).parameters.values()
        if p.name not in names | {"self"}
    ]
    return inspect.Signature(outer + sorted(inner, key=lambda p: p.kind))


robosuite_task.__signature__ = _robosuite_signature()
