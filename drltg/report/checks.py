"""Stage 1, check: no run twice, one task and one configuration a side, paired or not."""
from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from drltg.errors import UsageError
from drltg.report.curves import Curve
from drltg.report.run_state import partition, run_directory
from drltg.report.settings import CONFIG_KEYS_PER_RUN, ReportSettings
from drltg.store import rundir


@dataclass
class Sides:
    """Both run sets once checked; when paired, ``transfer[i]`` is the pair of ``baseline[i]``."""

    baseline: list[Curve]
    transfer: list[Curve]
    task: str | None
    paired: bool
    pairing: str

    def items(self) -> tuple[tuple[str, list[Curve]], ...]:
        return ("baseline", self.baseline), ("transfer", self.transfer)

    @property
    def runs(self) -> list[Curve]:
        return self.baseline + self.transfer


def check_runs(baseline: Sequence[Curve], transfer: Sequence[Curve], s: ReportSettings,
               warnings: list[str]) -> Sides:
    """No run twice, one task, one configuration a side (unless ``--allow-mixed``), and the pairing."""
    baseline, transfer = list(baseline), list(transfer)
    if not baseline or not transfer:
        raise UsageError("both a baseline and a transfer run set are needed.")
    baseline, left_b = partition("baseline", baseline, bool(s.include_unfinished), warnings)
    transfer, left_t = partition("transfer", transfer, bool(s.include_unfinished), warnings)
    for side, runs, left in (("baseline", baseline, left_b), ("transfer", transfer, left_t)):
        if not runs:
            raise UsageError(f"no {side} run can be counted, each is {' or '.join(left)} "
                             f"({', '.join(r for runs in left.values() for r in runs)}); finish them, or pass "
                             "--include-unfinished.")
    _check_duplicates(baseline, transfer)
    _check_copies(baseline, transfer, bool(s.allow_mixed or s.include_unfinished))
    task = _check_tasks(baseline, transfer)
    for side, runs in (("baseline", baseline), ("transfer", transfer)):
        _check_configs(side, runs, bool(s.allow_mixed), warnings)
    _check_sides(baseline, transfer, bool(s.allow_mismatch), warnings)
    paired, pairing, transfer = _pairing(baseline, transfer, s.paired)
    if paired:
        _check_sources(baseline, transfer)
    for side, runs in (("baseline", baseline), ("transfer", transfer)):
        seeds = tuned_on(runs)
        if seeds:
            warnings.append(f"the {side} runs' recipe was chosen on seed{'s' if len(seeds) > 1 else ''} "
                            f"{', '.join(map(str, seeds))} (their config's tuned_on), which this report reads: a "
                            "result tuned on the seeds it reports, not a fresh-seed one.")
    return Sides(baseline, transfer, task, paired, pairing)


def nothing_learned(sides, threshold: float | None, budget: float) -> str | None:
    """Why the comparison measures nothing, where no run of either side ever reached ``threshold`` within
    ``budget`` frames (the best evaluation of any run below it: the crossing rule aside, none got there):
    a difference between two sides that both failed says nothing about transfer. ``None`` otherwise."""
    runs = [*sides.baseline, *sides.transfer]
    if threshold is None or not runs:
        return None
    best = max(float(np.max(c.values[c.frames <= budget], initial=-np.inf)) for c in runs)
    if best >= threshold:
        return None
    return (f"no run of either side ever reached the threshold {threshold:.4g} (the best evaluation of all "
            f"{len(runs)} runs is {best:.4g}): neither learned the task within the budget, so this comparison "
            "measures nothing about transfer; train longer, or check the task's reward and the learner's "
            "settings (a sparse reward may need a lower sac.alpha_init, docs/gymnasium.md).")


def tuned_on(runs: Sequence[Curve]) -> list[int]:
    """The seeds of ``runs`` that also chose their recipe (``tuned_on`` in the runs' configs)."""
    chosen = {int(x) for c in runs for x in ((c.config or {}).get("tuned_on") or ())}
    return sorted(chosen & {int(c.config["seed"]) for c in runs if (c.config or {}).get("seed") is not None})


def run_name(curve: Curve) -> str:
    return f"'{curve.label}' ({curve.source})"


def _check_duplicates(baseline: Sequence[Curve], transfer: Sequence[Curve]) -> None:
    """The same log file named twice would count as two seeds."""
    seen: dict[Path, str] = {}
    for side, curves in (("baseline", baseline), ("transfer", transfer)):
        for c in curves:
            if not Path(c.source).exists():
                continue
            key = Path(c.source).resolve()
            if seen.get(key) == side:
                raise UsageError(f"'{c.source}' is given twice among the {side} runs; a run counts as one "
                                 "seed, so name it once.")
            if key in seen:
                raise UsageError(f"'{c.source}' is both a baseline and a transfer run; compare two "
                                 "different run sets.")
            seen[key] = side


