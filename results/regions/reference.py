"""The docs' reference tables, from drltg's registries: tasks, methods and config keys."""
from __future__ import annotations

from drltg.analysis.tables import render


def _builtin(obj) -> bool:
    """Defined by drltg itself, not by a plugin or a test registered in the same process."""
    return getattr(obj, "__module__", "").startswith("drltg.")


def _kind(name: str, task) -> str:
    if name.startswith(("fourrooms", "gridrooms")):
        return "rooms"
    return "gym" if "gym_id" in task.fixed else "robosuite"


def tasks_table(kind: str) -> str:
    """drltg's registered tasks and pairs of one kind (``"rooms"``: FourRooms and its grid; ``"robosuite"``;
    ``"gym"``: Gymnasium envs)."""
    from drltg.envs import PAIRS, TASKS

    tasks = {name: t for name, t in TASKS.items() if _builtin(t.factory) and _kind(name, t) == kind}
    rows = [("task", "description")] + [(f"`{name}`", t.description) for name, t in tasks.items()]
    pairs = [("pair", "source → target", "description")] + [
        (f"`{name}`", f"`{p.source}` → `{p.target}`", p.description) for name, p in PAIRS.items()
        if p.source in tasks and p.target in tasks]
    return render(rows, "markdown") + "\n" + render(pairs, "markdown")


def _methods() -> dict:
    from drltg.config import METHODS

    return {name: m for name, m in METHODS.items() if _builtin(m.build)}


def methods_table() -> str:
    rows = [("`transfer.method`", "source", "what it is")]
    for name, spec in _methods().items():
        source = {None: "—", "run": "a run", "policy": "a run or `demonstrator:TASK`"}[spec.source]
        rows.append((f"`{name}`", source, spec.help))
    return render(rows, "markdown")


def config_table() -> str:
    """``drltg.config.describe()`` for drltg's own keys (a plugin's method keys left out)."""
    from drltg import config

    builtin = _methods()
    own = {f"transfer.{key}" for m in builtin.values() for key in m.options}
    lines = []
    for line in config.describe().splitlines():
        key = line.split("`")[1] if line.startswith("| `") else None
        if key is None or not key.startswith("transfer.") or key in own or key.removeprefix("transfer.") not in \
                config.option_owners():
            if key == "transfer.method":
                cells = line.split(" | ")
                cells[2] = "one of " + ", ".join(builtin)
                line = " | ".join(cells)
            lines.append(line)
    return "\n".join(lines) + "\n"
