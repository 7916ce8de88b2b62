"""`drltg experiment PAIR --method M --seeds N --frames F --out DIR`: one transfer experiment.

    DIR/experiment.yaml        the experiment's settings (re-running with other settings is refused)
    DIR/source/seed-<s>/       source runs (methods with a source): the source task, no transfer
    DIR/baseline/seed-<s>/     target task, no transfer
    DIR/transfer/seed-<s>/     target task with the method; run i transfers from source run i
    DIR/report/                transfer_metrics.{json,csv}, transfer_plot.{png,svg} (drltg report)

A method without a source (reward shaping) needs only the target task, a pair's or one given alone:
its baseline learns from the task's plain reward and its transfer run with the method (both evaluated
on the task's own reward). A source given in the config (``-o transfer.source=RUN_DIR``, or
``-o transfer.source=demonstrator:lift`` for the methods that reuse a policy on the manipulation
tasks) serves every transfer run, no source runs are trained, and a task alone is a target; a source
written with ``{seed}`` (``-o transfer.source=sources/lift/seed-{seed}``) serves transfer run i from the
kept run of its own seed, ``sources/lift/seed-<seed + 100 i>``.
Baseline and transfer run i share the seed ``seed + 100 i`` (paired runs); source run i uses
``seed + 100 i + 50``, so no source and target run share a seed. A completed run is reused; an
interrupted one resumes from its checkpoint, so re-running the same command finishes what is missing.

Every run's config is built and checked (its task, env settings and learner) and the report settings
are parsed before anything is written; the folder is then owned by one ``drltg experiment`` at a time
(:func:`drltg.store.rundir.lock`). Runs are trained by :func:`drltg.experiments.executor.execute`, as a
sweep's are; each run's output and, if it fails, its traceback go to ``DIR/logs/<role>/seed-<s>.log``.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Sequence

import yaml

from drltg import config as config_lib
from drltg import safe_yaml
from drltg.analysis import figure_style, sequential
from drltg.analysis.figure_style import DEFAULT, FigureStyle
from drltg.config import RunConfig
from drltg.errors import RunFailed, UsageError
from drltg.store import rundir

SEED = "{seed}"  # in a given transfer.source: the transfer run's seed


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("pair", nargs="?", help="registered task pair (see `drltg tasks`); a task alone for a method "
                   "without a source, or with -o transfer.source=...")
    p.add_argument("--config", type=Path, metavar="FILE",
                   help="the settings as YAML, e.g. an experiment's experiment.yaml to run it again (pair, method, "
                        "algo, seeds, max_seeds, seed, frames, source_frames, source_success, overrides); the "
                        "command line's own settings win")
    p.add_argument("--dry-run", action="store_true", help="list the runs, what each run's folder holds already, the "
                   "units of work and the frames left; train nothing")
    p.add_argument("--method", help="transfer method (`drltg tasks` lists them)")
    p.add_argument("--algo", help="learner (default sac)")
    p.add_argument("--seeds", type=seed_count,
                   help="runs per side (default 5), or 'auto': paired seeds in rounds until the exact sign-flip "
                        "test decides the mean return gain, at most --max-seeds (drltg.analysis.sequential)")
    p.add_argument("--max-seeds", type=int, default=None,
                   help=f"the most pairs --seeds auto trains (default {AUTO_MAX_SEEDS})")
    p.add_argument("--seed", type=int, help="first seed (default 0)")
    p.add_argument("--frames", type=config_lib.frame_count,
                   help="frame budget of each target run (50000, 50k, 1e4, 1.5M)")
    p.add_argument("--source-frames", type=config_lib.frame_count,
                   help="frame budget of each source run (default --frames)")
    p.add_argument("--source-success", type=float, metavar="RATE",
                   help="end each source run at its first evaluation whose success rate reaches RATE (its "
                        "eval.stop_at_success), --source-frames its cap: sources reused at one success criterion")
    p.add_argument("--out", type=Path, required=True, help="experiment directory")
    p.add_argument("--workers", type=int, default=1, help="runs trained in parallel processes (default 1)")
    p.add_argument("--no-seed-groups", action="store_true",
                   help="train every run in its own task (default: runs that differ only in their seed train as one "
                        "seed group where the learner supports it)")
    p.add_argument("-o", "--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="config override applied to every run, e.g. -o transfer.upsilon=0.9")
    p.add_argument("--threshold", help="report threshold: a value, or a fraction of the best baseline like 80%%")
    p.add_argument("--value-range", metavar="LOW,HIGH",
                   help="the range every evaluation return lies in, for a task that declares none (e.g. -50,0)")
    figure_style.add_arguments(p)
    p.add_argument("--no-progress", action="store_true", help="no progress bar (none is drawn when stderr is not "
                   "a terminal)")


def seed_count(text: str) -> int | str:
    """``--seeds``: a whole number or ``auto``."""
    if text == "auto":
        return text
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a whole number or 'auto', got {text!r}") from None


MAX_SEEDS = config_lib.MAX_SEEDS
"""The most runs a side one experiment plans (a larger count is a typo, and planning it would take long)."""
SEED_MAX = 2**31 - 1
PLAN_KEYS = {"task": "the PAIR argument", "algo": "--algo", "seed": "--seed", "frames": "--frames or --source-frames",
             "transfer.method": "--method", "eval.stop_at_success": "--source-success"}
"""The config keys an experiment sets per run, and the option that sets them."""


def owned_keys(key: str, value) -> list[str]:
    """The per-run keys (``PLAN_KEYS``) that setting ``key`` to ``value`` would set: the key itself, or the
    keys of a section given as a mapping (``transfer={method: x}`` sets ``transfer.method``)."""
    if isinstance(value, dict):
        return [k for sub, v in value.items() for k in owned_keys(f"{key}.{sub}", v)]
    return [key] if key in PLAN_KEYS else []


def refuse_plan_overrides(overrides, where: str, owner: str, flags: dict[str, str]) -> None:
    """Refuse, in one sentence, an override (``KEY=VALUE`` or a ``(key, value)`` pair) of a key the
    plan sets per run: it would give every run, the baseline included, the same value."""
    for item in overrides:
        key, value = config_lib.parse_override(item) if isinstance(item, str) else item
        for owned in owned_keys(str(key), value):
            given = "" if owned == key else f" (through '{key}')"
            raise UsageError(f"{where} may not set '{owned}'{given}: the {owner} sets it per run; "
                             f"use {flags[owned]} instead.")


def _check_counts(method: str, *, frames: int, seeds: int, seed: int, source_frames: int | None,
                  source_success: float | None) -> None:
    """One sentence for an experiment's method, budgets, seed counts or source criterion that cannot be run."""
    if method == "none":
        raise UsageError("--method none has nothing to compare; choose a transfer method (`drltg tasks`).")
    if seeds < 1 or frames < 1:
        raise UsageError("--seeds and --frames must be positive.")
    if source_frames is not None and source_frames < 1:
        raise UsageError(f"--source-frames must be positive, got {source_frames}; omit it to give source runs "
                         "--frames.")
    if source_success is not None and not (isinstance(source_success, (int, float)) and 0 < source_success <= 1):
        raise UsageError(f"--source-success must be a success rate in (0, 1], got {source_success!r}.")
    if seeds > MAX_SEEDS:
        raise UsageError(f"--seeds {seeds} is more than the {MAX_SEEDS} runs a side an experiment plans; "
                         "split it into experiments with different --seed.")
    if not 0 <= seed <= SEED_MAX - 100 * (seeds - 1) - 50:
        raise UsageError(f"--seed {seed} with --seeds {seeds} gives run seeds outside [0, {SEED_MAX}] "
                         f"(run i uses seed + 100 i, its source seed + 100 i + 50).")