def _check_copies(baseline: Sequence[Curve], transfer: Sequence[Curve], allow_pooled: bool) -> None:
    """Two drltg runs with the same config, seed included, and the same curve are one run copied (or
    trained twice from one seed: the same run again); counted twice they would fake a seed. A side that
    pools drltg runs with logs that carry no config cannot be checked for one configuration: refused
    unless ``allow_pooled`` (``--allow-mixed``, or ``--include-unfinished`` for config-less drltg runs)."""
    for side, curves in (("baseline", baseline), ("transfer", transfer)):
        seen: dict[str, Curve] = {}
        for c in curves:
            if not c.config or c.config.get("seed") is None:
                continue
            key = json.dumps([c.config, c.frames.tolist(), c.values.tolist()], sort_keys=True, default=str)
            if key in seen:
                raise UsageError(f"{run_name(c)} and {run_name(seen[key])} are the same run (same config, seed "
                                 f"{c.config.get('seed')}, same curve); a run counts as one seed, so give it once.")
            seen[key] = c
        with_config = [c for c in curves if c.config]
        if with_config and len(with_config) < len(curves) and not allow_pooled:
            other = next(c for c in curves if not c.config)
            raise UsageError(f"the {side} runs pool drltg runs ({run_name(with_config[0])}) with logs that carry no "
                             f"config ({run_name(other)}), so one configuration a side cannot be checked; report "
                             "each kind apart, or pass --allow-mixed.")


def _check_tasks(baseline: Sequence[Curve], transfer: Sequence[Curve]) -> str | None:
    for side, curves in (("baseline", baseline), ("transfer", transfer)):
        known = [c for c in curves if c.task]
        if len({c.task for c in known}) > 1:
            a, b = known[0], next(c for c in known if c.task != known[0].task)
            raise UsageError(
                f"the {side} runs mix tasks: {run_name(a)} is on '{a.task}' but {run_name(b)} on '{b.task}'."
            )
    b = next((c for c in baseline if c.task), None)
    t = next((c for c in transfer if c.task), None)
    if b and t and b.task != t.task:
        raise UsageError(
            f"baseline and transfer are on different tasks: {run_name(b)} is on '{b.task}' but "
            f"{run_name(t)} on '{t.task}'; compare runs on the same target task."
        )
    return (b or t).task if (b or t) else None


def _flat(config: dict, prefix: str = "") -> dict:
    out = {}
    for key, value in config.items():
        if isinstance(value, dict):
            out.update(_flat(value, f"{prefix}{key}."))
        else:
            out[f"{prefix}{key}"] = value
    return out


def _check_configs(side: str, curves: Sequence[Curve], allow_mixed: bool, warnings: list[str]) -> None:
    """One side must be one method and one configuration (seeds, lengths, devices and sources may differ;
    a key a config saved by an older drltg lacks stands for its default, the built-in methods' options
    included). The task registry is never imported here (it needs torch), so an ``env.*`` key that only
    some configs set cannot be checked against its default: it is not compared, and a warning says so.
    Each config is compared with the fullest one (the most keys: the newest drltg's)."""
    known = [c for c in curves if c.config]
    if len(known) < 2:
        return
    from drltg.config import config_changes, env_keys_set_once

    first = max(known, key=lambda c: len(_flat(c.config)))
    unchecked: set[str] = set()
    for c in known:
        if c is first:
            continue
        ref, other = _flat(first.config), _flat(c.config)
        unchecked.update(env_keys_set_once(first.config, c.config))
        diff = [k for k in config_changes(first.config, c.config, env_defaults=False)
                if not any(k == p or k.startswith(p + ".") for p in CONFIG_KEYS_PER_RUN)]
        if diff:
            k = diff[0]
            more = f" ({len(diff)} keys differ)" if len(diff) > 1 else ""
            text = (f"the {side} runs mix configurations: {run_name(first)} has {k}={ref.get(k, '(unset)')} "
                    f"but {run_name(c)} has {k}={other.get(k, '(unset)')}{more}")
            if not allow_mixed:
                raise UsageError(text + "; compare one configuration per side, or pass --allow-mixed.")
            warnings.append(text + " (accepted by --allow-mixed).")
            return
    if unchecked:
        keys = sorted(unchecked)
        warnings.append(f"some {side} configs were saved without {', '.join(keys[:3])}"
                        + (f" and {len(keys) - 3} more env settings" if len(keys) > 3 else "")
                        + "; those keys are not compared (their defaults are the task's, which the report "
                        "does not load).")


PER_RUN = ("seed", "device", "threads", "log", "checkpoint", "transfer", "tuned_on")
"""Config sections and keys that do not change what a curve means (``transfer`` is what the report compares)."""


