"""Rewrite the generated regions of README.md, docs/ and results/ from the committed numbers.

    python results/claims.py           # rewrite every region between <!-- claims:NAME --> and <!-- /claims:NAME -->
    python results/claims.py --check   # change nothing; name the regions that differ and exit 1

Every table and every sentence that states a result in those regions comes from the reports
(``transfer_metrics.json``), sweep summaries and curves under ``results/``, or from drltg's registries
(tasks, methods, config keys), through :mod:`drltg.analysis.claims`' rules. ``tests/test_claims.py`` runs
the check, so a changed number fails the suite until the prose is regenerated.

Families: a sentence that reads one report's headline (the mean return gain, named in advance as the
report's headline metric) reads its interval alone; a sentence that reads a sweep reads the same metric
in every report of the sweep as one family, Holm-adjusted.
"""
from __future__ import annotations

import csv
import json
import math
import sys
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "results"
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from drltg.analysis import claims as cl  # noqa: E402
from drltg.analysis import metrics as mx  # noqa: E402
from drltg.analysis import stats  # noqa: E402
from drltg.analysis.tables import estimate, render  # noqa: E402

PRIMARY = "mean_return_gain"
METHOD_NAMES = {"model-reuse": "model reuse", "value-shaping": "value shaping", "policy-reuse": "policy reuse",
                "reward-shaping": "reward shaping (oracle potential)", "demonstrations": "demonstrations",
                "jumpstart": "jumpstart"}


def load(path: Path) -> dict:
    return json.loads(Path(path).read_text())


# ------------------------------------------------------------------------------------------ sweeps
def sweep_reports(root: Path, report: str = "report") -> dict[tuple[str, str], dict]:
    """``{(pair[ variant], method): report}`` of a sweep's ``PAIR/ALGO[/VARIANT]/METHOD/<report>/``."""
    out = {}
    for path in sorted(Path(root).glob(f"*/*/**/{report}/transfer_metrics.json")):
        pair, _algo, *variant, method, _ = path.parent.relative_to(root).parts
        out[(" ".join([pair, *variant]), method)] = load(path)
    return dict(sorted(out.items(), key=lambda kv: (_rank(kv[0][0]), kv[0])))


def _rank(pair: str) -> int:
    """Targets by distance from the source goal where they have one, else by name."""
    order = ["near", "inner", "northwest", "southeast", "far"]
    target = _target(pair.split(" ")[0])
    return order.index(target) if target in order else len(order)


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


def _cell(m, key, fmt="+.2f"):
    return estimate(m.get(key), m.get(f"{key}_ci"), fmt)


def _time_to(report, side):
    times = [r.get("time_to_threshold") for r in report["per_seed"][side]]
    median = report["metrics"].get(f"time_to_threshold_{side}")
    value = "—" if median is None else cl.frames(median)
    return f"{value} ({sum(t is not None for t in times)}/{len(times)})"


def sweep_table(root: Path) -> str:
    """The sweep's reports as one Markdown table (the table of ``results/summarize.py``)."""
    reports = sweep_reports(root)
    adjusted = family(reports)
    rows = [("pair", "method", "mean return gain", "Holm p (sweep)", "jumpstart", "asymptotic", "transfer ratio",
             "frames to threshold, B / T (seeds holding it)", "P(T > B)")]
    for (pair, method), r in reports.items():
        m, conv = r["metrics"], r["settings"].get("convergence", {})
        moving = any(str(v) != "converged" for v in conv.values())
        p = getattr(adjusted.get((pair, method)), "t", None)
        rows.append((pair, method, _cell(m, PRIMARY), "" if p is None else cl.p_text(p), _cell(m, "jumpstart"),
                     _cell(m, "asymptotic_performance") + (" (final)" if moving else ""),
                     _cell(m, "transfer_ratio"), f"{_time_to(r, 'baseline')} / {_time_to(r, 'transfer')}",
                     _cell(m, "probability_of_improvement", ".2f")))
    return render(rows, "markdown")


def _target(pair: str) -> str:
    return pair.split("-", 1)[1] if "-" in pair else pair


def sweep_verdicts(root: Path, order: list[str]) -> str:
    """One bullet per method: its mean return gain on each target, read as one family (Holm over the
    sweep's reports); then, per target, whether any method is best."""
    reports = sweep_reports(root)
    adjusted = family(reports)
    n = len(adjusted)
    lines = [f"Read as one family: the mean return gain of the {n} reports, Holm-adjusted; a gain is called "
             "higher or lower only where its interval excludes 0 and both its t test and its exact sign-flip test "
             "have an adjusted p below 0.05."]
    for method in order:
        parts = []
        for (pair, meth), r in reports.items():
            if meth != method:
                continue
            parts.append(f"{_target(pair)} {said(r, PRIMARY, adjusted.get((pair, meth)))}")
        lines.append(f"- **{METHOD_NAMES.get(method, method)}**: " + "; ".join(parts) + ".")
    pairs = list(dict.fromkeys(pair for pair, _ in reports))
    for pair in pairs:
        methods = {meth: r for (p, meth), r in reports.items() if p == pair}
        lines.append(f"- {cl.best_sentence(methods, _target(pair))}.")
    return "\n".join(lines) + "\n"


def threshold_lines(root: Path, side: str, methods: list[str] | None = None) -> str:
    """Each target's seeds that hold the threshold under the report's sustained rule."""
    reports = sweep_reports(root)
    lines, seen = [], set()
    for (pair, method), r in reports.items():
        if methods is not None and method not in methods:
            continue
        if side == "baseline":
            if pair in seen:
                continue
            seen.add(pair)
            who = f"{_target(pair)}, baseline"
        else:
            who = f"{_target(pair)}, {METHOD_NAMES.get(method, method)}"
        lines.append(f"- {threshold(r, side, who)}.")
    return "\n".join(lines) + "\n"


TARGETS = {"near": "near (1.0, same room)", "inner": "inner (2.1, same room)",
           "northwest": "northwest (6.1, adjacent room)", "southeast": "southeast (6.1, adjacent room)",
           "far": "far (9.9, opposite room)"}


def results_table() -> str:
    """docs/results.md's table: the graded sweep's mean return gain per target and method; bold where the gain is a
    finding within the sweep's family (interval excludes 0; the t and exact tests' Holm-adjusted p < 0.05)."""
    reports = sweep_reports(GRADED)
    adjusted = family(reports)
    methods = ["model-reuse", "value-shaping", "policy-reuse", "reward-shaping"]
    rows = [("target (free-path distance from the source goal)", *(METHOD_NAMES[m] for m in methods))]
    for target, label in TARGETS.items():
        cells = []
        for method in methods:
            key = (f"fourrooms-{target}", method)
            m = reports[key]["metrics"]
            ci = m.get(f"{PRIMARY}_ci")
            value = cl.signed(m[PRIMARY])
            if cl.direction(ci, adjusted.get(key)):
                value = f"**{value}**"
            cells.append(f"{value} [{cl.signed(ci[0])}, {cl.signed(ci[1])}]" if ci else value)
        rows.append((label, *cells))
    return render(rows, "markdown")


def readme_others() -> str:
    """docs/results.md's paragraph on the other studies, each sentence from its reports."""
    grid = sweep_reports(RESULTS / "sweep-gridrooms")
    adj_g = family(grid)
    g = {k: said(r, PRIMARY, adj_g.get(k)) for k, r in grid.items()}
    h2h = {k: load(OPTIONS / "head-to-head" / f"fourrooms-{k}" / "transfer_metrics.json")
           for k in ("near-k2", "near-k4", "far-k2", "far-k4")}
    adj_h = family(h2h)
    lines = [
        f"- Grid FourRooms (`results/sweep-gridrooms/`, Holm over its {len(adj_g)} reports), mean return gain: "
        + "; ".join(f"{METHOD_NAMES[m]} near {g[('gridrooms-near', m)]}, far {g[('gridrooms-far', m)]}"
                    for m in ("model-reuse", "value-shaping", "policy-reuse")) + ".",
        "- Soft option-critic minus SAC, both with model reuse, head to head (`results/sweep-options/`, Holm over "
        f"{len(adj_h)}): " + "; ".join(
            f"{k.replace('-k', ', K = ')}: "
            f"{said(r, PRIMARY, adj_h.get(k), higher='SOC higher', lower='SOC lower')}"
            for k, r in h2h.items()) + ".",
    ]
    return "\n".join(lines) + "\n" + readme_lift()


