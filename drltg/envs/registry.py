"""Named tasks and task pairs (source -> target).

A task is a factory of :class:`~torchrl.envs.EnvBase` plus default keyword arguments; a pair names
a source task and a target task. Factories are called as
``factory(batch_size=..., device=..., **defaults, **overrides)``. A factory may be given as a string
``"module:attr"``, imported when the task is first built; its options (the keywords a config may set)
are then declared with it (``register_task(..., options=...)``, as Gymnasium's ``EnvSpec`` holds its
kwargs), so listing tasks and checking a config import neither torch nor the task's simulator. The
built-in tasks and pairs are registered by :mod:`drltg.envs.tasks`.

Examples:
    >>> from drltg.envs import make_env, register_task, register_pair, FourRoomsEnv
    >>> register_task("fourrooms/center-west", FourRoomsEnv, "goal near the west doorway", goal=(2.0, 4.0))
    >>> register_pair("my-pair", "fourrooms/northeast", "fourrooms/center-west", "goal to the west door")
    >>> env = make_env("fourrooms/center-west", batch_size=(8,), seed=0)
"""
from __future__ import annotations

import importlib
import inspect
import math
import numbers
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable, Sequence

from drltg.errors import UsageError, closest, short

if TYPE_CHECKING:
    import torch
    from torchrl.envs import EnvBase


@dataclass(frozen=True)
class TaskSpec:
    """A named task: ``factory(**defaults)`` builds it; ``train`` overrides the training config."""

    name: str
    entry: Callable[..., EnvBase] | str
    """The factory, or ``"module:attr"`` naming it (imported on first use of :attr:`factory`)."""
    description: str
    defaults: dict[str, Any] = field(default_factory=dict)
    train: dict[str, Any] = field(default_factory=dict)
    potential: Callable[[dict[str, Any]], Callable] | None = None
    """``potential(env_options)`` builds the task's shaping potential (``drltg.transforms.PotentialShaping``)."""
    returns: Callable[[dict[str, Any]], tuple[float, float]] | None = None
    """``returns(options)``: the range every episode's return lies in, from the factory's keywords (a report
    bounds its intervals by it: ``drltg.analysis.stats.betting_interval``)."""
    fixed: dict[str, Any] = field(default_factory=dict)
    """Registration fields (a Gymnasium id, the info keys read as flags): passed to the factory on every
    build and never options, so a config (a run directory's ``config.yaml``) cannot change what the task
    is made of, nor make :func:`gymnasium.make` import a module it names."""
    options: dict[str, Any] | None = None
    """The factory's keywords that a config may set, each with the default the factory gives it
    (``inspect.Parameter.empty``: none), as declared at :func:`register_task`; ``None``: the factory's
    signature says them (:func:`inspect.signature`, which imports a factory named ``"module:attr"``)."""

    def return_range(self, env_options: dict[str, Any] | None = None) -> tuple[float, float] | None:
        """The range of an episode's return with these env options (the factory's and the task's defaults
        under them); ``None`` where the task does not declare one."""
        if self.returns is None:
            return None
        low, high = self.returns(_Options({**self.defaults, **(env_options or {})}, self))
        return float(low), float(high)

    @property
    def factory(self) -> Callable[..., EnvBase]:
        if not isinstance(self.entry, str):
            return self.entry
        module, _, attr = self.entry.partition(":")
        try:
            return getattr(importlib.import_module(module), attr)
        except (ImportError, AttributeError) as err:
            raise UsageError(f"task {self.name!r}: its factory {self.entry!r} cannot be imported ({err}).") from None

    def without_registration(self, given: dict[str, Any]) -> dict[str, Any]:
        """``given`` less the registration fields it states with the task's own value (configs saved before
        :attr:`fixed` existed hold them); one stated with any other value stays, for the check to refuse."""
        def plain(value):
            return [plain(v) for v in value] if isinstance(value, (list, tuple)) else value

        return {k: v for k, v in given.items() if not (k in self.fixed and plain(v) == plain(self.fixed[k]))}

    def keywords(self) -> dict[str, Any]:
        """The task's options: the keywords declared with it (:attr:`options`), else those its factory's
        signature declares (name -> default; ``inspect.Parameter.empty``: none), less ``make_env``'s own
        (:data:`BUILD_KEYWORDS`) and the registration fields (:attr:`fixed`), and its registered defaults.
        A factory that also takes ``**kwargs`` (Gymnasium's ``make`` keywords) takes no more options than
        these: every key a config sets is one the task declares. Nothing is imported where the options are
        declared, so checking a config imports neither the env nor torch."""
        declared = self.options if self.options is not None else _signature_keywords(self.factory)
        return {name: default for name, default in {**declared, **self.defaults}.items()
                if name not in self.fixed and name not in BUILD_KEYWORDS}

    def check(self, given: dict[str, Any], *, key: Callable[[str], str] = "keyword {!r}".format) -> dict[str, Any]:
        """``given`` read as the types of the task's declared defaults (:meth:`keywords`): the one check of
        env options, made by ``make_env`` and by a config (``key`` names an option in its sentences, e.g.
        ``config key 'env.horizon'``); torch-free where :meth:`keywords` is. A registration field stated
        with the task's own value is dropped (:meth:`without_registration`); an unknown key, a registration
        field, or a value of another type is one sentence naming the key. Ranges are the env's to check."""
        given = self.without_registration(given)
        declared = {k: v for k, v in self.keywords().items() if k not in BUILD_KEYWORDS}
        for name, value in given.items():
            if name in self.fixed:
                raise UsageError(f"{key(name)} cannot be set: it is part of the task {self.name!r} as registered "
                                 f"({name}={self.fixed[name]!r}), not an option, got {short(value)}.")
            if name not in declared:
                raise UsageError(f"{key(name)} is not an option of task {self.name!r}; its options are: "
                                 f"{', '.join(sorted(declared)) or 'none'}.")
        checked = {}
        for name, value in given.items():
            what, read = _kind(declared[name])
            try:
                checked[name] = read(value)
            except (TypeError, ValueError, OverflowError):
                raise UsageError(f"{key(name)} must be {what} (task {self.name!r} declares {name}="
                                 f"{declared[name]!r}), got {short(value)}.") from None
        return checked


