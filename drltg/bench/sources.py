"""``drltg bench sources``: the teachers of a tier whose suite declares them (:class:`~drltg.bench.suite.Sources`),
trained once and shared by every row, so that a leaderboard ranks methods and not the sources they drew.

Each group's sources are runs on the pairs' shared source task, one per target seed the tier uses (the
leaderboard's ``seed + 100 i`` and the tuning seeds ``5000 + 100 i``), each at seed ``target + 50``, ending
at the first evaluation whose success rate reaches the criterion (``eval.stop_at_success``) within the
declared frames. They live in ``OUT/<version>/<tier>/sources/<group>/seed-<target seed>/``, and every
transfer run of the tier reads its own seed's (``transfer.source: .../seed-{seed}``); ``sources.json`` there
lists each source: the frames it trained, whether it met the criterion, and the SHA-256 of its networks and
config. A suite names its sources by those digests (:func:`~drltg.bench.suite.declared_sources`); a bench
run whose sources are other ones is marked on the board as off protocol.
"""
from __future__ import annotations

import json
import os
from pathlib import Path

from drltg.bench import suite
from drltg.bench.suite import REFERENCE_FILES as FILES
from drltg.bench.suite import SMOKE, Group, Tier, copy_run, declared_sources, tier_root
from drltg.errors import UsageError
from drltg.store import rundir

__all__ = ["bench_sources", "source_runs", "sources_root", "use_sources", "SOURCES"]

SOURCES = "sources.json"


def sources_root(tier_folder: Path) -> Path:
    return tier_folder / "sources"


def target_seeds(group: Group, smoke: bool) -> list[int]:
    """The target seeds a group's sources serve: the leaderboard's, then the tuning seeds."""
    from drltg.config import run_seeds

    count = SMOKE["seeds"] if smoke else group.spec["seeds"]
    tuning = SMOKE["seeds"] if smoke else suite.TUNE_SEEDS
    return run_seeds(group.spec["seed"], count) + run_seeds(suite.TUNE_SEED, tuning)


def source_runs(tier: Tier, tier_folder: Path, smoke: bool = False) -> list:
    """Every source run of the tier as an executor :class:`~drltg.experiments.executor.Run`."""
    from drltg import config as config_lib
    from drltg.bench.suite import smoke_budgets
    from drltg.envs import get_pair
    from drltg.experiments.executor import Run

    root = sources_root(tier_folder).resolve()
    runs = []
    for group in tier.groups:
        if group.sources is None:
            continue
        tasks = {get_pair(p).source for p in group.pairs}
        if len(tasks) != 1:
            raise UsageError(f"suite group {group.name} declares sources, but its pairs learn from "
                             f"{len(tasks)} source tasks ({', '.join(sorted(tasks))}); a group shares one.")
        (task,) = tasks
        spec = {**group.spec, "frames": group.sources.frames}
        if smoke:
            spec = {**spec, **smoke_budgets(spec)}
        base = dict(spec.get("overrides", {}))
        if group.sources.success is not None:
            base["eval.stop_at_success"] = group.sources.success
        for seed in target_seeds(group, smoke):
            cfg = config_lib.resolve(base, [], task=task, algo=spec["algos"][0],
                                     frames=spec["frames"], seed=config_lib.source_seed(seed))
            path = root / group.name / f"seed-{seed}"
            runs.append(Run("source", cfg, path, root / "logs" / group.name / f"seed-{seed}.log"))
    return runs


def record(runs: list, declared: dict[str, dict]) -> dict:
    """``sources.json``: each finished source's frames, criterion and digests, and whether it is the one the
    suite declares."""
    from drltg.store import manifest

    entries = {}
    for run in runs:
        key = f"{run.path.parent.name}/{run.path.name}"
        summary = json.loads((run.path / rundir.SUMMARY).read_text())
        stop = summary.get("stop_at_success") or {}
        digests = {"networks_sha256": manifest.digest(run.path / FILES[-1]),
                   "config_sha256": manifest.digest(run.path / rundir.CONFIG)}
        entries[key] = {"frames": summary.get("frames"), "met": stop.get("met"),
                        "success_rate": stop.get("success_rate", stop.get("best_success_rate")), **digests,
                        "declared": declared.get(key) == digests if declared else None}
    return entries


