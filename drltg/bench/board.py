r"""The leaderboard of a tier: every method's score per pair and in aggregate, each with a verdict that keeps
its level at the seeds used.

Rows are read from the reports ``drltg bench run`` left (each pair's ``transfer_metrics.json``: its seeds'
mean returns over the budget, the declared range, the exact sign-flip verdict). For method :math:`m` on
pair :math:`p` with normalised areas :math:`a_{T,i}, a_{B,i}` of seed :math:`i`:

- **FT** (:mod:`drltg.bench.suite`): :math:`FT_{p,i} = (a_{T,i} - a_{B,i}) / (1 - \bar a_B)`, the pair's
  score their mean; its verdict against no transfer is the report's exact sign-flip test of the paired
  differences (dividing by a constant changes no sign);
- **against the best reference row** (the top-ranked reference row): the sign-flip test of
  :math:`a_{m,i} - a_{best,i}` over the seeds both ran, on each pair both cover;
- **aggregates** (rliable): the IQM of all :math:`FT_{p,i}` and P(T > B) over the pairs, each with a 95%
  stratified-bootstrap interval; the aggregate verdicts are the stratified sign-flip test over the
  pairs (:func:`drltg.analysis.stats.stratified_sign_flip`).

**Ranking**: the rows on protocol by the IQM of FT alone, each over the pairs it covers (a method that cannot
run on a pair is ranked on the others, and the table says so). **Per-pair verdicts** are Holm-adjusted within
each row (:func:`drltg.analysis.stats.holm`): the family is that row's per-pair tests against no transfer (and,
apart, its per-pair tests against the best reference row), so a row's arrows together keep the level.
**p-values**: an enumerated one is exact; a Monte Carlo one (:math:`(b + 1)/(m + 1)` of :math:`m` draws) at its
floor is only a bound, written ``p ≤ 1e-05 (99,999 draws)`` by :func:`p_text`, the one formatter of the board.

A row run at other budgets, with fewer seeds, under another drltg or torch version than the reference, or
with pairs missing is marked with what differs, left out of the ranking and compared with no row but its own
baseline; it still appears on every table and figure.

Rows are paired by seed, so runs of one (pair, seed) slot must have learned from one source: each transfer
run's ``summary.json`` records the SHA-256 of the source networks and config it loaded
(:func:`drltg.transfer.source.record`), and a board whose slot holds two different ones is refused in one
sentence (:func:`check_sources`). A run written before drltg recorded them is paired as before and its row
said to be unverified. A smoke row, whose sources are its own at smoke budgets, is paired with no other.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from drltg.analysis.claims import LEVEL
from drltg.bench.checks import check_report, check_reps, check_source, read_json
from drltg.bench.run import read_record, tier_root
from drltg.bench.suite import Group, Tier
from drltg.errors import UsageError
from drltg.store import rundir

__all__ = ["leaderboard", "board_table", "pair_table", "label", "p_text", "test_name", "check_sources", "tuned_text",
           "baseline_sentence", "ALPHA"]

ALPHA = LEVEL  # the board's verdicts are at drltg's one level
PAIR_DRAWS = 9999
"""Draws of the per-pair test against the best reference row: exact while the 2^n sign patterns number at most
this (up to 13 seeds), else Monte Carlo, two-sided floor 2 / (draws + 1)."""
COMPARED_VERSIONS = ("drltg", "torch")


def _verdict(estimate: float, p: float | None) -> str:
    if p is None or p >= ALPHA or estimate == 0:
        return "undecided"
    return "higher" if estimate > 0 else "lower"


def p_text(p: float, draws: int | None = None, floor: float | None = None) -> str:
    """A p-value as the board prints it: ``p = 0.0039`` where it is exact or a Monte Carlo value above its
    floor; at the floor, where no draw was as extreme, ``p ≤ 1e-05 (99,999 draws)``: the draws bound p there,
    they do not measure it."""
    if draws is not None and floor is not None and p <= floor * (1 + 1e-9):
        return f"p ≤ {floor:.2g} ({draws:,} draws)"
    return f"p = {p:.2g}"


def test_name(test: str, draws: int | None) -> str:
    """The test's name and how its p-value was found: every sign pattern counted (exact) or a Monte Carlo (its
    draws in ``draws``, and in :func:`p_text` at the floor)."""
    return f"{test}, {'exact' if draws is None else 'Monte Carlo'}"


def _stratified(strata: list, seed: int) -> tuple[float, dict]:
    """:func:`drltg.analysis.stats.stratified_sign_flip` and how its p-value was found: exact while the pairs
    number at most ``STRATIFIED_EXACT_PAIRS``, else ``(b + 1)/(m + 1)`` of ``m`` draws (floor 1/(m + 1))."""
    from drltg.analysis.stats import STRATIFIED_EXACT_PAIRS, STRATIFIED_RESAMPLES, stratified_sign_flip

    total, p = stratified_sign_flip(strata, seed=seed, n_resamples=STRATIFIED_RESAMPLES,
                                    exact_pairs=STRATIFIED_EXACT_PAIRS)
    draws = None if sum(len(s) for s in strata) <= STRATIFIED_EXACT_PAIRS else STRATIFIED_RESAMPLES
    return total, {"p": p, "draws": draws, "p_floor": None if draws is None else 1 / (draws + 1)}


def _holm(tests: dict, direction) -> None:
    """``p_holm`` and ``verdict_holm`` of each of a row's per-pair tests, Holm-adjusted over the family."""
    from drltg.analysis.stats import holm

    keys = [k for k, t in tests.items() if t.get("p") is not None and t.get("verdict") != "equivalent"]
    for k, adjusted in zip(keys, holm([tests[k]["p"] for k in keys])):
        t = tests[k]
        t["p_holm"] = adjusted
        t["verdict_holm"] = _verdict(direction(t), adjusted) if t["verdict"] in _ARROW else t["verdict"]