def plan_runs(
    pair: str,
    method: str,
    *,
    frames: int,
    out: Path,
    shared: Path | None = None,
    algo: str = "sac",
    seeds: int = 5,
    seed: int = 0,
    source_frames: int | None = None,
    source_success: float | None = None,
    base: dict | None = None,
    overrides: list[str] = (),
) -> list[tuple[str, RunConfig, Path]]:
    """One experiment's runs as (role, config, run directory), sources first.

    Transfer runs go to ``out/transfer``, source and baseline runs to ``shared/{source,baseline}``
    (``shared`` defaults to ``out``; several methods' experiments can share one). ``base`` holds
    config keys (``{"eval.every": 1000}``) applied before the ``KEY=VALUE`` ``overrides``;
    ``source_success`` is the source runs' ``eval.stop_at_success`` (theirs only: every target trains its budget;
    ignored where no source run is planned).
    """
    from drltg.envs import PAIRS, TASKS
    from drltg.transfer import get_method

    refuse_plan_overrides(overrides, "-o", "experiment", PLAN_KEYS)
    spec = get_method(method)
    _check_counts(spec.name, frames=frames, seeds=seeds, seed=seed, source_frames=source_frames,
                  source_success=source_success)
    if pair in PAIRS:
        source_task, target_task = PAIRS[pair].source, PAIRS[pair].target
    elif pair in TASKS:  # a task alone: the method needs no source, or the config names one
        source_task, target_task = None, pair
    else:
        from drltg.envs import get_pair

        get_pair(pair)  # raises the "unknown pair" sentence
    given_source = config_lib.resolve(base, overrides, task=target_task, algo=algo).transfer.source
    needs_source = spec.source is not None
    if source_task is None and needs_source and given_source is None:
        raise UsageError(f"'{pair}' is a task, not a pair: {method} on it needs -o transfer.source=RUN_DIR "
                         f"(or demonstrator:TASK); `drltg tasks` lists the pairs.")
    out = Path(out).expanduser().resolve()
    shared = out if shared is None else Path(shared).expanduser().resolve()

    per_seed = given_source is not None and SEED in str(given_source)

    def cfg(task, seed, frames, method=None, source=None):
        """A run's config: the method named (a registered name), the source set as the path it is, never
        parsed again from text (a '#' or ': ' in a path would be YAML); a source given in the config serves
        the transfer runs only, so source and baseline runs have none."""
        over = [*overrides, f"transfer.method={method}"] if method else list(overrides)
        resolved = config_lib.resolve(base, over, task=task, algo=algo, frames=frames, seed=seed)
        return config_lib.updated(resolved, {"transfer.source": None if source is None else str(source)})

    runs = []
    for i in range(seeds):
        seed_i = config_lib.run_seeds(seed, seeds)[i]
        baseline = ("baseline", cfg(target_task, seed_i, frames), shared / "baseline" / f"seed-{seed_i}")
        if not needs_source or given_source is not None:  # no source runs to train
            sources, source = [], given_source
            if per_seed:  # the kept run of this seed, as its saved config reads it back
                source = Path(str(given_source).replace(SEED, str(seed_i))).expanduser().resolve()
        else:
            source = shared / "source" / f"seed-{config_lib.source_seed(seed_i)}"
            source_cfg = cfg(source_task, config_lib.source_seed(seed_i), source_frames or frames)
            if source_success is not None:
                source_cfg = config_lib.updated(source_cfg, {"eval.stop_at_success": float(source_success)})
            sources = [("source", source_cfg, source)]
        runs += [*sources, baseline,
                 ("transfer", cfg(target_task, seed_i, frames, method, source), out / "transfer" / f"seed-{seed_i}")]
    return runs


