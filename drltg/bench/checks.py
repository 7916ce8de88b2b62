"""The shape of what the bench reads, checked before any number of it is used: ``bench.json`` and each
pair's ``transfer_metrics.json``. A copied, hand-edited or truncated file is one sentence, never a traceback
or a board that ranks a wrong score: each report must be its pair's (target task, budget, value range),
every score finite and inside its range, every verdict a word the board knows."""
from __future__ import annotations

import json
import math
import re
from pathlib import Path

from drltg.errors import UsageError, short

__all__ = ["read_json", "check_record", "check_report", "check_reps", "check_source", "MAX_REPS", "VERDICTS"]

MIN_REPS, MAX_REPS = 100, 100_000
"""Bootstrap resamples of a board's intervals: at least as many as ``drltg report --bootstrap`` takes, and a
bound that keeps a report within minutes."""
VERDICTS = ("higher", "lower", "undecided")
_SHA256 = re.compile(r"[0-9a-f]{64}")


class _Bad(Exception):
    """What is wrong with a record, in words; turned into the reader's one sentence."""


def check_reps(reps) -> int:
    """``--reps`` as an integer in [MIN_REPS, MAX_REPS]."""
    if isinstance(reps, bool) or not isinstance(reps, int) or not MIN_REPS <= reps <= MAX_REPS:
        raise UsageError(f"--reps must be an integer from {MIN_REPS} to {MAX_REPS:,} bootstrap resamples, "
                         f"got {short(reps)}.")
    return reps


def read_json(path: Path, root: Path, limit: int, what: str):
    """The JSON of the regular file ``path``, which must lie inside ``root`` once links are followed (a link
    out of the bench folder would put another folder's numbers on this board)."""
    from drltg.regular import read_bytes

    real = path.resolve()
    if not real.is_relative_to(root.resolve()):
        raise UsageError(f"'{path}' is a link to '{real}', outside the bench folder '{root}'; a bench folder "
                         f"holds {what} itself, so copy the file in.")
    try:
        return json.loads(read_bytes(real, limit, what))
    except RecursionError:
        raise UsageError(f"'{path}' nests deeper than {what} does; remove it and run drltg bench run "
                         "again.") from None
    except ValueError as err:  # UnicodeDecodeError and json.JSONDecodeError are ValueErrors
        if isinstance(err, UsageError):
            raise
        raise UsageError(f"'{path}' is not {what} (not JSON: {err}); remove it and run drltg bench run "
                         "again.") from None


def _mapping(value, where: str) -> dict:
    if not isinstance(value, dict):
        raise _Bad(f"{where} is {short(value)}, not a mapping")
    return value


def _number(value, where: str) -> float:
    """A finite number (not a bool, a string or one past a float's range)."""
    try:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(float(value)):
            raise TypeError
    except (TypeError, OverflowError):
        raise _Bad(f"{where} is {short(value)}, not a finite number") from None
    return float(value)


def _words(value, where: str) -> dict:
    value = _mapping(value, where)
    for key, text in value.items():
        if not (text is None or isinstance(text, str)):
            raise _Bad(f"{where}['{key}'] is {short(text)}, not text")
    return value


def check_record(record, path: Path, version: str, tier: str) -> dict:
    """``record`` if it is a bench record of suite ``version``'s tier ``tier``, else one sentence."""
    try:
        _mapping(record, "the record")
        for key, want in (("suite", version), ("tier", tier)):
            if key in record and record[key] != want:
                raise _Bad(f"it records {key} {short(record[key])}, but it lies in the folder of {key} "
                           f"'{want}'")
        for method, entry in _mapping(record.get("methods"), "'methods'").items():
            where = f"method '{method}'"
            _mapping(entry, where)
            if not isinstance(entry.get("smoke", False), bool):
                raise _Bad(f"{where}'s 'smoke' is {short(entry['smoke'])}, not true or false")
            _words(entry.get("versions", {}), f"{where}'s 'versions'")
            _words(entry.get("left_out", {}), f"{where}'s 'left_out'")
            for group, spec in _mapping(entry.get("groups", {}), f"{where}'s 'groups'").items():
                _mapping(spec, f"{where}'s group '{group}'")
                pairs = spec.get("pairs", [])
                if not isinstance(pairs, list) or not all(isinstance(p, str) for p in pairs):
                    raise _Bad(f"{where}'s group '{group}' has pairs {short(pairs)}, not a list of names")
    except _Bad as why:
        raise UsageError(f"'{path}' is not a bench record of {version} {tier} ({why}); remove it and run drltg "
                         "bench run again.") from None
    return record


