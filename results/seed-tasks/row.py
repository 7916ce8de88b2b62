"""One row of the seed's tasks: its baseline and transfer runs, then its reports.

    taskset -c 0 python results/seed-tasks/row.py ROW --seeds 10 12 &               # re-running resumes
    taskset -c 1 python results/seed-tasks/row.py ROW --seeds 11 --sides transfer   # one process per core

Seeds 10, 11, 12 (never used to choose a recipe), 300k frames, evaluated every 10k frames on 10 episodes,
checkpoints every 20k. A transfer run of seed s reuses the source run of seed s + 50 at its best evaluation
(``study.py`` trains them, and runs every row a seed at a time). The runs of the seeds given train one
after another in this process, each alone (on one core that is faster than a seed group: benchmarks/README.md,
"Lift seeds on one core"); a finished run is reused (the lift-place-seed SAC baselines are
``results/seed_tasks.sh``'s). Each run is kept as it finishes (its curve and config, in the same place under
``results/seed-tasks/`` as under the runs folder); once every run of the row is finished, they are kept in
``results/seed-tasks/ROW/`` and reported: the return on the task's reward (threshold 50), and the success
and lifted rates (0.5 and 0.8; success alone on Lift).

``shaping-lift-seed`` is the earlier implementation's reward shaping on Lift: SAC on robosuite's dense reward
(``env.reward_shaping=true``) against the sparse one, both evaluated on Lift's own success.
"""
from __future__ import annotations

import argparse
import contextlib
import os
import re
import shutil
import signal
import sys
from pathlib import Path

import drltg.transfer  # noqa: F401  (registers the transfer methods the rows name)
from drltg import config as config_lib
from drltg.analysis.report import transfer_report
from drltg.errors import UsageError
from drltg.store.lock import lock

SEEDS = (10, 11, 12)
SOURCE_OFFSET = 50
FRAMES = 300_000
COMMON = ["eval.every=10000", "eval.episodes=10", "checkpoint.every=20000"]
ROWS = {  # name: (target task, algo, transfer overrides, source folder or None)
    "shaping-lift-seed": ("lift", "sac", ["env.reward_shaping=true"], None),
    "pi-reuse-place-seed": ("lift-place-seed", "sac", ["transfer.method=policy-reuse"], "lift-dense-sac"),
    "pi-reuse-barrier-seed": ("lift-place-barrier-seed", "sac", ["transfer.method=policy-reuse"], "lift-dense-sac"),
    "model-reuse-place-seed": ("lift-place-seed", "sac", ["transfer.method=model-reuse"], "lift-dense-sac"),
    "soc-model-reuse-place-seed": ("lift-place-seed", "soc", ["transfer.method=model-reuse"], "lift-dense-soc4"),
}
LAYER_NORM = ["network.layer_norm=critics"]
"""Model reuse copies the SAC source's networks whole, LayerNorm critics included (``study.py``'s recipe), so
both sides of that row have them: its baselines are ``baseline-ln``, and the two sides differ in the transfer
alone."""
KEPT = ("config.yaml", "eval.csv", "summary.json")


def sides(row: str, runs: Path) -> dict[str, tuple[list, list[Path]]]:
    """``{"baseline": (configs, dirs), "transfer": (configs, dirs)}`` of a row."""
    task, algo, overrides, source = ROWS[row]
    learner = ["soc.num_options=4"] if algo == "soc" else []
    ln = row == "model-reuse-place-seed"
    learner += LAYER_NORM if ln else []
    out = {}
    for side in ("baseline", "transfer"):
        cfgs = []
        for s in SEEDS:
            extra = [] if side == "baseline" else list(overrides)
            if side == "transfer" and source:
                extra += [f"transfer.source={runs / 'sources' / source / f'seed-{s + SOURCE_OFFSET}'}",
                          "transfer.source_checkpoint=best"]
            cfgs.append(config_lib.resolve(None, COMMON + learner + extra, task=task, algo=algo, seed=s,
                                           frames=FRAMES))
        folder = runs / task / algo / (row if side == "transfer" else "baseline-ln" if ln else "baseline")
        out[side] = (cfgs, [folder / f"seed-{s}" for s in SEEDS])
    return out


def train_runs(cfgs: list, dirs: list[Path], runs: Path) -> None:
    """Train each run not finished yet; a run that finishes is kept at once, in the same place under
    ``results/seed-tasks/`` as under ``runs`` (``study.py --restore`` reuses it in a new clone)."""
    from drltg.training.loop import train

    for cfg, run in zip(cfgs, dirs):
        if not (run / "summary.json").is_file():
            train(cfg, run, resume=(run / "config.yaml").is_file(), progress=False)
            if (run / "summary.json").is_file():
                keep(run, HERE / run.relative_to(runs), runs)


HERE = Path(__file__).resolve().parent
SOURCE_LINE = re.compile(r"^(  source: )(\S+)$", re.M)


