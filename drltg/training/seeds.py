"""Seed groups: N seeds of one config trained in one process, ``drltg train TASK --seeds N --seed S --run-dir DIR``.

Seeds S, S+100, … (:func:`drltg.config.run_seeds`) are written to ``DIR/seed-<s>/``, each an ordinary run
directory (``report`` reads it alone, ``--resume`` continues it, alone or with its group). Where the learner
supports it (:func:`~drltg.training.grouping.group_support`) the seeds train as one :class:`SeedGroup`:

* the seeds' learners are stacked into one :class:`~drltg.training.seed_group.SeedGroup`, whose update is the
  loss vmapped over seeds, each seed's own Adam and target update on the stacked tensors;
* the policy acts on one env of N × ``collector.num_envs`` envs, block k (envs ``k*E … k*E+E−1``) with seed
  k's parameters (:class:`GroupPolicy`, one vmapped call; :class:`SeedLoopPolicy`, one call per seed, for
  soft option-critic, whose option choice branches on the data). FourRooms and GridRooms step the whole
  batch in process; any other task steps one env per seed, each built and seeded as its run alone builds
  it, in worker processes (:func:`_worker_env`);
* a replay buffer per seed, and a transfer per seed composed onto its block: each seed's shaping potential
  on its own envs (:func:`seed_block_transforms`), each seed's policy-reuse mixer over its own source
  (:class:`SeedBlocks`; SF-GPI's with its own seed's live critics swapped in), model reuse loading each seed's
  own source before the seeds are stacked, and each seed's ``on_eval`` (jumpstart's curriculum) told its own
  seed's evaluated return of the group's policy, its ``state`` kept in its own checkpoint.

* a transfer's loss terms (behaviour cloning, distillation) inside the vmapped loss, each seed's with its own
  parameters, state and weight (:class:`~drltg.training.seed_group.StackedLoss`); a transfer's minibatches
  (demonstrations) from seed k's buffer; a transfer's pretraining (SF-GPI's psi) as one vmapped update too
  (:func:`~drltg.training.pretraining.pretrain_together`).

A transfer method groups if it declares a grouped form (``TransferMethod.grouped``; ``a+b`` if every part
does): it may set anything but a whole collector policy, and its loss terms must be ``LossTerm`` s. The
configs of a group may differ in ``transfer.source`` (an experiment's transfer run of seed s reads its own
seed's source run). Otherwise the seeds train one after another with
:func:`~drltg.training.loop.train`.

What a seed in a group shares with its run alone: its initial networks (built under
``torch.manual_seed(seed)``), its transfer, its replay buffer and, given the same parameters, batch and
random draws, its update (to float rounding: ``tests/test_seed_groups.py``). Its random draws are not its
run alone's: the in-process env is one env seeded with the group's first seed, and the exploration noise,
warm-up actions, minibatch indices and the losses' draws come from the process's one generator, seeded
with the group's first seed (``torch.vmap(randomness="different")`` gives each seed its own draws). So a
seed's curve in a group is not its curve alone, bit for bit; it is a draw from the same distribution
(``tests/test_seed_groups.py`` tests this over 20 seeds), and a group is reproduced exactly by the same
group (same ``--seeds`` and ``--seed``). Each seed's summary.json records its group (``seed_group.seeds``).
"""
from __future__ import annotations

import contextlib
import copy
import functools
import sys
from pathlib import Path
from typing import Callable, Sequence

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModuleBase, TensorDictSequential
from torchrl.data import LazyTensorStorage, ReplayBuffer
from torchrl.envs import (
    BatchSizeTransform,
    EnvBase,
    ParallelEnv,
    RewardSum,
    SerialEnv,
    TensorDictPrimer,
    TransformedEnv,
)

from drltg import config
from drltg.config import RunConfig
from drltg.errors import UsageError
from drltg.learners import sample_batches
from drltg.losses import SoftOptionCriticLoss
from drltg.losses.terms import LossTerm
from drltg.modules import make_option_policy
from drltg.store import rundir
from drltg.training import best, console, health, preflight
from drltg.training.grouping import batched, group_support, in_process
from drltg.training.loop import (
    EVAL_SEED_OFFSET,
    GUIDED_EVAL_SEED_OFFSET,
    build_env,
    check_config,
    deferred_signals,
    evaluate_seeds,
    make_collector,
    primers,
    run_loop,
    train,
    transfer_state,
)
from drltg.training.pretraining import pretrain_together
from drltg.training.replay import buffer_state
from drltg.training.seed_group import SeedGroup, StackedLoss, stacked_soft_update
from drltg.training.session import RunSession
from drltg.transfer import Transfer, get_method
from drltg.transfer.source import check as check_source
from drltg.transfer.source import start_record
from drltg.transforms import PotentialShaping