def readme_lift() -> str:
    """docs/tasks.md's sentences on the manipulation studies, each from its reports."""
    demo = load(LIFT / "demonstrations" / "report-success" / "transfer_metrics.json")
    place = {pair: load(PLACE / pair / "sac" / "demonstrations" / "report-lifted" / "transfer_metrics.json")
             for pair in ("lift-to-place", "lift-to-place-barrier")}
    adj_p = family(place)
    dense = load(DENSE / "vs-seed" / "transfer_metrics.json")
    lines = [
        f"- Lift from the scripted demonstrator (`results/sweep-lift-demonstrations/`): demonstrations with behaviour "
        f"cloning, mean success gain {said(demo)}; "
        f"{threshold(demo, 'transfer', 'success ≥ 0.8')}{_tuned('lift-demonstrations-variants', demo)}.",
        "- Lift → Lift+Place and Lift+Place with barrier from the same demonstrations "
        "(`results/sweep-lift-to-place/`), "
        f"mean lifted-rate gain (Holm over the {len(adj_p)} targets): "
        + "; ".join(f"{pair}: {said(r, PRIMARY, adj_p.get(pair))}" for pair, r in place.items()) + ".",
        f"- Lift on the dense reward against the seed project's one SB3 run (`results/lift-dense/`): mean return gain "
        f"{cl.signed(dense['metrics'][PRIMARY], 1)} over frames {dense['settings']['start']:,} to "
        f"{dense['settings']['budget']:,}, with no interval and no verdict (one run on one side); the SB3 curve is "
        f"{dense['settings']['convergence']['baseline']} where the comparison stops.",
    ]
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------------------------------ options
OPTIONS = RESULTS / "sweep-options"
GRADED = RESULTS / "sweep-fourrooms-graded"


def options_table() -> str:
    """SAC and SOC (K = 2, 4) with model reuse against their own baselines, and SOC − SAC head to head."""
    rows = [("pair", "learner + model reuse", "vs its own baseline: mean return gain", "jumpstart", "transfer ratio",
             "head to head, SOC − SAC: mean return gain", "P(SOC > SAC)")]
    for pair in ("near", "far"):
        sac = load(GRADED / f"fourrooms-{pair}" / "sac" / "model-reuse" / "report" / "transfer_metrics.json")["metrics"]
        rows.append((pair, "SAC", _cell(sac, PRIMARY), _cell(sac, "jumpstart"), _cell(sac, "transfer_ratio"), "", ""))
        for k in (2, 4):
            own = load(OPTIONS / f"fourrooms-{pair}" / "soc" / f"soc.num_options={k}" / "model-reuse" / "report"
                       / "transfer_metrics.json")["metrics"]
            h2h = load(OPTIONS / "head-to-head" / f"fourrooms-{pair}-k{k}" / "transfer_metrics.json")["metrics"]
            rows.append((pair, f"SOC K={k}", _cell(own, PRIMARY), _cell(own, "jumpstart"), _cell(own, "transfer_ratio"),
                         _cell(h2h, PRIMARY), _cell(h2h, "probability_of_improvement", ".2f")))
    return render(rows, "markdown")


def options_sources() -> str:
    """Final success on the source task of each learner's source runs (what there was to transfer)."""
    sides = [("SAC", GRADED / "fourrooms-near" / "sac" / "source")]
    sides += [(f"SOC K = {k}", OPTIONS / "fourrooms-near" / "soc" / f"soc.num_options={k}" / "source") for k in (2, 4)]
    lines = []
    for name, folder in sides:
        rates = [load(run / "summary.json")["final_eval"]["success_rate"] for run in _seeds(folder)]
        lines.append(f"- {name}: mean {sum(rates) / len(rates):.2f} ({', '.join(f'{r:.2f}' for r in rates)}).")
    return "\n".join(lines) + "\n"


def lift_variants() -> str:
    variants = RESULTS / "lift-demonstrations-variants"
    lines = []
    for name, label in (("replay-only", "replay only"), ("bc-q-filter", "Q-filtered cloning")):
        e = _evals(variants / name / "seed-0", "success_rate")
        best = max(e, key=e.get)
        lines.append(f"  - {label}, seed 0: highest success {e[best]:.1f}"
                     + (f" (first at {cl.frames(best)} frames)" if e[best] > 0 else "")
                     + f", final {e[max(e)]:.1f}.")
    r = load(variants / "bc-10-episodes-report-success" / "transfer_metrics.json")
    final = [load(run / "summary.json")["final_eval"]["success_rate"] for run in _seeds(variants / "bc-10-episodes")]
    lines.append(f"  - unfiltered cloning, 10 episodes, 3 seeds: mean success gain {said(r)}; final success "
                 f"{', '.join(f'{x:.1f}' for x in final)}; {threshold(r, 'transfer', 'success ≥ 0.8')}"
                 f"{_tuned('lift-demonstrations-variants', r)}.")
    return "\n".join(lines) + "\n"


def options_verdicts() -> str:
    h2h = {(f"fourrooms-{pair}", k): load(OPTIONS / "head-to-head" / f"fourrooms-{pair}-k{k}" / "transfer_metrics.json")
           for pair in ("near", "far") for k in (2, 4)}
    own = sweep_reports(OPTIONS)
    # one family: every test these sentences draw on, the head-to-head comparisons and the own baselines
    adjusted = family({**{("h2h", *k): r for k, r in h2h.items()}, **{("own", *k): r for k, r in own.items()}})
    lines = [f"Read as one family, Holm over all {len(adjusted)} mean return gains below ({len(h2h)} head to head, "
             f"{len(own)} against their own baselines).", "Head to head (SOC − SAC, mean return gain):"]
    for (pair, k), r in h2h.items():
        lines.append(f"- {_target(pair)}, K = {k}: "
                     f"{said(r, PRIMARY, adjusted.get(('h2h', pair, k)), higher='SOC higher', lower='SOC lower')}.")
    lines.append("Each SOC learner against its own baseline:")
    for (pair, method), r in own.items():
        lines.append(f"- {pair.replace('fourrooms-', '').replace('soc.num_options=', 'K = ')}: "
                     f"{said(r, PRIMARY, adjusted.get(('own', pair, method)))}.")
    for (pair, method), r in own.items():
        if pair.startswith("fourrooms-near"):
            who = pair.replace("fourrooms-near soc.num_options=", "near, SOC K = ") + " with model reuse"
            lines.append(f"- {threshold(r, 'transfer', who)}.")
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------------------------------ curves
def _evals(path: Path, column: str) -> dict[float, float]:
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
        evals = [_evals(p, column) for p in paths]
        cells = []
        for f in frames:
            if len(evals) == 1:
                cell = _at(evals[0], f, fmt)
                if note is not None:
                    cell += note(paths[0], f)
            else:
                cell = format(max(e[f] for e in evals), fmt)
            cells.append(cell)
        out.append((label, *cells))
    return render(out, "markdown")


def _placed(run: Path, frame: float) -> str:
    with open(run / "eval.csv") as f:
        row = next(r for r in csv.DictReader(f) if float(r["frames"]) == frame)
    placed = round(float(row["success_rate"]) * int(row["episodes"]))
    return f" ({placed} placed)" if placed else ""


def _seed_number(run: Path) -> int:
    return int(run.name.split("-")[1])


def _seeds(folder: Path) -> list[Path]:
    return sorted(folder.glob("seed-*"), key=_seed_number)


def lift_dense_curves() -> str:
    rows = [(f"drltg SAC, {p.name.replace('-', ' ')}", [p]) for p in _seeds(DENSE / "sac")]
    rows.append(("seed project, SB3 SAC", [ROOT / "tests" / "data" / "sb3_runs" / "lift_shaped_sac"]))
    return curve_table(rows, "return_mean", [float(f) for f in range(0, 150_001, 10_000)])


def lift_dense_study_table() -> str:
    study = RESULTS / "lift-dense-study"
    out = [("variant, seed", "return at 10k / 20k / 30k", "mean of the three", "frames/s")]
    for variant in ("default", "utd-0.5", "utd-2", "batch-128", "batch-512", "hidden-128"):
        for run in _seeds(study / variant):
            e = _evals(run, "return_mean")
            values = [e[f] for f in (10_000.0, 20_000.0, 30_000.0)]
            fps = load(run / "summary.json")["frames_per_s"]
            out.append((f"{variant}, {run.name}", " / ".join(f"{v:.1f}" for v in values),
                        f"{sum(values) / 3:.1f}", f"{fps:.1f}"))
    return render(out, "markdown")