def check_runs(runs: list[tuple[str, RunConfig, Path]]) -> None:
    """Build the task env and the learner of every distinct run config, and check the transfer section
    of those whose source is not one of ``runs``: a mistake fails here, before anything is written."""
    from drltg.training.loop import check_config
    from drltg.transfer.source import check as check_source

    planned = {str(d) for _, _, d in runs}
    seen = set()
    for _, cfg, _ in runs:
        source = cfg.transfer.source
        if source is None or str(source) not in planned:
            check_source(cfg)
        key = json.dumps({**cfg.model_dump(), "seed": 0, "frames": 0, "transfer": cfg.transfer.method}, sort_keys=True,
                         default=str)
        if key not in seen:
            seen.add(key)
            check_config(cfg)


def as_runs(runs: list[tuple[str, RunConfig, Path]], out: Path) -> list:
    """The plan as :class:`drltg.experiments.executor.Run` s: logs under ``out/logs/<role>/``, each transfer run
    after the source run it reads."""
    from drltg.experiments.executor import Run

    planned = {str(d) for _, _, d in runs}
    return [Run(role, cfg, d, out / "logs" / role / f"{d.name}.log",
                needs=Path(cfg.transfer.source) if str(cfg.transfer.source) in planned else None)
            for role, cfg, d in runs]


def check_existing(runs: list) -> None:
    """Refuse, before anything runs, a directory that holds a run with another config."""
    from drltg.config import config_changes

    for run in runs:
        saved = rundir.check_directory(run.path, "run directory") / rundir.CONFIG
        if saved.is_file():
            old = rundir.read_config(run.path)
            keys = config_changes(old if isinstance(old, dict) else {}, run.cfg)
            if keys:
                raise UsageError(f"'{run.path}' holds a run with another config (differs in {', '.join(keys)}); "
                                 "use another --out.")
        elif rundir.entries(run.path):
            raise UsageError(f"'{run.path}' exists but holds no config.yaml; move it away or use another --out.")