def _expected(pair: str, group: Group, ran: dict | None) -> dict:
    """What ``pair``'s report must record: its target task and the range the task declares (where the pair
    is registered and the group sets no env option), and the frames its group ran."""
    from drltg.envs import registry

    spec = registry.PAIRS.get(pair)
    declared = None
    if spec is not None and not any(k.startswith("env.") for k in group.spec.get("overrides", {})):
        try:
            declared = registry.get_task(spec.target).return_range()
        except (UsageError, KeyError, TypeError, ValueError):
            declared = None
    frames = (ran if isinstance(ran, dict) else group.spec).get("frames")
    return {"target": spec.target if spec is not None else None, "declared": declared,
            "frames": frames if isinstance(frames, int) and not isinstance(frames, bool) else None}


def _report(root: Path, group: Group, pair: str, method: str, entry: dict) -> dict | None:
    """The pair's report, checked to be that pair's (target task, budget, value range) with finite scores."""
    path = root / group.name / pair / "sac" / method / "report" / "transfer_metrics.json"
    if not path.is_file():
        return None
    report = read_json(path, root, 2**26, "a transfer report")
    return check_report(report, path, pair, **_expected(pair, group, entry.get("groups", {}).get(group.name)))


def _reads_source(method: str) -> bool:
    """Whether ``method``'s runs load a source run (a method not registered here is taken to)."""
    from drltg.config import get_method

    try:
        return get_method(method).source is not None
    except UsageError:
        return True


def _sources(root: Path, group: Group, pair: str, method: str, seeds: list[int]) -> dict[int, dict | None]:
    """The source each transfer run of the pair loaded, by digest: ``{seed: {"networks_sha256",
    "config_sha256"}}``, ``None`` for a run that records none; ``{}`` for a method that reads no source."""
    if not _reads_source(method):
        return {}
    folder = root / group.name / pair / "sac" / method / "transfer"
    out = {}
    for seed in seeds:
        path = folder / f"seed-{seed}" / rundir.SUMMARY
        out[seed] = check_source(read_json(path, root, 2**20, "a run summary"), path) if path.is_file() else None
    return out


def check_sources(rows: list[dict]) -> None:
    """Refuse, in one sentence, two rows whose runs of one (pair, seed) slot loaded different sources (their
    recorded digests differ): pairing them by seed would compare teachers, not methods. Smoke rows form slots
    of their own; a run that records no digest is not checked."""
    seen: dict[tuple, tuple[dict, tuple[str, str]]] = {}
    for r in rows:
        for pair, score in r["pairs"].items():
            for seed, source in score["sources"].items():
                if source is None:
                    continue
                digests = (source["networks_sha256"], source["config_sha256"])
                first, theirs = seen.setdefault((bool(r["entry"].get("smoke")), pair, seed), (r, digests))
                if theirs != digests:
                    what, k = ("networks", 0) if theirs[0] != digests[0] else ("config.yaml", 1)
                    raise UsageError(
                        f"{label(first)} and {label(r)} are paired by seed on {pair} seed {seed}, but their runs "
                        f"loaded different source {what} (SHA-256 {theirs[k][:12]}... and {digests[k][:12]}...), so "
                        "the board would compare teachers rather than methods; train both on one set of sources "
                        "(drltg bench run --reference) before setting them side by side.")


