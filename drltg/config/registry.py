"""What a config may name: the transfer methods (``transfer.method``), the learners (``algo``) and the
learners' options (the section named as the learner: ``sac.alpha_init``).

Each is a :class:`Registry`, a mapping of names that fills itself on its first lookup from the entry
points of its group, those of drltg itself (``pyproject.toml``) and of every installed plugin::

    [project.entry-points."drltg.methods"]         # a TransferMethod object
    my-method = "my_package.methods:MY_METHOD"
    [project.entry-points."drltg.learners"]        # a make_<algo>_agent(env, cfg) function
    my_algo = "my_package.learners:make_my_agent"
    [project.entry-points."drltg.learner_options"] # its options: a Section model, in a module without torch
    my_algo = "my_package.options:MyAlgoOptions"

So :func:`drltg.config.resolve` knows every built-in method and learner first thing in a fresh process,
whatever was imported before, and importing a method's module changes no config: the entry point is the
lookup. Code run in the process adds more (``register_method``, ``ALGOS[name] = make``). A learner's entry
point is loaded only when the learner is built (its name comes from the metadata, so a config is read
without torch); a method's is loaded with all the others the first time the config is built, since the
``transfer`` section holds every method's options.
"""
from __future__ import annotations

from collections.abc import Iterator, MutableMapping
from importlib.metadata import EntryPoint, entry_points
from typing import Any

from drltg.errors import UsageError, closest


class Registry(MutableMapping):
    """``name -> entry`` of one entry-point group, loaded when first looked up."""

    def __init__(self, group: str, noun: str, builtin: str):
        self.group, self.noun, self.builtin = group, noun, builtin
        self._entries: dict[str, Any] = {}
        self._found = False

    def _points(self) -> dict[str, Any]:
        """Every entry, the entry points not loaded yet among them (as :class:`EntryPoint`): the built-in
        default first, then in the order of the metadata (by name within a distribution)."""
        if not self._found:
            found = sorted(entry_points(group=self.group), key=lambda ep: ep.name != self.builtin)  # stable
            if self.builtin not in {ep.name for ep in found}:
                raise UsageError(f"drltg's {self.noun}s are entry points of its installed distribution (group "
                                 f"{self.group}) and none was found: its metadata predates them; reinstall drltg "
                                 "(pip install -e .).")
            self._entries = {ep.name: ep for ep in found}
            self._found = True
        return self._entries

    def __getitem__(self, name: str) -> Any:
        entries = self._points()
        entry = entries[name]
        if isinstance(entry, EntryPoint):
            entry = entries[name] = self._loaded(entry)
        return entry

    def _loaded(self, point: EntryPoint) -> Any:
        if point.dist is not None and point.dist.name == "drltg":  # drltg's own: a failure is a bug, shown whole
            entry = point.load()
        else:
            try:
                entry = point.load()
            except Exception as err:
                raise UsageError(f"the {self.noun} '{point.name}' ({point.value}) failed to load: {err}") from None
        if getattr(entry, "name", point.name) != point.name:
            raise UsageError(f"the entry point '{point.name}' ({point.value}) of group {self.group} names the "
                             f"{self.noun} {entry.name!r}; name the entry point as the {self.noun} is named.")
        return entry

    def __setitem__(self, name: str, entry: Any) -> None:
        self._points()[name] = entry

    def __delitem__(self, name: str) -> None:
        del self._points()[name]

    def __iter__(self) -> Iterator[str]:
        return iter(list(self._points()))

    def __len__(self) -> int:
        return len(self._points())

    def __contains__(self, name: object) -> bool:
        return name in self._points()

    def names(self) -> tuple[str, ...]:
        """The names, without loading any entry point."""
        return tuple(self._points())


METHODS = Registry("drltg.methods", "transfer method", builtin="none")
"""``transfer.method`` -> its :class:`drltg.transfer.TransferMethod` (``none``: plain learning)."""

LEARNERS = Registry("drltg.learners", "learner", builtin="sac")
"""``algo`` -> its ``make_<algo>_agent(env, cfg)`` (:data:`drltg.learners.ALGOS` is this registry)."""

LEARNER_OPTIONS = Registry("drltg.learner_options", "learner's options", builtin="sac")
"""A learner's name -> the :class:`~drltg.config.values.Section` model of its options, the config section of
that name (a learner without options has none). Loaded with the config, so it imports no torch."""


def method_names() -> tuple[str, ...]:
    """The values ``transfer.method`` takes (a combination ``a+b`` joins two or more of them)."""
    return METHODS.names()


def get_method(name: str):
    """The method ``name``, or the combination ``a+b`` of registered methods (each part's ``combine``)."""
    parts = []
    for part in name.split("+"):
        if part not in METHODS:
            hint = closest(part, METHODS.names())
            raise UsageError(f"unknown transfer method '{part}'" + (f"; did you mean '{hint}'?" if hint else
                             f"; choose one of: {', '.join(method_names())}."))
        parts.append(METHODS[part])
    return parts[0] if len(parts) == 1 else parts[0].combine(*parts[1:])
