"""Training N seeds of one config in one process: ``drltg train TASK --seeds N --seed S --run-dir DIR``.

Seeds S … S+N−1 are written to ``DIR/seed-<S+k>/``, each an ordinary run directory (``report`` reads it
alone, ``--resume`` continues it, alone or with its group). Where the learner supports it
(:func:`group_support`) the seeds train as one :class:`~drltg.seed_group.SeedGroup`: one batched env of
N × ``collector.num_envs`` envs (for a task without per-seed streams, robosuite's, a ``ParallelEnv`` of
each seed's own env, :func:`_worker_env`), one vmapped policy call (one call per seed for soft option-critic,
whose option choice branches on the data) and one vmapped update per step, a replay buffer per seed.
Otherwise they train one after another with :func:`~drltg.training.loop.train`.

A transfer method groups if it declares a grouped form (``TransferMethod.grouped``; ``a+b`` if every
part does): ``none``, ``model-reuse`` (each seed's networks load its own ``transfer.source`` before the
seeds are stacked; frozen parameters stay frozen in the stack), ``reward-shaping`` and
``value-shaping`` (seed k's env block shaped with seed k's own potential,
:meth:`~drltg.transforms.PotentialShaping.seed_blocks`), ``policy-reuse`` and ``jumpstart`` (seed k's
mixer over its own source policy on seed k's envs, :class:`~drltg.seed_group.SeedBlocks`, drawing from
seed k's stream). Each seed's transfer is built as its run alone builds it, at the same point of its
random stream. ``demonstrations`` (a demonstration buffer mixed into every minibatch) has none. The
configs of a group may differ in ``transfer.source`` (an experiment's transfer run of seed s reads its
own seed's source run).

What a seed shares with its run alone: its initial networks (built under ``torch.manual_seed(seed)`` as
a run alone builds them), its env's starts and noise, training and evaluation (a random stream per seed,
:mod:`drltg.envs.seeding`), its replay buffer, and its updates given a batch and random draws
(``tests/test_seed_groups.py``). For SAC on continuous actions on the CPU (:func:`streams_supported`)
the rest is the seed's too: each seed draws from its own :class:`~drltg.seed_group.SeedStreams` stream,
the state torch's global generator holds in its run alone once that run has built its networks and envs
(building robosuite's envs draws nothing from it: ``tests/test_robosuite_groups.py``),
in the same order and shapes (the warm-up's random actions, the policy's exploration draws, the replay
buffer's sampling, the losses' draws), so a seed in a group draws exactly the random numbers of its run
alone and its checkpoint holds its own stream; its parameters match its run alone to float rounding
(``tests/test_seed_groups.py``), which training amplifies over thousands of updates (batched products
round differently from single ones). For TD3, discrete SAC and soft option-critic (draws other than
``Normal.rsample``'s: TD3's loss draws its smoothing noise with ``randn_like``, discrete SAC samples
categorically, the option policy draws Bernoulli terminations and categorical options) those draws come
from the process's one generator, seeded with the group's first seed, so past frame 0 a seed's curve in
a group is not its curve alone. A group is reproduced exactly by the same group (same ``--seeds`` and
``--seed``); each seed's summary.json records its group (``seed_group.seeds``, the group's seeds in
order).
"""
from __future__ import annotations

import contextlib
import functools
import sys
from pathlib import Path
from typing import Callable

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictSequential
from torchrl.data import LazyTensorStorage, ReplayBuffer
from torchrl.envs import BatchSizeTransform, EnvBase, ParallelEnv, RewardSum, TransformedEnv
from torchrl.objectives import SACLoss

