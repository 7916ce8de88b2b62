"""Named transfer methods: what each one needs, which config keys it reads, and what it adds to a run.

A transfer method's ``build`` gets the run's config, learner and a probe env, may set the learner's
weights itself (model reuse, on a new run), and returns a :class:`Transfer` naming the places of the
pipeline it changes::

    env -> [train_transforms] -> Collector([policy], on_frames) -> buffer -> [batches] -> loss [+ loss_terms]
    every evaluation: the collector's policy evaluated too -> [on_eval];  checkpoints: [state]
    run directory: [files], summary.json: [summary]

``drltg train``, ``experiment`` and ``sweep`` read everything else from the :class:`TransferMethod`:
whether it trains source runs first, its ``transfer.*`` config keys and their ranges, and the rules
its config must follow. A new method is one module and one :func:`register_method` call::

    from pydantic import Field

    from drltg.transfer import Transfer, TransferMethod, register_method

    def build(cfg, agent, env, *, resuming):
        return Transfer(train_transforms=[MyTransform(scale=cfg.transfer.my_scale)])

    register_method(TransferMethod(
        "my-method", "what it transfers, in one line", build,
        options={"my_scale": (float, Field(1.0, ge=0.0, description="how strongly"))},
    ))

The methods live in the registry the config reads (:data:`drltg.config.METHODS`); the built-in ones are
its entry points (``pyproject.toml``), so importing their modules registers nothing.
"""
from __future__ import annotations

import itertools
import re
import types
from dataclasses import dataclass, field, replace
from typing import Annotated, Any, Callable, Iterable, Union, get_args, get_origin

from pydantic import BeforeValidator, Strict, ValidationError, create_model

from drltg import config
from drltg.config import METHODS, Bool, Float, Int, RunConfig, Section, Str, get_method
from drltg.errors import UsageError

__all__ = ["Transfer", "Pretraining", "TransferMethod", "METHODS", "register_method", "get_method", "combine",
           "TUNING_BUDGET"]


@dataclass
class Transfer:
    """What a transfer method adds to one run; every field is optional.

    Attributes:
        train_transforms: appended to the training env after the episode-return tracking, so the
            logged ``train/episode_return`` and every evaluation stay on the task's own reward.
        policy: the collector's policy instead of the learner's exploration policy.
        mixer: a module applied after the learner's exploration policy in the collector (policy reuse's
            :class:`~drltg.collectors.PolicyReuse`): the collector's policy is
            ``TensorDictSequential(learner's policy, mixer)``; in a seed group, seed k's mixer acts on
            seed k's envs.
        mixer_reads_learner: the mixer reads the learner's parameters (SF-GPI values actions with the learner's
            live critics): in a seed group, seed k's mixer runs with seed k's current parameters in its modules.
        on_frames: told the frames collected so far after every batch (schedules over training).
        on_eval: told, after every evaluation of the learner, the mean return of the collector's own policy
            evaluated as well, deterministically, on an evaluation env of its own (with the transfer's primers):
            the learner's actor followed by the ``mixer``, which for jumpstart is JSRL's combined policy
            (schedules that advance on evaluated returns); returns the scalars to log at that frame. In a seed
            group, seed k's is told seed k's return.
        state: a module whose ``state_dict`` every checkpoint keeps and a resumed run loads back (what a
            transfer learns as it trains that the frames alone cannot give back: a curriculum's stage).
        batches: ``batches(buffer, n)`` gives the ``n`` minibatches of one round of updates instead of
            ``n`` samples of the replay buffer.
        loss_terms: ``loss_terms(batch) -> {"loss_<name>": scalar}``, added to the learner's losses at
            every gradient step (a term named ``loss_actor_*`` is skipped with the actor's, under TD3's
            policy delay); a grouped method's is a :class:`~drltg.losses.terms.LossTerm`, which a seed
            group evaluates inside its vmapped loss with each seed's parameters.
        files: written into the run directory when the run starts (``name -> text``).
        summary: entries added to the run's ``summary.json``.
        pretraining: what the transfer learns before the run trains (:class:`Pretraining`, SF-GPI's psi).
    """

    train_transforms: list = field(default_factory=list)
    policy: Any = None
    mixer: Any = None
    mixer_reads_learner: bool = False
    on_frames: Callable[[int], None] | None = None
    on_eval: Callable[[float], dict] | None = None
    state: Any = None
    batches: Callable[[Any, int], Iterable] | None = None
    loss_terms: Callable[[Any], dict] | None = None
    files: dict[str, str] = field(default_factory=dict)
    summary: dict[str, Any] = field(default_factory=dict)
    pretraining: Pretraining | None = None


