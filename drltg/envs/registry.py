"""Named tasks and task pairs (source -> target).

A task is a factory of :class:`~torchrl.envs.EnvBase` plus default keyword arguments; a pair names
a source task and a target task. Factories are called as
``factory(batch_size=..., device=..., **defaults, **overrides)``. A factory may be given as a string
``"module:attr"``, imported when the task is first built or inspected: listing and validating tasks
then imports neither torch nor the task's simulator.

Examples:
    >>> from drltg.envs import make_env, register_task, register_pair, FourRoomsEnv
    >>> register_task("fourrooms/center-west", FourRoomsEnv, "goal near the west doorway", goal=(2.0, 4.0))
    >>> register_pair("my-pair", "fourrooms/northeast", "fourrooms/center-west", "goal to the west door")
    >>> env = make_env("fourrooms/center-west", batch_size=(8,), seed=0)
"""
from __future__ import annotations

import ast
import difflib
import functools
import importlib
import importlib.util
import inspect
import math
import numbers
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Sequence

from drltg.envs.limits import ROBOSUITE_HORIZON
from drltg.errors import UsageError

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

    def keywords(self) -> tuple[dict[str, Any], bool]:
        """The keyword arguments the factory declares (name -> default; ``inspect.Parameter.empty``: none)
        and whether it also takes other keywords (``**kwargs``). A factory named ``"module:attr"`` is read
        from its module's source where that suffices (:func:`_read_keywords`), so that checking a config
        imports neither the env nor torch."""
        read = _read_keywords(self.entry) if isinstance(self.entry, str) else None
        if read is not None:
            return read
        factory = self.factory
        params = inspect.signature(factory.__init__ if inspect.isclass(factory) else factory).parameters
        declared = {name: p.default for name, p in params.items()
                    if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY) and name != "self"}
        return declared, any(p.kind is p.VAR_KEYWORD for p in params.values())


class _Options(dict):
    """Env options as a task's ``returns`` reads them: ``options[key]`` for a key they lack is the factory's
    declared default, looked up only then (``get`` does not look), so that a report of runs whose range needs
    no factory default imports no env."""

    def __init__(self, given: dict[str, Any], spec: TaskSpec):
        super().__init__(given)
        self.spec = spec

    def __missing__(self, key: str) -> Any:
        default = self.spec.keywords()[0].get(key, inspect.Parameter.empty)
        if default is inspect.Parameter.empty:
            raise KeyError(key)
        return default


@functools.lru_cache(maxsize=None)
def _read_keywords(entry: str) -> tuple[dict[str, Any], bool] | None:
    """What :meth:`TaskSpec.keywords` says of the function or class ``"module:attr"``, read from the
    module's source: its own ``def`` (a class's ``__init__``), undecorated, every default a literal, no
    ``__signature__`` assigned; ``None`` when any of that does not hold (the factory is imported instead)."""
    module, _, attr = entry.partition(":")
    try:
        text = Path(importlib.util.find_spec(module).origin).read_text(encoding="utf-8")
        tree = ast.parse(text)
    except (ImportError, AttributeError, OSError, SyntaxError, TypeError, ValueError):
        return None
    if f"{attr}.__signature__" in text:
        return None
    node = next((n for n in tree.body if isinstance(n, (ast.ClassDef, ast.FunctionDef)) and n.name == attr), None)
    if isinstance(node, ast.ClassDef) and not node.decorator_list:
        node = next((n for n in node.body if isinstance(n, ast.FunctionDef) and n.name == "__init__"), None)
    if not isinstance(node, ast.FunctionDef) or node.decorator_list:
        return None
    args = node.args
    positional = args.posonlyargs + args.args
    defaults = [None] * (len(positional) - len(args.defaults)) + list(args.defaults)
    declared = {}
    try:
        for arg, default in [*zip(positional, defaults), *zip(args.kwonlyargs, args.kw_defaults)]:
            if arg in args.posonlyargs or arg.arg in ("self", "cls"):
                continue
            declared[arg.arg] = inspect.Parameter.empty if default is None else ast.literal_eval(default)
    except ValueError:  # a default that is not a literal: the imported signature says what it is
        return None
    return declared, args.kwarg is not None


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
    close = difflib.get_close_matches(name, list(table), n=1)
    hint = f"; did you mean {close[0]!r}?" if close else f"; known {kind}s: {', '.join(sorted(table))}."
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
    replace: bool = False,
    **defaults,
) -> TaskSpec:
    """Registers a task; ``factory`` is a callable or ``"module:attr"`` (imported when the task is first
    built); ``defaults`` are keyword arguments of ``factory``, ``train`` config overrides,
    ``potential(env_options)`` builds its reward-shaping potential, ``returns(options)`` gives the range of an
    episode's return (:attr:`TaskSpec.returns`). ``replace=True`` redefines a
    registered task (a notebook cell run twice)."""
    if dict.__contains__(TASKS, name) and not replace:
        raise UsageError(f"task {name!r} is already registered; pass replace=True to redefine it.")
    if isinstance(factory, str) and not all(factory.partition(":")[::2]):
        raise UsageError(f"task {name!r}: a factory named by a string is 'module:attr', got {factory!r}.")
    spec = TaskSpec(name, factory, description, dict(defaults), dict(train or {}), potential, returns)
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