def kept_source(source: Path) -> Path:
    """The folder in ``results/seed-tasks/sources/`` that keeps the training of ``source`` (a source run in
    ``runs/sources/NAME/seed-S``): ``seed-S``, or ``seed-S-retrained`` (``-retrained-2``, ...) where ``seed-S``
    keeps another training of that seed, told apart by their evaluations. A training kept nowhere yet gets
    the first free name."""
    base = HERE / "sources" / source.parent.name / source.name
    if not (source / "eval.csv").is_file():
        return base
    curve = (source / "eval.csv").read_bytes()
    names = [base] + [base.with_name(f"{base.name}-retrained{'' if i == 1 else f'-{i}'}") for i in range(1, 100)]
    for kept in names:
        if not (kept / "eval.csv").is_file() or (kept / "eval.csv").read_bytes() == curve:
            return kept
    raise RuntimeError(f"{source}: 100 trainings kept already")


def keep(run: Path, kept: Path, runs: Path) -> None:
    """Copy a run's ``KEPT`` files to ``kept``; a transfer's ``transfer.source`` (relative to its run) is
    pointed at the folder that keeps that source's training (:func:`kept_source`), so a report finds the
    source's frames and a reader its curve."""
    kept.mkdir(parents=True, exist_ok=True)
    for name in KEPT:
        if (run / name).is_file():
            shutil.copyfile(run / name, kept / name)

    sources = Path(os.path.normpath(runs.resolve() / "sources"))

    def moved(m: re.Match) -> str:
        source = Path(os.path.normpath(run.resolve() / m[2]))  # an absolute path stays itself
        if source.is_relative_to(sources):
            source = kept_source(source)
        elif source.parent.parent.name == "sources" and (HERE / "sources" / source.parent.name / source.name).is_dir():
            # a restored run names a kept source: this checkout's, or another checkout's of this study
            source = HERE / "sources" / source.parent.name / source.name
        else:
            return m[0]
        return m[1] + os.path.relpath(source, kept.resolve())

    config = kept / "config.yaml"
    if config.is_file():
        config.write_text(SOURCE_LINE.sub(moved, config.read_text()))


def keep_and_report(row: str, groups: dict, runs: Path) -> None:
    task = ROWS[row][0]
    out = Path(os.path.relpath(HERE / row))  # the reports name their runs relative to the repository
    for side, (_, dirs) in groups.items():
        for d in dirs:
            keep(d, out / side / d.name, runs)
    stages = [("report", None, 50)] + [(f"report-{tag}", f"{tag}_rate", threshold) for tag, threshold in
                                         (("success", 0.5), ("lifted", 0.8)) if task != "lift" or tag == "success"]
    for folder, tag, threshold in stages:
        if task == "lift" and tag is None:
            continue  # shaping's two sides are paid by different rewards: only the success rate compares
        transfer_report(out / "baseline", out / "transfer", out / folder, tag=tag, threshold=threshold,
                        baseline_label="no transfer", transfer_label=row, allow_mismatch=task == "lift")


def report_once(row: str, groups: dict, runs: Path) -> None:
    """:func:`keep_and_report`, by one process: of two that finish a row's last runs at the same time, the
    second finds the row's folder locked and leaves the report to the first."""
    folder = HERE / row
    folder.mkdir(parents=True, exist_ok=True)
    with contextlib.ExitStack() as held:
        try:
            held.enter_context(lock(folder, "row folder"))
        except UsageError:
            print(f"{row}: another process is reporting the row")
            return
        keep_and_report(row, groups, runs)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("row", choices=sorted(ROWS))
    parser.add_argument("--runs", type=Path, default=Path("runs/seed-tasks"))
    parser.add_argument("--seeds", type=int, nargs="+", default=list(SEEDS), choices=SEEDS,
                        help="the seeds whose baseline and transfer runs this process trains (default: all)")
    parser.add_argument("--sides", nargs="+", default=["baseline", "transfer"], choices=("baseline", "transfer"),
                        help="the sides this process trains, in this order (default: both)")
    parser.add_argument("--dry-run", action="store_true", help="list the runs and their settings, train nothing")
    args = parser.parse_args()
    groups = sides(args.row, args.runs)
    if args.dry_run:
        for side, (cfgs, dirs) in groups.items():
            for c, d in zip(cfgs, dirs):
                print(f"{side:9} {d}  task={c.task} algo={c.algo} seed={c.seed} method={c.transfer.method} "
                      f"source={c.transfer.source} env.reward_shaping={c.env.get('reward_shaping')}")
        return
    for side in args.sides:
        cfgs, dirs = groups[side]
        train_runs(*zip(*[(c, d) for c, d in zip(cfgs, dirs) if c.seed in args.seeds]), args.runs)
    if all((d / "summary.json").is_file() for _, dirs in groups.values() for d in dirs):
        report_once(args.row, groups, args.runs)
    else:
        print(f"{args.row}: other runs of the row are not finished yet; the last process to finish reports the row")


if __name__ == "__main__":
    signal.signal(signal.SIGTERM, lambda signum, frame: sys.exit(128 + signum))  # unwinds: the run's lock is released
    try:
        main()
    except UsageError as err:
        print(f"error: {err}", file=sys.stderr)
        raise SystemExit(2) from None