@dataclass
class Pretraining:
    """A learning problem a transfer solves before its run trains (SF-GPI's psi by TD): ``agent``'s loss
    (a :class:`drltg.learners.Agent`: loss, optimizer, target updater) stepped ``steps`` times on batches of
    ``buffer``, drawn from the random state ``rng``; ``stop(losses)`` is told each step's losses and, where
    ``can_stop``, may end it early; then ``finish(steps_taken, stopped)`` returns the entries it adds to the run's
    summary. A run alone solves it at once
    (:func:`drltg.training.pretraining.pretrain`); a seed group solves its members' as one vmapped update
    where none can stop early (:func:`drltg.training.seeds.pretrain_together`), and members of one ``key``
    (all the learning reads is the same) once."""

    agent: Any
    buffer: Any
    steps: int
    rng: Any
    finish: Callable[[int, bool], dict] | None
    stop: Callable[[Any], bool] | None = None
    can_stop: bool = False
    key: str | None = None


@dataclass(frozen=True)
class TransferMethod:
    """A named transfer method.

    Attributes:
        name: the value of ``transfer.method``.
        help: one line, shown by ``drltg tasks`` and in the docs.
        build: ``build(cfg, agent, env, *, resuming) -> Transfer``, called once a run's learner
            (:class:`drltg.learners.Agent`) and a probe env of its task exist; ``resuming`` is true when
            the run continues from a checkpoint (weights loaded now would be overwritten).
        source: ``None`` (no source), ``"run"`` (a source run's weights) or ``"policy"`` (a source run's
            actor, or ``demonstrator:TASK`` on the manipulation tasks). ``drltg experiment`` trains
            source runs on the pair's source task for methods that have one.
        options: the method's ``transfer.<key>`` config keys as ``key -> (type, default or Field(default, ...))``,
            the fields of its pydantic model (:func:`pydantic.create_model`), ``model``, built with the method.
        check: ``check(cfg)`` raises one :class:`UsageError` sentence on a config the method cannot
            run (rules that tie keys together); called by ``drltg.config.validate``.
        check_env: ``check_env(cfg, env)`` raises one :class:`UsageError` sentence on a task the method cannot
            run on, from a probe env of it (e.g. its action space); called before any run of a plan starts
            (:func:`drltg.training.loop.check_config`).
        algos: the learners it works with (``None``: every learner).
        takes: the places of the pipeline it owns alone (``"policy"``: the collector's policy,
            ``"batches"``: the minibatches, ``"weights"``: the learner's initial weights); two methods
            that take one place cannot be combined.
        grouped: whether its seeds can train as one seed group (:mod:`drltg.training.seeds`). The group
            calls ``build`` once per seed, on that seed's learner before the seeds' parameters are
            stacked, and shapes seed k's block of its batched env with seed k's ``train_transforms``
            joined (:func:`drltg.training.seeds.seed_block_transforms`), seed k's ``mixer`` on seed k's
            envs, seed k's ``batches`` of seed k's buffer, seed k's ``loss_terms`` (a
            :class:`~drltg.losses.terms.LossTerm`) with seed k's parameters, and every seed's
            ``on_frames``; a method whose ``Transfer`` sets the policy has no grouped form.
        alone: where it has none, why, in one clause: a dry run's plan and the run's log say it beside the
            runs that train one at a time.
        member_options: the options seed k's own parts read alone (built from seed k's config), so runs that
            differ in them still train as one seed group: a tuning grid's settings with their seeds.
        search: the method's tuning space, ``option -> values`` over its own options, each list starting
            at the option's default; its grid holds at most :data:`TUNING_BUDGET` settings, the budget
            every row of the leaderboard gets (:mod:`drltg.bench.tune`).
    """

    name: str
    help: str
    build: Callable[..., Transfer]
    source: str | None = None
    options: dict[str, tuple[Any, Any]] = field(default_factory=dict)
    check: Callable[[RunConfig], None] | None = None
    check_env: Callable[[RunConfig, Any], None] | None = None
    algos: tuple[str, ...] | None = None
    takes: tuple[str, ...] = ()
    grouped: bool = False
    alone: str = ""
    search: dict[str, tuple] = field(default_factory=dict)
    member_options: tuple[str, ...] = ()
    model: type[Section] | None = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        object.__setattr__(self, "model", options_model(self.name, self.options) if self.options else None)
        check_search(self)
        strays = [k for k in self.member_options if self.model is None or k not in self.model.model_fields]
        if strays:
            raise UsageError(f"transfer method {self.name!r}: member_options names {strays[0]!r}, which is not one of "
                             "its options.")

    @property
    def settings(self) -> list[dict[str, Any]]:
        """The settings ``drltg bench tune`` tries: every point of :attr:`search` (``transfer.<key>`` -> value),
        the defaults first; ``[{}]`` for a method without a search."""
        keys = list(self.search)
        return [{f"transfer.{k}": v for k, v in zip(keys, point)}
                for point in itertools.product(*(self.search[k] for k in keys))]

    def combine(self, *others: TransferMethod) -> TransferMethod:
        """This method followed by ``others`` (:func:`combine`)."""
        return combine(self, *others)

    def validate(self, cfg: RunConfig) -> None:
        if self.algos is not None and cfg.algo not in self.algos:
            raise UsageError(
                f"config key 'transfer.method' is {self.name}, which works with algo {' or '.join(self.algos)}, "
                f"not '{cfg.algo}'."
            )
        if self.check is not None:
            self.check(cfg)


