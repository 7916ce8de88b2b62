"""``drltg bench run``: one method on a tier of the suite, the no-transfer baselines and the sources taken
from a reference folder of the same suite version instead of being trained again.

Each group of the tier is one ``drltg sweep`` of that method into ``OUT/<version>/<tier>/<group>/`` (the
sweep's layout; seed groups, resumable, a local pool or Ray). Before it runs, every source and baseline
run the sweep plans that the reference holds, finished, at the same relative path is copied in as data
(config, curve, summary, manifest and the networks file a source is reused from); the sweep then skips it,
and refuses it in one sentence if its config is not the protocol's. A pair the method cannot run on (SF-GPI
where the dynamics differ) is recorded with the method's own sentence and left out.

What ran is recorded in ``OUT/<version>/<tier>/bench.json``: per method, the versions of drltg, torch and
Python it ran under, the specs, the pairs left out and why, and whether it ran at smoke budgets
(``OUT/<version>/<tier>-smoke/``), so that ``drltg bench report`` can mark a row that is not the protocol's.
"""
from __future__ import annotations

import dataclasses
import json
import platform
from pathlib import Path

from drltg.bench.sources import use_sources
from drltg.bench.suite import LATEST, REFERENCE_FILES, Group, copy_run, get_tier, tier_root, tuning_root
from drltg.errors import RunFailed, UsageError
from drltg.store import rundir

__all__ = ["bench_run", "tier_root", "read_record", "read_tuning", "tuning_root", "REFERENCE_FILES"]

RECORD = "bench.json"
TUNING = "tuning.json"


def read_tuning(out: str | Path, version: str, tier: str, method: str, smoke: bool = False) -> dict | None:
    """The method's ``tuning.json`` in a bench folder, checked to be a choice among its declared settings, or
    ``None`` where it was not tuned."""
    from drltg.bench.checks import read_json
    from drltg.transfer import get_method

    root = tuning_root(out, version, tier, method, smoke)
    path = root / TUNING
    if not path.exists() and not path.is_symlink():
        return None
    record = read_json(path, root, 2**22, "a tuning record")
    if method == "none":  # a choice per group, each among the group's own settings
        groups = get_tier(version, tier).groups
        chosen = record.get("choice") if isinstance(record, dict) else None
        good = isinstance(chosen, dict) and sorted(chosen) == sorted(g.name for g in groups) and all(
            chosen[g.name] in g.baseline_settings for g in groups)
    else:
        good = isinstance(record, dict) and record.get("choice") in get_method(method).settings
    if not good or record.get("method") != method:
        raise UsageError(f"'{path}' is not a tuning record of {method} choosing one of its declared settings; "
                         "run drltg bench tune again.")
    return record


def read_record(root: Path, version: str | None = None, tier: str | None = None) -> dict:
    """``bench.json`` of a tier folder (``{"methods": {}}`` where there is none), checked to be a bench record
    of that folder's suite ``version`` and ``tier`` (``root``'s own names where not given)."""
    from drltg.bench.checks import check_record, read_json

    path = root / RECORD
    if not path.exists() and not path.is_symlink():
        return {"methods": {}}
    version = version or root.parent.name
    tier = tier or root.name.removesuffix("-smoke")
    return check_record(read_json(path, root, 2**22, "a bench record"), path, version, tier)


def versions() -> dict:
    import torch
    import torchrl

    import drltg

    return {"drltg": drltg.__version__, "torch": torch.__version__, "torchrl": torchrl.__version__,
            "python": platform.python_version()}


def group_spec(group: Group, method: str, smoke: bool, given: dict[str, str], choice: dict) -> dict:
    """The sweep spec of ``method`` on ``group``: the suite's, its runs reading the suite's sources where it
    declares them (``given``: group -> ``.../seed-{seed}``) and the method reads one, at the tuned ``choice`` (the
    baseline's and the method's)."""
    from drltg.transfer import get_method

    spec = group.sweep_spec([method], smoke)
    reads = get_method(method).source is not None
    source = {"transfer.source": given[group.name]} if group.name in given and reads else {}
    return {**spec, "overrides": {**spec.get("overrides", {}), **source, **choice}}