def lift_demonstrations_curves() -> str:
    rows = [(f"demonstrations, {p.name.replace('-', ' ')}", [p]) for p in _seeds(LIFT / "demonstrations" / "transfer")]
    others = [*_seeds(LIFT / "baseline"), *_seeds(LIFT / "policy-reuse" / "transfer"),
              *_seeds(LIFT / "jumpstart" / "transfer")]
    rows.append((f"baseline, policy reuse, jumpstart ({len(others)} runs, the highest)", others))
    return curve_table(rows, "success_rate", [float(f) for f in range(0, 30_001, 2_500)])


def lift_to_place_curves() -> str:
    rows, baselines = [], []
    for pair, name in (("lift-to-place", "Lift+Place"), ("lift-to-place-barrier", "barrier")):
        d = PLACE / pair / "sac"
        rows += [(f"{name}, demonstrations, {p.name.replace('-', ' ')}", [p])
                 for p in _seeds(d / "demonstrations" / "transfer")]
        baselines += _seeds(d / "baseline")
    rows.append((f"baselines ({len(baselines)} runs, the highest)", baselines))
    return curve_table(rows, "lifted_rate", [float(f) for f in range(0, 20_001, 2_500)], note=_placed)


def lift_dense_peaks() -> str:
    parts = []
    for run in _seeds(DENSE / "sac"):
        e = _evals(run, "return_mean")
        peak = max(e, key=e.get)
        late = [v for f, v in e.items() if f > peak]
        parts.append(f"{run.name.replace('-', ' ')} peaks at {e[peak]:.1f} at {cl.frames(peak)} frames and then "
                     f"stays between {min(late):.1f} and {max(late):.1f}" if late else
                     f"{run.name.replace('-', ' ')} peaks at its last evaluation")
    return "drltg's runs: " + "; ".join(parts) + ".\n"


# ------------------------------------------------------------------------------------------- Lift
LIFT = RESULTS / "sweep-lift-demonstrations" / "lift" / "sac"
PLACE = RESULTS / "sweep-lift-to-place"


def _curve(path: Path, column: str) -> dict[int, float]:
    with open(path) as f:
        return {int(float(r["frames"])): float(r[column]) for r in csv.DictReader(f)}


def _frames(times) -> str:
    return ", ".join("never" if t is None else cl.frames(t) for t in times)


def lift_demonstrations_table() -> str:
    rows = [("method", "mean success gain", "asymptotic success (last 10%)", "mean return gain",
             "seeds holding success ≥ 0.8 (sustained)")]
    for method in ("demonstrations", "policy-reuse", "jumpstart"):
        s = load(LIFT / method / "report-success" / "transfer_metrics.json")
        r = load(LIFT / method / "report" / "transfer_metrics.json")["metrics"]
        times = [x.get("time_to_threshold") for x in s["per_seed"]["transfer"]]
        held = [t for t in times if t is not None]
        rows.append((method, _cell(s["metrics"], PRIMARY), _cell(s["metrics"], "asymptotic_performance"),
                     estimate(r[PRIMARY], r.get(PRIMARY + "_ci"), "+.0f"),
                     f"{len(held)} of {len(times)}" + (f" (from {_frames(held)})" if held else "")))
    return render(rows, "markdown")


def lift_demonstrations_verdicts() -> str:
    lines = []
    for method in ("demonstrations", "policy-reuse", "jumpstart"):
        s = load(LIFT / method / "report-success" / "transfer_metrics.json")
        tuned = _tuned("lift-demonstrations-variants", s) if method == "demonstrations" else ""
        lines.append(f"- **{method}**: mean success gain {said(s)}; "
                     f"{threshold(s, 'transfer', 'success ≥ 0.8')}{tuned}.")
        if method == "demonstrations":
            first = []
            for run in sorted((LIFT / method / "transfer").glob("seed-*")):
                curve = _curve(run / "eval.csv", "success_rate")
                crossing = next((f for f, v in sorted(curve.items()) if v >= 0.8), None)
                first.append(crossing)
            k = sum(f is not None for f in first)
            lines.append(f"  A first crossing, not sustained: {cl.seeds(k, len(first))} "
                         f"{cl.agree(k, len(first), 'touches', 'touch')} 0.8 at least once (at {_frames(first)} "
                         "frames); only the sustained count above says a seed holds it.")
    return "\n".join(lines) + "\n"


def lift_to_place_table() -> str:
    rows = [("target", "mean lifted-rate gain", "final lifted rate (last 10%)", "mean success-rate gain",
             "mean return gain")]
    for pair, name in (("lift-to-place", "Lift+Place"), ("lift-to-place-barrier", "Lift+Place with barrier")):
        d = PLACE / pair / "sac" / "demonstrations"
        lifted = load(d / "report-lifted" / "transfer_metrics.json")["metrics"]
        success = load(d / "report-success" / "transfer_metrics.json")["metrics"]
        ret = load(d / "report" / "transfer_metrics.json")["metrics"]
        rows.append((name, _cell(lifted, PRIMARY), _cell(lifted, "asymptotic_performance"),
                     _cell(success, PRIMARY, "+.3f"), _cell(ret, PRIMARY)))
    return render(rows, "markdown")


def lift_to_place_verdicts() -> str:
    lifted = {pair: load(PLACE / pair / "sac" / "demonstrations" / "report-lifted" / "transfer_metrics.json")
              for pair in ("lift-to-place", "lift-to-place-barrier")}
    adjusted = family(lifted)
    lines = [f"The report's headline metric on the lifted rate, the mean lifted-rate gain, on both targets (read "
             f"together: Holm over the {len(adjusted)}):"]
    wins = total = 0
    for pair, r in lifted.items():
        lines.append(f"- {pair}: {said(r, PRIMARY, adjusted.get(pair))}.")
        b = cl.per_seed_scores(r, "baseline")
        t = cl.per_seed_scores(r, "transfer")
        wins += sum(t[s] > b[s] for s in b)
        total += len(b)
    pooled_b = [v for r in lifted.values() for v in cl.per_seed_scores(r, "baseline").values()]
    pooled_t = [v for r in lifted.values() for v in cl.per_seed_scores(r, "transfer").values()]
    p = stats.sign_test(pooled_b, pooled_t)
    lines.append(f"- Over both targets' pairs, {wins} of {total} transfer runs lift the cube more often than their "
                 f"paired baseline (exact two-sided sign test p = {cl.p_text(p)}; a test chosen after the results "
                 "were seen, so read it as a description, not a confirmed finding).")
    for pair in lifted:
        s = load(PLACE / pair / "sac" / "demonstrations" / "report-success" / "transfer_metrics.json")
        lines.append(f"- {pair}, placing (mean success-rate gain): {said(s)}.")
    return "\n".join(lines) + "\n"


# ----------------------------------------------------------------------------------- Lift, dense
DENSE = RESULTS / "lift-dense"


def lift_dense_verdicts() -> str:
    r = load(DENSE / "vs-seed" / "transfer_metrics.json")
    m, st = r["metrics"], r["settings"]
    trend = st["convergence"]["baseline"]
    rising = cl.estimate(m["final_trend_baseline"], m.get("final_trend_baseline_ci"), 1)
    return (f"Over the overlapping range, frames {st['start']:,} to {st['budget']:,} (the seed project's run is "
            f"longer; it is cut there), drltg's {m['n_seeds_transfer']} seeds minus the seed project's "
            f"{m['n_seeds_baseline']} run give a mean return gain of {cl.signed(m[PRIMARY], 1)}, with no interval "
            f"(one run on one side) and so no verdict. The seed project's curve is {trend} at the end of that "
            f"range ({rising} per window of the last quarter), so the comparison stops while it climbs; the two "
            "curves were also evaluated on different grids and protocols. This is not a comparison of the two "
            "SAC implementations.\n")


# ------------------------------------------------------------------------------------------- demo
DEMO = RESULTS / "demo"