def make_out(runs: list, out: Path, reports: Sequence[Path]) -> None:
    """The last checks before any work, then ``out`` made: no link or odd file where a run, a log or a report
    is written (:func:`~drltg.store.rundir.refuse_links`), no run directory holds another run
    (:func:`check_existing`), what a script registered reaches the workers
    (:func:`~drltg.experiments.executor.registrations`)."""
    from drltg.experiments.executor import frames_file, registrations

    rundir.refuse_links(out, folders=[*(r.path for r in runs), *reports],
                        files=[f for r in runs for f in (r.log, frames_file(r.log))])
    check_existing(runs)
    registrations(runs)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise UsageError(f"cannot create --out '{out}' ({err.strerror}).") from None


AUTO_MAX_SEEDS = 20
"""The most pairs ``--seeds auto`` trains unless ``--max-seeds`` says otherwise."""

GROWS = ("seeds",)
"""Settings an experiment folder of a fixed seed count may be run again with: more (or fewer) seeds train what
is new and report the planned pairs; the runs already there are reused. A ``--seeds auto`` folder continues
only under its own plan (:func:`_check_plan`)."""


def check_settings(path: Path, settings: dict) -> None:
    """Refuse ``path`` (an experiment's ``experiment.yaml``) if it holds other settings than ``settings``
    beyond :data:`GROWS`, naming each one with its value there and here."""
    if not path.is_file():
        return
    saved = safe_yaml.load_file(path)
    if not isinstance(saved, dict):
        raise UsageError(f"'{path}' holds no experiment settings; move it away or use another --out.")
    # "out" and "imports" were kept by earlier versions; neither changes what the runs are
    saved = {k: v for k, v in saved.items() if k not in ("out", "imports")}
    _check_plan(path.parent, saved, settings)
    differ = [k for k in [*settings, *(k for k in saved if k not in settings)]
              if k not in (*GROWS, "max_seeds") and saved.get(k) != settings.get(k)]
    if differ:
        changes = "; ".join(f"{k} is {saved.get(k)!r} there, {settings.get(k)!r} now" for k in differ)
        raise UsageError(f"'{path.parent}' holds an experiment with other settings ({changes}); run it with its "
                         "settings (only --seeds may change: more seeds train the new ones), or choose another --out.")


def _check_plan(out: Path, saved: dict, settings: dict) -> None:
    """Refuse to change how an experiment counts its seeds once it has reported. A ``--seeds auto`` plan
    splits 0.05 over looks fixed before its first seed: a fixed count after it reports one more test at the
    full level, uncorrected for the looks already taken, and another cap moves every look's share. A plan
    started over a fixed-count folder would not be planned before the result it was seen with."""
    was, now = saved.get("seeds"), settings.get("seeds")
    if was == "auto" and now != "auto":
        raise UsageError(f"'{out}' holds a --seeds auto experiment, whose looks already spent its level; continue "
                         f"it with --seeds auto --max-seeds {saved.get('max_seeds')}, or train --seeds {now} into "
                         "another --out.")
    if was == "auto" and saved.get("max_seeds") != settings.get("max_seeds"):
        raise UsageError(f"'{out}' holds a --seeds auto experiment planned for --max-seeds {saved.get('max_seeds')}, "
                         "and another cap would change the share of each look already taken; continue it with "
                         f"--max-seeds {saved.get('max_seeds')}, or start the new plan in another --out.")
    if was is not None and was != "auto" and now == "auto":
        raise UsageError(f"'{out}' holds an experiment of --seeds {was} already reported, and a sequential plan "
                         "must be fixed before its first seed; start --seeds auto in another --out, or grow this "
                         "one with a --seeds count.")