from drltg import config
from drltg.config import RunConfig
from drltg.envs.seeding import set_block_seeds
from drltg.errors import UsageError
from drltg.learners import sample_batches
from drltg.losses import SoftOptionCriticLoss
from drltg.modules import make_option_policy
from drltg.seed_group import GroupPolicy, SeedBlocks, SeedGroup, SeedLoopPolicy, SeedStreams
from drltg.store import rundir
from drltg.training import best, health, preflight
from drltg.training.loop import (
    build_env,
    check_config,
    deferred_signals,
    evaluate_seeds,
    make_collector,
    make_envs,
    run_loop,
    train,
)
from drltg.training.replay import buffer_state
from drltg.training.session import RunSession
from drltg.transfer import Transfer, get_method
from drltg.transfer.source import check as check_source

__all__ = ["train_seeds", "train_group", "group_train_env", "group_support", "seed_dirs", "same_but_seed"]

GROUPED_ALGOS = ("sac", "td3", "soc")
"""Learners whose seeds train as one group (SAC covers discrete SAC on discrete tasks)."""


def seed_dirs(run_dir: Path, first: int, count: int) -> list[Path]:
    return [Path(run_dir) / f"seed-{s}" for s in config.run_seeds(first, count)]


def same_but_seed(a: RunConfig, b: RunConfig) -> bool:
    """Whether two configs differ at most in their seed and their ``transfer.source`` (an experiment's
    transfer run of seed s reads the source run of its own seed): their runs can share a seed group,
    each seed transferring from its own source."""
    def key(cfg: RunConfig) -> dict:
        dump = cfg.model_dump()
        return {**dump, "seed": 0, "transfer": {**dump["transfer"], "source": None}}

    return key(a) == key(b)


def group_support(cfg: RunConfig) -> str | None:
    """``None`` if the seeds of ``cfg`` can train as one group, else why not (one clause)."""
    if cfg.algo not in GROUPED_ALGOS:
        return f"--algo {cfg.algo} has no grouped update"
    if not get_method(cfg.transfer.method).grouped:
        return f"transfer method {cfg.transfer.method} has no grouped form"
    if cfg.optim.cudagraphs:
        return "a group's vmapped update is not captured as a CUDA graph (optim.cudagraphs)"
    from drltg.envs import get_task

    get_task(cfg.task)  # an unknown task is one UsageError sentence
    return None


def in_process(cfg: RunConfig) -> bool:
    """Whether the task's env gives each seed its own random stream in one batched env
    (:mod:`drltg.envs.seeding`); otherwise a group steps one env per seed in worker processes."""
    from drltg.envs import get_task

    return hasattr(get_task(cfg.task).factory, "set_block_seeds")


def train_seeds(cfg: RunConfig, run_dir: str | Path, seeds: int, *, resume: bool = False, progress: bool = True,
                group: bool = True) -> list[Path]:
    """Train seeds ``cfg.seed``, ``cfg.seed + 100``, … (:func:`drltg.config.run_seeds`, the seeds an experiment's
    runs use) of ``cfg`` into ``run_dir/seed-<s>/``;
    as one group where :func:`group_support` allows and ``group`` is true, else one after another (with
    a note on stderr saying why). Returns the run directories."""
    if not 1 <= seeds <= config.MAX_SEEDS:
        raise UsageError(f"--seeds must be between 1 and {config.MAX_SEEDS}, got {seeds}.")
    cfg, run_dir = config.as_config(cfg), rundir.check_directory(run_dir, "--run-dir")
    cfgs = [config.updated(cfg, {"seed": s}) for s in config.run_seeds(cfg.seed, seeds)]
    dirs = seed_dirs(run_dir, cfg.seed, seeds)
    reason = group_support(cfg) if group else "grouping is turned off"
    if reason is not None or seeds == 1:
        if reason is not None and seeds > 1:
            print(f"note: {reason}; training the {seeds} seeds one after another.", file=sys.stderr)
        return [train(c, d, resume=resume, progress=progress) for c, d in zip(cfgs, dirs)]
    return train_group(cfgs, dirs, resume=resume, progress=progress)