def _areas(report: dict) -> tuple[dict, dict]:
    """Each side's normalised area per seed, ``{seed: a}``."""
    lo, hi = report["settings"]["value_range"]
    return tuple({x["seed"]: (x["mean_return"] - lo) / (hi - lo) for x in report["per_seed"][side]}
                 for side in ("baseline", "transfer"))


def pair_score(report: dict) -> dict:
    """FT of one pair: per seed, their mean, and the report's verdict against no transfer."""
    b, t = _areas(report)
    seeds = sorted(set(b) & set(t))
    mean_b = float(np.mean([b[s] for s in seeds]))
    m = report["metrics"]
    out = {"value_range": report["settings"]["value_range"], "seeds": seeds,
           "transfer": [t[s] for s in seeds], "baseline": [b[s] for s in seeds],
           "verdict": m.get("mean_return_gain_verdict", "undecided"), "p": m.get("mean_return_gain_verdict_p"),
           "test": m.get("mean_return_gain_verdict_test")}
    if mean_b >= 1:
        return {**out, "ft": None, "ft_seeds": None, "note": "no transfer already scores the maximum"}
    ft = [(t[s] - b[s]) / (1 - mean_b) for s in seeds]
    return {**out, "ft": float(np.mean(ft)), "ft_seeds": ft}


def _rows(tier: Tier, version: str, root: Path, kind: str) -> list[dict]:
    record = read_record(root, version, tier.name)
    rows = []
    for method, entry in sorted(record["methods"].items()):
        pairs, missing = {}, []
        for group in tier.groups:
            for pair in group.pairs:
                if pair in entry.get("left_out", {}):
                    continue
                report = _report(root, group, pair, method, entry)
                if report is None:
                    missing.append(pair)
                else:
                    score = pair_score(report)
                    pairs[pair] = {**score, "sources": _sources(root, group, pair, method, score["seeds"])}
        unverified = [p for p, score in pairs.items() if None in score["sources"].values()]
        rows.append({"method": method, "kind": kind, "folder": str(root), "entry": entry, "pairs": pairs,
                     "missing": missing, "left_out": entry.get("left_out", {}), "unverified": unverified})
    return rows


def _choice(tuning: dict | None) -> dict:
    return (tuning or {}).get("choice") or {}


def _marks(row: dict, tier: Tier, versions: dict | None, baseline: dict | None) -> list[str]:
    """What makes a row not the protocol's, one phrase each (``baseline``: the reference's baseline tuning)."""
    entry, marks = row["entry"], []
    if entry.get("smoke"):
        marks.append("smoke budgets")
    if (entry.get("sources") or {}).get("declared") is False:
        marks.append("sources not the suite's (their digests differ from those it declares)")
    if tier.tunes_baseline and not entry.get("smoke"):
        mine = entry.get("baseline_tuning")
        if mine is None:
            marks.append("untuned baseline")
        elif baseline is not None and _choice(mine) != _choice(baseline):
            marks.append("baseline tuned to other settings than the reference's")
    for group in tier.groups:
        ran = entry.get("groups", {}).get(group.name)
        if ran is None:
            continue
        tuned = {**_choice(entry.get("baseline_tuning")).get(group.name, {}), **_choice(entry.get("tuning"))}
        kept = {"transfer.source"} if group.sources else set()  # the suite's sources, wherever a folder keeps them
        ran = {**ran, "overrides": {k: v for k, v in (ran.get("overrides") or {}).items()
                                    if k not in kept and not (k in tuned and tuned[k] == v)}}  # tuned: its own
        for key in ("frames", "source_frames", "overrides", "algos", "seed"):
            if ran.get(key) != group.spec.get(key) and not entry.get("smoke"):
                marks.append(f"{group.name} {key} {ran.get(key)} (suite {group.spec.get(key)})")
        fewer = [p for p in group.pairs if p in row["pairs"] and len(row["pairs"][p]["seeds"]) < group.spec["seeds"]]
        if fewer and not entry.get("smoke"):
            marks.append(f"fewer than {group.spec['seeds']} seeds on {', '.join(fewer)}")
    if row["missing"]:
        marks.append(f"no report for {', '.join(row['missing'])}")
    for name in COMPARED_VERSIONS if versions else ():
        mine = entry.get("versions", {}).get(name)
        if mine != versions.get(name):
            marks.append(f"{name} {mine} (reference {versions.get(name)})")
    return marks