def experiment(pair: str, method: str, *, frames: int | str, out: str | Path, seeds: int | str = 5, seed: int = 0,
               algo: str = "sac", source_frames: int | str | None = None, source_success: float | None = None,
               overrides: Sequence[str] = (),
               threshold: float | str | None = None, workers: int = 1, group_seeds: bool = True,
               progress: bool = True, max_seeds: int | None = None, value_range=None,
               dry_run: bool = False, figure: FigureStyle = DEFAULT) -> dict:
    """Train one experiment's source, baseline and transfer runs into ``out`` and report the transfer runs
    against the baselines; what is finished is reused and what was interrupted resumes.

    The arguments are ``drltg experiment``'s (frame counts as ``20000``, ``"20k"`` or ``"1e4"``;
    ``overrides`` as ``["transfer.upsilon=0.9"]``; ``value_range`` as ``(-50, 0)``, for a task that declares no
    return range; ``figure`` how the report's plot is drawn, a
    :class:`~drltg.analysis.figure_style.FigureStyle`). Returns the report, :func:`drltg.report.
    transfer_report`'s dict, with ``"diverged"``: the runs left out of it because their losses diverged.
    Raises :class:`~drltg.errors.UsageError` for a bad setting, before anything is written, and
    :class:`~drltg.errors.RunFailed` naming every run that failed.

    ``dry_run`` checks everything and returns ``{"plan": lines}``, the runs listed with what their folders
    hold, training nothing.

    ``seeds="auto"`` trains paired seeds in rounds, as :mod:`drltg.analysis.sequential` plans them up to
    ``max_seeds`` pairs (:data:`AUTO_MAX_SEEDS` unless given, and only then), and stops at the first round
    whose exact sign-flip test of the mean return gain decides at its share of the level; the report's
    ``settings.sequential`` records the plan, the looks taken and why it stopped, and
    ``mean_return_gain_verdict`` is the plan's verdict.

        >>> report = drltg.experiment("fourrooms-near", "policy-reuse", seeds=3, frames="20k", out="runs/near")
        >>> report["metrics"]["mean_return_gain"], report["out_dir"]
    """
    frames, source_frames = (None if f is None else config_lib.frame_count(str(f)) for f in (frames, source_frames))
    if workers < 1:
        raise UsageError("--workers must be at least 1.")
    if seeds == "auto":
        max_seeds = AUTO_MAX_SEEDS if max_seeds is None else max_seeds
        if isinstance(max_seeds, bool) or not isinstance(max_seeds, int) or not 1 <= max_seeds <= MAX_SEEDS:
            raise UsageError(f"--max-seeds must be a whole number from 1 to {MAX_SEEDS}, got {max_seeds!r}.")
        plan = sequential.looks(max_seeds)
        if dry_run:  # the plan at its cap: what the last look would have trained
            planned = _run(pair, method, frames, out, plan[-1].pairs, seed, algo, source_frames, overrides, threshold,
                           workers, group_seeds, progress, {"seeds": "auto", "max_seeds": max_seeds},
                           value_range=value_range, source_success=source_success, dry_run=True)
            looks = ", ".join(str(look.pairs) for look in plan)
            return {"plan": [f"--seeds auto: looks at {looks} pairs, each at {plan[0].alpha:.3g} of 0.05; the runs "
                             "to its cap:", *planned["plan"]]}
        taken, result = [], {}
        for k, look in enumerate(plan, 1):
            result = _run(pair, method, frames, out, look.pairs, seed, algo, source_frames, overrides, threshold,
                          workers, group_seeds, progress, {"seeds": "auto", "max_seeds": max_seeds},
                          value_range=value_range, source_success=source_success, figure=figure)
            p = result["metrics"].get("mean_return_gain_verdict_p", 1.0)
            taken.append(p)
            if progress:
                went = "decided" if p < look.alpha else ("at the cap" if k == len(plan) else "adding seeds")
                print(f"look {k} of {len(plan)}: {look.pairs} pairs, exact sign-flip p = {p:.3g} against its share "
                      f"{look.alpha:.3g} of 0.05: {went}", file=sys.stderr)
            if p < look.alpha:
                break
        return _with_sequential(result, sequential.record(plan, taken))
    if isinstance(seeds, bool) or not isinstance(seeds, int):
        raise UsageError(f"--seeds must be a whole number or 'auto', got {seeds!r}.")
    if max_seeds is not None:
        raise UsageError(f"--max-seeds caps --seeds auto; with --seeds {seeds} it would do nothing, so leave it out.")
    return _run(pair, method, frames, out, seeds, seed, algo, source_frames, overrides, threshold, workers,
                group_seeds, progress, {"seeds": seeds}, value_range=value_range, source_success=source_success,
                dry_run=dry_run, figure=figure)