def demo_sentence() -> str:
    """README's quote of the committed `make demo` output, with where it ran and how far a rerun may move."""
    r = load(DEMO / "report" / "transfer_metrics.json")
    machine = load(DEMO / "machine.json")
    source = _seeds(DEMO / "source")[0]
    success = load(source / "summary.json")["final_eval"]["success_rate"]
    ci = r["metrics"].get(f"{PRIMARY}_ci")
    install = ""
    if "install_s" in machine:
        total = (machine["install_s"] + machine["wall_s"]) / 60
        install = (f" Before it, {machine['install']} took {machine['install_s'] / 60:.1f} minutes: "
                   f"{total:.1f} minutes from a fresh clone to the report.")
    return (f"{cl.headline(r)} It ran on {machine['machine']} in {machine['wall_s'] / 60:.1f} minutes of wall time "
            f"with the load average at {machine['load']}, and {machine['cpu_s'] / 60:.1f} "
            f"CPU-minutes (about {machine['cpu_s'] / 60 / machine['cores']:.1f} minutes on {machine['cores']} free "
            f"cores).{install} "
            f"Its one source run ends at a success rate of {success:.2f} on the source task. Another machine "
            "follows another floating-point stream and trains another source: "
            + (f"the interval (half-width {(ci[1] - ci[0]) / 2:.2f}) covers" if ci else "the seeds measure")
            + " the spread of target training from this source only, so a rerun's gain may move further, with the "
            "quality of its source.\n")


# ------------------------------------------------------------------------------------ registries
def _builtin(obj) -> bool:
    """Defined by drltg itself, not by a plugin or a test registered in the same process."""
    return getattr(obj, "__module__", "").startswith("drltg.")


def _kind(name: str, task) -> str:
    if name.startswith(("fourrooms", "gridrooms")):
        return "rooms"
    return "gym" if "gym_id" in task.defaults else "robosuite"


def tasks_table(kind: str) -> str:
    """drltg's registered tasks and pairs of one kind (``"rooms"``: FourRooms and its grid; ``"robosuite"``;
    ``"gym"``: Gymnasium envs)."""
    from drltg.envs import PAIRS, TASKS

    tasks = {name: t for name, t in TASKS.items() if _builtin(t.factory) and _kind(name, t) == kind}
    rows = [("task", "description")] + [(f"`{name}`", t.description) for name, t in tasks.items()]
    pairs = [("pair", "source → target", "description")] + [
        (f"`{name}`", f"`{p.source}` → `{p.target}`", p.description) for name, p in PAIRS.items()
        if p.source in tasks and p.target in tasks]
    return render(rows, "markdown") + "\n" + render(pairs, "markdown")


def _methods() -> dict:
    import drltg.transfer  # noqa: F401  (registers the built-in methods and their transfer.* keys)
    from drltg.transfer.registry import METHODS

    return {name: m for name, m in METHODS.items() if _builtin(m.build)}


def methods_table() -> str:
    rows = [("`transfer.method`", "source", "what it is")]
    for name, spec in _methods().items():
        source = {None: "—", "run": "a run", "policy": "a run or `demonstrator:TASK`"}[spec.source]
        rows.append((f"`{name}`", source, spec.help))
    return render(rows, "markdown")


def config_table() -> str:
    """``drltg.config.describe()`` for drltg's own keys (a plugin's method keys left out)."""
    from drltg import config

    builtin = _methods()
    own = {f"transfer.{key}" for m in builtin.values() for key in m.options}
    lines = []
    for line in config.describe().splitlines():
        key = line.split("`")[1] if line.startswith("| `") else None
        if key is None or not key.startswith("transfer.") or key in own or key.removeprefix("transfer.") not in \
                config.METHOD_OPTIONS:
            if key == "transfer.method":
                cells = line.split(" | ")
                cells[2] = "one of " + ", ".join(builtin)
                line = " | ".join(cells)
            lines.append(line)
    return "\n".join(lines) + "\n"



# ------------------------------------------------------------------------------------- manipulation
MANIP = RESULTS / "manipulation"
ROW_SPECS = ROOT / "examples" / "sweeps" / "manipulation-rows"
WORKERS = 2


def _queue() -> tuple[list[str], dict[str, tuple[int, int]]]:
    """The queue's rows in order and its sources as ``{name: (runs, frames each)}``, read from queue.sh."""
    import re

    text = (MANIP / "queue.sh").read_text()
    rows = re.search(r'ROWS=\$\{ROWS:-"([^"]*)"\}', text).group(1).split()
    soc = int(re.search(r"SOC_FRAMES:-(\d+)", text).group(1))
    sac = int(re.search(r'\[lift-sac-ln-half\]="--frames (\d+)', text).group(1))
    seeds = len(re.search(r'SEEDS="([^"]*)"', text).group(1).split())
    return rows, {"lift-sac-ln-half": (seeds, sac), "lift-soc4": (seeds, soc)}


def run_rate(runs: Path = MANIP, pattern: str = "*/lift-to-place*/sac/**/seed-*/summary.json") -> tuple[float, int]:
    """The median frames/s (evaluations included) of the finished runs ``pattern`` finds under ``runs``
    (default: the rows' SAC runs on the placing targets kept so far, two at a time on this machine's 2 cores),
    and how many: a baseline kept by several rows (the same ``summary.json``) is one run."""
    import statistics

    runs_once = {p.read_bytes(): p for p in sorted(runs.glob(pattern))}
    rates = [load(p)["frames_per_s"] for p in runs_once.values()]
    return statistics.median(rates), len(rates)


def manipulation_cost() -> str:
    """results/manipulation/README.md's table of the study's one-command rows: what each adds in the queue's
    order (a target's baselines are trained by the first row that needs them) and its wall time on 2 cores at the
    measured rate."""
    rows, sources = _queue()
    fps, n = run_rate()
    soc_fps, soc_n = run_rate(MANIP / "sources" / "lift-soc4", "seed-*/summary.json")
    rate = {"lift-sac-ln-half": fps, "lift-soc4": soc_fps, "sac": fps, "soc": soc_fps}
    out = [("step", "command", "runs it adds × frames", "wall time on 2 cores")]
    hours = sum(k * f / rate[name] for name, (k, f) in sources.items()) / WORKERS / 3600
    out.append(("sources: " + ", ".join(f"`{name}` {k} × {cl.frames(f)}" for name, (k, f) in sources.items()),
                "`TRAIN_SOURCES=1 bash results/manipulation/queue.sh` (first step)",
                " + ".join(f"{k} × {cl.frames(f)}" for k, f in sources.values()), f"{hours:.1f} h"))
    total = hours
    seen = set()
    for row in rows:
        spec = yaml.safe_load((ROW_SPECS / f"{row}.yaml").read_text())
        script = (MANIP / f"{row}.sh").read_text()  # in RUNS/reference, with baselines of its own unless shared
        nested = "/reference exec" in script and "BASELINES=" not in script
        group = (nested, spec["pairs"][0], spec["algos"][0])
        k = spec["seeds"] * (1 if group in seen else 2)
        seen.add(group)
        h = math.ceil(k / WORKERS) * spec["frames"] / rate[spec["algos"][0]] / 3600
        total += h
        out.append((f"`{row}`", f"`bash results/manipulation/{row}.sh`", f"{k} × {cl.frames(spec['frames'])}",
                    f"{h:.1f} h"))
    return (render(out, "markdown") + f"\nWall time = ⌈runs / {WORKERS}⌉ × frames / rate (sources: all their frames / "
            f"({WORKERS} × rate)), at {fps:.1f} frames/s per run: the median of the {n} SAC runs of the rows "
            "kept so far (Lift+Place, two at a time on this machine's 2 cores, some beside other work, evaluations "
            "included); the soft option-critic's, "
            f"{soc_fps:.1f} frames/s, is the median of the {soc_n} kept `lift-soc4` source run{'s' * (soc_n != 1)} "
            "(Lift, two at a time): its update evaluates K option copies of every next state, and with demonstrations "
            f"the policy over options at each demonstrated state. All steps in the queue: about {total:.0f} h.\n")


SOURCE_THRESHOLD = 0.8


def _held(seeds: list[Path], threshold: float, column: str = "success_rate") -> tuple[int, str]:
    """How many of ``seeds`` hold ``column`` at or above ``threshold`` to their last evaluation (the
    report's sustained rule), and per seed from when or how low it fell over its second half."""
    held = []
    for p in seeds:
        ev = _evals(p, column)
        frames, values = list(ev), list(ev.values())
        since = mx.sustained_time_to_threshold(frames, values, threshold)
        late = [v for f, v in ev.items() if f >= frames[-1] / 2]
        held.append(f"seed {p.name.split('-')[1]} " + (f"from {cl.frames(since)}" if since is not None else
                    f"does not, lowest {min(late):.1f} over the second half"))
    return sum("from" in h for h in held), "; ".join(held)


