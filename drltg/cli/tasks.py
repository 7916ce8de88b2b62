"""`drltg tasks`: list the registered tasks, task pairs and transfer methods, one line each."""
from __future__ import annotations

import argparse

from drltg.envs import PAIRS, TASKS
from drltg.transfer import METHODS


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("pattern", nargs="?", default="", help="only list names containing this text")


def run(args: argparse.Namespace) -> int:
    tasks = [t for t in TASKS.values() if args.pattern in t.name]
    pairs = [p for p in PAIRS.values() if args.pattern in p.name]
    methods = [m for m in METHODS.values() if args.pattern in m.name]
    width = max((len(x.name) for x in [*tasks, *pairs, *methods]), default=0)
    print("tasks:")
    for task in tasks:
        print(f"  {task.name:<{width}}  {task.description}")
    print("pairs (source -> target):")
    for pair in pairs:
        print(f"  {pair.name:<{width}}  {pair.source} -> {pair.target}: {pair.description}")
    print("transfer methods (transfer.method; source: what transfer.source must be):")
    for method in methods:
        source = {None: "", "run": " [source: a run]", "policy": " [source: a run or demonstrator:TASK]"}[method.source]
        print(f"  {method.name:<{width}}  {method.help}{source}")
    if tasks:
        from drltg.gymnasium_ids import task_id

        print(f"as Gymnasium envs: drltg/<task, '/' as '-'>-v0, e.g. gymnasium.make(\"{task_id(tasks[0].name)}\") "
              f"for {tasks[0].name} (drltg.gymnasium_ids.task_id)")
    return 0