def _aggregate(row: dict, reps: int, seed: int) -> dict:
    """IQM of FT and P(T > B) over the row's pairs with stratified-bootstrap intervals, and their verdicts."""
    from rliable import metrics

    from drltg.analysis.aggregate import aggregates, interval_estimate, score_matrix

    scored = {p: s for p, s in row["pairs"].items() if s["ft_seeds"] is not None}
    if not scored:
        return {}
    runs = min(len(s["seeds"]) for s in scored.values())
    ft = score_matrix([s["ft_seeds"][:runs] for s in scored.values()])
    b = score_matrix([s["baseline"][:runs] for s in scored.values()])
    t = score_matrix([s["transfer"][:runs] for s in scored.values()])
    against_none = aggregates(b, t, reps=reps, seed=seed)
    mean_ft, test = _stratified([s["ft_seeds"] for s in scored.values()], seed)
    return {"pairs": list(scored), "runs_per_pair": runs,
            "ft_iqm": interval_estimate(ft, metrics.aggregate_iqm, reps=reps, seed=seed),
            "ft_mean": float(np.mean([s["ft"] for s in scored.values()])),
            "probability_of_improvement": against_none["probability_of_improvement"],
            "profile": against_none["profile"],
            "against_none": {"verdict": _verdict(mean_ft, test["p"]), **test,
                             "test": test_name("stratified sign-flip over pairs", test["draws"])}}


def _against(row: dict, best: dict, seed: int) -> dict:
    """Per pair and over pairs: the row's normalised areas against the best reference row's, seed by seed."""
    from drltg.analysis.stats import permutation_test

    per_pair, strata = {}, []
    for pair, s in row["pairs"].items():
        other = best["pairs"].get(pair)
        if other is None:
            continue
        mine, theirs = dict(zip(s["seeds"], s["transfer"])), dict(zip(other["seeds"], other["transfer"]))
        seeds = sorted(set(mine) & set(theirs))
        if len(seeds) < 2:
            continue
        a, b = np.array([theirs[k] for k in seeds]), np.array([mine[k] for k in seeds])
        p = permutation_test(a, b, paired=True, seed=seed, n_resamples=PAIR_DRAWS)
        diff = float((b - a).mean())
        mc = 2 ** len(seeds) > PAIR_DRAWS
        per_pair[pair] = {"difference": diff, "p": p, "verdict": _verdict(diff, p),
                          "draws": PAIR_DRAWS if mc else None, "p_floor": 2 / (PAIR_DRAWS + 1) if mc else None}
        strata.append(b - a)
    if not strata:
        return {"method": best["method"], "pairs": per_pair}
    _holm(per_pair, lambda t: t["difference"])
    total, test = _stratified(strata, seed)
    return {"method": best["method"], "pairs": per_pair, "verdict": _verdict(total, test["p"]), **test,
            "test": test_name("stratified sign-flip over pairs (normalised area, paired by seed)", test["draws"])}


def leaderboard(tier: Tier, version: str, *, out: str | Path | None = None, reference: str | Path | None = None,
                reps: int = 2000, seed: int = 0) -> dict:
    """The board of ``tier``: the reference's rows and those of ``out`` (its smoke rows included), each
    marked where it leaves the protocol, ranked by the IQM of FT (over the pairs each covers) among rows on
    protocol; those rows alone are compared with the best reference row, the top-ranked reference row."""
    check_reps(reps)
    roots = []
    if reference is not None:
        roots.append((tier_root(reference, version, tier.name), "reference"))
    if out is not None and (reference is None or Path(out).resolve() != Path(reference).resolve()):
        roots += [(tier_root(out, version, tier.name), "yours"),
                  (tier_root(out, version, tier.name, smoke=True), "yours")]
    rows = [r for root, kind in roots if root.is_dir() for r in _rows(tier, version, root, kind)]
    if not rows:
        raise UsageError(f"no bench rows for {version} {tier.name} under "
                         f"{' or '.join(str(r) for r, _ in roots) or 'nothing'}; run drltg bench run first.")
    check_sources(rows)
    ref_versions = next((r["entry"].get("versions") for r in rows if r["kind"] == "reference"), None)
    ref_baseline = next((r["entry"].get("baseline_tuning") for r in rows
                         if r["kind"] == "reference" and r["entry"].get("baseline_tuning")), None)
    for r in rows:
        r["marks"] = _marks(r, tier, ref_versions, ref_baseline)
        r["aggregate"] = _aggregate(r, reps, seed)
        _holm(r["pairs"], lambda t: t["ft"] if t["ft"] is not None else 0.0)
    ranked = [r for r in rows if not r["marks"] and r["aggregate"]]
    ranked.sort(key=lambda r: -r["aggregate"]["ft_iqm"][0])
    best = next((r for r in ranked if r["kind"] == "reference"), None)
    for r in rows:
        r["rank"] = ranked.index(r) + 1 if r in ranked else None
        if best is not None and r is not best and r["rank"] is not None:
            r["against_best"] = _against(r, best, seed)
    rows.sort(key=lambda r: (r["rank"] is None, r["rank"] or 0, r["method"]))
    return {"suite": version, "tier": tier.name, "pairs": tier.pairs, "best_reference": best and best["method"],
            "baseline_tuning": ref_baseline or next((r["entry"].get("baseline_tuning") for r in rows
                                                     if r["entry"].get("baseline_tuning")), None),
            "alpha": ALPHA, "rows": rows}