def _check_options(spec: TaskSpec, options: dict[str, Any]) -> None:
    factory = spec.factory
    params = inspect.signature(factory.__init__ if inspect.isclass(factory) else factory).parameters
    if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values()):
        return
    unknown = sorted(set(options) - set(params))
    if unknown:
        known = ", ".join(sorted(set(params) - {"self", "batch_size", "device", "seed"}))
        raise UsageError(f"task {spec.name!r} has no option {unknown[0]!r}; its options are: {known}.")
    for name, value in options.items():
        default = params[name].default
        kinds = _SCALAR_KINDS.get(type(default))
        if kinds and value is not None and (not isinstance(value, kinds) or
                                            (isinstance(value, bool) and not isinstance(default, bool))):
            raise UsageError(f"task {spec.name!r}: option {name!r} must be of type {type(default).__name__} (its "
                             f"default is {default!r}), got {value!r}.")


_SCALAR_KINDS = {bool: (bool,), int: (numbers.Integral,), float: (numbers.Real,), str: (str,)}
"""What a factory's scalar keyword accepts, by the type of its default (an int where a float is declared)."""


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
    options = {**spec.defaults, **overrides}
    _check_options(spec, options)
    env = spec.factory(batch_size=batch_size, device=device, **options)
    from torchrl.envs import EnvBase

    if not isinstance(env, EnvBase):
        raise UsageError(f"task {spec.name!r}: its factory returned {type(env).__name__}, not a TorchRL EnvBase; for a "
                         "Gymnasium environment register it with drltg.envs.gym.register_gym_task.")
    if seed is not None:
        env.set_seed(seed)
    return env


# Measured: with SAC's default alpha_init=1.0 the entropy bonus outweighs the sparse goal reward and
# SAC does not learn FourRooms in 200k frames; with alpha_init=0.01 and 2x64 nets it reaches ~0.8
# success in 10k frames (drltg train fourrooms/northeast --frames 50000).
ROOMS_TRAIN = {"sac": {"alpha_init": 0.01}, "network": {"hidden": [64, 64]}}
# Discrete SAC's automatic temperature aims at TorchRL's default entropy, 0.98 log 4 on the grid: the
# policy is kept near uniform and its greedy evaluation collapses to never reaching the goal after
# about 12k frames (measured: return 0.94 at 12k, then -1 from 16k to 40k). A fixed alpha of 0.01 keeps
# 0.94 to 40k frames.
GRID_TRAIN = {**ROOMS_TRAIN, "sac": {**ROOMS_TRAIN["sac"], "fixed_alpha": True}}


