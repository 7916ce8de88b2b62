"""`drltg sweep SPEC --out DIR`: many transfer experiments from one YAML spec, on a process pool or Ray.

The spec is a grid (every list is one axis; a scalar is a one-value axis)::

    pairs: [fourrooms-near, fourrooms-far]     # registered task pairs (see `drltg tasks`), or a task
                                               # alone for methods without a source or a given one
    methods: [reward-shaping, policy-reuse, model-reuse]
    algos: [sac]                               # default [sac]
    seeds: 5                                   # runs per side (default 5); first seed `seed` (default 0)
    frames: 20000                              # target budget; a list sweeps it
    source_frames: 40000                       # source budget (default: frames); a list sweeps it
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
import difflib
import itertools
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from drltg.config import RunConfig
from drltg.errors import UsageError
from drltg.experiments.executor import LocalBackend, RayBackend, Run, execute, registrations, seed_groups
from drltg.store import rundir

KEYS = ("pairs", "methods", "algos", "seeds", "seed", "frames", "source_frames", "overrides", "grid",
        "threshold", "primary_metric", "resources")
RESOURCES = ("num_cpus", "num_gpus")
MAX_RUNS = 10_000
"""The most transfer runs one sweep spec may expand to (counted before anything is planned)."""
SET_BY_SWEEP = {"task": "'pairs'", "algo": "'algos'", "seed": "'seed' and 'seeds'",
                "frames": "'frames' or 'source_frames'", "transfer.method": "'methods'"}
"""The config keys the sweep sets per run, and the spec key that sets them."""


# ------------------------------------------------------------------------------------------- spec
@dataclass
class Spec:
    pairs: list[str]
    methods: list[str]
    algos: list[str] = field(default_factory=lambda: ["sac"])
    seeds: int = 5
    seed: int = 0
    frames: list[int] = field(default_factory=list)
    source_frames: list[int] | None = None
    overrides: dict[str, Any] = field(default_factory=dict)
    grid: dict[str, list] = field(default_factory=dict)
    threshold: float | str | None = None
    primary_metric: str | None = None
    resources: dict[str, float] = field(default_factory=lambda: {"num_cpus": 1, "num_gpus": 0})


def _hint(word: str, choices) -> str:
    close = difflib.get_close_matches(str(word), list(choices), n=1)
    return f"; did you mean '{close[0]}'?" if close else f"; choose from: {', '.join(choices)}."


def _axis(data: dict, key: str, kind: type, where: str) -> list:
    """A spec entry as a non-empty list of ``kind`` (a scalar is a one-value list)."""
    value = data[key]
    values = value if isinstance(value, list) else [value]
    if not values:
        raise UsageError(f"{where}: '{key}' is an empty list; give at least one value.")
    for v in values:
        if kind is int and isinstance(v, float) and v.is_integer():
            continue
        if not isinstance(v, kind) or (kind is int and isinstance(v, bool)):
            raise UsageError(f"{where}: '{key}' must hold {kind.__name__} values, got {v!r}.")
    values = [int(v) if kind is int else v for v in values]
    _no_repeats(values, key, where)
    return values


def _no_repeats(values: list, key: str, where: str) -> None:
    seen = []
    for v in values:
        if v in seen:
            raise UsageError(f"{where}: '{key}' lists {v!r} twice; each value is one point of the sweep.")
        seen.append(v)


def _config_keys(mapping, key: str, where: str) -> dict:
    if not isinstance(mapping, dict):
        raise UsageError(f"{where}: '{key}' must be a mapping of config keys like {{eval.every: 1000}}.")
    from drltg.experiments.experiment import refuse_plan_overrides

    values = [(k, v) for k, vs in mapping.items() for v in (vs if key == "grid" and isinstance(vs, list) else [vs])]
    refuse_plan_overrides(values, f"{where}: '{key}'", "sweep", SET_BY_SWEEP)
    return dict(mapping)


def parse_spec(data: Any, where: str = "sweep spec") -> Spec:
    """Validate a loaded spec; every mistake is one :class:`UsageError` sentence."""

    if not isinstance(data, dict):
        raise UsageError(f"{where} must be a YAML mapping with keys like pairs, methods, seeds, frames.")
    for key in data:
        if key not in KEYS:
            raise UsageError(f"{where}: unknown key '{key}'{_hint(key, KEYS)}")
    for key in ("pairs", "methods", "frames"):
        if key not in data:
            raise UsageError(f"{where}: the key '{key}' is required.")
    spec = Spec(pairs=_axis(data, "pairs", str, where), methods=_axis(data, "methods", str, where),
                frames=_axis(data, "frames", int, where))
    _check_names(spec, data, where)
    for key in ("seeds", "seed"):
        if key in data:
            value = data[key]
            if not isinstance(value, int) or isinstance(value, bool):
                raise UsageError(f"{where}: '{key}' must be an integer, got {value!r}.")
            setattr(spec, key, value)
    if spec.seeds < 1 or min(spec.frames) < 1:
        raise UsageError(f"{where}: 'seeds' and 'frames' must be positive.")
    if data.get("source_frames") is not None:
        spec.source_frames = _axis(data, "source_frames", int, where)
        if min(spec.source_frames) < 1:
            raise UsageError(f"{where}: 'source_frames' must be positive; omit it to give source runs 'frames'.")
    spec.overrides = _config_keys(data.get("overrides") or {}, "overrides", where)
    spec.grid = _config_keys(data.get("grid") or {}, "grid", where)
    _check_grid(spec.grid, where)
    spec.threshold, primary = _report_keys(data, where)
    spec.primary_metric = primary
    spec.resources.update(_resources(data, where))
    runs = math.prod([len(spec.pairs), len(spec.methods), len(spec.algos), spec.seeds, len(spec.frames),
                      len(spec.source_frames or [None]), *map(len, spec.grid.values())])
    if runs > MAX_RUNS:
        raise UsageError(f"{where} expands to {runs:,} transfer runs (pairs x methods x algos x seeds x frames x grid "
                         f"values), more than the {MAX_RUNS:,} one sweep plans; split it into smaller sweeps.")
    return spec


def _check_names(spec: Spec, data: dict, where: str) -> None:
    """Every pair (or lone target task), method and algo of the spec is registered."""
    from drltg.envs import TASKS, get_pair
    from drltg.learners import ALGOS
    from drltg.transfer import METHODS, get_method

    for pair in spec.pairs:
        try:
            if pair not in TASKS:  # a task alone is a target (methods without a source, or a given one)
                get_pair(pair)
        except UsageError as err:
            raise UsageError(f"{where}: {err}") from None
    for method in spec.methods:
        for part in method.split("+"):
            if part not in METHODS or part == "none":
                raise UsageError(f"{where}: unknown method '{part}'{_hint(part, [m for m in METHODS if m != 'none'])}")
        try:
            get_method(method)
        except UsageError as err:
            raise UsageError(f"{where}: {err}") from None
    if "algos" in data:
        spec.algos = _axis(data, "algos", str, where)
    for algo in spec.algos:
        if algo not in ALGOS:
            raise UsageError(f"{where}: unknown algo '{algo}'{_hint(algo, sorted(ALGOS))}")


def _check_grid(grid: dict, where: str) -> None:
    """Each grid key sweeps a non-empty list of distinct, printable values (they name folders)."""
    for key, values in grid.items():
        if not isinstance(values, list) or not values:
            raise UsageError(f"{where}: grid key '{key}' must be a non-empty list of values.")
        _no_repeats(values, f"grid: {key}", where)
        named = next((v for v in values if any(ord(c) < 32 or c == "\x7f" for c in str(v))), None)
        if named is not None:
            raise UsageError(f"{where}: grid value {named!r} of '{key}' holds a control character; grid values name "
                             "the runs' folders, so give printable values.")


def _report_keys(data: dict, where: str) -> tuple:
    """``threshold`` and ``primary_metric`` (``None`` where not given), checked as ``drltg report`` checks them."""
    from drltg.analysis.report import check_metric, parse_threshold

    threshold = data.get("threshold")
    if threshold is not None and (isinstance(threshold, bool) or not isinstance(threshold, (int, float, str))):
        raise UsageError(f"{where}: 'threshold' must be a number or a percentage like \"80%\".")
    try:
        parse_threshold(threshold)
    except UsageError as err:
        raise UsageError(f"{where}: {err}".replace("--threshold", "threshold")) from None
    primary = data.get("primary_metric")
    if primary is not None:
        try:
            check_metric(str(primary), "primary_metric")
        except UsageError as err:
            raise UsageError(f"{where}: {err}") from None
        if primary not in SUMMARY_COLUMNS or primary.startswith("time_to"):
            raise UsageError(f"{where}: primary_metric '{primary}' is not a comparison the summary holds; choose "
                             f"one of {', '.join(c for c in SUMMARY_COLUMNS if not c.startswith('time_to'))}.")
    return threshold, primary


def _resources(data: dict, where: str) -> dict:
    """What each run asks of a Ray cluster (``num_cpus``, ``num_gpus``), non-negative numbers."""
    resources = data.get("resources") or {}
    if not isinstance(resources, dict):
        raise UsageError(f"{where}: 'resources' must be a mapping like {{num_cpus: 1, num_gpus: 0}}.")
    for key, value in resources.items():
        if key not in RESOURCES:
            raise UsageError(f"{where}: unknown resource '{key}'{_hint(key, RESOURCES)}")
        if isinstance(value, bool) or not isinstance(value, (int, float)) or value < 0:
            raise UsageError(f"{where}: resource '{key}' must be a non-negative number, got {value!r}.")
    return resources


def load_spec(path: str | Path) -> Spec:
    from drltg.config import load_yaml

    return parse_spec(load_yaml(path, "sweep spec"), where=f"sweep spec '{path}'")


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


def _variants(spec: Spec) -> list[tuple[str, int, int | None, dict]]:
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
    return json.dumps(cfg.model_dump(), sort_keys=True, default=str)


def plan(spec: Spec, out: Path) -> tuple[list[Run], list[Cell]]:
    """Expand the spec into unique runs (each after the run it needs) and the reports to write."""
    from drltg.experiments.experiment import plan_runs

    out = Path(out).expanduser().resolve()
    home: dict[str, Path] = {}  # resolved config -> the one directory that trains it
    moved: dict[Path, Path] = {}  # planned directory -> that directory
    runs: dict[Path, Run] = {}
    cells = []
    for pair, algo, (variant, frames, source_frames, values) in itertools.product(
        spec.pairs, spec.algos, _variants(spec)
    ):
        group = out / pair / algo / variant if variant else out / pair / algo
        for method in spec.methods:
            planned = plan_runs(pair, method, algo=algo, seeds=spec.seeds, seed=spec.seed, frames=frames,
                                source_frames=source_frames, base={**spec.overrides, **values},
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
def write_reports(cells: list[Cell], status: dict, threshold) -> list[dict]:
    """One ``drltg report`` per cell whose runs are all complete; a row per cell for the summary."""
    from drltg.analysis.report import transfer_report

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
                                         baseline_label="no transfer", transfer_label=c.method)
                row["metrics"] = result["metrics"]
                if diverged:
                    row["note"] = f"{diverged} run(s) diverged, left out"
            except UsageError as err:
                row["note"] = str(err)
        rows.append(row)
    return rows


SUMMARY_COLUMNS = ("mean_return_gain", "jumpstart", "asymptotic_performance", "transfer_ratio",
                   "probability_of_improvement", "time_to_threshold_baseline", "time_to_threshold_transfer")


LEVEL = 0.05
"""The level at which the summary counts findings (the reports' 95 % intervals)."""


def sweep_family(rows: list[dict], primary_metric: str | None = None) -> tuple[dict, str]:
    """Holm-adjusted p-values over the summary's family, ``{(row index, metric): p}``, and its headline.

    The family is the primary metric's p-value in every report when the spec named one in advance, else
    every p-value the summary shows (each report's own adjustment covers only that report)."""
    from drltg.analysis.stats import holm

    metrics = [primary_metric] if primary_metric else [m for m in SUMMARY_COLUMNS if not m.startswith("time_to")]
    members = [(i, name) for i, r in enumerate(rows) for name in metrics
               if (r["metrics"] or {}).get(f"{name}_p_value") is not None]
    adjusted = dict(zip(members, holm([rows[i]["metrics"][f"{name}_p_value"] for i, name in members])))
    found = [(i, name) for (i, name), p in adjusted.items() if p < LEVEL]
    raw = sum(rows[i]["metrics"][f"{name}_p_value"] < LEVEL for i, name in members)

    def sign(i, name):
        value = rows[i]["metrics"][name]
        return value - 0.5 if name.startswith("probability_of_improvement") else value

    up = sum(sign(i, name) > 0 for i, name in found)
    if primary_metric:
        family = (f"the primary metric {primary_metric} (named in the spec) in {len(members)} report(s)")
    else:
        family = (f"every interval of this table ({', '.join(metrics)}), {len(members)} p-values in "
                  f"{len(rows)} report(s), as the spec named no primary_metric")
    headline = (f"Family: {family}. Holm's adjustment over all {len(members)}: {len(found)} finding(s) at "
                f"{LEVEL:g} ({up} positive, {len(found) - up} negative); {raw} before adjustment.")
    return adjusted, headline


def summary_tables(rows: list[dict], primary_metric: str | None = None) -> tuple[str, str]:
    """The cells' metrics (value, CI bounds, p-value and the sweep-wide Holm-adjusted p-value) as CSV, and
    as a Markdown table under the headline of :func:`sweep_family`."""
    from drltg.analysis import tables

    adjusted, headline = sweep_family(rows, primary_metric)
    head = ["pair", "algo", "variant", "method", "seeds"]
    csv_rows = [head + [f"{m}{s}" for m in SUMMARY_COLUMNS for s in ("", "_ci_low", "_ci_high", "_p_value",
                                                                       "_p_holm_sweep")]
                + ["report", "note"]]
    md = [["pair", "algo", "method", *SUMMARY_COLUMNS, "seeds"]]
    for i, r in enumerate(rows):
        m = r["metrics"] or {}
        seeds = f"{m['n_seeds_baseline']}+{m['n_seeds_transfer']}" if m else ""
        line = [r["pair"], r["algo"], r["variant"], r["method"], seeds]
        cells = []
        for name in SUMMARY_COLUMNS:
            value, ci = m.get(name), m.get(f"{name}_ci") or (None, None)
            line += [value, *ci, m.get(f"{name}_p_value"), adjusted.get((i, name))]
            if not m:
                cells.append("-")
            elif name.startswith("time_to"):
                cells.append(tables.estimate(value, fmt=lambda x: f"{x / 1000:.3g}k", missing="not reached"))
            else:
                mark = "*" if adjusted.get((i, name), 1.0) < LEVEL else ""
                cells.append(tables.estimate(value, ci, ".3g") + mark)
        csv_rows.append(line + [r["report"] if m else "", r.get("note", "")])
        md.append([f"{r['pair']} {r['variant']}".strip(), r["algo"], r["method"], *cells, seeds or r.get("note", "")])
    md_text = (f"{headline}\n\n{tables.render(md, 'markdown')}\n"
               f"\\* a finding: Holm-adjusted p < {LEVEL:g} within the family above.\n")
    return tables.render(csv_rows, "csv"), md_text


def plot_transfer_matrix(rows: list[dict], metric: str = "mean_return_gain") -> bytes:
    """Heatmap PNG of ``metric`` over (pair, algo, variant) rows x method columns, mean and CI per cell."""
    import numpy as np

    from drltg.analysis.plot import plot_matrix

    one_algo = len({r["algo"] for r in rows}) == 1

    def label(r: dict) -> str:
        return " / ".join(x for x in (r["pair"], None if one_algo else r["algo"], r["variant"]) if x)

    labels = list(dict.fromkeys(map(label, rows)))
    methods = list(dict.fromkeys(r["method"] for r in rows))
    table = np.full((len(labels), len(methods)), np.nan)
    text = np.full(table.shape, "n/a", dtype=object)
    for r in rows:
        i, j = labels.index(label(r)), methods.index(r["method"])
        value = (r["metrics"] or {}).get(metric)
        if value is not None:
            ci = r["metrics"].get(f"{metric}_ci")
            table[i, j] = value
            text[i, j] = f"{value:+.2f}" + (f"\n[{ci[0]:+.2f}, {ci[1]:+.2f}]" if ci else "")
    title = f"{metric}, transfer - baseline [95% CI; none below 3 seeds a side]"
    return plot_matrix(table, labels, methods, metric, text=text, axis_labels=("pair", "method"), title=title)[0]


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
    p.add_argument("--dry-run", action="store_true", help="list the runs and reports, run nothing")
    p.add_argument("--no-progress", action="store_true", help="no progress bar (none is drawn when stderr is not "
                   "a terminal)")


def sweep(spec: str | Path | dict, out: str | Path, *, backend: str = "local", workers: int | None = None,
          address: str | None = None, num_cpus: float | None = None, num_gpus: float | None = None,
          metric: str = "mean_return_gain", group_seeds: bool = True, progress: bool = True) -> dict:
    """Train a sweep's runs into ``out`` (what is finished is reused, what was interrupted resumes) and
    write a report per cell and the summary; the arguments are ``drltg sweep``'s, ``spec`` a YAML file or
    the same mapping (``{"pairs": [...], "methods": [...], "seeds": 5, "frames": 20000}``).

    Returns ``{"rows": one per report (pair, algo, variant, method, report folder, metrics or a note),
    "status": {run directory: (status, detail)}, "summary": the summary table as Markdown, "logs": {run
    directory: its log file}}``. A run that failed or diverged is in ``status``; the reports leave it out.

        >>> result = drltg.sweep("examples/sweeps/fourrooms.yaml", "runs/sweep", workers=2)
    """
    from drltg.analysis.report import check_metric
    from drltg.experiments.experiment import check_existing, check_runs

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
    check_existing(runs)
    registrations(runs)  # what a worker process could not register is refused now
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise UsageError(f"cannot create --out '{out}' ({err.strerror}).") from None
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
        return _write_summary(parsed, out, runs, cells, status, metric)


def run(args: argparse.Namespace) -> int:
    if args.dry_run:
        return _dry_run(args)
    result = sweep(args.spec, args.out, backend=args.backend, workers=args.workers, address=args.address,
                   num_cpus=args.num_cpus, num_gpus=args.num_gpus, metric=args.metric,
                   group_seeds=not args.no_seed_groups, progress=not args.no_progress)
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
    """List the runs and reports of the spec and the units of work they train in; run nothing."""
    from drltg.analysis.report import check_metric

    check_metric(args.metric)
    spec = load_spec(args.spec)
    _resources_for(spec, args.num_cpus, args.num_gpus, args.backend, args.address)
    out = rundir.check_directory(args.out, "--out")
    rundir.refuse_run_directory(out, "--out")
    runs, cells = plan(spec, out)
    for r in runs:
        print(f"{r.role:<9} {r.frames:>9} frames  {r.path.relative_to(out)}")
    units = [[r] for r in runs] if args.no_seed_groups else seed_groups(runs)
    groups = [u for u in units if len(u) > 1]
    print(f"{len(runs)} runs, {len(cells)} reports; {len(units)} units of work: {len(groups)} seed groups "
          f"of {sum(map(len, groups))} runs, {len(units) - len(groups)} runs alone")
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


def _write_summary(spec: Spec, out: Path, runs: list[Run], cells: list[Cell], status: dict, metric: str) -> dict:
    """A report per cell whose runs are complete, then summary.{csv,md}, runs.csv and the matrix plot."""
    from drltg.analysis import tables

    rows = write_reports(cells, status, spec.threshold)
    csv_text, md_text = summary_tables(rows, spec.primary_metric)
    runs_csv = tables.render([("run", "role", "status", "detail", "log")] + [
        (r.path.relative_to(out), r.role, *status[r.path], r.log.relative_to(out)) for r in runs], "csv")
    files = {"summary.csv": csv_text.encode(), "summary.md": md_text.encode(), "runs.csv": runs_csv.encode()}
    if any(r["metrics"] for r in rows):
        files["transfer_matrix.png"] = plot_transfer_matrix(rows, metric)
    rundir.write_files(out, files)
    return {"rows": rows, "status": {r.path: status[r.path] for r in runs}, "summary": md_text,
            "logs": {r.path: r.log for r in runs}}