def baseline_tuning(tier, out, reference, version: str, smoke: bool) -> dict | None:
    """The tuning record of the tier's baseline (``drltg bench tune --method none``): ``out``'s, else the
    reference's; ``None`` where the tier tunes no baseline. A tier that does and has none is one sentence,
    since a row against an untuned baseline flatters the method (a smoke row runs at the defaults)."""
    if not tier.tunes_baseline:
        return None
    for folder in (out, reference):
        if folder is not None and (found := read_tuning(folder, version, tier.name, "none", smoke)) is not None:
            return found
    if smoke:
        return None
    raise UsageError(f"suite {version}'s tier {tier.name} tunes its baseline before any row: run `drltg bench tune "
                     f"--method none --suite {version} --tier {tier.name}` first, or pass a --reference that holds "
                     "its tuning.")


def _tuning_entry(tuning: dict | None) -> dict | None:
    return None if tuning is None else {k: tuning[k] for k in ("budget", "choice", "rule", "seeds")}


def applicable_pairs(group: Group, method: str, smoke: bool, out: Path,
                     spec: dict | None = None) -> tuple[list[str], dict[str, str]]:
    """The group's pairs the method runs on (with ``spec``, default the suite's), and for each other pair the
    method's sentence why not."""
    from drltg.experiments.experiment import check_runs
    from drltg.experiments.spec import parse_spec
    from drltg.experiments.sweep import plan

    whole = parse_spec(spec or group.sweep_spec([method], smoke), f"suite group {group.name}")
    kept, left_out = [], {}
    for pair in group.pairs:
        try:
            runs, _ = plan(dataclasses.replace(whole, pairs=[pair]), out)
            check_runs([(r.role, r.cfg, r.path) for r in runs])
        except UsageError as err:
            left_out[pair] = str(err)
        else:
            kept.append(pair)
    return kept, left_out


def in_reference(runs, out: Path, reference: Path) -> dict[Path, Path]:
    """The planned source and baseline runs not finished here whose reference run, at the same relative path,
    is finished (a source with its networks file): run directory -> the reference's."""
    held = {}
    for run in runs:
        if run.role not in ("source", "baseline") or (run.path / rundir.SUMMARY).exists():
            continue
        kept = reference / run.path.relative_to(out)
        if rundir.is_complete(kept) and (run.role != "source" or (kept / REFERENCE_FILES[-1]).is_file()):
            held[run.path] = kept
    return held


def copy_reference(runs, out: Path, reference: Path) -> int:
    """Copy the finished source and baseline runs the reference holds at each planned run's relative path;
    the number copied."""
    held = in_reference(runs, out, reference)
    for path, kept in held.items():
        copy_run(kept, path)
    return len(held)


def plan_tier(groups: list[tuple[str, dict, Path]], reference_root: Path | None, group_seeds: bool) -> list[str]:
    """What a tier's command would train, group by group, before anything trains: ``(name, sweep spec, folder)``
    each, listed as units of work (seed groups and their sizes) and the frames left, the runs the reference
    holds counted as copied."""
    from drltg.experiments.executor import plan_of
    from drltg.experiments.spec import parse_spec
    from drltg.experiments.sweep import plan

    lines, left, total = [], 0, 0
    for name, spec, out in groups:
        runs, cells = plan(parse_spec(spec), out.resolve())
        held = in_reference(runs, out.resolve(), (reference_root / name).resolve()) if reference_root else {}
        planned = plan_of(runs, group_seeds, frozenset(held))
        lines += [f"{name}: {line}" for line in planned.summary(runs, len(cells))]
        left, total = left + planned.left, total + sum(r.frames for r in runs)
    lines.append(f"the tier: about {left:,} of {total:,} frames left to train")
    return lines