def manipulation_sources() -> str:
    """The kept sources' success rate over training, and per source how many seeds hold 0.8 to the end."""
    rows, lines = [], []
    for source in sorted(p for p in (MANIP / "sources").iterdir() if p.is_dir()):
        seeds = _seeds(source)
        rows += [(f"`{source.name}` seed {p.name.split('-')[1]}", [p]) for p in seeds]
        n, held = _held(seeds, SOURCE_THRESHOLD)
        last = max(max(_evals(p, "success_rate")) for p in seeds)
        lines.append(f"- `{source.name}`: {n} of {len(seeds)} seeds {'holds' if n == 1 else 'hold'} a success rate "
                     f"≥ {SOURCE_THRESHOLD} to the end of {cl.frames(last)} frames ({held}).")
        lines += _best_evaluated(source.name, seeds)
    frames = sorted({f for _, (p,) in rows for f in _evals(p, "success_rate")})
    lines.append(_how_strict(frames, episodes=int(load(seeds[0] / "summary.json")["final_eval"]["episodes"])))
    return curve_table(rows, "success_rate", frames, fmt=".1f") + "\n" + "\n".join(lines) + "\n"


def _how_strict(frames: list[float], episodes: int, p: float = 0.9, low: float = 0.3) -> str:
    """How often evaluations of ``episodes`` episodes make a policy whose true success rate is ``p`` miss
    the 0.8 rule over the second half of ``frames``, against how rarely they show ``low`` or less."""
    from scipy.stats import binom

    late = sum(f >= frames[-1] / 2 for f in frames)
    below = binom.cdf(math.ceil(SOURCE_THRESHOLD * episodes) - 1, episodes, p)
    deep = binom.cdf(math.floor(low * episodes), episodes, p)
    return (f"- How strict the rule is: an evaluation on {episodes} episodes of a policy whose true success rate "
            f"is {p} shows less than {SOURCE_THRESHOLD} with probability {below:.2f}, so at least one of {late} "
            f"second-half evaluations does with probability {1 - (1 - below) ** late:.2f}; it shows {low} or less "
            f"with probability {deep:.0e}. A fall to {low} or below means the policy changed, not the sample.")


def _best_evaluated(name: str, seeds: list[Path], threshold: float = SOURCE_THRESHOLD,
                    what: str = "the checkpoint the rows reuse, `best.pt`") -> list[str]:
    """The line on ``name``'s kept best checkpoints, evaluated on fresh episodes by queue.sh
    (``evaluate-best-*-50ep.json``), if any seed has one."""
    found = {p: sorted(p.glob("evaluate-best-*-50ep.json")) for p in seeds}
    if not any(found.values()):
        return []
    parts, n = [], 0
    for p, files in found.items():
        seed = p.name.split("-")[1]
        if not files:
            kept = (p / "checkpoints" / "best.pt").is_file()
            why = "not evaluated" if kept else "kept no best.pt: it was trained without keep_best"
            parts.append(f"seed {seed} {why}")
            continue
        r = load(files[0])
        lo, hi = r["success_rate_ci95"]
        n += r["success_rate"] >= threshold
        parts.append(f"seed {seed} {r['success_rate']:.2f} [{lo:.2f}, {hi:.2f}] at {cl.frames(r['frames'])}")
    episodes = load(next(f for files in found.values() for f in files))["episodes"]
    return [f"  - {what}, on {episodes} fresh episodes (95% Clopper-Pearson): "
            f"{n} of {len(seeds)} at or above {threshold} ({'; '.join(parts)})."]


def critic_scale() -> str:
    """The kept SAC sources' critics at the demonstrator's states against the ceiling 1 / (1 - gamma)
    (``results/manipulation/sources/critic_scale.csv``), and which of them dipped."""
    rows = list(csv.DictReader((MANIP / "sources" / "critic_scale.csv").open()))
    table = [("run", "Q(s, a) at demonstrated steps", "Q(s, μ(s))", "ceiling", "final success",
              "lowest success, second half")]
    table += [(f"`{r['source']}` seed {r['seed']}", r["q_demonstrated"], r["q_actor"], r["ceiling"],
               f"{float(r['final_success']):.1f}", f"{float(r['lowest_success_second_half']):.1f}") for r in rows]

    def name(r):
        return f"`{r['source']}` seed {r['seed']}"

    over = [r for r in rows if float(r["q_demonstrated"]) > float(r["ceiling"])]
    under = [r for r in rows if r not in over]

    def dipped(group):
        return [r for r in group if float(r["lowest_success_second_half"]) < SOURCE_THRESHOLD]

    def listed(group):
        return ", ".join(f"{name(r)} (Q {float(r['q_demonstrated']):.0f}, lowest "
                         f"{float(r['lowest_success_second_half']):.1f})" for r in group) or "none"

    sentence = (f"{len(over)} of {len(rows)} SAC sources end with critics that value the demonstrator's states "
                f"above the ceiling, {len(dipped(over))} of them dipping below {SOURCE_THRESHOLD} over the second "
                f"half: {listed(over)}. Of the {len(under)} below it, {len(dipped(under))} dipped as well: "
                f"{listed(dipped(under))}; {listed([r for r in under if r not in dipped(under)])} did not.")
    return render(table, "markdown") + "\n" + sentence + "\n"


PLACE_THRESHOLD = 0.5


def _shared_baselines() -> dict[tuple[str, str], tuple[list[str], list[Path]]]:
    """Per placing target and learner, the rows whose kept baselines are its baselines, and one kept run per
    seed: the rows on one target share them (``row.sh``), so a seed kept by two rows must be the same curve."""
    shared: dict[tuple[str, str], tuple[list[str], dict[str, Path]]] = {}
    for side in sorted(MANIP.glob("*/lift-to-place*/*/baseline")):
        row, pair, algo = side.relative_to(MANIP).parts[:3]
        rows, seeds = shared.setdefault((pair, algo), ([], {}))
        rows.append(row)
        for run in _seeds(side):
            first = seeds.setdefault(run.name, run)
            if (first / "eval.csv").read_bytes() != (run / "eval.csv").read_bytes():
                raise ValueError(f"{first} and {run} should be one baseline run, kept twice, but their curves differ.")
    return {key: (rows, sorted(seeds.values(), key=_seed_number))
            for key, (rows, seeds) in shared.items()}


def manipulation_placing() -> str:
    """The study's finished runs on the placing targets, kept so far whether or not their row is complete:
    success rate (the cube resting on the target) over training, and per row and side how many seeds
    hold 0.5 to the end; then the measurements beside the rows (``results/manipulation/measurements/NAME``)."""
    groups = []  # (name in the table, name in its line, seeds)
    for (pair, algo), (rows, seeds) in sorted(_shared_baselines().items()):
        named = ", ".join(f"`{row}`" for row in rows)
        side = "no transfer" if algo == "sac" else f"{algo}, no transfer"  # SAC: every row but SOC's
        groups.append((f"`{pair}`, {side}", f"`{pair}`, {side} (the baselines of {named})", seeds))
    for side in sorted(MANIP.glob("*/lift-to-place*/*/*/transfer")):
        row, pair = side.relative_to(MANIP).parts[:2]
        groups.append((f"`{row}`, {side.parent.name}", f"`{row}` ({pair}), {side.parent.name}", _seeds(side)))
    for measured in sorted(p for p in (MANIP / "measurements").glob("*") if p.is_dir()):
        seeds = _seeds(measured)
        task = yaml.safe_load((seeds[0] / "config.yaml").read_text())["task"] if seeds else ""
        groups.append((f"`measurements/{measured.name}`", f"`measurements/{measured.name}` ({task})", seeds))
    rows, lines = [], []
    for name, line, seeds in groups:
        if not seeds:
            continue
        rows += [(f"{name}, seed {p.name.split('-')[1]}", [p]) for p in seeds]
        n, held = _held(seeds, PLACE_THRESHOLD)
        last = max(max(_evals(p, "success_rate")) for p in seeds)
        lines.append(f"- {line}: {n} of {len(seeds)} finished seeds {'holds' if n == 1 else 'hold'} "
                     f"a success rate ≥ {PLACE_THRESHOLD} to the end of {cl.frames(last)} frames ({held}).")
        lines += _best_evaluated(name, seeds, PLACE_THRESHOLD, "its best checkpoint, `best.pt`")
    if not rows:
        return "No run on a placing target has finished yet.\n"
    frames = sorted({f for _, (p,) in rows for f in _evals(p, "success_rate")})
    return curve_table(rows, "success_rate", frames, fmt=".1f") + "\n" + "\n".join(lines) + "\n"