TUNING_BUDGET = 4
"""The most settings a method's search space holds: every leaderboard row is tuned on the same budget."""


def check_search(method: TransferMethod) -> None:
    """A search space is a grid of the method's own options, each axis a list of distinct values its option
    accepts that starts at the option's default, with at most :data:`TUNING_BUDGET` points."""
    where = f"transfer method {method.name!r}: its search"
    size = 1
    for key, values in method.search.items():
        if method.model is None or key not in method.model.model_fields:
            raise UsageError(f"{where} names {key!r}, which is not one of its options.")
        if not isinstance(values, (list, tuple)) or not values:
            raise UsageError(f"{where} over {key!r} must be a non-empty list of values.")
        default = method.model.model_fields[key].get_default(call_default_factory=True)
        if values[0] != default or len({repr(v) for v in values}) < len(values):
            raise UsageError(f"{where} over {key!r} must list distinct values, the default {default!r} first.")
        for value in values:
            try:
                method.model.model_validate({key: value})
            except ValidationError as err:
                raise UsageError(f"{where}: " + config.sentence(err, {key: value}, method.model, "transfer.")) from None
        size *= len(values)
    if size > TUNING_BUDGET:
        raise UsageError(f"{where} holds {size} settings; the budget every row gets is {TUNING_BUDGET}.")


NONE = TransferMethod("none", "plain learning on the task: the baseline", lambda *a, **k: Transfer(), grouped=True)

_SOURCES = (None, "run", "policy")


