"""The `drltg` command. Each subcommand lives in its own module exposing
``add_arguments(parser)`` and ``run(args) -> int``; modules are imported only when used."""
from __future__ import annotations

import argparse
import importlib
import logging
import re
import signal
import sys
from importlib.metadata import version

from drltg import plugins
from drltg.errors import RunFailed, UsageError

SUBCOMMANDS = {
    "tasks": ("drltg.cli.tasks", "list the registered tasks and task pairs"),
    "train": ("drltg.cli.train", "train one agent on one task (writes a run directory)"),
    "evaluate": ("drltg.cli.evaluate",
                 "evaluate a run's last or best checkpoint on fresh episodes, with confidence intervals"),
    "demo": ("drltg.cli.demo", "a short FourRooms run on the built-in defaults"),
    "experiment": ("drltg.experiments.experiment",
                   "train source, baseline and transfer runs over seeds, then report"),
    "sweep": ("drltg.experiments.sweep",
              "many experiments from one YAML spec, on a local process pool or a Ray cluster"),
    "bench": ("drltg.cli.bench", "the transfer benchmark: run a method on a tier, then the leaderboard"),
    "report": ("drltg.cli.report", "transfer metrics, plots and tables from baseline vs transfer runs"),
    "video": ("drltg.video", "render episodes of a trained policy or the demonstrator to video and a filmstrip"),
}


class _BadArguments(Exception):
    """What argparse refused, after the name of the parser that refused it (``drltg train`` for a train
    option): :func:`main` prints it as one sentence and returns 2 (argparse's convention)."""


class _Once(argparse.Action):
    """An option that takes one value, refused when given twice: argparse keeps the last (``--seeds auto ...
    --seeds 14`` would train 14), which one was meant depends on where each was typed."""

    def __call__(self, parser, namespace, values, option_string=None):
        given = namespace.__dict__.setdefault("_given", {})
        if self.dest in given:
            parser.error(f"argument {'/'.join(self.option_strings)} is given twice ({given[self.dest]!r}, then "
                         f"{values!r}); give it once")
        given[self.dest] = values
        setattr(namespace, self.dest, values)


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):
        raise _BadArguments(f"{self.prog}: error: {message}")

    def add_argument(self, *names, **kwargs):
        if names and names[0].startswith("-") and kwargs.get("action", "store") == "store":
            kwargs["action"] = _Once
        return super().add_argument(*names, **kwargs)


NEGATIVE_VALUED = ("--value-range", "--threshold")
"""Options whose value may start with a minus sign (``--value-range -50,0``), which argparse would take for
an option of its own."""


def _joined_negative_values(argv: list[str]) -> list[str]:
    """``["--value-range", "-50,0"]`` as ``["--value-range=-50,0"]``."""
    out, i = [], 0
    while i < len(argv):
        if argv[i] in NEGATIVE_VALUED and i + 1 < len(argv) and re.match(r"-[0-9.]", argv[i + 1]):
            out.append(f"{argv[i]}={argv[i + 1]}")
            i += 2
        else:
            out.append(argv[i])
            i += 1
    return out


def main(argv: list[str] | None = None) -> int:
    argv = _joined_negative_values(sys.argv[1:] if argv is None else argv)
    parser = _Parser(prog="drltg", description="DRL Transfer Gym: transfer learning for deep RL on TorchRL.")
    parser.add_argument("--version", action="version", version=f"drltg {version('drltg')}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True
    plugin_options = _Parser(add_help=False)
    plugin_options.add_argument("--import", dest="imports", action="append", default=[], metavar="MODULE",
                                help="import MODULE first, e.g. one that registers your tasks: a module name, "
                                     "one in the working directory, or a file or package path (./my_tasks.py; "
                                     "repeatable; also DRLTG_IMPORT=a,b and the drltg.plugins entry points)")
    for name, (module, help_text) in SUBCOMMANDS.items():
        p = sub.add_parser(name, help=help_text, description=help_text, parents=[plugin_options])
        p.set_defaults(_module=module)
        if argv[:1] == [name]:  # import only the module that runs (keeps `drltg tasks` fast)
            importlib.import_module(module).add_arguments(p)
    try:
        args = parser.parse_args(argv)
    except _BadArguments as err:
        bare = [argv[i + 1] for i, a in enumerate(argv[:-1]) if a in ("-o", "--set") and "=" not in argv[i + 1]]
        hint = f"; -o takes KEY=VALUE as one argument, e.g. -o {bare[0]}=VALUE" if bare else ""
        print(f"{err}{hint}", file=sys.stderr)
        return 2
    previous = signal.signal(signal.SIGTERM, _terminate)
    messages = logging.StreamHandler(sys.stdout)  # what the library logs (e.g. model reuse's summary) shows here
    messages.setFormatter(logging.Formatter("%(message)s"))
    logger = logging.getLogger("drltg")
    logger.addHandler(messages)
    level = logger.level
    logger.setLevel(logging.INFO)
    try:
        check_mujoco_gl()
        plugins.load(args.imports)
        return importlib.import_module(args._module).run(args) or 0
    except UsageError as err:
        print(f"drltg {args.command}: error: {err}", file=sys.stderr)
        return 2
    except RunFailed as err:
        print(f"drltg {args.command}: {err}.", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"drltg {args.command}: interrupted", file=sys.stderr)
        return 130
    finally:
        signal.signal(signal.SIGTERM, previous)
        logger.removeHandler(messages)
        logger.setLevel(level)


MUJOCO_GL_VALUES = {"linux": ("egl", "osmesa", "glx"), "win32": ("wgl",), "darwin": ("cgl",)}
MUJOCO_GL_ANY = ("", "glfw", "enable", "enabled", "on", "true", "1", "disable", "disabled", "off", "false", "0")


def check_mujoco_gl() -> None:
    """Refuse a ``MUJOCO_GL`` that MuJoCo rejects: it reads it when TorchRL's envs are imported, for every
    command, and fails there with a traceback."""
    import os

    value = os.environ.get("MUJOCO_GL")
    allowed = MUJOCO_GL_ANY + MUJOCO_GL_VALUES.get(sys.platform, ())
    if value is not None and value.lower().strip() not in allowed:
        raise UsageError(f"MUJOCO_GL={value!r} is not a MuJoCo GL backend; set it to one of "
                         f"{', '.join(v for v in allowed if v)} or unset it.")


def _terminate(signum, frame):
    """SIGTERM unwinds like Ctrl-C: locks are released and a failed start is removed."""
    raise SystemExit(128 + signum)


