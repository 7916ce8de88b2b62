"""Users' own tasks, pairs and potentials on every command: plugins imported before a command runs.

A plugin is any importable module that registers things when imported (``register_task``,
``register_pair``). drltg imports

- every entry point of the group ``drltg.plugins`` of the installed distributions, e.g. in the
  plugin's ``pyproject.toml``::

      [project.entry-points."drltg.plugins"]
      my_tasks = "my_package.tasks"

- the modules named by ``--import MODULE`` (any command, repeatable) and by the environment variable
  ``DRLTG_IMPORT`` (comma-separated): a module name, a module of the working directory, or the path of a
  Python file or package folder (``--import ./my_tasks.py``).

``--import`` modules are added to ``DRLTG_IMPORT`` of this process, so the worker processes of
``drltg experiment`` and ``drltg sweep`` (which call :func:`load` too) register the same things.
"""
from __future__ import annotations

import importlib
import importlib.util
import os
import sys
from importlib.metadata import entry_points
from pathlib import Path

from drltg.errors import UsageError

GROUP = "drltg.plugins"
ENV_VAR = "DRLTG_IMPORT"


def _modules_from_env() -> list[str]:
    return [m.strip() for m in os.environ.get(ENV_VAR, "").split(",") if m.strip()]


def _located(name: str) -> str:
    """``name`` as the workers import it too: a file or folder path (``./my_tasks.py``, ``plugins/mine``)
    made absolute; a module name that only this working directory holds (``my_tasks`` for ``./my_tasks.py``,
    as ``python -m`` would find it) as that file's absolute path; any other module name as it is."""
    path = Path(name).expanduser()
    if name.endswith(".py") or os.sep in name or (os.altsep and os.altsep in name):
        if not (path.is_file() or (path / "__init__.py").is_file()):
            raise UsageError(f"cannot import plugin '{name}': no such Python file or package folder.")
        return str(path.resolve())
    if importlib.util.find_spec(name.split(".")[0]) is None:
        for local in (Path.cwd() / f"{name}.py", Path.cwd() / name):
            if local.is_file() or (local / "__init__.py").is_file():
                return str(local.resolve())
    return name


def _import(name: str) -> None:
    """Import a module name, or the module a file or package folder path holds, its folder first on
    ``sys.path`` (so it imports its neighbours, as a script does)."""
    path = Path(name)
    if not path.is_absolute():
        importlib.import_module(name)
        return
    folder = str(path.parent)
    if folder not in sys.path:
        sys.path.insert(0, folder)
    importlib.import_module(path.stem if path.is_file() else path.name)


def load(modules=()) -> list[str]:
    """Import the entry-point plugins, ``DRLTG_IMPORT`` and ``modules``; export ``modules`` to
    ``DRLTG_IMPORT``; returns the names imported. Importing twice is harmless (modules are cached)."""
    names = list(dict.fromkeys([*_modules_from_env(), *modules]))
    loaded = []
    for ep in entry_points(group=GROUP):
        try:
            ep.load()
        except SystemExit as err:
            raise UsageError(f"the drltg plugin '{ep.name}' ({ep.value}) called sys.exit({err.code!r}) while it "
                             "was imported; a plugin module must only define and register.") from None
        except Exception as err:
            raise UsageError(f"the drltg plugin '{ep.name}' ({ep.value}) failed to load: {err}") from None
        loaded.append(ep.value)
    names = [_located(name) for name in names]
    for name in names:
        try:
            _import(name)
        except ModuleNotFoundError as err:
            if err.name and name.startswith(err.name):
                raise UsageError(f"cannot import plugin module '{name}': no module named '{err.name}' "
                                 "(is it installed or on PYTHONPATH?).") from None
            raise UsageError(f"plugin module '{name}' failed to import: {err}") from None
        except UsageError:
            raise
        except SystemExit as err:
            raise UsageError(f"plugin module '{name}' called sys.exit({err.code!r}) while it was imported; a plugin "
                             "module must only define and register.") from None
        except Exception as err:
            raise UsageError(f"plugin module '{name}' failed to import: {type(err).__name__}: {err}") from None
        loaded.append(name)
    if modules:  # only what imported: a worker process must not fail on a name the parent refused
        os.environ[ENV_VAR] = ",".join(names)
    return loaded