BUILD_KEYWORDS = ("batch_size", "device", "seed")
"""``make_env``'s own keywords, which every factory takes: no option of a task."""


def _number(value: Any) -> float | int:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(value)
    if not (isinstance(value, numbers.Integral) or math.isfinite(value)):
        raise ValueError(value)
    return value


def _integer(value: Any) -> int:
    if not (isinstance(_number(value), numbers.Integral) or float(value).is_integer()):
        raise ValueError(value)
    return int(value)


def _exactly(kind: type) -> Callable[[Any], Any]:
    def read(value):
        if not isinstance(value, kind):
            raise TypeError(value)
        return value
    return read


def _list_of(read: Callable[[Any], Any], least: int) -> Callable[[Any], list]:
    def read_list(value):
        if not isinstance(value, (list, tuple)) or len(value) < least:
            raise TypeError(value)
        return [read(v) for v in value]
    return read_list


def _kind(default: Any) -> tuple[str, Callable[[Any], Any]]:
    """What an option whose declared default is ``default`` takes, in words, and its reader: a bool takes
    ``True``/``False`` only; an int an integral number (``1e3`` is 1000); a float a finite number (read as
    float); a str a string; a list of numbers (or strings) one of the like; any other default any value."""
    if isinstance(default, bool):
        return "true or false", _exactly(bool)
    if isinstance(default, int):
        return "an integer", _integer
    if isinstance(default, float):
        return "a number", lambda v: float(_number(v))
    if isinstance(default, str):
        return "a string", _exactly(str)
    if isinstance(default, (list, tuple)) and default:
        if all(isinstance(v, numbers.Real) and not isinstance(v, bool) for v in default):
            return "a list of numbers", _list_of(_number, 1)
        if all(isinstance(v, str) for v in default):
            return "a list of strings", _list_of(_exactly(str), 0)
    return "any value", lambda v: v


class _Options(dict):
    """Env options as a task's ``returns`` reads them: ``options[key]`` for a key they lack is the factory's
    declared default, looked up only then (``get`` and ``in`` see the options alone). A run's config holds every
    declared keyword, so a report of drltg runs imports no env for their range."""

    def __init__(self, given: dict[str, Any], spec: TaskSpec):
        super().__init__(given)
        self.spec = spec

    def __missing__(self, key: str) -> Any:
        default = self.spec.keywords().get(key, inspect.Parameter.empty)
        if default is inspect.Parameter.empty:
            raise KeyError(key)
        return default


def _signature_keywords(factory: Callable) -> dict[str, Any]:
    """The keywords a function or class ``factory`` takes by name, with their defaults, from its signature."""
    params = inspect.signature(factory.__init__ if inspect.isclass(factory) else factory).parameters
    return {name: p.default for name, p in params.items()
            if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY) and name not in ("self", "cls")}


@dataclass(frozen=True)
class PairSpec:
    """A transfer problem: learn ``source``, then transfer to ``target``."""

    name: str
    source: str
    target: str
    description: str


RESOLVERS: list[Callable[[str], bool]] = []
"""``resolve(name)`` registers the task ``name`` if it can make it on first use (``gym/<ID>``: drltg.envs.gym)."""
ON_REGISTER: list[Callable[[TaskSpec], None]] = []
"""Called with every task registered from then on (drltg.gymnasium_ids gives it a Gymnasium id)."""