__all__ = ["train_seeds", "train_group", "group_train_env", "seed_dirs",
           "SeedGroup", "StackedLoss", "stacked_soft_update", "GroupPolicy", "SeedLoopPolicy", "SeedBlocks"]

"""Learners whose seeds train as one group (SAC covers discrete SAC on discrete tasks)."""


# ----------------------------------------------------------------------------- the group's policy
class GroupPolicy(TensorDictModuleBase):
    """A seed group's policy on its batched env: the flat batch of ``seeds * E`` envs is split into
    ``seeds`` blocks and ``module`` acts on block k with seed k's parameters (one vmapped call, each
    seed drawing its own exploration noise).

    Args:
        module: one seed's actor (its own parameters are not used).
        params: the stacked parameters of ``module``, with a leading seed dimension.
        then: a module applied to the whole batch afterwards (TD3's exploration noise).
    """

    def __init__(self, module: TensorDictModuleBase, params: TensorDictBase, then: TensorDictModuleBase | None = None):
        super().__init__()
        self.module, self.then = copy.deepcopy(module), then
        self.params = params
        self.in_keys = list(module.in_keys)
        self.out_keys = list(module.out_keys)
        self._act = torch.vmap(self._seed_act, (0, 0), randomness="different")

    def _seed_act(self, params: TensorDictBase, td: TensorDictBase) -> TensorDictBase:
        with params.copy().unlock_().to_module(self.module):
            return self.module(td)

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        seeds = self.params.batch_size[0]
        td = tensordict.select(*self.in_keys, strict=False).reshape(seeds, -1)
        out = self._act(self.params, td)
        tensordict.update(out.reshape(tensordict.batch_size).select(*self.out_keys, strict=False))
        return tensordict if self.then is None else self.then(tensordict)


class SeedLoopPolicy(TensorDictModuleBase):
    """A seed group's policy called once per seed block, for a policy ``torch.vmap`` cannot batch
    (soft option-critic's option choice branches on the data): ``make_policy(loss)`` is built on the
    group's loss, and block k runs with seed k's parameters swapped into it."""

    def __init__(self, group: SeedGroup, make_policy):
        super().__init__()
        self.__dict__["group"] = group  # not a submodule: the group owns the parameters
        self.policy = make_policy(group.loss)
        self.in_keys, self.out_keys = list(self.policy.in_keys), list(self.policy.out_keys)

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        group, loss = self.group, self.group.loss
        blocks = tensordict.reshape(group.seeds, -1)
        outs = []
        for k in range(group.seeds):
            params = group.params[k].copy().unlock_()
            with params.to_module(loss), params["actor_network_params"].to_module(loss.actor_network):
                outs.append(self.policy(blocks[k].copy()))
        out = torch.stack(outs).reshape(tensordict.batch_size)
        tensordict.update(out.select(*self.out_keys, strict=False))
        return tensordict


class SeedBlocks(TensorDictModuleBase):
    """Per-seed modules on a seed group's batched env: block k of the flat batch (seed k's envs) goes
    through ``modules[k]`` (e.g. seed k's policy-reuse mixer over its own source policy), inside
    ``context(k)`` where given (:meth:`SeedGroup.seed_params`, for a module that reads seed k's learner)."""

    def __init__(self, modules: Sequence[TensorDictModuleBase],
                 context: Callable[[int], contextlib.AbstractContextManager] | None = None):
        super().__init__()
        self.blocks = torch.nn.ModuleList(modules)
        self.context = context or (lambda k: contextlib.nullcontext())
        self.in_keys = list(dict.fromkeys(k for m in modules for k in m.in_keys))
        self.out_keys = list(dict.fromkeys(k for m in modules for k in m.out_keys))

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        blocks = tensordict.reshape(len(self.blocks), -1)
        outs = []
        for k, (module, block) in enumerate(zip(self.blocks, blocks)):
            with self.context(k):
                outs.append(module(block.copy()))
        out = torch.stack(outs)
        return tensordict.update(out.reshape(tensordict.batch_size).select(*self.out_keys, strict=False))