def _rooms_returns(o: dict) -> tuple[float, float]:
    """FourRooms: -step_cost on every step but the goal's, +1 there: from never reaching it to reaching it at once."""
    return -o["step_cost"] * o["horizon"], 1.0


def _named_potential(entry: str, option: str, options: dict[str, Any]):
    """The potential class (or factory) named ``"module:attr"``, imported on use, of ``options[option]``."""
    module, _, attr = entry.partition(":")
    return getattr(importlib.import_module(module), attr)(options[option])


_rooms_potential = functools.partial(_named_potential, "drltg.envs.fourrooms:FourRoomsPotential", "goal")
_grid_potential = functools.partial(_named_potential, "drltg.envs.gridrooms:GridFourRoomsPotential", "goal")

register_task(
    "fourrooms/northeast",
    "drltg.envs.fourrooms:FourRoomsEnv",
    "continuous FourRooms, goal disc (r 0.5) at (8.0, 8.0) in the north-east room, random start",
    goal=(8.0, 8.0),
    step_cost=0.01,
    train=ROOMS_TRAIN,
    returns=_rooms_returns,
    potential=_rooms_potential,
)
register_task(
    "fourrooms/northeast-shifted",
    "drltg.envs.fourrooms:FourRoomsEnv",
    "continuous FourRooms, goal disc (r 0.5) at (8.0, 7.0), 1 unit south of fourrooms/northeast",
    goal=(8.0, 7.0),
    step_cost=0.01,
    train=ROOMS_TRAIN,
    returns=_rooms_returns,
    potential=_rooms_potential,
)
register_task(
    "fourrooms/southwest",
    "drltg.envs.fourrooms:FourRoomsEnv",
    "continuous FourRooms, goal disc (r 0.5) at (2.0, 2.0) in the south-west room, random start",
    goal=(2.0, 2.0),
    step_cost=0.01,
    train=ROOMS_TRAIN,
    returns=_rooms_returns,
    potential=_rooms_potential,
)
# Graded targets for the source goal (8, 8): shortest free path from the source goal through the
# doorways, 1.0 (northeast-shifted), 2.1 (northeast-inner), 6.1 (southeast, northwest) and 9.9
# (southwest) units.
register_task(
    "fourrooms/northeast-inner",
    "drltg.envs.fourrooms:FourRoomsEnv",
    "continuous FourRooms, goal disc (r 0.5) at (6.5, 6.5), the north-east room's inner corner",
    goal=(6.5, 6.5),
    step_cost=0.01,
    train=ROOMS_TRAIN,
    returns=_rooms_returns,
    potential=_rooms_potential,
)
register_task(
    "fourrooms/southeast",
    "drltg.envs.fourrooms:FourRoomsEnv",
    "continuous FourRooms, goal disc (r 0.5) at (8.0, 2.0) in the south-east room, random start",
    goal=(8.0, 2.0),
    step_cost=0.01,
    train=ROOMS_TRAIN,
    returns=_rooms_returns,
    potential=_rooms_potential,
)
register_task(
    "fourrooms/northwest",
    "drltg.envs.fourrooms:FourRoomsEnv",
    "continuous FourRooms, goal disc (r 0.5) at (2.0, 8.0) in the north-west room, random start",
    goal=(2.0, 8.0),
    step_cost=0.01,
    train=ROOMS_TRAIN,
    returns=_rooms_returns,
    potential=_rooms_potential,
)
register_task(
    "gridrooms/northeast",
    "drltg.envs.gridrooms:GridFourRoomsEnv",
    "grid FourRooms 13x13, goal cell (row 3, col 9) in the north-east room, random start",
    goal=(3, 9),
    step_cost=0.01,
    train=GRID_TRAIN,
    returns=_rooms_returns,
    potential=_grid_potential,
)
register_task(
    "gridrooms/northeast-shifted",
    "drltg.envs.gridrooms:GridFourRoomsEnv",
    "grid FourRooms 13x13, goal cell (row 4, col 9), 1 cell below gridrooms/northeast",
    goal=(4, 9),
    step_cost=0.01,
    train=GRID_TRAIN,
    returns=_rooms_returns,
    potential=_grid_potential,
)
register_task(
    "gridrooms/southwest",
    "drltg.envs.gridrooms:GridFourRoomsEnv",
    "grid FourRooms 13x13, goal cell (row 9, col 3) in the south-west room, random start",
    goal=(9, 3),
    step_cost=0.01,
    train=GRID_TRAIN,
    returns=_rooms_returns,
    potential=_grid_potential,
)
register_pair(
    "fourrooms-near",
    "fourrooms/northeast",
    "fourrooms/northeast-shifted",
    "the goal moves 1 unit within the north-east room (transfer should help)",
)
register_pair(
    "fourrooms-far",
    "fourrooms/northeast",
    "fourrooms/southwest",
    "the goal moves to the opposite, south-west room",
)
register_pair(
    "fourrooms-inner",
    "fourrooms/northeast",
    "fourrooms/northeast-inner",
    "the goal moves 2.1 units to the north-east room's inner corner",
)
register_pair(
    "fourrooms-southeast",
    "fourrooms/northeast",
    "fourrooms/southeast",
    "the goal moves to the adjacent south-east room (through the east doorway)",
)
register_pair(
    "fourrooms-northwest",
    "fourrooms/northeast",
    "fourrooms/northwest",
    "the goal moves to the adjacent north-west room (through the north doorway)",
)
register_pair(
    "gridrooms-near",
    "gridrooms/northeast",
    "gridrooms/northeast-shifted",
    "the goal moves 1 cell within the north-east room (transfer should help)",
)
register_pair(
    "gridrooms-far",
    "gridrooms/northeast",
    "gridrooms/southwest",
    "the goal moves to the opposite, south-west room",
)