FALLEN_BELOW = -0.01
"""m: a cube whose centre ends below the target's (which rests on the table) has left the table."""


def _off_table(row: dict) -> bool:
    return float(row["height_m"]) < FALLEN_BELOW


def manipulation_collapse() -> str:
    """Where the cube is at the end of each kept measurement's episodes, at ``best.pt`` and at ``last.pt``
    (``results/manipulation/measurements/NAME/collapse.csv``, written by ``collapse.py``)."""
    out = [("run", "checkpoint", "placed at the end", "ever lifted", "held at the end", "off the table",
            "steps placed (mean)", "gap to the demonstrator's action", "min Q at its states")]
    lines = []
    for path in sorted((MANIP / "measurements").glob("*/collapse.csv")):
        rows = list(csv.DictReader(path.open()))
        demo = path.with_name("demonstrated.csv")
        gaps = {(int(r["seed"]), r["checkpoint"]): r for r in csv.DictReader(demo.open())} if demo.is_file() else {}
        seeds = sorted({int(r["seed"]) for r in rows})
        fewer, unplaced = [], []
        for seed in seeds:
            placed = {}
            for checkpoint in ("best", "last"):
                rs = [r for r in rows if int(r["seed"]) == seed and r["checkpoint"] == checkpoint]
                n = len(rs)
                count = {k: sum(int(r[k]) for r in rs) for k in ("placed", "lifted", "grasped")}
                fallen = sum(map(_off_table, rs))
                out.append((f"`measurements/{path.parent.name}` seed {seed}",
                            f"`{checkpoint}.pt` ({cl.frames(int(rs[0]['frames']))})",
                            f"{count['placed']}/{n}", f"{count['lifted']}/{n}", f"{count['grasped']}/{n}",
                            f"{fallen}/{n}", f"{sum(int(r['steps_placed']) for r in rs) / n:.0f}",
                            *((f"{float(g['action_gap']):.3f}", f"{float(g['q_demonstrated']):.0f}")
                              if (g := gaps.get((seed, checkpoint))) else ("—", "—"))))
                placed[checkpoint] = count["placed"]
                if checkpoint == "last":
                    unplaced += [r for r in rs if not int(r["placed"])]
            if placed["last"] < placed["best"]:
                fewer.append(seed)
        fallen = sum(map(_off_table, unplaced))
        held = sum(bool(int(r["grasped"])) and not _off_table(r) for r in unplaced)
        rest = [r for r in unplaced if not int(r["grasped"]) and not _off_table(r)]
        away = (f" ({100 * sum(float(r['distance_m']) for r in rest) / len(rest):.0f} cm from the target's centre "
                "on average)" if rest else "")
        lines.append(f"- `measurements/{path.parent.name}`: at `last.pt` {len(fewer)} of {len(seeds)} seeds place "
                     f"in fewer episodes than at `best.pt`"
                     + (f" (seed{'s' * (len(fewer) > 1)} {', '.join(map(str, fewer))})" if fewer else "")
                     + f"; of the {len(unplaced)} episodes that end unplaced at `last.pt`, the cube is off the table "
                     f"in {fallen}, held in the gripper in {held} and resting on the table in {len(rest)}{away}.")
        if gaps:
            lines.append(f"  - at the demonstrator's own states ({_demo_episodes()} seeded episodes), the actor's mean "
                         "absolute gap to its action (each dimension in [−1, 1]) is "
                         + " and ".join(f"{_span(gaps, c, 'action_gap', '.3f')} at `{c}.pt`" for c in ("best", "last"))
                         + "; the smaller critic values those states at "
                         + " and ".join(f"{_span(gaps, c, 'q_demonstrated', '.0f')} at `{c}.pt`"
                                        for c in ("best", "last"))
                         + " (the ceiling 1 / (1 − γ) is 100).")
    if not lines:
        return "No measurement has a collapse.csv yet.\n"
    return render(out, "markdown") + "\n" + "\n".join(lines) + "\n"


def _span(rows: dict, checkpoint: str, key: str, fmt: str) -> str:
    """``a–b``: the smallest and largest ``key`` over the seeds at ``checkpoint`` (``a`` when they agree)."""
    values = sorted(float(r[key]) for (_, c), r in rows.items() if c == checkpoint)
    low, high = format(values[0], fmt), format(values[-1], fmt)
    return low if low == high else f"{low}–{high}"


def _demo_episodes() -> int:
    import re

    text = (RESULTS / "manipulation" / "measurements" / "collapse.py").read_text()
    return int(re.search(r"^DEMO_EPISODES = (\d+)$", text, re.M).group(1))


EARLIER = MANIP / "earlier"


def _row_report(row: str, tag: str = "success") -> dict | None:
    """The study's report of ``row`` on ``tag`` (``results/manipulation/ROW/PAIR/ALGO/METHOD/report-TAG/``)."""
    found = sorted((MANIP / row).glob(f"*/*/*/report-{tag}/transfer_metrics.json"))
    return load(found[0]) if found else None


def _ends(report: dict) -> str:
    """Where a gain over the whole budget comes from: the difference at the first evaluation and at the end
    (nothing where both are 0.00)."""
    m, st = report["metrics"], report["settings"]
    if round(abs(m["jumpstart"]), 2) == 0 and round(abs(m["asymptotic_performance"]), 2) == 0:
        return ""
    text = (f" (at the first evaluation {cl.signed(m['jumpstart'])}, over the last {st['asymptote_window']:.0%} of "
            f"the budget {cl.signed(m['asymptotic_performance'])}")
    b, t = _curves(report, "baseline"), _curves(report, "transfer")
    if round(abs(m["jumpstart"]), 2) and all(len(c.frames) > 1 for c in b + t):
        second = float(np.mean([c.values[1] for c in t]) - np.mean([c.values[1] for c in b]))
        if round(abs(second), 2) == 0:
            text += (f"; gone by the second evaluation, {cl.frames(t[0].frames[1])} frames: {cl.signed(second)}, so "
                     "this gain is the frame-0 jumpstart carried over the first interval, not a gain over the run")
    return text + ")"


RECIPES = {
    "demonstrations-reference": "the placement reference's recipe (measurements/place-reference-ln-half-noisy)",
    "lift-demonstrations-variants": "the Lift cloning defaults (lift-demonstrations-variants)",
}
"""Recipes chosen after seeing runs, by the result names that use them; the seeds come from the runs' configs
(``tuned_on``), through the report (``settings.tuned_on``)."""


def _tuned(name: str, report: dict) -> str:
    """A clause naming the seeds of ``report`` that also chose its recipe (none: empty)."""
    shared = (report["settings"].get("tuned_on") or {}).get("transfer") or []
    if not shared:
        return ""
    what = next((w for prefix, w in RECIPES.items() if name.startswith(prefix)), "its recipe")
    return (f"; {what}: chosen on seed{'s' if len(shared) > 1 else ''} {', '.join(map(str, shared))}, which "
            f"{'are' if len(shared) > 1 else 'is'} reported here too (tuned on the seeds it reports, not a "
            "fresh-seed result)")


