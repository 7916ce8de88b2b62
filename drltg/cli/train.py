"""`drltg train TASK --algo sac --frames N --seed S [--seeds N] --run-dir DIR [--config FILE] [-o KEY=VALUE ...]`"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from drltg import config as config_lib
from drltg.errors import RunFailed, UsageError
from drltg.store.rundir import CONFIG, absolute_source, check_directory


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("task", nargs="?", help="registered task name (see `drltg tasks`)")
    p.add_argument("--algo", help="learning algorithm: sac (discrete SAC on discrete tasks), td3, ...")
    p.add_argument("--options", type=int, metavar="K", help="number of options for --algo soc (soc.num_options)")
    p.add_argument("--frames", type=config_lib.frame_count,
                   help="environment frames to train for (50000, 50k, 1e4, 1.5M)")
    p.add_argument("--seed", type=int, help="random seed (envs, networks, sampling)")
    p.add_argument("--seeds", type=int, metavar="N",
                   help="train seeds S, S+100, ..., S+100(N-1) (S: --seed; an experiment's seeds) in one process, "
                        "into RUN_DIR/seed-<s>/ (one vmapped "
                        "update for all seeds where the learner supports it, else one seed after another)")
    p.add_argument("--no-group", action="store_true", help="with --seeds: train the seeds one after another")
    p.add_argument("--run-dir", type=Path,
                   help="output run directory (default: runs/<task>/<algo>-seed<seed>; with --seeds, "
                        "runs/<task>/<algo>-seeds)")
    p.add_argument("--config", type=Path, help="YAML config file (e.g. a run's config.yaml, to reproduce it)")
    p.add_argument("-o", "--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a config key, e.g. -o optim.lr=1e-3 -o network.hidden=[64,64] (repeatable)")
    p.add_argument("--resume", action="store_true", help="continue an interrupted run from its last checkpoint")
    p.add_argument("--no-progress", action="store_true", help="no progress bar (none is drawn when stderr is not "
                   "a terminal)")


def run(args: argparse.Namespace) -> int:
    if args.resume and args.run_dir is None:
        raise UsageError("--resume needs --run-dir, the run directory to continue.")
    if args.no_group and args.seeds is None:
        raise UsageError("--no-group applies to --seeds N; add --seeds.")
    if args.run_dir is not None:
        args.run_dir = check_directory(args.run_dir, "--run-dir")
    if args.config is not None:  # a relative transfer.source is relative to the file's folder
        base = absolute_source(config_lib.load_yaml(args.config), Path(args.config).parent)
    elif args.resume and (args.run_dir / CONFIG).is_file():
        base = absolute_source(config_lib.load_yaml(args.run_dir / CONFIG), args.run_dir)
    elif args.resume and args.seeds is not None and (first := _first_seed(args.run_dir)) is not None:
        base = absolute_source(first[1], first[0])  # a seed group: its first seed's config
    else:
        base = {}
    if args.task is None and "task" not in base:
        raise UsageError("name a task (see `drltg tasks`) or pass --config.")
    if args.options is not None and (args.algo or base.get("algo")) != "soc":
        raise UsageError("--options sets the number of options of the soft option-critic; add --algo soc.")
    explicit = {"soc.num_options": args.options} if args.options is not None else {}
    config_lib.refuse_conflicts(args.overrides)
    cfg = config_lib.resolve(
        base, args.overrides, task=args.task, algo=args.algo, frames=args.frames, seed=args.seed, **explicit
    )
    if args.seeds is not None:
        from drltg.training.seeds import train_seeds

        run_dir = args.run_dir or Path("runs") / cfg.task.replace("/", "-") / f"{cfg.algo}-seeds"
        dirs = train_seeds(cfg, run_dir, args.seeds, resume=args.resume, progress=not args.no_progress,
                           group=not args.no_group)
        _refuse_diverged(dirs)
        for d in dirs:
            _say_how_it_went(d, d.name)
        print(f"run directories: {', '.join(str(d) for d in dirs)}")
        print(f"  curves:  drltg report --baseline {run_dir} --transfer OTHER_RUNS (a folder of seed runs)")
        return 0
    run_dir = args.run_dir or Path("runs") / cfg.task.replace("/", "-") / f"{cfg.algo}-seed{cfg.seed}"
    from drltg.transfer.source import check as check_source

    check_source(cfg)
    from drltg.training.loop import train  # torch: only once the command line is known to be right

    run_dir = train(cfg, run_dir, resume=args.resume, progress=not args.no_progress)
    _refuse_diverged([run_dir])
    _say_how_it_went(run_dir)
    print(f"run directory: {run_dir}")
    print(f"  eval curve:  {run_dir / 'eval.csv'}")
    print(f"  tensorboard: tensorboard --logdir {run_dir / 'logs' / 'tensorboard'}")
    return 0


def _say_how_it_went(run_dir: Path, name: str | None = None) -> None:
    """The run's final and best evaluation, and a collapse warning (on stderr), from its eval.csv."""
    from drltg.store.rundir import EVAL, read_config, read_eval_csv
    from drltg.training.best import outcome

    cfg = config_lib.build(read_config(run_dir), saved=True)
    went = outcome(cfg, read_eval_csv(run_dir / EVAL))
    if went is not None:
        print(f"{name}: {went.final}" if name else went.final)
        if went.collapse:
            print(f"warning: {went.collapse}", file=sys.stderr)


def _first_seed(run_dir: Path) -> tuple[Path, dict] | None:
    """The seed group's run directory (``seed-*/`` under ``run_dir``) whose config names the lowest seed, with
    that config."""
    configs = [(p.parent, config_lib.load_yaml(p)) for p in sorted(run_dir.glob("seed-*/" + CONFIG))]
    seeded = [(d, c) for d, c in configs if isinstance(c, dict) and isinstance(c.get("seed"), int)]
    return min(seeded, key=lambda dc: dc[1]["seed"], default=None)


def _refuse_diverged(dirs: list[Path]) -> None:
    """A resumed run that had diverged is finished without a result: say so, exit non-zero."""
    from drltg.store.rundir import DIVERGED, summary_status

    diverged = [d for d in dirs if (summary_status(d) or ("",))[0] == DIVERGED]
    if diverged:
        names = ", ".join(f"'{d}'" for d in diverged)
        raise RunFailed(f"cannot resume {names}: its summary.json says status diverged "
                        f"({summary_status(diverged[0])[1]}), so it is finished without a result; train it anew "
                        f"into another --run-dir with a changed config (e.g. a lower optim.lr)")
