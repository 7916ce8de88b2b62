"""`drltg sweep SPEC --out DIR`: many transfer experiments from one YAML spec, on a process pool or Ray.

The spec is a grid (every list is one axis; a scalar is a one-value axis)::

    pairs: [fourrooms-near, fourrooms-far]     # registered task pairs (see `drltg tasks`), or a task
                                               # alone for methods without a source or a given one
    methods: [reward-shaping, policy-reuse, model-reuse]
    algos: [sac]                               # default [sac]
    seeds: 5                                   # runs per side (default 5); first seed `seed` (default 0)
    frames: 20000                              # target budget; a list sweeps it
    source_frames: 40000                       # source budget (default: frames); a list sweeps it
    source_success: 0.9                        # sources end at the first evaluation with this success
                                               # rate (eval.stop_at_success), source_frames their cap
    overrides: {eval.every: 1000}              # config keys of every run (a transfer.source given
                                               # here serves every transfer run: no source runs;
                                               # DIR/seed-{seed}: each its own seed's kept run)
    grid: {optim.lr: [3.0e-4, 1.0e-3]}         # config keys swept, each a list
    threshold: 0.5                             # report threshold: a value or "80%"
    primary_metric: mean_return_gain           # the comparison the summary's headline counts, named in
                                               # advance (default: every interval of the summary)
    resources: {num_cpus: 1, num_gpus: 0}      # per run, for --backend ray

Each (pair, algo, variant, method) is one ``drltg experiment`` (same runs, same paired and spaced
seeds: ``seed + 100 i`` for baseline and transfer run i, ``+ 50`` for its source), laid out as

    DIR/<pair>/<algo>[/<variant>]/source/seed-<s>/     shared by every method that needs a source
    DIR/<pair>/<algo>[/<variant>]/baseline/seed-<s>/   shared by every method
    DIR/<pair>/<algo>[/<variant>]/<method>/transfer/seed-<s>/
    DIR/<pair>/<algo>[/<variant>]/<method>/report/     drltg report of transfer vs baseline
    DIR/logs/<same relative path>.log                  each run's output and traceback
    DIR/runs.csv                                       each run's status (done, failed, skipped) and log
    DIR/summary.{csv,md}, DIR/transfer_matrix.png      all reports in one table and one heatmap; the
                                                       headline counts findings after Holm's adjustment
                                                       over its family (the primary metric's p-values)

``<variant>`` (e.g. ``frames=20000,optim.lr=0.001``) names the point on the swept axes; it is absent
when nothing but pairs, algos, methods and seeds varies. Runs are deduplicated by their resolved
config: a run that several experiments need (the baseline of every method, a source shared by
policy and model reuse) trains once, in the first place the expansion order puts it.

Re-running is safe: complete runs (``summary.json`` in place, written last) are skipped, interrupted
ones resume from ``checkpoints/last.pt``, a failed run is reported with its log and the others go on.
The same spec gives the same run directories and, run by run, the same numbers on both backends.
Every run's task, env settings and learner are built once and the threshold parsed before anything is
written, and one sweep at a time owns DIR (:func:`drltg.store.rundir.lock`).
"""
from __future__ import annotations

import argparse
import itertools
import json
import math
import os
from dataclasses import dataclass
from pathlib import Path

import yaml

from drltg.analysis import figure_style
from drltg.analysis.figure_style import DEFAULT, FigureStyle
from drltg.config import RunConfig
from drltg.errors import UsageError
from drltg.experiments.backends import LocalBackend, RayBackend
from drltg.experiments.executor import Run, execute, plan_lines
from drltg.experiments.spec import Spec, load_spec, parse_spec
from drltg.experiments.summary import across_targets, plot_transfer_matrix, summary_aggregates, summary_tables
from drltg.store import rundir


# ------------------------------------------------------------------------------------------- plan
@dataclass
class Cell:
    """One report: transfer runs of ``method`` against the baseline runs of one (pair, algo, variant)."""

    pair: str
    algo: str
    variant: str
    method: str
    baseline: list[Path]
    transfer: list[Path]

    @property
    def report(self) -> Path:
        return self.transfer[0].parent.parent / "report"