def _check_sides(baseline: Sequence[Curve], transfer: Sequence[Curve], allow: bool, warnings: list[str]) -> None:
    """Baseline and transfer runs must share every setting that changes what their curves mean: the task's
    options, the learner and its network, buffer, collector and optimizer, the evaluation's episodes and
    interval, and the frames; a mismatch is refused, or with ``--allow-mismatch`` listed in the report."""
    from drltg.config import config_changes

    configs = [max((c for c in side if c.config), key=lambda c: len(_flat(c.config)), default=None)
               for side in (baseline, transfer)]
    if None in configs:
        return
    b, t = configs
    keys = [k for k in config_changes(b.config, t.config, env_defaults=False) if k.split(".")[0] not in PER_RUN]
    if not keys:
        return
    ref, other = _flat(b.config), _flat(t.config)
    leaves = [x for k in keys for x in sorted({x for x in (*ref, *other) if x == k or x.startswith(f"{k}.")})]
    text = ", ".join(f"{k} ({ref.get(k, '(unset)')} vs {other.get(k, '(unset)')})" for k in leaves)
    if not allow:
        raise UsageError(f"the baseline {run_name(b)} and transfer {run_name(t)} runs differ in settings that "
                         f"change what a curve means: {text}; compare like with like, or pass --allow-mismatch.")
    warnings.append(f"baseline and transfer settings differ (--allow-mismatch): {text}")


SEED_FOLDER = re.compile(r"seed[-_]?(\d+)")


def seed_of(curve: Curve):
    """The run's seed: its config's, else the number of a ``seed-N`` folder on its path (foreign logs kept
    one folder per seed, as ``drltg experiment`` keeps runs); ``None`` if neither says."""
    seed = (curve.config or {}).get("seed")
    if isinstance(seed, int) and not isinstance(seed, bool):
        return seed
    return _folder_seed(curve)


def _folder_seed(curve: Curve) -> int | None:
    named = [m for part in curve.source.parts if (m := SEED_FOLDER.fullmatch(part))]
    return int(named[-1].group(1)) if named else None


def source_digest(curve: Curve) -> str | None:
    """The SHA-256 of the source networks a drltg run loaded, as its ``summary.json`` records it
    (:func:`drltg.transfer.source.record`); ``None`` for a run that reused no source, or a foreign log."""
    run = run_directory(curve)
    path = None if run is None else run / rundir.SUMMARY
    if path is None or not path.is_file():
        return None
    from drltg.regular import MAX_META_BYTES, read_bytes

    try:
        source = json.loads(read_bytes(path, MAX_META_BYTES, "a run summary")).get("source")
    except (OSError, ValueError, AttributeError):
        return None  # an unreadable summary is the run state's sentence (incomplete), not this one's
    digest = source.get("networks_sha256") if isinstance(source, dict) else None
    return digest if isinstance(digest, str) else None


def _check_sources(baseline: list[Curve], transfer: list[Curve]) -> None:
    """Paired runs that both reused a source reused the same one (by its networks' SHA-256): else the pairs'
    differences would measure two teachers, not two methods."""
    for b, t in zip(baseline, transfer):
        mine, theirs = source_digest(b), source_digest(t)
        if mine is not None and theirs is not None and mine != theirs:
            raise UsageError(f"the pair of seed {seed_of(b)} learned from two sources ({run_name(b)} loaded networks "
                             f"{mine[:12]}..., {run_name(t)} {theirs[:12]}..., by the SHA-256 each summary.json "
                             "records), so paired by seed the report would compare teachers, not methods; compare "
                             "runs that reused the same sources.")


def _pairing(baseline: list[Curve], transfer: list[Curve], paired: bool | None) -> tuple[bool, str, list[Curve]]:
    """Whether the runs are analysed in pairs, why, and the transfer runs in the baseline's order."""
    sb, st = [seed_of(c) for c in baseline], [seed_of(c) for c in transfer]
    recorded = all(s is not None for s in sb + st)
    one_to_one = recorded and len(set(sb)) == len(sb) and len(set(st)) == len(st) and set(sb) == set(st)
    if paired is False:
        return False, "unpaired: paired=False was given", transfer
    if one_to_one:
        order = {s: c for s, c in zip(st, transfer)}
        if all(c.config and seed_of(c) == (c.config or {}).get("seed") for c in baseline + transfer):
            how, where = "--paired" if paired else "drltg runs", "in its config.yaml"
        else:
            how, where = "--paired" if paired else "seed-N folders", "(its config.yaml, or its seed-N folder)"
        return True, (f"paired by seed ({how}): each baseline run has the transfer run with the same seed "
                      f"{where}"), [order[s] for s in sb]
    if recorded:
        why = (f"the baseline seeds {sorted(sb)} and transfer seeds {sorted(st)} do not match one to one")
        if paired:
            raise UsageError(f"--paired cannot pair these runs: {why}.")
        return False, f"unpaired: {why}", transfer
    if paired:
        if len(baseline) != len(transfer):
            raise UsageError(f"--paired needs as many transfer runs as baseline runs (got {len(baseline)} "
                             f"baseline, {len(transfer)} transfer).")
        return True, "paired in the order given (--paired; the logs record no seed)", transfer
    return False, ("unpaired: not every run records its seed (foreign logs); pass --paired when run i of "
                   "both sides shares seed and initial weights"), transfer