def register_method(method: TransferMethod, *, replace: bool = False) -> TransferMethod:
    """Make ``method`` a value of ``transfer.method`` and add its options to the config's ``transfer``
    section. ``replace=True`` redefines a method of the same name (e.g. a notebook cell run twice)."""
    if method.name in METHODS and not replace:
        raise UsageError(f"transfer method {method.name!r} is already registered; pass replace=True to redefine it.")
    if method.source not in _SOURCES:
        raise UsageError(
            f"transfer method {method.name!r}: source must be None, 'run' or 'policy', got {method.source!r}."
        )
    if "+" in method.name:
        raise UsageError(f"transfer method {method.name!r}: '+' joins the methods of a combination; choose another "
                         "name.")
    previous = METHODS.get(method.name)
    METHODS[method.name] = method
    try:
        config.option_owners()  # its keys are its own
    except UsageError:
        if previous is None:
            del METHODS[method.name]
        else:
            METHODS[method.name] = previous
        raise
    return method


def combine(*methods: TransferMethod) -> TransferMethod:
    """One method that applies several, in order (``transfer.method=model-reuse+demonstrations``).

    The parts' ``Transfer`` fields are joined: transforms and loss terms add up, schedules are all told
    the frames, files and summaries are merged; a part that brings its own batches (demonstrations)
    collects them through the others' training transforms (``reward-shaping+demonstrations`` shapes the
    demonstrated rewards as it shapes the learner's). A place only one method may own (``takes``) refuses a
    second owner, and so do sources of different kinds: with one ``transfer.source``, a method that
    reuses a run's weights and one that asks for a demonstrator cannot share it. The combination trains
    as a seed group only if every part does.
    """
    names = [m.name for m in methods]
    name = "+".join(names)
    if len(methods) < 2 or "none" in names or len(set(names)) < len(names):
        raise UsageError(f"transfer.method '{name}': a combination joins two or more different methods, none of "
                         "them 'none'.")
    owners: dict[str, str] = {}
    for m in methods:
        for place in m.takes:
            if place in owners:
                raise UsageError(f"transfer.method '{name}': {owners[place]} and {m.name} both set the "
                                 f"{_PLACES[place]}; combine at most one of them.")
            owners[place] = m.name
    algos = None
    for m in methods:
        if m.algos is not None:
            algos = tuple(a for a in (algos or m.algos) if a in m.algos)
    if algos == ():
        each = "; ".join(f"{m.name}: {', '.join(m.algos)}" for m in methods if m.algos)
        raise UsageError(f"transfer.method '{name}': its parts share no learner ({each}).")
    sources = {m.source for m in methods} - {None}
    source = "run" if "run" in sources else next(iter(sources), None)

    def check(cfg: RunConfig) -> None:
        for m in methods:
            m.validate(cfg)

    def check_env(cfg: RunConfig, env) -> None:
        for m in methods:
            if m.check_env is not None:
                m.check_env(cfg, env)

    def build(cfg: RunConfig, agent, env, *, resuming: bool) -> Transfer:
        # a part that brings batches of its own (demonstrations) is built last, and collects its data
        # through the other parts' training transforms: its rewards are shaped as the learner's own are
        built: dict[int, Transfer] = {}
        for i in sorted(range(len(methods)), key=lambda i: "batches" in methods[i].takes):
            if "batches" in methods[i].takes:  # one owner at most, the last built
                others = [x for part in built.values() for x in part.train_transforms]
                agent = replace(agent, env_transforms=[*agent.env_transforms, *others])
            built[i] = methods[i].build(cfg, agent, env, resuming=resuming)
        return _join([built[i] for i in range(len(methods))])

    options = {k: v for m in methods for k, v in m.options.items()}
    return TransferMethod(name, " + ".join(m.help for m in methods), build, source=source, options=options,
                          check=check, check_env=check_env, algos=algos, takes=tuple(owners),
                          grouped=all(m.grouped for m in methods),
                          alone="; ".join(f"{m.name}: {m.alone}" for m in methods if not m.grouped and m.alone),
                          member_options=tuple(k for m in methods for k in m.member_options))


_STRICT = {int: Int, float: Float, bool: Bool, str: Str}