def _with_sequential(result: dict, record: dict) -> dict:
    """The last look's report with the plan's record and verdict, written back to its transfer_metrics.json."""
    from drltg.report.outputs import json_text

    m = result["metrics"]
    gain = m.get("mean_return_gain") or 0.0
    verdict = ("higher" if gain > 0 else "lower") if record["stopped"] == "decided" and gain != 0 else "undecided"
    m.update({"mean_return_gain_verdict": verdict, "mean_return_gain_verdict_test": "sign-flip, sequential",
              "mean_return_gain_verdict_p": record["taken"][-1]["p"]})
    result["settings"]["sequential"] = record
    path = Path(result["out_dir"]) / "transfer_metrics.json"
    saved = json.loads(path.read_text())
    saved["metrics"].update({k: m[k] for k in ("mean_return_gain_verdict", "mean_return_gain_verdict_test",
                                               "mean_return_gain_verdict_p")})
    saved["settings"]["sequential"] = record
    rundir.atomic_write(path, json_text(saved))
    return result


def _run(pair, method, frames, out, seeds, seed, algo, source_frames, overrides, threshold, workers, group_seeds,
         progress, counted: dict, value_range=None, source_success=None, dry_run: bool = False,
         figure: FigureStyle = DEFAULT) -> dict:
    """One experiment of ``seeds`` pairs (``counted``: how its settings name the seed count); with ``dry_run``,
    its checks and ``{"plan": lines}`` listing its runs (:func:`~drltg.experiments.executor.plan_lines`)."""
    from drltg.experiments.executor import check_order, plan_lines
    from drltg.report import parse_threshold
    from drltg.report.settings import parse_range

    parse_threshold(threshold)
    parse_range(value_range)
    out = rundir.check_directory(out, "--out")
    rundir.refuse_run_directory(out, "--out")
    overrides = list(overrides)
    config_lib.refuse_conflicts(overrides)
    runs = plan_runs(pair, method, algo=algo, seeds=seeds, seed=seed, frames=frames, source_frames=source_frames,
                     source_success=source_success, overrides=overrides, out=out)
    if source_success is not None and not any(role == "source" for role, _, _ in runs):
        raise UsageError(f"--source-success applies to the source runs an experiment trains, and {method} on "
                         f"'{pair}' trains none; leave it out.")
    check_runs(runs)
    settings = {"pair": pair, "method": method, "algo": algo, **counted, "seed": seed, "frames": frames,
                "source_frames": source_frames, **({"source_success": source_success} if source_success else {}),
                "overrides": overrides}
    saved = out / "experiment.yaml"
    check_settings(saved, settings)
    planned = as_runs(runs, out)
    check_order(planned)
    if dry_run:
        return {"plan": plan_lines(planned, out, 1, group_seeds)}
    make_out(planned, out, [out / "report"])
    return execute_and_report(runs, out, saved, settings, workers=workers, name="experiment", threshold=threshold,
                              method=method, group_seeds=group_seeds, progress=progress, value_range=value_range,
                              figure=figure)


SETTINGS = {"pair": None, "method": None, "algo": "sac", "seeds": 5, "max_seeds": None, "seed": 0, "frames": None,
            "source_frames": None, "source_success": None}
"""What ``--config`` may hold besides ``overrides`` (an ``experiment.yaml``'s keys), with the defaults of those
given neither there nor on the command line."""


def settings_of(args: argparse.Namespace) -> dict:
    """The experiment's settings: the command line's, then ``--config``'s, then :data:`SETTINGS`' defaults. The
    file's overrides come first and the command line's after them; a key both set keeps the command line's."""
    given = {} if args.config is None else config_lib.load_yaml(args.config, "--config")
    given = {k: v for k, v in given.items() if k not in ("out", "imports")}  # kept by earlier versions
    unknown = sorted(set(given) - set(SETTINGS) - {"overrides"})
    if unknown:
        raise UsageError(f"--config '{args.config}' holds {', '.join(map(repr, unknown))}, no experiment setting; "
                         f"it may hold {', '.join([*SETTINGS, 'overrides'])}.")
    overrides = given.get("overrides") or []
    if not isinstance(overrides, list) or not all(isinstance(o, str) for o in overrides):
        raise UsageError(f"--config '{args.config}': overrides must be a list of KEY=VALUE strings.")
    mine = {config_lib.parse_override(o)[0] for o in args.overrides}
    settings = {key: next((v for v in (getattr(args, key), given.get(key)) if v is not None), default)
                for key, default in SETTINGS.items()}
    settings["overrides"] = [o for o in overrides if config_lib.parse_override(o)[0] not in mine] + args.overrides
    missing = [f"--{k}" if k != "pair" else "a pair" for k in ("pair", "method", "frames") if settings[k] is None]
    if missing:
        raise UsageError(f"name {', '.join(missing)} on the command line or in --config FILE.")
    return settings