def manipulation_rows() -> str:
    """One line per reported row, in the queue's order: the transfer side's gain over no transfer in mean
    success rate over the budget (the area under the curve per frame, paired by seed), and on the placing
    targets in lifted rate; the gains are read in the family of every test of the row's reports, Holm-adjusted
    (:func:`whole_family`). Where any seed holds the
    report's success threshold to the end (its sustained rule), how many on each side do."""
    lines, queue = [], _queue()[0]
    for row in queue:
        reports = {tag: r for tag in ("success", "lifted") if (r := _row_report(row, tag)) is not None}
        if "success" not in reports:
            continue
        adjusted = whole_family(reports)
        m, st = reports["success"]["metrics"], reports["success"]["settings"]
        gains = "; ".join(f"{tag} rate {said(r, PRIMARY, adjusted.get(tag))}{_ends(r)}"
                          for tag, r in reports.items())
        size = next(iter(adjusted.values())).size if adjusted else 0
        gains += (f" (Holm over all {size} test{'s' if size != 1 else ''} of its {len(reports)} "
                  f"report{'s' if len(reports) > 1 else ''})")
        held = {side: round(m[f"threshold_reached_{side}"] * m[f"n_seeds_{side}"]) for side in ("transfer", "baseline")}
        if any(held.values()):
            gains += (f"; success rate ≥ {st['threshold']:g} held to the end by {held['transfer']} of "
                      f"{m['n_seeds_transfer']} seeds with transfer and {held['baseline']} of {m['n_seeds_baseline']} "
                      "without")
        never = [side for side in ("baseline", "transfer") if m[f"total_reward_{side}"] == 0]
        what = "placed" if st["task"] != "lift" else "lifted"
        if never:
            side = {"baseline": "without transfer", "transfer": "with transfer"}
            who = "on either side" if len(never) == 2 else side[never[0]]
            gains += f"; no run {who} {what} a cube in any evaluation"
        gains += _tuned(row, reports["success"])
        lines.append(f"- `{row}` ({st['task']}, {st['transfer_label']} against {st['baseline_label']}, "
                     f"{m['n_seeds_transfer']} paired seeds × {cl.frames(st['budget'])} frames), mean gain in {gains}.")
    if not lines:
        return "No row of the queue is complete yet (the runs finished so far are below).\n"
    left = len(queue) - len(lines)
    return "\n".join(lines) + "\n" + (f"{left} of the queue's {len(queue)} rows are not complete yet (the runs "
                                     "finished so far are below).\n" if left else "")


SEED = RESULTS / "seed-tasks"
SEED_ROWS = ("shaping-lift-seed", "pi-reuse-place-seed", "pi-reuse-barrier-seed", "model-reuse-place-seed",
             "soc-model-reuse-place-seed")
SEED_REPORTS = {"return": "report", "success": "report-success", "lifted": "report-lifted"}


def seed_rows() -> str:
    """One line per reported row of the seed's tasks (``results/seed-tasks/ROW/report*/``): the transfer side's
    mean gain over no transfer in return on the task's reward, strict success rate and lifted rate, read in the
    family of every test of the row's reports, Holm-adjusted (:func:`whole_family`)."""
    lines = []
    for row in SEED_ROWS:
        reports = {tag: load(p) for tag, sub in SEED_REPORTS.items()
                   if (p := SEED / row / sub / "transfer_metrics.json").is_file()}
        if not reports:
            continue
        adjusted = whole_family(reports)
        first = next(iter(reports.values()))
        m, st = first["metrics"], first["settings"]
        gains = "; ".join(f"{tag}{'' if tag == 'return' else ' rate'} {said(r, PRIMARY, adjusted.get(tag))}{_ends(r)}"
                          for tag, r in reports.items())
        size = next(iter(adjusted.values())).size if adjusted else 0
        gains += f" (Holm over all {size} test{'s' if size != 1 else ''} of its {len(reports)} report" \
                 f"{'s' if len(reports) > 1 else ''})"
        lines.append(f"- `{row}` ({st['task']}, {st['transfer_label']} against {st['baseline_label']}, "
                     f"{m['n_seeds_transfer']} paired seeds × {cl.frames(st['budget'])} frames), mean gain in {gains}.")
    left = len(SEED_ROWS) - len(lines)
    if not lines:
        return f"No row of the {len(SEED_ROWS)} is reported yet: the table above shows their runs so far.\n"
    return "\n".join(lines) + "\n" + (f"{left} of the {len(SEED_ROWS)} rows are not reported yet.\n" if left else "")


def manipulation_earlier() -> str:
    """The earlier implementation's rows (one run a side, its own reward) beside the study's (3 paired seeds)."""
    out = [("row", "earlier runs: no transfer → transfer", "frames", "final return, B / T", "mean return gain",
            "gain at 100k frames", "drltg: mean success-rate gain, 3 paired seeds")]
    order = _queue()[0]
    for folder in sorted((p for p in EARLIER.iterdir() if p.is_dir()), key=lambda p: order.index(p.name)):
        whole, cut = load(folder / "transfer_metrics.json"), load(folder / "at-100k" / "transfer_metrics.json")
        m, st = whole["metrics"], whole["settings"]
        ours = _row_report(folder.name)
        mine = ("not trained yet" if ours is None else
                estimate(ours["metrics"]["mean_return_gain"], ours["metrics"].get("mean_return_gain_ci"),
                         lambda x: format(x if round(x, 2) else 0.0, "+.2f")))  # no "-0.00"
        out.append((f"`{folder.name}`", f"`{Path(st['baseline'][0]).parent.name}` → "
                    f"`{Path(st['transfer'][0]).parent.name}`", cl.frames(st["budget"]),
                    f"{m['final_performance_baseline']:.0f} / {m['final_performance_transfer']:.0f}",
                    estimate(m["mean_return_gain"], None, "+.1f"),
                    estimate(cut["metrics"]["mean_return_gain"], None, "+.1f"), mine))
    return render(out, "markdown")


PLACEMENT = MANIP / "placement-diagnostics"


def placement_noise() -> str:
    s = load(PLACEMENT / "summary.json")
    out = [("task", *(f"σ = {r['sigma']:g}" for r in s["noise"] if r["task"] == "lift-place"))]
    for task in ("lift-place", "lift-place-barrier"):
        cells = [f"lifted {r['lifted']}/{r['episodes']}, placed {r['placed']}/{r['episodes']}, "
                 f"return {r['return_mean']:.0f}" for r in s["noise"] if r["task"] == task]
        out.append((task, *cells))
    return render(out, "markdown")


def source_noise() -> str:
    """The learned Lift sources as noisy demonstrators on lift-place (``source_noise.py``)."""
    with open(PLACEMENT / "source-noise.csv") as f:
        rows = list(csv.DictReader(f))
    sigmas = sorted({float(r["sigma"]) for r in rows})
    sources = sorted({r["source"] for r in rows}, key=lambda name: int(name.rsplit("-", 1)[1]))
    cell = {(r["source"], float(r["sigma"])): f"{r['lifted']}/{r['episodes']}" for r in rows}
    table = [("source (best.pt)", *(f"σ = {x:g}" for x in sigmas))]
    table += [(f"`{name}`", *(cell[name, x] for x in sigmas)) for name in sources]
    total = {x: (sum(int(r["lifted"]) for r in rows if float(r["sigma"]) == x),
                 sum(int(r["episodes"]) for r in rows if float(r["sigma"]) == x)) for x in sigmas}
    low, high = sigmas[0], sigmas[-1]
    scripted = next(r for r in load(PLACEMENT / "summary.json")["noise"]
                    if r["task"] == "lift-place" and r["sigma"] == high)
    return (render(table, "markdown").rstrip() + f"\n\nThe learned sources lift the cube in {total[low][0]} of "
            f"{total[low][1]} episodes without noise and in {total[high][0]} of {total[high][1]} at σ = {high:g}, "
            f"where the scripted demonstrator places in {scripted['placed']} of {scripted['episodes']} "
            "(the table above).")


SHAPING = MANIP / "shaping-diagnostics"


def shaping_stages() -> str:
    """The ``lift-shaping`` row's final policies on Lift, stage by stage (``stages.py``)."""
    with open(SHAPING / "stages.csv") as f:
        rows = list(csv.DictReader(f))
    table = [("side", "seed", "start (m)", "closest (m)", "mean (m)", "steps grasped", "grasped", "lifted")]
    table += [(r["side"], r["seed"], r["start_m"], r["closest_m"], r["mean_m"], r["grasped_share"],
               f"{r['grasped']}/{r['episodes']}", f"{r['lifted']}/{r['episodes']}") for r in rows]
    sides: dict[str, list[dict]] = {}
    for r in rows:
        sides.setdefault(r["side"], []).append(r)
    parts = []
    for side, runs in sides.items():
        mean = {k: sum(float(r[k]) for r in runs) / len(runs) for k in ("start_m", "closest_m", "mean_m")}
        episodes = sum(int(r["episodes"]) for r in runs)
        closer = sum(float(r["closest_m"]) < float(r["start_m"]) - 0.01 for r in runs)
        parts.append(f"{side} ({len(runs)} seeds), the gripper comes {mean['start_m'] - mean['closest_m']:.3f} m "
                     f"closer to the cube than where it starts ({mean['start_m']:.3f} m) on average, more than "
                     f"1 cm closer in {closer} of {len(runs)} runs, and averages {mean['mean_m']:.2f} m from it; "
                     f"the cube is grasped in {sum(int(r['grasped']) for r in runs)} and lifted in "
                     f"{sum(int(r['lifted']) for r in runs)} of {episodes} episodes")
    return render(table, "markdown").rstrip() + "\n\nAt the last checkpoint, " + "; ".join(parts) + ".\n"


