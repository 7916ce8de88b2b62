"""The FourRooms, grid and options sweeps and the Pendulum study: their tables, verdicts and thresholds."""
from __future__ import annotations

import json
from pathlib import Path

from drltg.analysis import claims as cl
from drltg.analysis.tables import estimate, render
from results.regions.common import (
    METHOD_NAMES,
    PRIMARY,
    RESULTS,
    cell,
    family,
    load,
    report_curves,
    said,
    seed_dirs,
    threshold,
)
from results.regions.lift import readme_lift


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
        p = getattr(adjusted.get((pair, method)), "exact", None)  # the verdict's test, the gate
        rows.append((pair, method, cell(m, PRIMARY), "" if p is None else cl.p_text(p), cell(m, "jumpstart"),
                     cell(m, "asymptotic_performance") + (" (final)" if moving else ""),
                     cell(m, "transfer_ratio"), f"{_time_to(r, 'baseline')} / {_time_to(r, 'transfer')}",
                     cell(m, "probability_of_improvement", ".2f")))
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
             "higher or lower only where its exact sign-flip test has an adjusted p below 0.05 (the interval beside "
             "it is the range-bounded one, the worst case over the returns' range, not the gate)."]
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
    finding within the sweep's family (the exact sign-flip test's Holm-adjusted p < 0.05)."""
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
            if cl.direction(m[PRIMARY], ci, adjusted.get(key)):
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


OPTIONS = RESULTS / "sweep-options"
GRADED = RESULTS / "sweep-fourrooms-graded"


def options_table() -> str:
    """SAC and SOC (K = 2, 4) with model reuse against their own baselines, and SOC − SAC head to head."""
    rows = [("pair", "learner + model reuse", "vs its own baseline: mean return gain", "jumpstart", "transfer ratio",
             "head to head, SOC − SAC: mean return gain", "P(SOC > SAC)")]
    for pair in ("near", "far"):
        sac = load(GRADED / f"fourrooms-{pair}" / "sac" / "model-reuse" / "report" / "transfer_metrics.json")["metrics"]
        rows.append((pair, "SAC", cell(sac, PRIMARY), cell(sac, "jumpstart"), cell(sac, "transfer_ratio"), "", ""))
        for k in (2, 4):
            own = load(OPTIONS / f"fourrooms-{pair}" / "soc" / f"soc.num_options={k}" / "model-reuse" / "report"
                       / "transfer_metrics.json")["metrics"]
            h2h = load(OPTIONS / "head-to-head" / f"fourrooms-{pair}-k{k}" / "transfer_metrics.json")["metrics"]
            rows.append((pair, f"SOC K={k}", cell(own, PRIMARY), cell(own, "jumpstart"), cell(own, "transfer_ratio"),
                         cell(h2h, PRIMARY), cell(h2h, "probability_of_improvement", ".2f")))
    return render(rows, "markdown")


def options_sources() -> str:
    """Final success on the source task of each learner's source runs (what there was to transfer)."""
    sides = [("SAC", GRADED / "fourrooms-near" / "sac" / "source")]
    sides += [(f"SOC K = {k}", OPTIONS / "fourrooms-near" / "soc" / f"soc.num_options={k}" / "source") for k in (2, 4)]
    lines = []
    for name, folder in sides:
        rates = [load(run / "summary.json")["final_eval"]["success_rate"] for run in seed_dirs(folder)]
        lines.append(f"- {name}: mean {sum(rates) / len(rates):.2f} ({', '.join(f'{r:.2f}' for r in rates)}).")
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
    late = {side: cl.late_crossings(report, side, report_curves(report, side)) for side in ("baseline", "transfer")}
    sentences = cl.report_sentences(report, ("mean_return_gain", "jumpstart", "asymptotic_performance"), late)
    return render(rows, "markdown") + "\n" + "\n".join(f"- {s}" for s in sentences) + "\n"
