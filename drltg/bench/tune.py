"""``drltg bench tune --method NAME``: the method's declared search space tried on tuning seeds, its choice
written where ``drltg bench run`` applies it, so every row of the leaderboard gets the same budget.

Each group of the tier is one sweep of the method over its settings (:attr:`TransferMethod.settings`, at
most :data:`~drltg.transfer.TUNING_BUDGET`) into ``OUT/<version>/<tier>/tuning/<method>/<group>/``, on
:data:`~drltg.bench.suite.TUNE_SEEDS` paired seeds from :data:`~drltg.bench.suite.TUNE_SEED` (``5000 + 100
i``, sources ``+ 50``): no leaderboard run has one of them, so the rows are never scored on the seeds that
chose them. The baseline and the sources of a setting are those of every other setting (trained once).

**The rule.** The score of a setting is its mean FT over the tier's pairs (:func:`drltg.bench.board.pair_score`,
the leaderboard's own score); the choice is the setting of the highest score, the earlier in the declared
order on a tie, so the defaults (first) stand unless another setting beats them. ``tuning.json`` records the
budget, the seeds, the rule, every setting with its score per pair, and the choice.

**The baseline** (``--method none``, on a tier whose groups declare
:attr:`~drltg.bench.suite.Group.baseline_search`) gets the same budget over the learner's own settings, group
by group, scored by its mean normalised area over the group's pairs (:data:`BASELINE_RULE`), and is tuned
first: every method's tuning and row then train at its choice, so transfer is measured against a tuned
learner, never against defaults nobody tuned. Where the suite declares its sources (v2), every tuning run
reads them (:mod:`drltg.bench.sources`).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from drltg.bench import suite
from drltg.bench.board import pair_score
from drltg.bench.run import TUNING, applicable_pairs, plan_tier, tuning_root
from drltg.bench.suite import LATEST, SMOKE, TUNE_SEED, get_tier
from drltg.errors import RunFailed, UsageError
from drltg.store import rundir

__all__ = ["bench_tune", "RULE", "BASELINE_RULE"]

RULE = "the highest mean FT over the tier's pairs on the tuning seeds; the earlier setting on a tie"
BASELINE_RULE = ("in each group, the highest mean normalised area (AUC) over its pairs on the tuning seeds; the "
                 "earlier setting on a tie")
def bench_tune(method: str, *, tier: str = "quick", out: str | Path = "runs/bench", version: str = LATEST,
               reference: str | Path | None = None, smoke: bool = False, workers: int | None = None,
               backend: str = "local", group_seeds: bool = True, progress: bool = True, dry_run: bool = False) -> dict:
    """Try each of ``method``'s settings on the tier at the tuning seeds; write and return the tuning record
    (with ``dry_run``, ``{"plan": lines}``: the work, :func:`~drltg.bench.run.plan_tier`, and nothing written).
    ``method="none"`` tunes the baseline over each group's :attr:`~drltg.bench.suite.Group.baseline_search`,
    scored by its mean normalised area; a method is tuned at the baseline's choice, on the suite's sources where it
    declares them (from ``reference`` where it holds them).

        >>> drltg.bench.bench_tune("policy-reuse", out="runs/bench", workers=2)["choice"]
        {'transfer.psi': 1.0, 'transfer.upsilon': 0.95}
    """
    from drltg.bench.run import baseline_tuning, group_spec, tier_root
    from drltg.bench.sources import use_sources
    from drltg.transfer import get_method

    the_tier = get_tier(version, tier)
    spec_of = get_method(method)
    root = rundir.check_directory(tuning_root(out, version, tier, method, smoke), "--out")
    seeds = SMOKE["seeds"] if smoke else suite.TUNE_SEEDS
    if method == "none":
        if not the_tier.tunes_baseline:
            raise UsageError(f"suite {version}'s tier {tier} tunes no baseline ('none' is the baseline every row is "
                             "compared with); name a transfer method.")
        return _tune_baseline(the_tier, version, root, seeds, smoke, workers, group_seeds, progress, dry_run)
    settings = spec_of.settings
    grid = {key: list(spec_of.search[key.removeprefix("transfer.")]) for key in settings[0]}
    reference_root = tier_root(reference, version, tier) if reference is not None else None
    given, _ = use_sources(the_tier, tier_root(out, version, tier, smoke), reference_root, smoke, dry_run)
    baseline = baseline_tuning(the_tier, out, reference, version, smoke)
    fixed = baseline["choice"] if baseline else {}  # group -> the baseline's setting
    scores: list[dict[str, float]] = [{} for _ in settings]
    left_out: dict[str, str] = {}
    specs = {}
    for group in the_tier.groups:
        spec = {**group_spec(group, method, smoke, given, fixed.get(group.name, {})), "seed": TUNE_SEED,
                "seeds": seeds, "grid": grid}
        pairs, missed = applicable_pairs(group, method, smoke, root / group.name, spec)
        left_out.update(missed)
        if pairs:
            specs[group.name] = {**spec, "pairs": pairs}
    extra = {"baseline": fixed} if baseline else {}
    if len(settings) == 1:  # no search declared: the defaults are the choice, and nothing trains to say so
        return {"plan": ["nothing to train: the method declares no search, so its budget is 1, its defaults"]} \
            if dry_run else _write(root, method, version, tier, smoke, seeds, settings, scores, left_out, extra)
    if dry_run:
        return {"plan": plan_tier([(g, spec, root / g) for g, spec in specs.items()], None, group_seeds)}
    none_roots = [tuning_root(folder, version, tier, "none", smoke) for folder in (out, reference) if folder]
    for name, spec in specs.items():
        _copy_baseline_runs(spec, root / name, [r / name for r in none_roots], fixed.get(name, {}))
        for cell, report in _swept(spec, root / name, method, backend, workers, group_seeds, progress):
            ft = pair_score(report)["ft"]
            if ft is not None:  # no transfer already at the maximum: the pair scores no setting
                scores[cell][report["pair"]] = ft
    return _write(root, method, version, tier, smoke, seeds, settings, scores, left_out, extra)


def _copy_baseline_runs(spec: dict, group_out: Path, none_groups: list[Path], choice: dict) -> None:
    """Copy into a method's tuning sweep the baseline runs the baseline's own tuning trained at its choice, on
    the same seeds with the same config (``none_groups``: that tuning's group folders, this bench folder's then
    the reference's), as data, as ``bench run`` copies a reference's: trained once."""
    from drltg.bench.suite import copy_run
    from drltg.config import config_changes
    from drltg.experiments.spec import parse_spec
    from drltg.experiments.sweep import plan

    variant = ",".join(f"{k}={v}" for k, v in choice.items()) or "defaults"
    runs, _ = plan(parse_spec(spec), group_out.resolve())
    for run in runs:
        if run.role != "baseline" or rundir.is_complete(run.path):
            continue
        pair, algo = run.path.relative_to(group_out.resolve()).parts[:2]
        for none_group in none_groups:
            kept = none_group.resolve() / pair / algo / variant / "baseline" / run.path.name
            if rundir.is_complete(kept) and not config_changes(rundir.read_config(kept), run.cfg):
                copy_run(kept, run.path)
                break


def _swept(spec: dict, group_out: Path, method: str, backend: str, workers, group_seeds: bool, progress: bool):
    """Sweep one group of a method's tuning; yield ``(setting index, report)`` of every cell."""
    from drltg.bench.checks import read_json
    from drltg.experiments.spec import parse_spec
    from drltg.experiments.sweep import plan, sweep

    result = sweep(spec, group_out, backend=backend, workers=workers, group_seeds=group_seeds, progress=progress)
    _refuse_failed(result["status"], method, group_out)
    _, cells = plan(parse_spec(spec), group_out.resolve())
    names = [name for name, *_ in _grid_points(spec)]
    for cell in cells:
        report = read_json(cell.report / "transfer_metrics.json", group_out, 2**26, "a transfer report")
        yield (names.index(cell.variant) if spec.get("grid") else 0), {**report, "pair": cell.pair}


def _refuse_failed(status: dict, method: str, folder: Path) -> None:
    failed = [str(p) for p, (state, _) in status.items() if state in ("failed", "diverged")]
    if failed:
        raise RunFailed(f"{len(failed)} tuning run(s) of {method} in {folder} failed or diverged (first: "
                        f"{failed[0]}); see their logs under {folder / 'logs'}, then run the same command again "
                        "to resume")


def _tune_baseline(tier, version: str, root: Path, seeds: int, smoke: bool, workers, group_seeds: bool,
                   progress: bool, dry_run: bool) -> dict:
    """The baseline's tuning, group by group (each group's search starts at its own tasks' defaults): each
    setting trained alone (no transfer) on the tuning seeds of every pair, scored by the mean over the group's
    pairs of its seeds' mean normalised area (the board's AUC_B); the choice is the highest, the earlier on a tie."""
    from drltg import config as config_lib
    from drltg.bench.suite import smoke_budgets
    from drltg.envs import get_pair
    from drltg.experiments.backends import LocalBackend
    from drltg.experiments.executor import Run, execute, plan_lines
    from drltg.experiments.experiment import make_out
    from drltg.training.loop import check_config

    root = root.resolve()
    runs, cells = [], []
    for group in tier.groups:
        spec = {**group.spec, **smoke_budgets(group.spec)} if smoke else group.spec
        for pair in group.pairs:
            for i, setting in enumerate(group.baseline_settings):
                variant = ",".join(f"{k}={v}" for k, v in setting.items()) or "defaults"
                folder = root / group.name / pair / spec["algos"][0] / variant / "baseline"
                runs_here = []
                for seed in config_lib.run_seeds(TUNE_SEED, seeds):
                    cfg = config_lib.resolve({**spec.get("overrides", {}), **setting}, [], task=get_pair(pair).target,
                                             algo=spec["algos"][0], frames=spec["frames"], seed=seed)
                    path = folder / f"seed-{seed}"
                    runs_here.append(Run("baseline", cfg, path,
                                         root / "logs" / path.relative_to(root).with_suffix(".log")))
                runs += runs_here
                cells.append((group.name, i, pair, runs_here))
    for cfg in {id(r): r.cfg for r in runs[::seeds]}.values():
        check_config(cfg)
    if dry_run:
        return {"plan": plan_lines(runs, root, 0, group_seeds)}
    make_out(runs, root, [])
    with rundir.lock(root, "tuning folder"):
        pool = LocalBackend(workers or 1)
        try:
            status = execute(runs, pool, desc="tune none", group_seeds=group_seeds, progress=progress)
        finally:
            pool.close()
        _refuse_failed(status, "the baseline", root)
        scores = {g.name: [{} for _ in g.baseline_settings] for g in tier.groups}
        for name, i, pair, dirs in cells:
            scores[name][i][pair] = float(np.mean([normalised_area(run) for run in dirs]))
        tried, choice = [], {}
        for group in tier.groups:
            settings = group.baseline_settings
            means = [float(np.mean(list(s.values()))) for s in scores[group.name]]
            choice[group.name] = settings[max(range(len(settings)), key=lambda i: (means[i], -i))]
            tried += [{"group": group.name, "setting": s, "score": m, "per_pair": p}
                      for s, m, p in zip(settings, means, scores[group.name])]
        record = {"method": "none", "suite": version, "tier": tier.name, "smoke": smoke, "rule": BASELINE_RULE,
                  "seeds": config_lib.run_seeds(TUNE_SEED, seeds),
                  "budget": max(len(g.baseline_settings) for g in tier.groups), "settings": tried, "choice": choice,
                  "left_out": {}}
        rundir.write_files(root, {TUNING: (json.dumps(record, indent=1, sort_keys=True) + "\n").encode()})
    return record


def normalised_area(run) -> float:
    """A run's mean return over its budget (the report's ``mean_return``: the area under its evaluation curve
    over the frames) normalised to [0, 1] by its task's declared return range: the board's AUC."""
    from drltg.analysis.metrics import area_under_curve
    from drltg.envs.registry import TASKS
    from drltg.report.curves import read_eval_csv

    curve = read_eval_csv(run.path / rundir.EVAL)
    lo, hi = TASKS[run.cfg.task].return_range(run.cfg.model_dump()["env"])
    return (area_under_curve(curve.frames, curve.values, 0, run.cfg.frames) / run.cfg.frames - lo) / (hi - lo)


def _write(root: Path, method: str, version: str, tier: str, smoke: bool, seeds: int, settings: list[dict],
           scores: list[dict[str, float]], left_out: dict, extra: dict) -> dict:
    means = [float(np.mean(list(s.values()))) if s else None for s in scores]
    best = max(range(len(settings)), key=lambda i: (-np.inf if means[i] is None else means[i], -i))
    record = {"method": method, "suite": version, "tier": tier, "smoke": smoke, "rule": RULE,
              "seeds": [TUNE_SEED + 100 * i for i in range(seeds)], "budget": len(settings),
              "settings": [{"setting": s, "score": m, "per_pair": p} for s, m, p in zip(settings, means, scores)],
              "choice": settings[best], "left_out": left_out, **extra}
    rundir.write_files(root, {TUNING: (json.dumps(record, indent=1, sort_keys=True) + "\n").encode()})
    return record


def _grid_points(spec: dict):
    from drltg.experiments.spec import parse_spec
    from drltg.experiments.sweep import variants

    return variants(parse_spec(spec))