def placement_verdicts() -> str:
    s = load(PLACEMENT / "summary.json")
    p, h, phi = s["place_demonstrator"], s["lift_demonstrator_on_lift_place"], s["phi_states"]
    gain = phi["resting_on_target"] - phi["held_above_target"]
    release = "does not pay the release" if gain <= 0 else f"pays the release {gain:.2f}"
    lines = [
        f"- The sparse reward pays placing and nothing else: on one noise-free episode (seed 0) the place "
        f"demonstrator grasps at step {p['first_grasped']}, lifts at {p['first_lifted']}, places at "
        f"{p['first_placed']} and earns {p['return']:.0f} (discounted, γ = {s['gamma']}: "
        f"{p['discounted_return']:.1f}); the Lift demonstrator on the same task grasps at {h['first_grasped']}, "
        f"lifts at {h['first_lifted']}, holds the cube up to the end and earns {h['return']:.0f}. A hold is not paid "
        "like a placement, so the reward does not hold a learner at lifting; it pays nothing until a carry and a "
        "release, which the Lift source never shows, have been found.",
        f"- The registered shaping potential {release}: Φ is {phi['held_above_target']:.2f} with the "
        f"cube held 5 cm above the target's centre and {phi['resting_on_target']:.2f} with it released on the "
        f"target; along the episode Φ goes from {p['phi_start']:.2f} to {p['phi_end']:.2f} for the place "
        f"demonstrator and to {h['phi_end']:.2f} for the Lift demonstrator (the cube lifted, away from the target). "
        "Under `reward-shaping` only the sparse term tells a carry-and-hold from a placement.",
    ]
    parts = []
    for task in ("lift-place", "lift-place-barrier"):
        cells = [r for r in s["noise"] if r["task"] == task]
        every = [r["sigma"] for r in cells if r["placed"] == r["episodes"]]
        none = [r["sigma"] for r in cells if r["placed"] == 0]
        parts.append(f"on {task} it places in every episode up to σ = {max(every):g}" if every else
                     f"on {task} it never places in every episode")
        if none:
            lifted = sum(r["lifted"] for r in cells if r["sigma"] >= min(none))
            parts[-1] += f" and in none from σ = {min(none):g} (lifting in {lifted} of those episodes)"
    lines.append("- With Gaussian action noise (the table above), " + "; ".join(parts) + ".")
    return "\n".join(lines) + "\n"

# --------------------------------------------------------------------------------------- regions
def _curves(report: dict, side: str) -> list:
    """The side's runs as the report read them (its per-seed sources, relative to the repository)."""
    from drltg.analysis.curves import read_curves

    st = report["settings"]
    return [read_curves(ROOT / row["source"], format=st["format"], tag=st["tag"])[0]
            for row in report["per_seed"][side]]


def threshold(report: dict, side: str = "transfer", who: str | None = None) -> str:
    """:func:`drltg.analysis.claims.threshold_sentence`, with the seeds that cross too late to be confirmed."""
    return cl.threshold_sentence(report, side, who, late=cl.late_crossings(report, side, _curves(report, side)))


def pendulum_heavier() -> str:
    """The Pendulum study (results/pendulum-heavier/report): its table and its report's sentences."""
    report = json.loads((RESULTS / "pendulum-heavier" / "report" / "transfer_metrics.json").read_text())
    m = report["metrics"]
    rows = [("mean return gain", "jumpstart", "asymptotic (last 10%)", "transfer ratio", "P(T > B)",
             "final return, B / T")]
    rows.append((*(estimate(m.get(k), m.get(f"{k}_ci"), "+.0f") for k in ("mean_return_gain", "jumpstart",
                                                                          "asymptotic_performance")),
                 estimate(m.get("transfer_ratio"), m.get("transfer_ratio_ci"), "+.2f"),
                 estimate(m.get("probability_of_improvement"), m.get("probability_of_improvement_ci"), ".2f"),
                 f"{m['final_performance_baseline']:.0f} / {m['final_performance_transfer']:.0f}"))
    late = {side: cl.late_crossings(report, side, _curves(report, side)) for side in ("baseline", "transfer")}
    sentences = cl.report_sentences(report, ("mean_return_gain", "jumpstart", "asymptotic_performance"), late)
    return render(rows, "markdown") + "\n" + "\n".join(f"- {s}" for s in sentences) + "\n"


REGIONS = {
    "results/README.md": {
        "graded-table": lambda: sweep_table(GRADED),
        "graded-verdicts": lambda: sweep_verdicts(GRADED, ["model-reuse", "value-shaping", "policy-reuse",
                                                           "reward-shaping"]),
        "graded-thresholds": lambda: threshold_lines(GRADED, "baseline") + threshold_lines(
            GRADED, "transfer", ["model-reuse", "value-shaping"]),
        "grid-table": lambda: sweep_table(RESULTS / "sweep-gridrooms"),
        "grid-verdicts": lambda: sweep_verdicts(RESULTS / "sweep-gridrooms", ["model-reuse", "value-shaping",
                                                                               "policy-reuse", "reward-shaping"]),
        "grid-thresholds": lambda: threshold_lines(RESULTS / "sweep-gridrooms", "baseline"),
        "options-table": options_table,
        "options-verdicts": options_verdicts,
        "options-sources": options_sources,
        "lift-variants": lift_variants,
        "lift-dense-curves": lift_dense_curves,
        "lift-dense-verdicts": lift_dense_verdicts,
        "lift-dense-peaks": lift_dense_peaks,
        "lift-dense-study": lift_dense_study_table,
        "lift-demonstrations-curves": lift_demonstrations_curves,
        "lift-to-place-curves": lift_to_place_curves,
        "lift-demonstrations-table": lift_demonstrations_table,
        "demo": demo_sentence,
        "lift-demonstrations-verdicts": lift_demonstrations_verdicts,
        "lift-to-place-table": lift_to_place_table,
        "lift-to-place-verdicts": lift_to_place_verdicts,
        "pendulum-heavier": pendulum_heavier,
        "placement-noise": placement_noise,
        "placement-verdicts": placement_verdicts,
        "source-noise": source_noise,
        "shaping-stages": shaping_stages,
    },
    "README.md": {"demo": demo_sentence},
    "docs/tasks.md": {
        "tasks": lambda: tasks_table("rooms"),
        "tasks-robosuite": lambda: tasks_table("robosuite"),
        "tasks-gym": lambda: tasks_table("gym"),
        "lift-summary": readme_lift,
    },
    "docs/training.md": {"config": config_table},
    "docs/methods.md": {"methods": methods_table},
    "docs/results.md": {
        "results-table": results_table,
        "results-verdicts": lambda: sweep_verdicts(GRADED, ["model-reuse", "value-shaping", "policy-reuse",
                                                            "reward-shaping"]),
        "results-others": readme_others,
    },
    "results/seed-tasks/README.md": {"seed-rows": seed_rows},
    "results/manipulation/README.md": {
        "manipulation-cost": manipulation_cost,
        "manipulation-sources": manipulation_sources,
        "manipulation-critics": critic_scale,
        "manipulation-rows": manipulation_rows,
        "manipulation-earlier": manipulation_earlier,
        "manipulation-placing": manipulation_placing,
        "manipulation-collapse": manipulation_collapse,
    },
}


def generated(file: str) -> dict[str, str]:
    return {name: make() for name, make in REGIONS[file].items()}


def main(argv: list[str]) -> int:
    check = "--check" in argv
    drift = []
    for file in REGIONS:
        path = ROOT / file
        text = path.read_text()
        new = cl.fill_regions(text, generated(file))
        if new != text:
            drift.append(file)
            if not check:
                path.write_text(new)
    if check and drift:
        print(f"generated regions differ from the numbers in: {', '.join(drift)}; run python results/claims.py")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
