r"""The leaderboard of a tier: every method's score per pair and in aggregate, each with a verdict that keeps
its level at the seeds used.

Rows are read from the reports ``drltg bench run`` left (each pair's ``transfer_metrics.json``: its seeds'
mean returns over the budget, the declared range, the exact sign-flip verdict). For method :math:`m` on
pair :math:`p` with normalised areas :math:`a_{T,i}, a_{B,i}` of seed :math:`i`:

- **FT** (:mod:`drltg.bench.suite`): :math:`FT_{p,i} = (a_{T,i} - a_{B,i}) / (1 - \bar a_B)`, the pair's
  score their mean; its verdict against no transfer is the report's exact sign-flip test of the paired
  differences (dividing by a constant changes no sign);
- **against the best reference row** (the highest IQM of FT among the reference rows on protocol that cover
  every pair): the exact sign-flip test of :math:`a_{m,i} - a_{best,i}` over the seeds both ran;
- **aggregates** (rliable): the IQM of all :math:`FT_{p,i}` and P(T > B) over the pairs, each with a 95%
  stratified-bootstrap interval; the aggregate verdicts are the stratified exact sign-flip test over the
  pairs (:func:`drltg.analysis.stats.stratified_sign_flip`).

A row run at other budgets, with fewer seeds, under another drltg or torch version than the reference, or
with pairs missing is marked with what differs and left out of the ranking.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from drltg.bench.run import read_record, tier_root
from drltg.bench.suite import Tier
from drltg.errors import UsageError

__all__ = ["leaderboard", "board_table", "pair_table", "label", "ALPHA"]

ALPHA = 0.05
COMPARED_VERSIONS = ("drltg", "torch")


def _verdict(estimate: float, p: float | None) -> str:
    if p is None or p >= ALPHA or estimate == 0:
        return "undecided"
    return "higher" if estimate > 0 else "lower"


def _report(root: Path, group: str, pair: str, method: str) -> dict | None:
    from drltg.regular import read_bytes

    path = root / group / pair / "sac" / method / "report" / "transfer_metrics.json"
    if not path.is_file():
        return None
    return json.loads(read_bytes(path, 2**26, "a transfer report"))


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


def _rows(tier: Tier, root: Path, kind: str) -> list[dict]:
    record = read_record(root)
    rows = []
    for method, entry in sorted(record["methods"].items()):
        pairs, missing = {}, []
        for group in tier.groups:
            for pair in group.pairs:
                if pair in entry.get("left_out", {}):
                    continue
                report = _report(root, group.name, pair, method)
                if report is None:
                    missing.append(pair)
                else:
                    pairs[pair] = pair_score(report)
        rows.append({"method": method, "kind": kind, "folder": str(root), "entry": entry, "pairs": pairs,
                     "missing": missing, "left_out": entry.get("left_out", {})})
    return rows


def _marks(row: dict, tier: Tier, versions: dict | None) -> list[str]:
    """What makes a row not the protocol's, one phrase each."""
    entry, marks = row["entry"], []
    if entry.get("smoke"):
        marks.append("smoke budgets")
    for group in tier.groups:
        ran = entry.get("groups", {}).get(group.name)
        if ran is None:
            continue
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
    from drltg.analysis.stats import stratified_sign_flip

    scored = {p: s for p, s in row["pairs"].items() if s["ft_seeds"] is not None}
    if not scored:
        return {}
    runs = min(len(s["seeds"]) for s in scored.values())
    ft = score_matrix([s["ft_seeds"][:runs] for s in scored.values()])
    b = score_matrix([s["baseline"][:runs] for s in scored.values()])
    t = score_matrix([s["transfer"][:runs] for s in scored.values()])
    against_none = aggregates(b, t, reps=reps, seed=seed)
    mean_ft, p = stratified_sign_flip([s["ft_seeds"] for s in scored.values()], seed=seed)
    return {"pairs": list(scored), "runs_per_pair": runs,
            "ft_iqm": interval_estimate(ft, metrics.aggregate_iqm, reps=reps, seed=seed),
            "ft_mean": float(np.mean([s["ft"] for s in scored.values()])),
            "probability_of_improvement": against_none["probability_of_improvement"],
            "profile": against_none["profile"],
            "against_none": {"verdict": _verdict(mean_ft, p), "p": p, "test": "stratified sign-flip over pairs"}}