# robosuite manipulation (drltg.envs.robosuite; robosuite is imported only when a task is built).
# SAC settings known to work on Lift: replay 1e6, batch 256, 2x256 nets, lr 3e-4, one update per frame
# (Stable-Baselines3's SAC defaults; results/README.md's lift-dense study found none better at 30k frames).
def _manipulation_returns(o: dict) -> tuple[float, float]:
    """Every manipulation reward pays between 0 and ``reward_scale`` (1) per step."""
    return 0.0, o.get("horizon", ROBOSUITE_HORIZON) * (1.0 if o.get("reward_scale") is None else o["reward_scale"])


ROBOSUITE_TRAIN = {
    "buffer": {"size": 1_000_000, "batch_size": 256},
    "network": {"hidden": [256, 256]},
    "optim": {"lr": 3.0e-4, "updates_per_batch": 100},
    "collector": {"num_envs": 2, "frames_per_batch": 100, "init_random_frames": 5_000},
    "eval": {"every": 25_000, "episodes": 4},
    "checkpoint": {"every": 50_000},
}


_manipulation_potential = functools.partial(_named_potential, "drltg.envs.robosuite.potentials:potential_for", "task")

register_task(
    "lift",
    "drltg.envs.robosuite.env:robosuite_task",
    "robosuite Lift: the Panda lifts the cube 4 cm (reward 1 per lifted step), horizon 500",
    task="lift",
    train=ROBOSUITE_TRAIN,
    returns=_manipulation_returns,
    potential=_manipulation_potential,
)
register_task(
    "lift-place",
    "drltg.envs.robosuite.env:robosuite_task",
    "lift the cube and set it down on the green target disc 0.32 m away, horizon 500",
    task="lift-place",
    train=ROBOSUITE_TRAIN,
    returns=_manipulation_returns,
    potential=_manipulation_potential,
)
register_task(
    "lift-place-barrier",
    "drltg.envs.robosuite.env:robosuite_task",
    "lift-place with a heavy 7 cm wall between cube and target (pushing cannot work), horizon 500",
    task="lift-place-barrier",
    train=ROBOSUITE_TRAIN,
    returns=_manipulation_returns,
    potential=_manipulation_potential,
)
register_task(
    "lift-dense",
    "drltg.envs.robosuite.env:robosuite_task",
    "robosuite Lift with robosuite's dense reward (reach + grasp + lift, at most 1 per step), horizon 500",
    task="lift",
    reward_shaping=True,
    train=ROBOSUITE_TRAIN,
    returns=_manipulation_returns,
)
# The earlier implementation's place reward (drltg.envs.robosuite.tasks.SeedReward) on drltg's scenes: dense
# stages plus a contact bonus that pays pushing like placing; success stays drltg's strict check.
register_task(
    "lift-place-seed",
    "drltg.envs.robosuite.env:robosuite_task",
    "lift-place with the earlier implementation's dense reward (reach, grasp, lift, place; contact pays 1), "
    "horizon 500",
    task="lift-place-seed",
    train=ROBOSUITE_TRAIN,
    returns=_manipulation_returns,
)
register_task(
    "lift-place-barrier-seed",
    "drltg.envs.robosuite.env:robosuite_task",
    "lift-place-barrier with the earlier implementation's dense reward (contact pays 1), horizon 500",
    task="lift-place-barrier-seed",
    train=ROBOSUITE_TRAIN,
    returns=_manipulation_returns,
)
register_pair("lift-to-place", "lift", "lift-place", "lifting skills reused to lift and place")
register_pair("lift-to-place-barrier", "lift", "lift-place-barrier", "lifting reused where pushing cannot work")
register_pair(
    "lift-dense-to-place", "lift-dense", "lift-place", "a Lift policy learned from dense reward reused to place"
)
register_pair(
    "lift-dense-to-place-barrier", "lift-dense", "lift-place-barrier", "a dense-reward Lift policy reused over the wall"
)
register_pair("lift-dense-to-place-seed", "lift-dense", "lift-place-seed",
              "the earlier implementation's pair: dense-reward Lift to its dense place reward")