def variants(spec: Spec) -> list[tuple[str, int, int | None, dict]]:
    """(name, frames, source_frames, grid values) for every point on the swept axes."""
    axes: list[tuple[str, list]] = []
    if len(spec.frames) > 1:
        axes.append(("frames", spec.frames))
    if spec.source_frames and len(spec.source_frames) > 1:
        axes.append(("source_frames", spec.source_frames))
    axes += [(k, v) for k, v in spec.grid.items()]
    out = []
    for point in itertools.product(*(values for _, values in axes)):
        values = dict(zip((k for k, _ in axes), point))
        name = ",".join(f"{k}={v}" for k, v in values.items()).replace("/", "_")
        frames = values.pop("frames", spec.frames[0])
        source_frames = values.pop("source_frames", spec.source_frames[0] if spec.source_frames else None)
        out.append((name, frames, source_frames, values))
    return out


def _key(cfg: RunConfig) -> str:
    """A run's identity: its resolved config, the options of methods it does not use at their defaults (a
    baseline is one run whatever a grid sets another method's knobs to), so such a run trains once."""
    from drltg import config as config_lib

    data = cfg.model_dump()
    used = set(cfg.transfer.method.split("+"))
    defaults = config_lib.defaults()["transfer"]
    owners = config_lib.option_owners()
    data["transfer"] = {k: defaults[k] if owners.get(k, cfg.transfer.method) not in used else v
                        for k, v in data["transfer"].items()}
    return json.dumps(data, sort_keys=True, default=str)


def plan(spec: Spec, out: Path) -> tuple[list[Run], list[Cell]]:
    """Expand the spec into unique runs (each after the run it needs) and the reports to write."""
    from drltg.experiments.experiment import plan_runs

    out = Path(out).expanduser().resolve()
    home: dict[str, Path] = {}  # resolved config -> the one directory that trains it
    moved: dict[Path, Path] = {}  # planned directory -> that directory
    runs: dict[Path, Run] = {}
    cells = []
    for pair, algo, (variant, frames, source_frames, values) in itertools.product(
        spec.pairs, spec.algos, variants(spec)
    ):
        group = out / pair / algo / variant if variant else out / pair / algo
        for method in spec.methods:
            planned = plan_runs(pair, method, algo=algo, seeds=spec.seeds, seed=spec.seed, frames=frames,
                                source_frames=source_frames, source_success=spec.source_success,
                                base={**spec.overrides, **values},
                                out=group / method, shared=group)
            sides: dict[str, list[Path]] = {"baseline": [], "transfer": []}
            for role, cfg, path in planned:
                needs = moved.get(Path(str(cfg.transfer.source)))  # None: no source, or one given
                if needs is not None:
                    cfg.transfer.source = str(needs)
                moved[path] = home.setdefault(_key(cfg), path)
                path = moved[path]
                if path in runs and _key(runs[path].cfg) != _key(cfg):
                    raise UsageError(f"two runs of the spec would share '{path}'; check the grid values.")
                log = out / "logs" / path.relative_to(out).with_suffix(".log")
                if path not in runs:
                    rundir.check_name_lengths(log, "the run log")
                    rundir.check_name_lengths(path / "checkpoints" / f".last.pt.{'x' * 8}.tmp", "the run directory")
                runs.setdefault(path, Run(role, cfg, path, log, needs))
                sides.get(role, []).append(path)
            cells.append(Cell(pair, algo, variant, method, sides["baseline"], sides["transfer"]))
    return list(runs.values()), cells


# ---------------------------------------------------------------------------------------- reports
def write_reports(cells: list[Cell], status: dict, threshold, value_range=None,
                  figure: FigureStyle = DEFAULT) -> list[dict]:
    """One ``drltg report`` per cell whose runs are all complete (its plot drawn as ``figure`` says); a row per
    cell for the summary."""
    from drltg.report import transfer_report

    rows = []
    for c in cells:
        row = {"pair": c.pair, "algo": c.algo, "variant": c.variant, "method": c.method,
               "report": str(c.report), "metrics": None}
        states = [status.get(p, ("",))[0] for p in c.baseline + c.transfer]
        missing = sum(state not in ("done", "skipped", "diverged") for state in states)
        diverged = states.count("diverged")
        if missing:
            row["note"] = f"{missing} run(s) incomplete"
        else:
            try:
                result = transfer_report(c.baseline, c.transfer, c.report, threshold=threshold,
                                         value_range=value_range, baseline_label="no transfer",
                                         transfer_label=c.method, figure=figure)
                row["metrics"] = result["metrics"]
                row["per_seed"], row["value_range"] = result["per_seed"], result["settings"].get("value_range")
                if diverged:
                    row["note"] = f"{diverged} run(s) diverged, left out"
            except UsageError as err:
                row["note"] = str(err)
        rows.append(row)
    return rows


