"""What every region reads: reports and their families of tests, curves at given frames, and the pieces
of sentences the studies share."""
from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from drltg.analysis import claims as cl
from drltg.analysis import stats
from drltg.analysis.tables import estimate, render

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "results"

PRIMARY = "mean_return_gain"
METHOD_NAMES = {"model-reuse": "model reuse", "value-shaping": "value shaping", "policy-reuse": "policy reuse",
                "reward-shaping": "reward shaping (oracle potential)", "demonstrations": "demonstrations",
                "jumpstart": "jumpstart"}


def load(path: Path) -> dict:
    return json.loads(Path(path).read_text())


def family(reports: dict, metric: str = PRIMARY) -> dict:
    """``metric``'s p-values over every report given (those with one), Holm-adjusted as one family: the t
    tests' and, separately, the exact tests' (:func:`drltg.analysis.claims.exact_p`)."""
    keys = [k for k in reports if reports[k]["metrics"].get(f"{metric}_p_value") is not None]
    t = stats.holm([reports[k]["metrics"][f"{metric}_p_value"] for k in keys])
    ms = [reports[k]["metrics"] for k in keys]
    exact = stats.holm([m[f"{metric}_p_value"] if cl.exact_p(m, metric) is None else cl.exact_p(m, metric) for m in ms])
    return {k: cl.Adjusted(a, e, len(keys)) for k, a, e in zip(keys, t, exact)}


def whole_family(reports: dict, metric: str = PRIMARY) -> dict:
    """``metric`` of each report read in the family of every test the reports hold (each report's
    ``settings.family``: all its metrics, trends included), Holm-adjusted together, the interval's tests and
    apart the exact tests (:func:`drltg.analysis.claims.exact_p`)."""
    keys = [(tag, k) for tag, r in reports.items() for k in (r["settings"].get("family") or {}).get("metrics", [])
            if r["metrics"].get(f"{k}_p_value") is not None]
    ms = [reports[tag]["metrics"] for tag, _ in keys]
    t = stats.holm([m[f"{k}_p_value"] for m, (_, k) in zip(ms, keys)])
    exact = stats.holm([m[f"{k}_p_value"] if cl.exact_p(m, k) is None else cl.exact_p(m, k)
                        for m, (_, k) in zip(ms, keys)])
    return {tag: cl.Adjusted(a, e, len(keys)) for (tag, k), a, e in zip(keys, t, exact) if k == metric}


def said(report: dict, name: str = PRIMARY, p_adjusted: cl.Adjusted | None = None, **words) -> str:
    """The verdict sentence of metric ``name`` of a report: read alone (its exact test's own p-value) or in
    a family (``p_adjusted``, :func:`family`)."""
    return cl.verdict_of(report, name, p_adjusted, **words)


def cell(m, key, fmt="+.2f"):
    return estimate(m.get(key), m.get(f"{key}_ci"), fmt)


def evals_at(path: Path, column: str) -> dict[float, float]:
    from drltg.analysis.curves import read_run

    if Path(path).is_dir() and (Path(path) / "eval.csv").is_file():
        with open(Path(path) / "eval.csv") as f:
            return {float(r["frames"]): float(r[column]) for r in csv.DictReader(f)}
    c = read_run(path)  # a foreign log (Stable-Baselines3)
    return dict(zip(map(float, c.frames), map(float, c.values)))


def _at(evals: dict[float, float], frame: float, fmt: str) -> str:
    if frame in evals:
        return format(evals[frame], fmt)
    later = [f for f in evals if f >= frame]
    return "" if not later else f"{format(evals[min(later)], fmt)} (at {min(later):,.0f})"