class GroupLearner:
    """A :class:`SeedGroup` as the training loop's learner (see :class:`~drltg.training.loop.AgentLearner`):
    a replay buffer per seed, stacked batches, per-seed evaluation on a blocked env."""

    def __init__(self, group: SeedGroup, buffers: list[ReplayBuffer], eval_env, transfers: list[Transfer]):
        self.group, self.buffers, self.eval_env = group, buffers, eval_env
        self.seeds, self.actor_delay = group.seeds, group.actor_delay
        first = group.agents[0]
        if isinstance(first.loss, SoftOptionCriticLoss):  # the option choice branches on the data: no vmap
            self.policy = self.actor = SeedLoopPolicy(group, make_option_policy)
        else:
            actor_params = group.params["actor_network_params"]
            noise = None if first.policy is first.actor else first.policy[-1]
            self.policy = GroupPolicy(first.actor, actor_params, then=noise, streams=group.streams)
            self.actor = GroupPolicy(first.actor, actor_params, streams=group.streams)
        if transfers[0].mixer is not None:  # seed k's mixer (policy reuse over its own source) on its envs
            self.policy = TensorDictSequential(self.policy, SeedBlocks([t.mixer for t in transfers], group.streams))
        self.on_frames = [t.on_frames for t in transfers if t.on_frames is not None]
        self.in_keys = list(group.loss.in_keys)

    def split(self, data: TensorDictBase) -> list[TensorDictBase]:
        return list(data.reshape(self.seeds, -1).unbind(0))

    def store(self, data: list[TensorDictBase], frames: int) -> None:
        for tell in self.on_frames:
            tell(frames)
        for buffer, piece in zip(self.buffers, data):
            buffer.extend(piece.select(*self.in_keys))

    def batches(self, count: int):
        streams = self.group.streams
        per_seed = []
        for k, buffer in enumerate(self.buffers):
            with contextlib.nullcontext() if streams is None else streams.use(k):
                per_seed.append(sample_batches(buffer, count))
        return (torch.stack(batch) for batch in zip(*per_seed))

    def update(self, batch: TensorDictBase, update_actor: bool) -> TensorDictBase:
        return self.group.update(batch, update_actor)

    def evaluate(self, check: Callable[[], None] = lambda: None) -> list[dict]:
        return evaluate_seeds(self.eval_env, self.actor, self.seeds, check=check)

    def state(self) -> list[dict]:
        self.group.sync()
        streams = self.group.streams
        rngs = [torch.get_rng_state()] * self.seeds if streams is None else [s.clone() for s in streams.states]
        return [
            {"loss": agent.loss.state_dict(), "optimizer": self.group.optimizer_state(k),
             "buffer": buffer_state(buffer), "rng": rngs[k]}
            for k, (agent, buffer) in enumerate(zip(self.group.agents, self.buffers))
        ]