class SeedBlockPotential(torch.nn.Module):
    """``Phi`` of a seed group's batched env: the batch split into ``len(shapings)`` equal blocks,
    block k's potential is ``shapings[k]``'s (each evaluated on its own block, as on its env alone)."""

    def __init__(self, shapings: Sequence[PotentialShaping]):
        super().__init__()
        self.shapings = torch.nn.ModuleList(shapings)

    def forward(self, tensordict: TensorDictBase) -> torch.Tensor:
        blocks = tensordict.reshape(len(self.shapings), -1)
        return torch.cat([s.potential_of(block) for s, block in zip(self.shapings, blocks.unbind(0))])


# ----------------------------------------------------------------------------- which seeds group
def seed_dirs(run_dir: Path, first: int, count: int) -> list[Path]:
    return [Path(run_dir) / f"seed-{s}" for s in config.run_seeds(first, count)]


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


# ----------------------------------------------------------------------------- the group's learner and envs
class GroupLearner:
    """A :class:`SeedGroup` as the training loop's learner (see :class:`~drltg.training.loop.AgentLearner`):
    a replay buffer per seed, stacked batches, per-seed evaluation on a blocked env (the collector's policy too,
    on ``guided_env``, where the seeds' transfers ask for it: each seed's ``on_eval`` told its own seed's)."""

    def __init__(self, group: SeedGroup, buffers: list[ReplayBuffer], eval_env, transfers: list[Transfer],
                 guided_env=None):
        self.group, self.buffers, self.eval_env = group, buffers, eval_env
        self.transfers, self.guided_env = transfers, guided_env
        self.seeds, self.actor_delay = group.seeds, group.actor_delay
        first = group.agents[0]
        if isinstance(first.loss, SoftOptionCriticLoss):  # the option choice branches on the data: no vmap
            self.policy = self.actor = SeedLoopPolicy(group, make_option_policy)
        else:
            actor_params = group.params["actor_network_params"]
            noise = None if first.policy is first.actor else first.policy[-1]
            self.policy = GroupPolicy(first.actor, actor_params, then=noise)
            self.actor = GroupPolicy(first.actor, actor_params)
        if transfers[0].mixer is not None:  # seed k's mixer (policy reuse over its own source) on its envs
            live = group.seed_params if transfers[0].mixer_reads_learner else None
            self.policy = TensorDictSequential(self.policy, SeedBlocks([t.mixer for t in transfers], live))
        self.on_frames = [t.on_frames for t in transfers if t.on_frames is not None]
        self.make_batches = None if transfers[0].batches is None else [t.batches for t in transfers]
        self.in_keys = list(group.loss.in_keys)

    def split(self, data: TensorDictBase) -> list[TensorDictBase]:
        return list(data.reshape(self.seeds, -1).unbind(0))

    def store(self, data: list[TensorDictBase], frames: int) -> None:
        for tell in self.on_frames:
            tell(frames)
        for buffer, piece in zip(self.buffers, data):
            buffer.extend(piece.select(*self.in_keys))

    def batches(self, count: int):
        if self.make_batches is None:
            per_seed = [sample_batches(buffer, count) for buffer in self.buffers]
            return (torch.stack(batch) for batch in zip(*per_seed))
        return self._transfer_batches(count)

    def _transfer_batches(self, count: int):
        """Seed k's minibatches from its transfer's ``batches`` (demonstrations mixed into its own samples),
        one batch at a time. For the soft option-critic, whose demonstrations' option labels are drawn with
        the networks just before their update, seed k's batch is drawn with seed k's current parameters in its
        own modules; the other learners' batches read no parameter and skip that swap (about 1.6 ms a seed on
        FourRooms' networks)."""
        iterators = [iter(make(buffer, count)) for make, buffer in zip(self.make_batches, self.buffers)]
        reads_params = isinstance(self.group.loss, SoftOptionCriticLoss)
        for _ in range(count):
            batch = []
            for k, iterator in enumerate(iterators):
                with self.group.seed_params(k) if reads_params else contextlib.nullcontext():
                    batch.append(next(iterator))
            yield torch.stack(batch)

    def update(self, batch: TensorDictBase, update_actor: bool) -> TensorDictBase:
        return self.group.update(batch, update_actor)

    def evaluate(self, check: Callable[[], None] = lambda: None) -> list[dict]:
        return evaluate_seeds(self.eval_env, self.actor, self.seeds, check=check)

    def evaluate_guided(self, check: Callable[[], None] = lambda: None) -> list[dict]:
        if self.transfers[0].on_eval is None:
            return []
        rows = evaluate_seeds(self.guided_env, self.policy, self.seeds, check=check)
        return [{"eval/guided_return_mean": row["return_mean"], **transfer.on_eval(row["return_mean"])}
                for row, transfer in zip(rows, self.transfers)]

    def state(self) -> list[dict]:
        self.group.sync()
        rng = torch.get_rng_state()  # the group's one generator: every seed's checkpoint holds it
        return [
            {"loss": agent.loss.state_dict(), "optimizer": self.group.optimizer_state(k),
             "buffer": buffer_state(buffer), "rng": rng.clone(), **transfer_state(transfer)}
            for k, (agent, buffer, transfer) in enumerate(zip(self.group.agents, self.buffers, self.transfers))
        ]