def _strict(annotation: Any) -> Any:
    """``annotation`` with plain ``int``, ``float``, ``bool`` and ``str`` (also inside ``Optional``, ``list``,
    ``Annotated``) read as the built-in keys read them: :data:`~drltg.config.Int`, ``Float``, ``Bool``, ``Str``."""
    if isinstance(annotation, type) and annotation in _STRICT:
        return _STRICT[annotation]
    origin, args = get_origin(annotation), get_args(annotation)
    if origin is Annotated:  # one of the types above, or a plain type with constraints
        if any(isinstance(m, (BeforeValidator, Strict)) for m in args[1:]):
            return annotation
        return Annotated[(_strict(args[0]), *args[1:])]
    if origin in (Union, types.UnionType):
        return Union[tuple(_strict(a) for a in args)]
    if origin is list and len(args) == 1:
        return list[_strict(args[0])]
    return annotation


def options_model(method: str, options: dict[str, Any]) -> type[Section]:
    """The model of a method's ``transfer.*`` options, from ``key -> (type, default or Field(...))`` (the
    form of :func:`pydantic.create_model`; plain ``int``, ``float``, ``bool`` and ``str`` are read as the
    built-in keys are), built once when the method is declared; its defaults must pass its own checks."""
    name = "".join(part.capitalize() for part in re.split(r"[^0-9A-Za-z]+", method) if part) + "Options"
    fields = {k: (_strict(v[0]), v[1]) if isinstance(v, tuple) and len(v) == 2 else v for k, v in options.items()}
    try:
        model = create_model(name, __base__=Section, **fields)
    except (TypeError, ValueError) as err:  # pydantic's schema errors are TypeErrors, its usage errors too
        raise UsageError(f"transfer method {method!r}: its options cannot be declared ({err}).") from None
    defaults = {k: f.get_default(call_default_factory=True) for k, f in model.model_fields.items()}
    try:
        model.model_validate(defaults)
    except ValidationError as err:
        raise UsageError(f"transfer method {method!r} declares a default its option refuses: "
                         + config.sentence(err, defaults, model, "transfer.")) from None
    return model


_PLACES = {"policy": "collector's policy", "batches": "minibatches", "weights": "learner's initial weights"}


def _join(parts: list[Transfer]) -> Transfer:
    policies = [t.policy for t in parts if t.policy is not None]
    mixers = [t.mixer for t in parts if t.mixer is not None]
    batches = [t.batches for t in parts if t.batches is not None]
    on_frames = [t.on_frames for t in parts if t.on_frames is not None]
    on_eval = [t.on_eval for t in parts if t.on_eval is not None]
    states = [t.state for t in parts if t.state is not None]
    terms = [t.loss_terms for t in parts if t.loss_terms is not None]
    pretraining = [t.pretraining for t in parts if t.pretraining is not None]
    assert len(policies) + len(mixers) <= 1 and len(batches) <= 1 and len(pretraining) <= 1, \
        "combine() admits one owner per place"

    def tell(frames: int) -> None:
        for f in on_frames:
            f(frames)

    def evaluated(value: float) -> dict:
        return {k: v for f in on_eval for k, v in f(value).items()}

    def loss_terms(batch) -> dict:
        return {k: v for f in terms for k, v in f(batch).items()}

    import torch

    from drltg.losses.terms import LossTerm, LossTerms

    if terms and all(isinstance(f, LossTerm) for f in terms):
        loss_terms = LossTerms(terms)  # which a seed group can evaluate inside its vmapped loss

    return Transfer(
        train_transforms=[x for t in parts for x in t.train_transforms],
        policy=policies[0] if policies else None,
        mixer=mixers[0] if mixers else None,
        mixer_reads_learner=any(t.mixer_reads_learner for t in parts),
        on_frames=tell if on_frames else None,
        on_eval=evaluated if on_eval else None,
        state=states[0] if len(states) == 1 else (torch.nn.ModuleList(states) if states else None),
        batches=batches[0] if batches else None,
        loss_terms=loss_terms if terms else None,
        files={k: v for t in parts for k, v in t.files.items()},
        summary={k: v for t in parts for k, v in t.summary.items()},
        pretraining=pretraining[0] if pretraining else None,
    )