_ARROW = {"higher": "↑", "lower": "↓", "undecided": "·"}


def label(r: dict) -> str:
    """A row's name on the board: the method, and whose row it is where it is not the reference's."""
    return r["method"] + (" (yours)" if r["kind"] == "yours" else "")


def board_table(board: dict) -> str:
    """The ranking as Markdown: aggregates with intervals and both verdicts, the marks of rows off protocol."""
    from drltg.analysis import tables

    rows = [("rank", "method", "pairs", "IQM of FT", "mean FT", "P(T > B)", "vs no transfer",
             f"vs {board['best_reference'] or 'best reference'}", "tuned", "off protocol")]
    for r in board["rows"]:
        a = r["aggregate"]
        if not a:
            rows.append((r["rank"] or "-", label(r), "0", "n/a", "n/a", "n/a", "", "", tuned_text(r["entry"]),
                         "; ".join(r["marks"])))
            continue
        vs, none = r.get("against_best", {}), a["against_none"]
        shared = len(vs.get("pairs", ()))
        best = (f"{vs['verdict']} ({p_text(vs['p'], vs['draws'], vs['p_floor'])}"
                + (f", on the {'one pair' if shared == 1 else f'{shared} pairs'} both cover)"
                   if shared < len(a["pairs"]) else ")") if "verdict" in vs
                else "-" if r["method"] == board["best_reference"] and r["kind"] == "reference" and r["rank"]
                else "not compared" if r["marks"] else "")
        covered = f"{len(a['pairs'])} of {len(board['pairs'])}"
        rows.append((r["rank"] or "-", label(r),
                     covered + (", ranked on these" if r["rank"] and len(a["pairs"]) < len(board["pairs"]) else ""),
                     tables.estimate(*a["ft_iqm"], fmt="+.2f"), f"{a['ft_mean']:+.2f}",
                     tables.estimate(*a["probability_of_improvement"], fmt=".2f"),
                     f"{none['verdict']} ({p_text(none['p'], none['draws'], none['p_floor'])})", best,
                     tuned_text(r["entry"]), "; ".join(r["marks"])))
    return tables.render(rows, "markdown")


def _setting(choice: dict) -> str:
    return ", ".join(f"{k}={v}" for k, v in choice.items()) or "the defaults"


def tuned_text(entry: dict) -> str:
    """A row's tuning in a cell: its choice among how many settings, or that it ran at its defaults."""
    tuning = entry.get("tuning")
    if not tuning:
        return "untuned (defaults)"
    return f"{_setting(tuning['choice'])} (of {tuning['budget']})"


def baseline_sentence(tuning: dict | None) -> str:
    """What the board's baseline ran at, as a sentence."""
    if not tuning:
        return "No transfer ran at the learner's defaults (this tier tunes no baseline)."
    at = "; ".join(f"{group}: {_setting(choice)}" for group, choice in tuning["choice"].items())
    return (f"No transfer ran at the learner's settings chosen among at most {tuning['budget']} per group on seeds "
            f"{', '.join(map(str, tuning['seeds']))} ({tuning['rule']}): {at}. Every row trained at them.")


def pair_table(board: dict) -> str:
    """FT per pair, with ↑ / ↓ / · for the verdict against no transfer, Holm-adjusted within the row (n/a: the
    method cannot run there)."""
    from drltg.analysis import tables

    rows = [("method", *board["pairs"])]
    for r in board["rows"]:
        cells = []
        for pair in board["pairs"]:
            s = r["pairs"].get(pair)
            if pair in r["left_out"]:
                cells.append("n/a")
            elif s is None:
                cells.append("missing")
            else:
                arrow = _ARROW.get(s.get("verdict_holm", s["verdict"]), "·")
                cells.append("n/a" if s["ft"] is None else f"{s['ft']:+.2f} {arrow}")
        rows.append((label(r), *cells))
    return tables.render(rows, "markdown")
