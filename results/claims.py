"""Rewrite the generated regions of results/README.md and README.md from the committed numbers.

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
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "results"
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from drltg.analysis import claims as cl  # noqa: E402
from drltg.analysis import metrics as mx  # noqa: E402
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
    return out


def family(reports: dict, metric: str = PRIMARY) -> dict:
    """Holm-adjusted p-values of ``metric`` over every report given (those with a p-value)."""
    keys = [k for k in reports if reports[k]["metrics"].get(f"{metric}_p_value") is not None]
    adjusted = mx.holm([reports[k]["metrics"][f"{metric}_p_value"] for k in keys])
    return dict(zip(keys, adjusted))


def said(m: dict, name: str = PRIMARY, p_adjusted: float | None = None, **words) -> str:
    """The verdict sentence of metric ``name`` of a report's ``metrics``."""
    return cl.verdict(m[name], m.get(f"{name}_ci"), p_adjusted, **words)


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
        p = adjusted.get((pair, method))
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
             "higher or lower only where its interval excludes 0 and its adjusted p is below 0.05."]
    for method in order:
        parts = []
        for (pair, meth), r in reports.items():
            if meth != method:
                continue
            m = r["metrics"]
            parts.append(f"{_target(pair)} {said(m, PRIMARY, adjusted.get((pair, meth)))}")
        lines.append(f"- **{METHOD_NAMES.get(method, method)}**: " + "; ".join(parts) + ".")
    pairs = sorted({pair for pair, _ in reports})
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
        lines.append(f"- {cl.threshold_sentence(r, side, who)}.")
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


def options_verdicts() -> str:
    h2h = {(f"fourrooms-{pair}", k): load(OPTIONS / "head-to-head" / f"fourrooms-{pair}-k{k}" / "transfer_metrics.json")
           for pair in ("near", "far") for k in (2, 4)}
    own = sweep_reports(OPTIONS)
    adj_h, adj_o = family(h2h), family(own)
    lines = [f"Head to head (SOC − SAC, mean return gain, Holm over the {len(adj_h)} comparisons):"]
    for (pair, k), r in h2h.items():
        m = r["metrics"]
        lines.append(f"- {_target(pair)}, K = {k}: "
                     f"{said(m, PRIMARY, adj_h.get((pair, k)), higher='SOC higher', lower='SOC lower')}.")
    lines.append(f"Each SOC learner against its own baseline (Holm over the {len(adj_o)} reports):")
    for (pair, method), r in own.items():
        m = r["metrics"]
        lines.append(f"- {pair.replace('fourrooms-', '').replace('soc.num_options=', 'K = ')}: "
                     f"{said(m, PRIMARY, adj_o.get((pair, method)))}.")
    for (pair, method), r in own.items():
        if pair.startswith("fourrooms-near"):
            who = pair.replace("fourrooms-near soc.num_options=", "near, SOC K = ") + " with model reuse"
            lines.append(f"- {cl.threshold_sentence(r, 'transfer', who)}.")
    return "\n".join(lines) + "\n"


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
        m = s["metrics"]
        lines.append(f"- **{method}**: mean success gain {said(m)}; "
                     f"{cl.threshold_sentence(s, 'transfer', 'success ≥ 0.8')}.")
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
    lines = [f"The primary metric, the mean lifted-rate gain, on both targets (Holm over the {len(adjusted)}):"]
    wins = total = 0
    for pair, r in lifted.items():
        m = r["metrics"]
        lines.append(f"- {pair}: {said(m, PRIMARY, adjusted.get(pair))}.")
        b = cl.per_seed_scores(r, "baseline")
        t = cl.per_seed_scores(r, "transfer")
        wins += sum(t[s] > b[s] for s in b)
        total += len(b)
    pooled_b = [v for r in lifted.values() for v in cl.per_seed_scores(r, "baseline").values()]
    pooled_t = [v for r in lifted.values() for v in cl.per_seed_scores(r, "transfer").values()]
    p = mx.sign_test(pooled_b, pooled_t)
    lines.append(f"- Over both targets' pairs, {wins} of {total} transfer runs lift the cube more often than their "
                 f"paired baseline (exact two-sided sign test p = {cl.p_text(p)}; a test chosen after the results "
                 "were seen, so read it as a description, not a confirmed finding).")
    for pair in lifted:
        s = load(PLACE / pair / "sac" / "demonstrations" / "report-success" / "transfer_metrics.json")["metrics"]
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
    r = load(DEMO / "report" / "transfer_metrics.json")
    machine = load(DEMO / "machine.json")
    src = [json.loads((DEMO / "source" / d / "summary.json").read_text())["final_eval"]["success_rate"]
           for d in sorted(p.name for p in (DEMO / "source").iterdir())]
    return (f"{cl.headline(r)} Measured on {machine['machine']}: {machine['wall_s'] / 60:.1f} minutes of wall "
            f"time, {machine['cpu_s'] / 60:.1f} CPU-minutes, with the load average at {machine['load']} from other "
            f"work. The source run reaches a success rate of {', '.join(f'{x:.2f}' for x in src)} on the source "
            f"task. {machine['rerun']}\n")


# ------------------------------------------------------------------------------------ registries
def tasks_table() -> str:
    from drltg.envs import PAIRS, TASKS

    rows = [("task", "description")] + [(f"`{name}`", t.description) for name, t in TASKS.items()]
    pairs = [("pair", "source → target", "description")] + [
        (f"`{name}`", f"`{p.source}` → `{p.target}`", p.description) for name, p in PAIRS.items()]
    return render(rows, "markdown") + "\n" + render(pairs, "markdown")


def methods_table() -> str:
    from drltg.transfer.registry import METHODS

    rows = [("`transfer.method`", "source", "what it is")]
    for name, spec in METHODS.items():
        source = {None: "—", "run": "a run", "policy": "a run or `demonstrator:TASK`"}[spec.source]
        rows.append((f"`{name}`", source, spec.help))
    return render(rows, "markdown")


def config_table() -> str:
    import drltg.transfer  # noqa: F401  (the methods register their transfer.* keys)
    from drltg import config

    return config.describe() + "\n"


# --------------------------------------------------------------------------------------- regions
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
        "lift-dense-verdicts": lift_dense_verdicts,
        "lift-demonstrations-table": lift_demonstrations_table,
        "lift-demonstrations-verdicts": lift_demonstrations_verdicts,
        "lift-to-place-table": lift_to_place_table,
        "lift-to-place-verdicts": lift_to_place_verdicts,
    },
    "README.md": {
        "demo": demo_sentence,
        "tasks": tasks_table,
        "methods": methods_table,
        "config": config_table,
        "results-verdicts": lambda: sweep_verdicts(GRADED, ["model-reuse", "value-shaping", "policy-reuse",
                                                            "reward-shaping"]),
        "lift-demonstrations-verdicts": lift_demonstrations_verdicts,
        "lift-to-place-verdicts": lift_to_place_verdicts,
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