def curve_table(rows: list[tuple[str, list[Path]]], column: str, frames: list[float], fmt: str = ".1f",
                note=None) -> str:
    """Each row's evaluation at each frame; a row of several runs shows the highest of them."""
    out = [("run", *(cl.frames(f) if f else "0" for f in frames))]
    for label, paths in rows:
        evals = [evals_at(p, column) for p in paths]
        cells = []
        for f in frames:
            if len(evals) == 1:
                text = _at(evals[0], f, fmt)
                if note is not None:
                    text += note(paths[0], f)
            else:
                text = format(max(e[f] for e in evals), fmt)
            cells.append(text)
        out.append((label, *cells))
    return render(out, "markdown")


def seed_number(run: Path) -> int:
    return int(run.name.split("-")[1])


def seed_dirs(folder: Path) -> list[Path]:
    return sorted(folder.glob("seed-*"), key=seed_number)


def ends(report: dict) -> str:
    """Where a gain over the whole budget comes from: the difference at the first evaluation and at the end
    (nothing where both are 0.00)."""
    m, st = report["metrics"], report["settings"]
    if round(abs(m["jumpstart"]), 2) == 0 and round(abs(m["asymptotic_performance"]), 2) == 0:
        return ""
    text = (f" (at the first evaluation {cl.signed(m['jumpstart'])}, over the last {st['asymptote_window']:.0%} of "
            f"the budget {cl.signed(m['asymptotic_performance'])}")
    b, t = report_curves(report, "baseline"), report_curves(report, "transfer")
    if round(abs(m["jumpstart"]), 2) and all(len(c.frames) > 1 for c in b + t):
        second = float(np.mean([c.values[1] for c in t]) - np.mean([c.values[1] for c in b]))
        # the frame-0 difference fading to 0 by the second evaluation adds j (f1 - f0) / 2 to the area
        budget, start = st.get("budget", t[0].frames[-1]), st.get("start", t[0].frames[0])
        carried = m["jumpstart"] * (t[0].frames[1] - t[0].frames[0]) / 2 / (budget - start)
        gain = m["mean_return_gain"]
        if round(abs(second), 2) == 0 and gain * m["jumpstart"] > 0 and round(abs(gain - carried), 2) == 0:
            word = "gain" if gain > 0 else "loss"
            text += (f"; gone by the second evaluation, {cl.frames(t[0].frames[1])} frames: {cl.signed(second)}, so "
                     f"this {word} is the frame-0 jumpstart carried over the first interval, not a {word} over the run")
    return text + ")"


RECIPES = {
    "demonstrations-reference": "the placement reference's recipe (measurements/place-reference-ln-half-noisy)",
    "lift-demonstrations-variants": "the Lift cloning defaults (lift-demonstrations-variants)",
}
"""Recipes chosen after seeing runs, by the result names that use them; the seeds come from the runs' configs
(``tuned_on``), through the report (``settings.tuned_on``)."""


def tuned(name: str, report: dict) -> str:
    """A clause naming the seeds of ``report`` that also chose its recipe (none: empty)."""
    shared = (report["settings"].get("tuned_on") or {}).get("transfer") or []
    if not shared:
        return ""
    what = next((w for prefix, w in RECIPES.items() if name.startswith(prefix)), "its recipe")
    return (f"; {what}: chosen on seed{'s' if len(shared) > 1 else ''} {', '.join(map(str, shared))}, which "
            f"{'are' if len(shared) > 1 else 'is'} reported here too (tuned on the seeds it reports, not a "
            "fresh-seed result)")


def report_curves(report: dict, side: str) -> list:
    """The side's runs as the report read them (its per-seed sources, relative to the repository)."""
    from drltg.analysis.curves import read_curves

    st = report["settings"]
    return [read_curves(ROOT / row["source"], format=st["format"], tag=st["tag"])[0]
            for row in report["per_seed"][side]]


def threshold(report: dict, side: str = "transfer", who: str | None = None) -> str:
    """:func:`drltg.analysis.claims.threshold_sentence`, with the seeds that cross too late to be confirmed."""
    return cl.threshold_sentence(report, side, who, late=cl.late_crossings(report, side, report_curves(report, side)))
