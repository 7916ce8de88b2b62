"""Named transfer methods: what each one needs, which config keys it reads, and what it adds to a run.

A transfer method's ``build`` gets the run's config, learner and a probe env, may set the learner's
weights itself (model reuse, on a new run), and returns a :class:`Transfer` naming the places of the
pipeline it changes::

    env -> [train_transforms] -> Collector([policy], on_frames) -> buffer -> [batches] -> loss [+ loss_terms]
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

from dataclasses import dataclass, field, replace
from typing import Any, Callable, Iterable

from drltg import config
from drltg.config import METHODS, RunConfig, Section, get_method
from drltg.errors import UsageError

__all__ = ["Transfer", "TransferMethod", "METHODS", "register_method", "get_method", "combine"]


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
        on_frames: told the frames collected so far after every batch (schedules over training).
        batches: ``batches(buffer, n)`` gives the ``n`` minibatches of one round of updates instead of
            ``n`` samples of the replay buffer.
        loss_terms: ``loss_terms(batch) -> {"loss_<name>": scalar}``, added to the learner's losses at
            every gradient step (a term named ``loss_actor_*`` is skipped with the actor's, under TD3's
            policy delay); a grouped method's is a :class:`~drltg.losses.terms.LossTerm`, which a seed
            group evaluates inside its vmapped loss with each seed's parameters.
        files: written into the run directory when the run starts (``name -> text``).
        summary: entries added to the run's ``summary.json``.
    """

    train_transforms: list = field(default_factory=list)
    policy: Any = None
    mixer: Any = None
    on_frames: Callable[[int], None] | None = None
    batches: Callable[[Any, int], Iterable] | None = None
    loss_terms: Callable[[Any], dict] | None = None
    files: dict[str, str] = field(default_factory=dict)
    summary: dict[str, Any] = field(default_factory=dict)


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
    model: type[Section] | None = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        object.__setattr__(self, "model", config.options_model(self.name, self.options) if self.options else None)

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
    owners = {key: m.name for m in METHODS.values() if m.name != method.name for key in m.options}
    for key in method.options:
        if key in owners or key in config.TRANSFER_KEYS:
            raise UsageError(
                f"transfer method {method.name!r}: config key 'transfer.{key}' already belongs to "
                f"{owners.get(key, 'every method')}; choose another name."
            )
    METHODS[method.name] = method
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
                          grouped=all(m.grouped for m in methods))


_PLACES = {"policy": "collector's policy", "batches": "minibatches", "weights": "learner's initial weights"}


def _join(parts: list[Transfer]) -> Transfer:
    policies = [t.policy for t in parts if t.policy is not None]
    mixers = [t.mixer for t in parts if t.mixer is not None]
    batches = [t.batches for t in parts if t.batches is not None]
    on_frames = [t.on_frames for t in parts if t.on_frames is not None]
    terms = [t.loss_terms for t in parts if t.loss_terms is not None]
    assert len(policies) + len(mixers) <= 1 and len(batches) <= 1, "combine() admits one owner per place"

    def tell(frames: int) -> None:
        for f in on_frames:
            f(frames)

    def loss_terms(batch) -> dict:
        return {k: v for f in terms for k, v in f(batch).items()}

    from drltg.losses.terms import LossTerm, LossTerms

    if terms and all(isinstance(f, LossTerm) for f in terms):
        loss_terms = LossTerms(terms)  # which a seed group can evaluate inside its vmapped loss

    return Transfer(
        train_transforms=[x for t in parts for x in t.train_transforms],
        policy=policies[0] if policies else None,
        mixer=mixers[0] if mixers else None,
        on_frames=tell if on_frames else None,
        batches=batches[0] if batches else None,
        loss_terms=loss_terms if terms else None,
        files={k: v for t in parts for k, v in t.files.items()},
        summary={k: v for t in parts for k, v in t.summary.items()},
    )
