"""`drltg tasks`: list the registered tasks and task pairs, one line each."""
from __future__ import annotations

import argparse

from drltg.envs import PAIRS, TASKS


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("pattern", nargs="?", default="", help="only list names containing this text")


def run(args: argparse.Namespace) -> int:
    tasks = [t for t in TASKS.values() if args.pattern in t.name]
    pairs = [p for p in PAIRS.values() if args.pattern in p.name]
    width = max((len(x.name) for x in [*tasks, *pairs]), default=0)
    print("tasks:")
    for task in tasks:
        print(f"  {task.name:<{width}}  {task.description}")
    print("pairs (source -> target):")
    for pair in pairs:
        print(f"  {pair.name:<{width}}  {pair.source} -> {pair.target}: {pair.description}")
    return 0