def _against(row: dict, best: dict, seed: int) -> dict:
    """Per pair and over pairs: the row's normalised areas against the best reference row's, seed by seed."""
    from drltg.analysis.stats import permutation_test, stratified_sign_flip

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
        p = permutation_test(a, b, paired=True, seed=seed)
        diff = float((b - a).mean())
        per_pair[pair] = {"difference": diff, "p": p, "verdict": _verdict(diff, p)}
        strata.append(b - a)
    if not strata:
        return {"method": best["method"], "pairs": per_pair}
    total, p = stratified_sign_flip(strata, seed=seed)
    return {"method": best["method"], "pairs": per_pair, "verdict": _verdict(total, p), "p": p,
            "test": "stratified sign-flip over pairs (normalised area, paired by seed)"}


def leaderboard(tier: Tier, version: str, *, out: str | Path | None = None, reference: str | Path | None = None,
                reps: int = 2000, seed: int = 0) -> dict:
    """The board of ``tier``: the reference's rows and those of ``out`` (its smoke rows included), each
    marked where it leaves the protocol, ranked by the IQM of FT among rows on protocol."""
    roots = []
    if reference is not None:
        roots.append((tier_root(reference, version, tier.name), "reference"))
    if out is not None and (reference is None or Path(out).resolve() != Path(reference).resolve()):
        roots += [(tier_root(out, version, tier.name), "yours"),
                  (tier_root(out, version, tier.name, smoke=True), "yours")]
    rows = [r for root, kind in roots if root.is_dir() for r in _rows(tier, root, kind)]
    if not rows:
        raise UsageError(f"no bench rows for {version} {tier.name} under "
                         f"{' or '.join(str(r) for r, _ in roots) or 'nothing'}; run drltg bench run first.")
    ref_versions = next((r["entry"].get("versions") for r in rows if r["kind"] == "reference"), None)
    for r in rows:
        r["marks"] = _marks(r, tier, ref_versions)
        r["aggregate"] = _aggregate(r, reps, seed)
    ranked = [r for r in rows if not r["marks"] and r["aggregate"]]
    ranked.sort(key=lambda r: (-len(r["aggregate"]["pairs"]), -r["aggregate"]["ft_iqm"][0]))
    full = [r for r in ranked if r["kind"] == "reference" and len(r["aggregate"]["pairs"]) == len(tier.pairs)]
    best = max(full, key=lambda r: r["aggregate"]["ft_iqm"][0]) if full else None
    for r in rows:
        r["rank"] = ranked.index(r) + 1 if r in ranked else None
        if best is not None and r is not best:
            r["against_best"] = _against(r, best, seed)
    rows.sort(key=lambda r: (r["rank"] is None, r["rank"] or 0, r["method"]))
    return {"suite": version, "tier": tier.name, "pairs": tier.pairs, "best_reference": best and best["method"],
            "alpha": ALPHA, "rows": rows}


_ARROW = {"higher": "↑", "lower": "↓", "undecided": "·"}


def label(r: dict) -> str:
    """A row's name on the board: the method, and whose row it is where it is not the reference's."""
    return r["method"] + (" (yours)" if r["kind"] == "yours" else "")


def board_table(board: dict) -> str:
    """The ranking as Markdown: aggregates with intervals and both verdicts, the marks of rows off protocol."""
    from drltg.analysis import tables

    rows = [("rank", "method", "pairs", "IQM of FT", "mean FT", "P(T > B)", "vs no transfer",
             f"vs {board['best_reference'] or 'best reference'}", "off protocol")]
    for r in board["rows"]:
        a = r["aggregate"]
        if not a:
            rows.append((r["rank"] or "-", label(r), "0", "n/a", "n/a", "n/a", "", "", "; ".join(r["marks"])))
            continue
        vs = r.get("against_best", {})
        best = f"{vs['verdict']} (p = {vs['p']:.2g})" if "verdict" in vs else ("-" if vs == {} else "")
        rows.append((r["rank"] or "-", label(r), f"{len(a['pairs'])} of {len(board['pairs'])}",
                     tables.estimate(*a["ft_iqm"], fmt="+.2f"), f"{a['ft_mean']:+.2f}",
                     tables.estimate(*a["probability_of_improvement"], fmt=".2f"),
                     f"{a['against_none']['verdict']} (p = {a['against_none']['p']:.2g})", best,
                     "; ".join(r["marks"])))
    return tables.render(rows, "markdown")


def pair_table(board: dict) -> str:
    """FT per pair, with ↑ / ↓ / · for the exact verdict against no transfer (n/a: the method cannot run there)."""
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
                cells.append("n/a" if s["ft"] is None else f"{s['ft']:+.2f} {_ARROW[s['verdict']]}")
        rows.append((label(r), *cells))
    return tables.render(rows, "markdown")