class StreamedRandomActions(TransformedEnv):
    """A group's training env whose random actions (the collector's warm-up) are drawn block by block,
    block k from seed k's stream, as ``rand_action`` draws them on seed k's env alone."""

    def __init__(self, env, streams: SeedStreams):
        super().__init__(env, auto_unwrap=False)
        self.__dict__["_streams"] = streams
        self.__dict__["_one_seed_spec"] = None

    def rand_action(self, tensordict: TensorDictBase | None = None) -> TensorDictBase:
        seeds = len(self._streams.states)
        if self._one_seed_spec is None:  # the action spec of one seed's env alone
            self.__dict__["_one_seed_spec"] = self.full_action_spec[: self.batch_size[0] // seeds]
        parts = []
        for k in range(seeds):
            with self._streams.use(k):
                parts.append(self._one_seed_spec.rand())
        actions = torch.cat(parts)
        if tensordict is None:
            return actions
        return tensordict.update(actions)


def streams_supported(agent, cfg: RunConfig) -> bool:
    """Whether a group of this learner can give each seed its own random stream (its run alone): SAC on
    continuous actions on the CPU, whose only random draws are ``Normal.rsample``'s."""
    return type(agent.loss) is SACLoss and torch.device(cfg.device).type == "cpu"


class SeedMajor(BatchSizeTransform):
    """A ``ParallelEnv`` of per-seed envs (batch ``[seeds, E]``) seen as one flat batch ``[seeds * E]``,
    seed k's envs at ``k*E … k*E+E−1``: the layout of a blocked env (:mod:`drltg.envs.seeding`). A partial
    reset's ``_reset`` mask is unflattened for the workers too."""

    def __init__(self):
        super().__init__(reshape_fn=_flatten)

    def _reset_env_preprocess(self, tensordict: TensorDictBase | None) -> TensorDictBase | None:
        if tensordict is None:
            return None
        return tensordict.reshape(self.parent.batch_size)


def _flatten(data):
    return data.reshape(data.shape.numel())  # an explicit size: TorchRL's bounded specs refuse reshape(-1)


def _worker_env(cfg: RunConfig, seeds: list[int], per_seed: int, seed_offset: int) -> EnvBase:
    """One worker process per seed, each building the env its run alone builds (same factory, settings
    and seed), flattened seed-major; the workers start as ``env.mp_start_method`` says (TorchRL's default
    if unset). Transforms go on an env around this one: the flattening must come first on both ways.

    A seed's worker steps its ``per_seed`` envs itself (``parallel=False``, for a task that takes it) unless
    ``env.parallel`` says otherwise or there are cores for every env of the group: processes of its own
    would only add a gigabyte each (an interpreter and a simulation) and a pipe round trip a step, with the
    seeds' workers already running side by side. The simulations and their seeds are the same either way."""
    from drltg.envs import get_task
    from drltg.envs.limits import usable_cpus

    serial = ("parallel" in get_task(cfg.task).keywords() and cfg.env.get("parallel") is None
              and len(seeds) * per_seed > usable_cpus())
    build = functools.partial(build_env, cfg, batch_size=(per_seed,), **({"parallel": False} if serial else {}))
    workers = ParallelEnv(len(seeds), build,
                          create_env_kwargs=[{"seed": s + seed_offset} for s in seeds],
                          mp_start_method=cfg.env.get("mp_start_method"))
    return TransformedEnv(workers, SeedMajor())


def _group_env(cfg: RunConfig, seeds: list[int], per_seed: int, seed_offset: int, transforms=(), streams=None):
    blocked = in_process(cfg)
    if blocked:
        base = build_env(cfg, batch_size=(len(seeds) * per_seed,), seed=seeds[0] + seed_offset)
    else:
        base = _worker_env(cfg, seeds, per_seed, seed_offset)
    env = TransformedEnv(base, auto_unwrap=False) if streams is None else StreamedRandomActions(base, streams)
    if blocked:
        set_block_seeds(env, [s + seed_offset for s in seeds])
    for t in transforms:
        env.append_transform(t.clone())
    return env


def _seed_block_transforms(name: str, transfers: list[Transfer]) -> list:
    """The group's training-env transforms: position by position, the seeds' own transforms joined by
    their ``seed_blocks`` (seed k's shapes block k). A grouped method sets nothing a group cannot give
    each seed (a whole collector policy, minibatches, loss terms)."""
    for field in ("policy", "batches", "loss_terms"):
        if getattr(transfers[0], field) is not None:
            raise UsageError(f"transfer method {name} is registered with grouped=True but sets the Transfer's "
                             f"{field}, which a seed group cannot give each seed; register it without grouped.")
    joined = []
    for parts in zip(*(t.train_transforms for t in transfers), strict=True):
        seed_blocks = getattr(type(parts[0]), "seed_blocks", None)
        if seed_blocks is None:
            raise UsageError(f"transfer method {name} is registered with grouped=True but its transform "
                             f"{type(parts[0]).__name__} has no seed_blocks to shape each seed's envs apart.")
        joined.append(seed_blocks(parts))
    return joined


def group_train_env(cfgs: list[RunConfig], transforms, transfers: list[Transfer], streams=None) -> EnvBase:
    """A group's training env: ``collector.num_envs`` envs per seed, the learner's ``transforms``, the
    episode-return tracking, then each seed's transfer transforms on its own block (after ``RewardSum``,
    as in a run alone: ``train/episode_return`` stays the task's return)."""
    cfg = cfgs[0]
    env = _group_env(cfg, [c.seed for c in cfgs], cfg.collector.num_envs, 0, transforms, streams)
    env.append_transform(RewardSum())
    for shaping in _seed_block_transforms(get_method(cfg.transfer.method).name, transfers):
        env.append_transform(shaping)
    return env


def train_group(cfgs: list[RunConfig], dirs: list[Path], *, resume: bool = False, progress: bool = True,
                on_frames: Callable[[int], None] | None = None) -> list[Path]:
    """Train ``cfgs`` (configs equal but for their seeds and sources, :func:`same_but_seed`;
    :func:`group_support` true) as one seed group into ``dirs``, one run directory each; ``resume``
    continues them from their checkpoints."""
    cfg, count = cfgs[0], len(cfgs)
    with RunSession(cfgs, dirs, resume=resume) as session:
        if session.finished:
            return dirs
        if session.mixed:
            session.close()
            print("note: the group's seeds stopped at different points; resuming them one after another.",
                  file=sys.stderr)
            return [train(c, d, resume=True, progress=progress, on_frames=on_frames) for c, d in zip(cfgs, dirs)]

        torch.set_num_threads(cfg.threads)
        method = get_method(cfg.transfer.method)
        agents, transfers, rng_states = [], [], []
        for c, ckpt in zip(cfgs, session.checkpoints):
            # each seed's networks and transfer as its run alone builds them (model reuse loads the seed's
            # own source into them, before they are stacked), and its random stream from there on
            torch.manual_seed(c.seed)
            check_source(c)
            probe, agent = check_config(c)
            if streams_supported(agent, c) and in_process(c):
                make_envs(c, agent.env_transforms)  # the draws a run alone makes before its loop (env seeds)
            transfers.append(method.build(c, agent, probe, resuming=ckpt is not None))
            agents.append(agent)
            rng_states.append(torch.get_rng_state())
        torch.manual_seed(cfg.seed)
        buffers = [ReplayBuffer(storage=LazyTensorStorage(cfg.buffer.size, device=cfg.device),
                                batch_size=cfg.buffer.batch_size) for _ in cfgs]
        session.restore(agents, buffers)
        ckpts = session.checkpoints
        streams = None
        if streams_supported(agents[0], cfg):
            streams = SeedStreams(rng_states if ckpts[0] is None else [ckpt["rng"] for ckpt in ckpts])
        group = SeedGroup(agents, streams=streams)
        seeds = [c.seed for c in cfgs]
        transforms = agents[0].env_transforms  # what the policy needs the env to carry (SOC's option)
        train_env = group_train_env(cfgs, transforms, transfers, streams)
        session.callback(train_env.close, raise_if_closed=False)  # worker processes, where the task has them
        eval_env = _group_env(cfg, seeds, cfg.eval.episodes, 10_000, transforms)
        best.check_metric(cfg, eval_env)
        session.callback(eval_env.close, raise_if_closed=False)
        learner = GroupLearner(group, buffers, eval_env, transfers)

        session.claim()
        preflight.warn_budget(cfg)  # every check passed and the directories are ours: training starts now
        writers = session.writers(transfers)
        frames, updates = session.position()
        collector = make_collector(cfg, train_env, learner.policy, frames, seeds=count)
        summaries = [{**transfer.summary, "seed_group": {"seeds": seeds}} for transfer in transfers]
        with deferred_signals() as stop_if_signalled:
            try:
                run_loop(cfg, collector, learner, writers, frames=frames, updates=updates, progress=progress,
                         stop_if_signalled=stop_if_signalled, extra_summary=summaries, on_frames=on_frames)
            except health.Diverged as err:  # a diverged seed is finished; the others resume from their checkpoints
                for k in range(count) if err.seeds is None else err.seeds:
                    health.write_diverged(dirs[k], cfgs[k], err)
                raise
    return dirs