def _seeds(value, where: str, lo: float, hi: float) -> dict[int, float]:
    """``{seed: mean return}`` of one side, each return finite and inside the value range."""
    if not isinstance(value, list) or not value:
        raise _Bad(f"{where} is {short(value)}, not a list of seeds")
    out = {}
    for x in value:
        x = _mapping(x, f"a seed of {where}")
        seed = x.get("seed")
        if isinstance(seed, bool) or not isinstance(seed, int) or seed in out:
            raise _Bad(f"{where} has seed {short(seed)}, not an integer seen once")
        r = _number(x.get("mean_return"), f"the mean return of {where} seed {seed}")
        if not lo - 1e-9 * (hi - lo) <= r <= hi + 1e-9 * (hi - lo):
            raise _Bad(f"the mean return of {where} seed {seed}, {r:.4g}, lies outside the value range "
                       f"[{lo:.4g}, {hi:.4g}]")
        out[seed] = r
    return out


def check_report(report, path: Path, pair: str, *, target: str | None, frames: int | None,
                 declared: tuple[float, float] | None) -> dict:
    """``report`` if it is ``pair``'s: on its target task, over about the ``frames`` its group ran, on the
    task's ``declared`` value range, with finite scores inside it and a known verdict; else one sentence."""
    try:
        _mapping(report, "the report")
        st, m = _mapping(report.get("settings"), "'settings'"), _mapping(report.get("metrics"), "'metrics'")
        if target is not None and st.get("task") != target:
            raise _Bad(f"it is on task {short(st.get('task'))}, not {pair}'s target task '{target}'")
        vr = st.get("value_range")
        if not isinstance(vr, list) or len(vr) != 2:
            raise _Bad(f"its value range is {short(vr)}, not [low, high]")
        lo, hi = _number(vr[0], "the value range's low"), _number(vr[1], "the value range's high")
        if not lo < hi:
            raise _Bad(f"its value range [{lo:.4g}, {hi:.4g}] does not have low < high")
        if declared is not None and not all(math.isclose(a, b, rel_tol=1e-9) for a, b in zip((lo, hi), declared)):
            raise _Bad(f"its value range [{lo:.4g}, {hi:.4g}] is not the [{declared[0]:.4g}, {declared[1]:.4g}] "
                       f"the target task declares")
        if frames is not None and st.get("budget") is not None:
            budget = _number(st["budget"], "its budget")
            if abs(budget - frames) > max(frames / 10, 1024):
                raise _Bad(f"its budget is {budget:,.0f} frames, not the {frames:,} its group ran")
        sides = _mapping(report.get("per_seed"), "'per_seed'")
        b, t = (_seeds(sides.get(s), f"the {s} side", lo, hi) for s in ("baseline", "transfer"))
        if not set(b) & set(t):
            raise _Bad("no seed is on both sides")
        verdict = m.get("mean_return_gain_verdict")
        if verdict not in VERDICTS:
            raise _Bad(f"its verdict is {short(verdict)}, not one of {', '.join(VERDICTS)}")
        p = m.get("mean_return_gain_verdict_p")
        if p is not None and not 0 <= _number(p, "its verdict's p-value") <= 1:
            raise _Bad(f"its verdict's p-value {p:.4g} lies outside [0, 1]")
        if not isinstance(m.get("mean_return_gain_verdict_test"), (str, type(None))):
            raise _Bad(f"its verdict's test is {short(m['mean_return_gain_verdict_test'])}, not text")
    except _Bad as why:
        raise UsageError(f"'{path}' is not a transfer report of {pair} ({why}); remove it and run drltg bench run "
                         "again to rewrite it.") from None
    return report


def check_source(summary, path: Path) -> dict | None:
    """The digests a transfer run's ``summary.json`` records of the source it loaded, ``{"networks_sha256",
    "config_sha256"}`` (:func:`drltg.transfer.source.record`); ``None`` for a run that records none (one
    written before drltg recorded it); anything else one sentence."""
    try:
        source = _mapping(summary, "the summary").get("source")
        if source is None:
            return None
        source = _mapping(source, "its 'source'")
        for key in ("networks_sha256", "config_sha256"):
            if not isinstance(source.get(key), str) or not _SHA256.fullmatch(source[key]):
                raise _Bad(f"its source's {key} is {short(source.get(key))}, not a SHA-256 in hex")
    except _Bad as why:
        raise UsageError(f"'{path}' is not a run summary ({why}); remove the run and run drltg bench run again "
                         "to train it.") from None
    return {key: source[key] for key in ("networks_sha256", "config_sha256")}