def bench_run(method: str, *, tier: str = "quick", out: str | Path = "runs/bench", version: str = LATEST,
              reference: str | Path | None = None, smoke: bool = False, workers: int | None = None,
              backend: str = "local", group_seeds: bool = True, progress: bool = True, imports=(),
              dry_run: bool = False) -> dict:
    """Train ``method`` on every group of the tier into ``out`` and record it; returns the bench record
    (with ``dry_run``, ``{"plan": lines}``: the tier's work, :func:`plan_tier`, and nothing written).

        >>> drltg.bench.bench_run("kickstarting", out="runs/bench", reference="results/bench", workers=2)
    """
    from drltg.experiments.spec import parse_spec
    from drltg.experiments.sweep import plan, sweep
    from drltg.transfer import get_method

    the_tier = get_tier(version, tier)
    get_method(method)
    if method == "none":
        raise UsageError("'none' is the baseline every row is compared with; name a transfer method.")
    root = rundir.check_directory(tier_root(out, version, tier, smoke), "--out")
    reference_root = None
    if reference is not None and not smoke:
        reference_root = tier_root(rundir.check_directory(reference, "--reference"), version, tier)
    read_record(root, version, tier)  # a broken record is refused before anything trains
    tuning = read_tuning(out, version, tier, method, smoke)
    given, declared = use_sources(the_tier, root, reference_root, smoke, dry_run)  # the first step, first
    baseline = baseline_tuning(the_tier, out, reference, version, smoke)
    learner = baseline["choice"] if baseline else {}
    choice = tuning["choice"] if tuning else {}
    entry = {"versions": versions(), "smoke": smoke, "imports": list(imports), "groups": {}, "left_out": {},
             "reference": str(reference_root) if reference_root else None, "copied": 0,
             "tuning": _tuning_entry(tuning), "baseline_tuning": _tuning_entry(baseline),
             "sources": None if not given else {"declared": declared}}
    for group in the_tier.groups:
        spec = group_spec(group, method, smoke, given, {**learner.get(group.name, {}), **choice})
        pairs, left_out = applicable_pairs(group, method, smoke, root / group.name, spec)
        entry["left_out"].update(left_out)
        if pairs:
            entry["groups"][group.name] = {**spec, "pairs": pairs}
    if dry_run:
        return {"plan": plan_tier([(g, spec, root / g) for g, spec in entry["groups"].items()], reference_root,
                                  group_seeds)}
    for name, spec in entry["groups"].items():
        group_out = root / name
        if reference_root is not None:
            runs, _ = plan(parse_spec(spec), group_out.resolve())
            entry["copied"] += copy_reference(runs, group_out.resolve(), (reference_root / name).resolve())
        result = sweep(spec, group_out, backend=backend, workers=workers, group_seeds=group_seeds,
                       progress=progress)
        failed = [str(p) for p, (state, _) in result["status"].items() if state in ("failed", "diverged")]
        if failed:
            raise RunFailed(f"{len(failed)} run(s) of {method} on {name} failed or diverged (first: "
                            f"{failed[0]}); see their logs under {group_out / 'logs'}, then run the same command "
                            "again to resume")
    record = read_record(root, version, tier)  # another method may have finished meanwhile
    record.setdefault("suite", version)
    record.setdefault("tier", tier)
    record["methods"][method] = entry
    rundir.write_files(root, {RECORD: (json.dumps(record, indent=1, sort_keys=True) + "\n").encode()})
    for group in the_tier.groups:
        summarise_group(group, record, smoke, root / group.name)
    return record


def summarise_group(group: Group, record: dict, smoke: bool, group_out: Path) -> None:
    """Rewrite a group's summaries, aggregates and Holm families over every method the record holds there:
    the sweep of one method summarises that method alone, which in a folder shared by several methods would
    drop the others'. Nothing trains; a run not finished is an incomplete cell, as in the sweep's summary."""
    from drltg.experiments.spec import parse_spec
    from drltg.experiments.sweep import plan, write_summary

    methods = {m: e["groups"][group.name] for m, e in sorted(record["methods"].items())
               if group.name in e.get("groups", {})}
    if len(methods) < 2:
        return  # the sweep's own summary holds the one method
    runs, cells, spec = {}, [], None
    for method, ran in methods.items():  # as it ran: its pairs, and its tuned setting among the overrides
        spec = parse_spec({**group.sweep_spec([method], smoke), "pairs": ran["pairs"],
                           "overrides": ran.get("overrides", group.spec.get("overrides", {}))},
                          f"suite group {group.name}")
        planned, planned_cells = plan(spec, group_out.resolve())
        for r in planned:
            runs.setdefault(r.path, r)
        cells += planned_cells
    status = {}
    for path in runs:
        ended = rundir.summary_status(path)
        status[path] = (("skipped" if ended[0] == "complete" else ended[0]), ended[1]) if ended else ("not started", "")
    with rundir.lock(group_out, "sweep folder"):
        write_summary(spec, group_out.resolve(), list(runs.values()), cells, status, "mean_return_gain")