register_pair("lift-dense-to-place-barrier-seed", "lift-dense", "lift-place-barrier-seed",
              "the earlier implementation's pair over the wall, on its dense place reward")


# Gymnasium's Pendulum with two gravities (drltg.envs.gym.make_gym_env; Gymnasium is imported when one is built).
# SAC as RL Zoo tunes it for Pendulum (lr 1e-3, one update per frame) with 2x64 nets: single-threaded,
# small nets are several times faster and Pendulum needs no more.
PENDULUM_TRAIN = {
    "network": {"hidden": [64, 64]},
    "optim": {"lr": 1.0e-3, "updates_per_batch": 32},
    "collector": {"num_envs": 4, "frames_per_batch": 32, "init_random_frames": 1000},
    "eval": {"every": 1000, "episodes": 5},
    "checkpoint": {"every": 5000},
}

def _pendulum_returns(o: dict) -> tuple[float, float]:
    """Pendulum-v1 costs theta^2 + 0.1 thetadot^2 + 0.001 u^2 per step, at most pi^2 + 0.1 * 8^2 + 0.001 * 2^2."""
    return -(math.pi ** 2 + 6.4 + 0.004) * o.get("max_episode_steps", 200), 0.0


_GYM = "drltg.envs.gym:make_gym_env"  # drltg.envs.gym.register_gym_task's factory
register_task("pendulum/g10", _GYM, "Gymnasium Pendulum-v1, gravity g = 10 (its default)",
              gym_id="Pendulum-v1", g=10.0, train=PENDULUM_TRAIN, returns=_pendulum_returns)
register_task("pendulum/g15", _GYM, "Gymnasium Pendulum-v1, gravity g = 15: a heavier swing-up",
              gym_id="Pendulum-v1", g=15.0, train=PENDULUM_TRAIN, returns=_pendulum_returns)
register_pair("pendulum-heavier", "pendulum/g10", "pendulum/g15", "Pendulum's gravity rises from 10 to 15")