def run(args: argparse.Namespace) -> int:
    settings = settings_of(args)
    options = dict(frames=settings["frames"], out=args.out, seeds=settings["seeds"], seed=settings["seed"],
                   algo=settings["algo"], source_frames=settings["source_frames"],
                   source_success=settings["source_success"], overrides=settings["overrides"],
                   threshold=args.threshold, workers=args.workers, group_seeds=not args.no_seed_groups,
                   progress=not args.no_progress, max_seeds=settings["max_seeds"], value_range=args.value_range,
                   figure=figure_style.from_args(args))
    if args.dry_run:
        print("\n".join(experiment(settings["pair"], settings["method"], **options, dry_run=True)["plan"]))
        return 0
    try:
        result = experiment(settings["pair"], settings["method"], **options)
    except RunFailed as err:
        print(err)
        return 1
    print_report(result)
    return 1 if result["diverged"] else 0


def print_report(result: dict) -> None:
    """What the commands print of an experiment's report: its warnings (on stderr, as ``drltg report``
    prints them), the diverged runs, the table, the headline."""
    from drltg.analysis.claims import headline
    from drltg.report import format_table

    for w in result["settings"]["warnings"]:
        print(f"warning: {w}", file=sys.stderr)
    if result["diverged"]:
        print("diverged runs (left out of the report):\n  " + "\n  ".join(result["diverged"]))
    print(format_table(result))
    print("\n" + headline(result))
    print(f"\nreport: {result['out_dir']}")


def execute_and_report(runs, out: Path, saved: Path, settings: dict, *, workers: int, name: str, threshold,
                       method: str, group_seeds: bool = True, progress: bool = True, value_range=None,
                       figure: FigureStyle = DEFAULT) -> dict:
    """Under the folder's lock: save the settings, train every run not finished yet on ``workers``
    processes, then report the transfer runs against the baselines (the report's dict, with ``"diverged"``:
    the runs left out of it). Raises :class:`~drltg.errors.RunFailed` if a run failed: no report then."""
    from drltg.experiments.backends import LocalBackend
    from drltg.experiments.executor import execute
    from drltg.report import transfer_report

    with rundir.lock(out, f"{name} folder"):
        check_settings(saved, settings)  # another process may have started it meanwhile
        rundir.atomic_write(saved, yaml.safe_dump(settings, sort_keys=False))
        backend = LocalBackend(workers)
        try:
            status = execute(as_runs(runs, out), backend, desc=name, group_seeds=group_seeds, progress=progress)
        finally:
            backend.close()
        failures = [f"{path}: {detail}" for path, (state, detail) in status.items() if state == "failed"]
        if failures:
            raise RunFailed("failed runs:\n  " + "\n  ".join(failures))
        diverged = [f"{path}: {detail}" for path, (state, detail) in status.items() if state == "diverged"]
        result = transfer_report(
            [d for role, _, d in runs if role == "baseline"],
            [d for role, _, d in runs if role == "transfer"],
            out / "report",
            threshold=threshold,
            value_range=value_range,
            baseline_label="no transfer",
            transfer_label=method,
            figure=figure,
        )
    never = never_succeeded([d for role, _, d in runs if role == "source"])
    if never:
        result["settings"]["warnings"].insert(0, f"{len(never)} source run(s) never succeeded in any evaluation "
                                              f"({', '.join(never)}): the transfer runs reuse what did not solve the "
                                              "source task, so the comparison says little about transfer.")
    return {**result, "diverged": diverged}


def never_succeeded(run_dirs: Sequence[Path]) -> list[str]:
    """The runs among ``run_dirs`` whose ``eval.csv`` records a success rate that is 0 at every evaluation (a
    task without one is not judged here; the report checks the threshold)."""
    never = []
    for run in run_dirs:
        try:
            rates = [row.get("success_rate") for row in rundir.read_eval_csv(run / rundir.EVAL)]
        except UsageError:
            continue
        if rates and all(r not in (None, "") for r in rates) and max(float(r) for r in rates) == 0:
            never.append(str(run))
    return never