class SeedMajor(BatchSizeTransform):
    """A ``ParallelEnv`` of per-seed envs (batch ``[seeds, E]``) seen as one flat batch ``[seeds * E]``,
    seed k's envs at ``k*E … k*E+E−1``: the layout of an in-process group env. A partial
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
    """One env per seed, each the env its run alone builds (same factory, settings and seed), flattened
    seed-major: side by side in this process for a task whose envs step here (:func:`in_process`), else one
    worker process each, started as ``env.mp_start_method`` says (TorchRL's default if unset). Transforms go
    on an env around this one: the flattening must come first on both ways.

    A seed's worker steps its ``per_seed`` envs itself (``parallel=False``, for a task that takes it) unless
    ``env.parallel`` says otherwise or there are cores for every env of the group: processes of its own
    would only add a gigabyte each (an interpreter and a simulation) and a pipe round trip a step, with the
    seeds' workers already running side by side. The simulations and their seeds are the same either way."""
    from drltg.envs import get_task
    from drltg.envs.limits import usable_cpus

    serial = ("parallel" in get_task(cfg.task).keywords() and cfg.env.get("parallel") is None
              and len(seeds) * per_seed > usable_cpus())
    build = functools.partial(build_env, cfg, batch_size=(per_seed,), **({"parallel": False} if serial else {}))
    each = [{"seed": s + seed_offset} for s in seeds]
    if in_process(cfg):
        return TransformedEnv(SerialEnv(len(seeds), build, create_env_kwargs=each), SeedMajor())
    workers = ParallelEnv(len(seeds), build, create_env_kwargs=each, mp_start_method=cfg.env.get("mp_start_method"))
    return TransformedEnv(workers, SeedMajor())


def _group_env(cfg: RunConfig, seeds: list[int], per_seed: int, seed_offset: int, transforms=()) -> TransformedEnv:
    """``per_seed`` envs per seed, seed-major: one batched env seeded with the group's first seed where the
    task steps its batch as one (:func:`batched`), else one env per seed, seeded as its run alone
    (:func:`_worker_env`)."""
    if batched(cfg):
        base = build_env(cfg, batch_size=(len(seeds) * per_seed,), seed=seeds[0] + seed_offset)
    else:
        base = _worker_env(cfg, seeds, per_seed, seed_offset)
    env = TransformedEnv(base, auto_unwrap=False)
    for t in transforms:
        env.append_transform(t.clone())
    return env


def seed_block_transforms(name: str, transfers: list[Transfer]) -> list:
    """The group's training-env transforms: position by position, the seeds' own transforms joined into
    one: their shapings into one :class:`~drltg.transforms.PotentialShaping` whose potential on block k is
    seed k's (:class:`SeedBlockPotential`), a primer (policy reuse's episode choice) once for every block.
    A grouped method sets nothing a group cannot give each seed: a whole collector policy, or loss terms
    that are not :class:`~drltg.losses.terms.LossTerm` modules (a plain function of the batch reads one
    seed's parameters, not the group's)."""
    if transfers[0].policy is not None:
        raise UsageError(f"transfer method {name} is registered with grouped=True but sets the Transfer's policy, "
                         "which a seed group cannot give each seed; register it without grouped.")
    if transfers[0].loss_terms is not None and not isinstance(transfers[0].loss_terms, LossTerm):
        raise UsageError(f"transfer method {name} is registered with grouped=True but its loss_terms is not a "
                         "drltg.losses.terms.LossTerm, which a seed group evaluates with each seed's parameters; "
                         "make it one or register the method without grouped.")
    joined = []
    for parts in zip(*(t.train_transforms for t in transfers), strict=True):
        first = parts[0]
        if isinstance(first, PotentialShaping):
            if len({(p.gamma, p.reward_key, p.task_reward_key, p.potential_key) for p in parts}) > 1:
                raise UsageError(f"transfer method {name}: the seeds' shapings differ in gamma or keys.")
            joined.append(PotentialShaping(SeedBlockPotential(parts), gamma=first.gamma, reward_key=first.reward_key,
                                           task_reward_key=first.task_reward_key, potential_key=first.potential_key))
        elif isinstance(first, TensorDictPrimer):  # a primer declares per-env state: one serves every block
            joined.append(first)
        else:
            raise UsageError(f"transfer method {name} is registered with grouped=True but its transform "
                             f"{type(first).__name__} cannot be given to each seed's envs apart.")
    return joined


def group_train_env(cfgs: list[RunConfig], transforms, transfers: list[Transfer]) -> EnvBase:
    """A group's training env: ``collector.num_envs`` envs per seed, the learner's ``transforms``, the
    episode-return tracking, then each seed's transfer transforms on its own block (after ``RewardSum``,
    as in a run alone: ``train/episode_return`` stays the task's return)."""
    cfg = cfgs[0]
    env = _group_env(cfg, [c.seed for c in cfgs], cfg.collector.num_envs, 0, transforms)
    env.append_transform(RewardSum())
    for transform in seed_block_transforms(get_method(cfg.transfer.method).name, transfers):
        env.append_transform(transform)
    return env


def train_group(cfgs: list[RunConfig], dirs: list[Path], *, resume: bool = False, progress: bool = True,
                on_frames: Callable[[int], None] | None = None) -> list[Path]:
    """Train ``cfgs`` (configs equal but for their seeds and sources, :func:`~drltg.training.grouping.same_but_seed`;
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

        console.plain_unless_terminal()  # TorchRL's colour codes reach a terminal, never a log file
        torch.set_num_threads(cfg.threads)
        method = get_method(cfg.transfer.method)
        agents, transfers, sources = [], [], []
        for c, ckpt, d in zip(cfgs, session.checkpoints, dirs):
            # each seed's networks and transfer as its run alone builds them (model reuse loads the seed's
            # own source into them, before they are stacked)
            torch.manual_seed(c.seed)
            check_source(c)
            probe, agent = check_config(c)
            transfers.append(method.build(c, agent, probe, resuming=ckpt is not None))
            sources.append(start_record(c, d, ckpt is not None, transfers[-1].files))  # the seed's source, as loaded
            agents.append(agent)
        if transfers[0].pretraining is not None:
            for transfer, entries in zip(transfers, pretrain_together([t.pretraining for t in transfers])):
                transfer.summary.update(entries)
        torch.manual_seed(cfg.seed)
        buffers = [ReplayBuffer(storage=LazyTensorStorage(cfg.buffer.size, device=cfg.device),
                                batch_size=cfg.buffer.batch_size) for _ in cfgs]
        session.restore(agents, buffers, transfers)
        seeds = [c.seed for c in cfgs]
        transforms = agents[0].env_transforms  # what the policy needs the env to carry (SOC's option)
        train_env = group_train_env(cfgs, transforms, transfers)  # which refuses a transfer a group cannot give
        session.callback(train_env.close, raise_if_closed=False)  # worker processes, where the task has them
        group = SeedGroup(agents, terms=[t.loss_terms for t in transfers if t.loss_terms is not None])
        eval_env = _group_env(cfg, seeds, cfg.eval.episodes, EVAL_SEED_OFFSET, transforms)
        best.check_metric(cfg, eval_env)
        session.callback(eval_env.close, raise_if_closed=False)
        guided_env = None
        if transfers[0].on_eval is not None:  # each seed's combined policy, on envs apart from its evaluation's
            guided_env = _group_env(cfg, seeds, cfg.eval.episodes, GUIDED_EVAL_SEED_OFFSET,
                                    [*transforms, *primers(transfers[0])])
            session.callback(guided_env.close, raise_if_closed=False)
        learner = GroupLearner(group, buffers, eval_env, transfers, guided_env)

        session.claim()
        preflight.warn_budget(cfg)  # every check passed and the directories are ours: training starts now
        writers = session.writers(transfers)
        frames, updates = session.position()
        collector = make_collector(cfg, train_env, learner.policy, frames, seeds=count)
        summaries = [{**transfer.summary, **source, "seed_group": {"seeds": seeds}}
                     for transfer, source in zip(transfers, sources)]
        with deferred_signals() as stop_if_signalled:
            try:
                run_loop(cfg, collector, learner, writers, frames=frames, updates=updates, progress=progress,
                         stop_if_signalled=stop_if_signalled, extra_summary=summaries, on_frames=on_frames)
            except health.Diverged as err:  # a diverged seed is finished; the others resume from their checkpoints
                for k in range(count) if err.seeds is None else err.seeds:
                    health.write_diverged(dirs[k], cfgs[k], err)
                raise
    return dirs