def bench_sources(*, tier: str = "quick", out: str | Path = "runs/bench", version: str = "v2", smoke: bool = False,
                  workers: int | None = None, group_seeds: bool = True, progress: bool = True,
                  dry_run: bool = False) -> dict:
    """Train the tier's sources into ``out`` (what is finished is kept, what was interrupted resumes) and write
    ``sources.json``; returns it (with ``dry_run``, ``{"plan": lines}``)."""
    from drltg.bench.suite import get_tier
    from drltg.experiments.backends import LocalBackend
    from drltg.experiments.executor import execute, plan_lines
    from drltg.experiments.experiment import make_out
    from drltg.training.loop import check_config

    the_tier = get_tier(version, tier)
    if not any(g.sources for g in the_tier.groups):
        raise UsageError(f"suite {version}'s tier {tier} declares no sources: each method trains its own there.")
    folder = tier_root(rundir.check_directory(out, "--out"), version, tier, smoke)
    runs = source_runs(the_tier, folder, smoke)
    for cfg in {json.dumps(r.cfg.model_dump(exclude={"seed"}), sort_keys=True, default=str): r.cfg
                for r in runs}.values():
        check_config(cfg)
    root = sources_root(folder).resolve()
    if dry_run:
        return {"plan": plan_lines(runs, root, 0, group_seeds)}
    make_out(runs, root, [])
    with rundir.lock(root, "sources folder"):
        pool = LocalBackend(workers or os.cpu_count() or 1)
        try:
            status = execute(runs, pool, desc="sources", group_seeds=group_seeds, progress=progress)
        finally:
            pool.close()
        failed = [str(p) for p, (state, _) in status.items() if state in ("failed", "diverged")]
        if failed:
            from drltg.errors import RunFailed

            raise RunFailed(f"{len(failed)} source run(s) failed or diverged (first: {failed[0]}); see their logs "
                            f"under {root / 'logs'}, then run the same command again to resume")
        entries = record(runs, {} if smoke else declared_sources(the_tier))
        rundir.write_files(root, {SOURCES: (json.dumps(entries, indent=1, sort_keys=True) + "\n").encode()})
    return entries


def use_sources(tier: Tier, tier_folder: Path, reference_folder: Path | None, smoke: bool,
                dry_run: bool = False) -> tuple[dict, bool | None]:
    """The ``transfer.source`` override of each group with sources (``{group: ".../seed-{seed}"}``), the tier's
    sources first copied from ``reference_folder`` where it holds them and they are not here; and whether they
    are the ones the suite declares (``None`` where it declares none). Missing sources are one sentence; a
    ``dry_run`` copies nothing and reads the reference's where they are."""
    from drltg.experiments.experiment import SEED

    runs = source_runs(tier, tier_folder, smoke)
    if not runs:
        return {}, None
    here = folder = sources_root(tier_folder).resolve()
    if reference_folder is not None and not smoke:
        kept = sources_root(reference_folder).resolve()
        absent = [r.path.relative_to(here) for r in runs
                  if not rundir.is_complete(r.path) and rundir.is_complete(kept / r.path.relative_to(here))]
        if dry_run and absent:
            folder = kept
        for name in () if dry_run else absent:
            copy_run(kept / name, here / name)
    missing = [r.path.relative_to(here) for r in runs if not rundir.is_complete(folder / r.path.relative_to(here))
               or not (folder / r.path.relative_to(here) / FILES[-1]).is_file()]
    if missing:
        flags = " --smoke" if smoke else ""
        raise UsageError(f"{len(missing)} of the tier's {len(runs)} sources are not finished in {folder} (first: "
                         f"{missing[0]}); train them with `drltg bench sources --suite {tier_folder.parent.name} "
                         f"--tier {tier.name}{flags} --out OUT`, or pass --reference with a folder that holds them.")
    overrides = {g.name: str(folder / g.name / f"seed-{SEED}") for g in tier.groups if g.sources}
    declared = {} if smoke or dry_run else declared_sources(tier)
    if not declared:
        return overrides, None
    entries = record(runs, declared)
    return overrides, all(e["declared"] for e in entries.values()) and len(entries) == len(declared)