class _TaskTable(dict):
    """Tasks by name; a name nobody registered may still be made on first use by a resolver
    (``gym/<ID>``, :func:`drltg.envs.gym.resolve`), so every lookup (``in``, ``[]``) sees it."""

    def _resolve(self, name) -> bool:
        return isinstance(name, str) and any(resolve(name) for resolve in RESOLVERS)

    def __contains__(self, name) -> bool:
        return dict.__contains__(self, name) or self._resolve(name)

    def __missing__(self, name):
        if self._resolve(name):
            return dict.__getitem__(self, name)
        raise KeyError(name)


TASKS: dict[str, TaskSpec] = _TaskTable()
PAIRS: dict[str, PairSpec] = {}


def _lookup(table: dict, name: str, kind: str):
    if name in table:
        return table[name]
    close = closest(name, table)
    hint = f"; did you mean {close!r}?" if close else f"; known {kind}s: {', '.join(sorted(table))}."
    raise UsageError(f"unknown {kind} {name!r}{hint} (`drltg tasks` lists them)")


def get_task(name: str) -> TaskSpec:
    """The registered task ``name``; a :class:`UsageError` suggesting a close name otherwise."""
    return _lookup(TASKS, name, "task")


def get_pair(name: str) -> PairSpec:
    """The registered pair ``name``; a :class:`UsageError` suggesting a close name otherwise."""
    return _lookup(PAIRS, name, "pair")


def register_task(
    name: str,
    factory: Callable[..., EnvBase] | str,
    description: str,
    *,
    train: dict[str, Any] | None = None,
    potential: Callable[[dict[str, Any]], Callable] | None = None,
    returns: Callable[[dict[str, Any]], tuple[float, float]] | None = None,
    fixed: dict[str, Any] | None = None,
    options: dict[str, Any] | None = None,
    replace: bool = False,
    **defaults,
) -> TaskSpec:
    """Registers a task; ``factory`` is a callable or ``"module:attr"`` (imported when the task is first
    built); ``defaults`` are keyword arguments of ``factory`` (the task's options, which a config may set),
    ``fixed`` keyword arguments that make the task what it is and that no config may set
    (:attr:`TaskSpec.fixed`), ``train`` config overrides, ``potential(env_options)`` builds its reward-shaping
    potential, ``returns(options)`` gives the range of an episode's return (:attr:`TaskSpec.returns`).
    ``options`` declares the factory's other keywords a config may set, each with the default the factory
    gives it (:attr:`TaskSpec.options`; without it they are read from the factory's signature, importing
    a factory named by a string when a config is checked). ``replace=True`` redefines a registered task
    (a notebook cell run twice)."""
    if dict.__contains__(TASKS, name) and not replace:
        raise UsageError(f"task {name!r} is already registered; pass replace=True to redefine it.")
    if isinstance(factory, str) and not all(factory.partition(":")[::2]):
        raise UsageError(f"task {name!r}: a factory named by a string is 'module:attr', got {factory!r}.")
    both = sorted(set(defaults) & set(fixed or {}))
    if both:
        raise UsageError(f"task {name!r}: {both[0]!r} is given both as an option and as a registration field.")
    both = sorted(set(options or {}) & (set(fixed or {}) | set(BUILD_KEYWORDS)))
    if both:
        raise UsageError(f"task {name!r}: {both[0]!r} is declared as an option, but it is "
                         + ("a registration field." if both[0] in (fixed or {}) else "make_env's own keyword."))
    spec = TaskSpec(name, factory, description, dict(defaults), dict(train or {}), potential, returns,
                    dict(fixed or {}), None if options is None else dict(options))
    TASKS[name] = spec
    for hook in ON_REGISTER:
        hook(spec)
    return spec


def register_pair(name: str, source: str, target: str, description: str, *, replace: bool = False) -> PairSpec:
    """Registers a task pair; both tasks must already be registered; ``replace=True`` redefines it."""
    if name in PAIRS and not replace:
        raise UsageError(f"pair {name!r} is already registered; pass replace=True to redefine it.")
    get_task(source), get_task(target)
    spec = PairSpec(name, source, target, description)
    PAIRS[name] = spec
    return spec


def make_env(
    name: str,
    *,
    batch_size: Sequence[int] | torch.Size = (),
    device: torch.device | str | None = None,
    seed: int | None = None,
    **overrides,
) -> EnvBase:
    """Builds the task ``name`` with its defaults updated by ``overrides``, then seeds it."""
    spec = get_task(name)
    options = {**spec.defaults, **spec.check(overrides)}
    env = spec.factory(batch_size=batch_size, device=device, **spec.fixed, **options)
    from torchrl.envs import EnvBase

    if not isinstance(env, EnvBase):
        raise UsageError(f"task {spec.name!r}: its factory returned {type(env).__name__}, not a TorchRL EnvBase; for a "
                         "Gymnasium environment register it with drltg.envs.gym.register_gym_task.")
    if seed is not None:
        env.set_seed(seed)
    return env
