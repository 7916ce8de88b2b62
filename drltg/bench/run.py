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

import json
import platform
import shutil
from pathlib import Path

from drltg.bench.suite import LATEST, Group, get_tier
from drltg.errors import RunFailed, UsageError
from drltg.store import rundir

__all__ = ["bench_run", "tier_root", "read_record", "REFERENCE_FILES"]

REFERENCE_FILES = ("config.yaml", "eval.csv", "summary.json", "manifest.json", "checkpoints/last.safetensors")
"""What a reference run holds and a bench run copies: the curve a report reads, and the networks a source
is reused from."""
RECORD = "bench.json"


def tier_root(out: str | Path, version: str, tier: str, smoke: bool = False) -> Path:
    return Path(out) / version / (f"{tier}-smoke" if smoke else tier)


def read_record(root: Path) -> dict:
    """``bench.json`` of a tier folder (``{"methods": {}}`` where there is none)."""
    from drltg.regular import read_bytes

    path = root / RECORD
    if not path.exists():
        return {"methods": {}}
    try:
        record = json.loads(read_bytes(path, 2**22, "a bench record"))
        if not isinstance(record.get("methods"), dict):
            raise ValueError
        return record
    except (ValueError, AttributeError):
        raise UsageError(f"'{path}' is not a bench record (JSON with a 'methods' mapping); remove it and run "
                         "drltg bench run again.") from None


def versions() -> dict:
    import torch
    import torchrl

    import drltg

    return {"drltg": drltg.__version__, "torch": torch.__version__, "torchrl": torchrl.__version__,
            "python": platform.python_version()}


def applicable_pairs(group: Group, method: str, smoke: bool, out: Path) -> tuple[list[str], dict[str, str]]:
    """The group's pairs the method runs on, and for each other pair the method's sentence why not."""
    from drltg.experiments.experiment import check_runs
    from drltg.experiments.spec import parse_spec
    from drltg.experiments.sweep import plan

    kept, left_out = [], {}
    for pair in group.pairs:
        spec = {**group.sweep_spec([method], smoke), "pairs": [pair]}
        try:
            runs, _ = plan(parse_spec(spec, f"suite group {group.name}"), out)
            check_runs([(r.role, r.cfg, r.path) for r in runs])
        except UsageError as err:
            left_out[pair] = str(err).removeprefix(f"suite group {group.name}: ")
        else:
            kept.append(pair)
    return kept, left_out


def copy_reference(runs, out: Path, reference: Path) -> int:
    """Copy the finished source and baseline runs the reference holds at each planned run's relative path;
    the number copied."""
    copied = 0
    for run in runs:
        if run.role not in ("source", "baseline") or (run.path / "summary.json").exists():
            continue
        kept = reference / run.path.relative_to(out)
        if not rundir.is_complete(kept) or (run.role == "source" and not (kept / REFERENCE_FILES[-1]).is_file()):
            continue
        for name in REFERENCE_FILES:
            if (kept / name).is_file():
                (run.path / name).parent.mkdir(parents=True, exist_ok=True)
                shutil.copyfile(kept / name, run.path / name)
        copied += 1
    return copied


def bench_run(method: str, *, tier: str = "quick", out: str | Path = "runs/bench", version: str = LATEST,
              reference: str | Path | None = None, smoke: bool = False, workers: int | None = None,
              backend: str = "local", group_seeds: bool = True, progress: bool = True, imports=()) -> dict:
    """Train ``method`` on every group of the tier into ``out`` and record it; returns the bench record.

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
    read_record(root)  # a broken record is refused before anything trains
    entry = {"versions": versions(), "smoke": smoke, "imports": list(imports), "groups": {}, "left_out": {},
             "reference": str(reference_root) if reference_root else None, "copied": 0}
    for group in the_tier.groups:
        group_out = root / group.name
        pairs, left_out = applicable_pairs(group, method, smoke, group_out)
        entry["left_out"].update(left_out)
        if not pairs:
            continue
        spec = {**group.sweep_spec([method], smoke), "pairs": pairs}
        entry["groups"][group.name] = spec
        if reference_root is not None:
            runs, _ = plan(parse_spec(spec), group_out.resolve())
            entry["copied"] += copy_reference(runs, group_out.resolve(), (reference_root / group.name).resolve())
        result = sweep(spec, group_out, backend=backend, workers=workers, group_seeds=group_seeds,
                       progress=progress)
        failed = [str(p) for p, (state, _) in result["status"].items() if state in ("failed", "diverged")]
        if failed:
            raise RunFailed(f"{len(failed)} run(s) of {method} on {group.name} failed or diverged (first: "
                            f"{failed[0]}); see their logs under {group_out / 'logs'}, then run the same command "
                            "again to resume")
    record = read_record(root)  # another method may have finished meanwhile
    record.setdefault("suite", version)
    record.setdefault("tier", tier)
    record["methods"][method] = entry
    rundir.write_files(root, {RECORD: (json.dumps(record, indent=1, sort_keys=True) + "\n").encode()})
    return record
