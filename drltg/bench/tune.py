"""``drltg bench tune --method NAME``: the method's declared search space tried on tuning seeds, its choice
written where ``drltg bench run`` applies it, so every row of the leaderboard gets the same budget.

Each group of the tier is one sweep of the method over its settings (:attr:`TransferMethod.settings`, at
most :data:`~drltg.transfer.TUNING_BUDGET`) into ``OUT/<version>/<tier>/tuning/<method>/<group>/``, on
:data:`TUNE_SEEDS` paired seeds from :data:`TUNE_SEED` (``5000 + 100 i``, sources ``+ 50``): no leaderboard
run has one of them, so the rows are never scored on the seeds that chose them. The baseline and the
sources of a setting are those of every other setting (trained once).

**The rule.** The score of a setting is its mean FT over the tier's pairs (:func:`drltg.bench.board.pair_score`,
the leaderboard's own score); the choice is the setting of the highest score, the earlier in the declared
order on a tie, so the defaults (first) stand unless another setting beats them. ``tuning.json`` records the
budget, the seeds, the rule, every setting with its score per pair, and the choice.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from drltg.bench.run import TUNING, applicable_pairs, plan_tier, tuning_root
from drltg.bench.suite import LATEST, SMOKE, get_tier
from drltg.errors import RunFailed, UsageError
from drltg.store import rundir

__all__ = ["bench_tune", "TUNE_SEED", "TUNE_SEEDS", "RULE"]

TUNE_SEED = 5_000
TUNE_SEEDS = 3
RULE = "the highest mean FT over the tier's pairs on the tuning seeds; the earlier setting on a tie"
def bench_tune(method: str, *, tier: str = "quick", out: str | Path = "runs/bench", version: str = LATEST,
               smoke: bool = False, workers: int | None = None, backend: str = "local", group_seeds: bool = True,
               progress: bool = True, dry_run: bool = False) -> dict:
    """Try each of ``method``'s settings on the tier at the tuning seeds; write and return the tuning record
    (with ``dry_run``, ``{"plan": lines}``: the work, :func:`~drltg.bench.run.plan_tier`, and nothing written).

        >>> drltg.bench.bench_tune("policy-reuse", out="runs/bench", workers=2)["choice"]
        {'transfer.psi': 1.0, 'transfer.upsilon': 0.95}
    """
    from drltg.bench.board import pair_score
    from drltg.bench.checks import read_json
    from drltg.experiments.spec import parse_spec
    from drltg.experiments.sweep import plan, sweep
    from drltg.transfer import get_method

    the_tier = get_tier(version, tier)
    spec_of = get_method(method)
    if method == "none":
        raise UsageError("'none' is the baseline every row is compared with; name a transfer method.")
    settings = spec_of.settings
    root = rundir.check_directory(tuning_root(out, version, tier, method, smoke), "--out")
    seeds = SMOKE["seeds"] if smoke else TUNE_SEEDS
    grid = {key: list(spec_of.search[key.removeprefix("transfer.")]) for key in settings[0]}
    scores: list[dict[str, float]] = [{} for _ in settings]
    left_out: dict[str, str] = {}
    specs = {}
    for group in the_tier.groups:
        pairs, missed = applicable_pairs(group, method, smoke, root / group.name)
        left_out.update(missed)
        if pairs:
            specs[group.name] = {**group.sweep_spec([method], smoke), "pairs": pairs, "seed": TUNE_SEED,
                                 "seeds": seeds, "grid": grid}
    if dry_run:
        return {"plan": plan_tier([(g, spec, root / g) for g, spec in specs.items()], None, group_seeds)}
    for name, spec in specs.items():
        group_out = root / name
        result = sweep(spec, group_out, backend=backend, workers=workers, group_seeds=group_seeds, progress=progress)
        failed = [str(p) for p, (state, _) in result["status"].items() if state in ("failed", "diverged")]
        if failed:
            raise RunFailed(f"{len(failed)} tuning run(s) of {method} on {name} failed or diverged (first: "
                            f"{failed[0]}); see their logs under {group_out / 'logs'}, then run the same command "
                            "again to resume")
        _, cells = plan(parse_spec(spec), group_out.resolve())
        names = [name for name, *_ in _grid_points(spec)]
        for cell in cells:
            report = read_json(cell.report / "transfer_metrics.json", root, 2**26, "a transfer report")
            ft = pair_score(report)["ft"]
            if ft is not None:  # no transfer already at the maximum: the pair scores no setting
                scores[names.index(cell.variant) if grid else 0][cell.pair] = ft
    means = [float(np.mean(list(s.values()))) if s else float("nan") for s in scores]
    best = max(range(len(settings)), key=lambda i: (np.nan_to_num(means[i], nan=-np.inf), -i))
    record = {"method": method, "suite": version, "tier": tier, "smoke": smoke, "rule": RULE,
              "seeds": [TUNE_SEED + 100 * i for i in range(seeds)], "budget": len(settings),
              "settings": [{"setting": s, "score": m, "per_pair": p} for s, m, p in zip(settings, means, scores)],
              "choice": settings[best], "left_out": left_out}
    rundir.write_files(root, {TUNING: (json.dumps(record, indent=1, sort_keys=True) + "\n").encode()})
    return record


def _grid_points(spec: dict):
    from drltg.experiments.spec import parse_spec
    from drltg.experiments.sweep import variants

    return variants(parse_spec(spec))