# ---------------------------------------------------------------------------------------------- CLI
def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("spec", type=Path, help="sweep spec (YAML), e.g. examples/sweeps/fourrooms.yaml")
    p.add_argument("--out", type=Path, required=True, help="sweep directory (re-run to resume)")
    p.add_argument("--backend", choices=("local", "ray"), default="local",
                   help="local: a process pool on this machine (default); ray: Ray tasks")
    p.add_argument("--no-seed-groups", action="store_true",
                   help="train every run in its own task (default: runs that differ only in their seed train as one "
                        "seed group where the learner supports it)")
    p.add_argument("--workers", type=int, default=os.cpu_count(),
                   help="local: runs in parallel (default: the CPU count); ray without --address: "
                        "CPUs of the local Ray instance")
    p.add_argument("--address", help="ray: a running cluster ('auto' or HOST:PORT); default: start a local one")
    p.add_argument("--num-cpus", type=float, help="ray: CPUs per run (overrides the spec's resources)")
    p.add_argument("--num-gpus", type=float, help="ray: GPUs per run (overrides the spec's resources)")
    p.add_argument("--metric", default="mean_return_gain",
                   help="the metric of the transfer-matrix heatmap (default: mean_return_gain)")
    p.add_argument("--dry-run", action="store_true", help="list the runs and reports, what each run's folder "
                   "holds already and the frames left; run nothing")
    p.add_argument("--no-progress", action="store_true", help="no progress bar (none is drawn when stderr is not "
                   "a terminal)")
    figure_style.add_arguments(p)


def sweep(spec: str | Path | dict, out: str | Path, *, backend: str = "local", workers: int | None = None,
          address: str | None = None, num_cpus: float | None = None, num_gpus: float | None = None,
          metric: str = "mean_return_gain", group_seeds: bool = True, progress: bool = True,
          figure: FigureStyle = DEFAULT) -> dict:
    """Train a sweep's runs into ``out`` (what is finished is reused, what was interrupted resumes) and
    write a report per cell and the summary; the arguments are ``drltg sweep``'s, ``spec`` a YAML file or
    the same mapping (``{"pairs": [...], "methods": [...], "seeds": 5, "frames": 20000}``), ``figure`` how
    every plot is drawn (:class:`~drltg.analysis.figure_style.FigureStyle`).

    Returns ``{"rows": one per report (pair, algo, variant, method, report folder, metrics or a note),
    "status": {run directory: (status, detail)}, "summary": the summary table as Markdown, "logs": {run
    directory: its log file}}``. A run that failed or diverged is in ``status``; the reports leave it out.

        >>> result = drltg.sweep("examples/sweeps/fourrooms.yaml", "runs/sweep", workers=2)
    """
    from drltg.experiments.experiment import check_existing, check_runs, make_out
    from drltg.report import check_metric

    if workers is not None and workers < 1:
        raise UsageError("--workers must be at least 1.")
    check_metric(metric)
    if isinstance(spec, dict):
        parsed, text = parse_spec(spec), yaml.safe_dump(spec, sort_keys=False).encode()
    else:
        parsed, text = load_spec(spec), Path(spec).read_bytes()
    resources = _resources_for(parsed, num_cpus, num_gpus, backend, address)
    out = rundir.check_directory(out, "--out")
    rundir.refuse_run_directory(out, "--out")
    runs, cells = plan(parsed, out)
    check_runs([(r.role, r.cfg, r.path) for r in runs])
    make_out(runs, out, [c.report for c in cells])
    with rundir.lock(out, "sweep folder"):
        check_existing(runs)  # another sweep may have written them meanwhile
        if backend == "ray":
            pool = RayBackend(address, resources, num_cpus=workers)
        else:
            pool = LocalBackend(workers or os.cpu_count() or 1)
        try:
            rundir.write_files(out, {"sweep.yaml": text})
            status = execute(runs, pool, desc="sweep", group_seeds=group_seeds, progress=progress)
        finally:
            pool.close()
        return write_summary(parsed, out, runs, cells, status, metric, figure)


def run(args: argparse.Namespace) -> int:
    figure = figure_style.from_args(args)
    if args.dry_run:
        return _dry_run(args)
    result = sweep(args.spec, args.out, backend=args.backend, workers=args.workers, address=args.address,
                   num_cpus=args.num_cpus, num_gpus=args.num_gpus, metric=args.metric,
                   group_seeds=not args.no_seed_groups, progress=not args.no_progress, figure=figure)
    out, status = rundir.check_directory(args.out, "--out"), result["status"]
    print(result["summary"])
    counts = [s for s, _ in status.values()]
    failed = [path for path, (state, _) in status.items() if state == "failed"]
    for path in failed:
        log = result["logs"][path]
        print(f"failed: {path.relative_to(out)}: {status[path][1]}" + (f"\n        log: {log}" if log.exists() else ""))
    for path, (state, detail) in status.items():
        if state == "diverged":
            print(f"diverged: {path.relative_to(out)}: {detail}")
    diverged = f"{counts.count('diverged')} diverged, " if "diverged" in counts else ""
    print(f"{len(status)} runs: {counts.count('done')} done, {len(failed)} failed, {diverged}"
          f"{counts.count('skipped')} skipped (complete before); summary: {out / 'summary.md'}")
    return 1 if failed or "diverged" in counts else 0


def _dry_run(args: argparse.Namespace) -> int:
    """List the runs and reports of the spec, what each run's folder holds already, the units of work they
    train in and the frames left; run nothing."""
    from drltg.report import check_metric

    check_metric(args.metric)
    spec = load_spec(args.spec)
    _resources_for(spec, args.num_cpus, args.num_gpus, args.backend, args.address)
    out = rundir.check_directory(args.out, "--out")
    rundir.refuse_run_directory(out, "--out")
    runs, cells = plan(spec, out)
    print("\n".join(plan_lines(runs, out, len(cells), group_seeds=not args.no_seed_groups)))
    return 0


def _resources_for(spec: Spec, num_cpus: float | None, num_gpus: float | None, backend: str,
                   address: str | None) -> dict:
    """What each run asks of Ray: the spec's ``resources``, ``num_cpus`` / ``num_gpus`` where given, checked."""
    resources = {**spec.resources, **{k: v for k, v in (("num_cpus", num_cpus), ("num_gpus", num_gpus))
                                      if v is not None}}
    _check_resources(resources, backend, address)
    return resources


def _check_resources(resources: dict, backend: str, address: str | None) -> None:
    """Per-run resources must be finite and not negative; on the local Ray instance (no ``--address``) a
    run may not ask for more GPUs than this machine has, or Ray would wait for them forever."""
    for key, value in resources.items():
        if not math.isfinite(value) or value < 0:
            raise UsageError(f"--{key.replace('_', '-')} must be a finite number >= 0, got {value}.")
    if backend == "ray" and address is None and resources.get("num_gpus", 0) > 0:
        import torch

        if resources["num_gpus"] > torch.cuda.device_count():
            raise UsageError(f"each run asks for {resources['num_gpus']:g} GPU(s) but this machine has "
                             f"{torch.cuda.device_count()}; the local Ray instance could never start one. Use "
                             "--num-gpus 0, or --address of a cluster with GPUs.")


def write_summary(spec: Spec, out: Path, runs: list[Run], cells: list[Cell], status: dict, metric: str,
                  figure: FigureStyle = DEFAULT) -> dict:
    """A report per cell whose runs are complete, then summary.{csv,md}, runs.csv and the matrix plot, every
    figure drawn as ``figure`` says."""
    from drltg.analysis import tables

    rows = write_reports(cells, status, spec.threshold, spec.value_range, figure)
    csv_text, md_text = summary_tables(rows, spec.primary_metric)
    runs_csv = tables.render([("run", "role", "status", "detail", "log")] + [
        (r.path.relative_to(out), r.role, *status[r.path], r.log.relative_to(out)) for r in runs], "csv")
    files = {"summary.csv": csv_text.encode(), "summary.md": md_text.encode(), "runs.csv": runs_csv.encode()}
    if any(r["metrics"] for r in rows):
        files.update(plot_transfer_matrix(rows, metric, figure))
    files.update(summary_aggregates(rows, figure))
    if across := across_targets(rows):
        files["across_targets.json"] = (json.dumps(across, indent=1) + "\n").encode()
    rundir.write_files(out, files)
    return {"rows": rows, "status": {r.path: status[r.path] for r in runs}, "summary": md_text,
            "logs": {r.path: r.log for r in runs}}
