"""A sweep's summary: the metrics of its reports side by side, the sweep-wide Holm family that the headline
counts findings in, and the transfer-matrix heatmap. Pure functions of the report rows: they write nothing."""
from __future__ import annotations

from drltg.analysis.claims import LEVEL
from drltg.analysis.figure_style import DEFAULT, FigureStyle

__all__ = ["SUMMARY_COLUMNS", "LEVEL", "p_of", "sweep_family", "across_targets", "across_targets_table",
           "summary_tables", "summary_aggregates", "plot_transfer_matrix"]

SUMMARY_COLUMNS = ("mean_return_gain", "jumpstart", "asymptotic_performance", "transfer_ratio",
                   "probability_of_improvement", "time_to_threshold_baseline", "time_to_threshold_transfer")


def p_of(metrics: dict, name: str) -> float | None:
    """The p-value a summary counts for metric ``name``: its verdict's (the exact test's), else its interval's."""
    return metrics.get(f"{name}_verdict_p", metrics.get(f"{name}_p_value"))


def sweep_family(rows: list[dict], primary_metric: str | None = None) -> tuple[dict, str]:
    """Holm-adjusted p-values over the summary's family, ``{(row index, metric): p}``, and its headline.

    The family is the primary metric's p-value in every report when the spec named one in advance, else
    every p-value the summary shows (each report's own adjustment covers only that report). A metric's
    p-value is its verdict's, the exact randomization test's (``<name>_verdict_p``), where the report gives
    one, else its interval's."""
    from drltg.analysis.stats import holm

    metrics = [primary_metric] if primary_metric else [m for m in SUMMARY_COLUMNS if not m.startswith("time_to")]
    members = [(i, name) for i, r in enumerate(rows) for name in metrics
               if p_of(r["metrics"] or {}, name) is not None]
    adjusted = dict(zip(members, holm([p_of(rows[i]["metrics"], name) for i, name in members])))
    found = [(i, name) for (i, name), p in adjusted.items() if p < LEVEL]
    raw = sum(p_of(rows[i]["metrics"], name) < LEVEL for i, name in members)

    def sign(i, name):
        value = rows[i]["metrics"][name]
        return value - 0.5 if name.startswith("probability_of_improvement") else value

    up = sum(sign(i, name) > 0 for i, name in found)
    if primary_metric:
        family = (f"the primary metric {primary_metric} (named in the spec) in {len(members)} report(s)")
    else:
        family = (f"every interval of this table ({', '.join(metrics)}), {len(members)} p-values in "
                  f"{len(rows)} report(s), as the spec named no primary_metric")
    headline = (f"Family: {family}. Holm's adjustment over all {len(members)}: {len(found)} finding(s) at "
                f"{LEVEL:g} ({up} positive, {len(found) - up} negative); {raw} before adjustment.")
    return adjusted, headline


def across_targets(rows: list[dict], score: str = "mean_return", seed: int = 0) -> list[dict]:
    r"""Per (algo, variant, method), one verdict over all the targets of the sweep: does the method change
    ``score`` against no transfer anywhere?

    Each report whose runs pair by seed is a stratum of the stratified exact sign-flip test
    (:func:`drltg.analysis.aggregate.across_pairs`: the sum of the per-target mean differences, signs flipped within
    each target's seed pairs), valid at any seed count with no range or normality. The methods are read together:
    the verdict (``higher`` / ``lower`` than no transfer, else ``undecided``) is at ``LEVEL`` after Holm over them.
    Each entry: ``algo``, ``variant``, ``method`` and :func:`~drltg.analysis.aggregate.across_pairs`'s keys, with
    ``p_holm`` and ``verdict``."""
    from drltg.analysis.aggregate import across_pairs
    from drltg.analysis.stats import holm

    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        if r.get("per_seed"):
            groups.setdefault((r["algo"], r["variant"], r["method"]), []).append(r)
    out = []
    for (algo, variant, method), members in groups.items():
        found = across_pairs([(r["pair"], r["per_seed"]) for r in members], score, seed)
        if found is not None:
            out.append({"algo": algo, "variant": variant, "method": method, **found})
    for entry, adjusted in zip(out, holm([e["p"] for e in out])):
        decided = adjusted < LEVEL and entry["mean_difference"] != 0
        entry["p_holm"] = adjusted
        entry["verdict"] = ("higher" if entry["mean_difference"] > 0 else "lower") if decided else "undecided"
    return out


def across_targets_table(entries: list[dict]) -> str:
    """The Markdown section of :func:`across_targets`: a line that names the test and the family, then a table."""
    from drltg.analysis import tables

    if not entries:
        return ""
    rows = [["algo", "method", "targets", "seed pairs", "mean over targets of the mean difference", "p", "p (Holm)",
             "verdict against no transfer"]]
    for e in entries:
        rows.append([e["algo"], f"{e['method']} {e['variant']}".strip(), ", ".join(e["pairs"]), e["seed_pairs"],
                     f"{e['mean_difference']:+.3g}", f"{e['p']:.2g}", f"{e['p_holm']:.2g}", e["verdict"]])
    return (f"Across targets: each method against no transfer over all its targets at once, by the stratified exact "
            f"sign-flip test of the sum of the per-target mean differences in {entries[0]['score']} (signs flipped "
            f"within each target's seed pairs; no range or normality assumed), Holm over the {len(entries)} "
            f"method(s) at {LEVEL:g}.\n\n" + tables.render(rows, "markdown"))


def summary_tables(rows: list[dict], primary_metric: str | None = None) -> tuple[str, str]:
    """The cells' metrics (value, CI bounds, p-value and the sweep-wide Holm-adjusted p-value) as CSV, and
    as a Markdown table under the headline of :func:`sweep_family`."""
    from drltg.analysis import tables

    adjusted, headline = sweep_family(rows, primary_metric)
    head = ["pair", "algo", "variant", "method", "seeds"]
    csv_rows = [head + [f"{m}{s}" for m in SUMMARY_COLUMNS for s in ("", "_ci_low", "_ci_high", "_p_value",
                                                                       "_p_holm_sweep")]
                + ["report", "note"]]
    md = [["pair", "algo", "method", *SUMMARY_COLUMNS, "seeds"]]
    for i, r in enumerate(rows):
        m = r["metrics"] or {}
        seeds = f"{m['n_seeds_baseline']}+{m['n_seeds_transfer']}" if m else ""
        line = [r["pair"], r["algo"], r["variant"], r["method"], seeds]
        cells = []
        for name in SUMMARY_COLUMNS:
            value, ci = m.get(name), m.get(f"{name}_ci") or (None, None)
            line += [value, *ci, p_of(m, name), adjusted.get((i, name))]
            if not m:
                cells.append("-")
            elif name.startswith("time_to"):
                cells.append(tables.estimate(value, fmt=lambda x: f"{x / 1000:.3g}k", missing="not reached"))
            else:
                mark = "*" if adjusted.get((i, name), 1.0) < LEVEL else ""
                cells.append(tables.estimate(value, ci, ".3g") + mark)
        csv_rows.append(line + [r["report"] if m else "", r.get("note", "")])
        md.append([f"{r['pair']} {r['variant']}".strip(), r["algo"], r["method"], *cells, seeds or r.get("note", "")])
    labels = sorted({m[f"{name}_ci_assumes"] for r in rows for m in [r["metrics"] or {}] for name in SUMMARY_COLUMNS
                     if f"{name}_ci_assumes" in m})
    assumed = "" if not labels else f" Each interval is its report's, assuming {'; or '.join(labels)}."
    md_text = (f"{headline}\n\n{tables.render(md, 'markdown')}\n"
               f"\\* a finding: Holm-adjusted p < {LEVEL:g} within the family above.{assumed}\n")
    across = across_targets_table(across_targets(rows))
    if across:
        md_text += f"\n{across}"
    return tables.render(csv_rows, "csv"), md_text


def plot_transfer_matrix(rows: list[dict], metric: str = "mean_return_gain",
                         figure: FigureStyle = DEFAULT) -> dict[str, bytes]:
    """``transfer_matrix.png`` (and the format ``figure`` asks beside it): a heatmap of ``metric`` over
    (pair, algo, variant) rows x method columns, mean and CI per cell."""
    import numpy as np

    from drltg.analysis.plot import files, plot_matrix

    one_algo = len({r["algo"] for r in rows}) == 1

    def label(r: dict) -> str:
        return " / ".join(x for x in (r["pair"], None if one_algo else r["algo"], r["variant"]) if x)

    labels = list(dict.fromkeys(map(label, rows)))
    methods = list(dict.fromkeys(r["method"] for r in rows))
    table = np.full((len(labels), len(methods)), np.nan)
    text = np.full(table.shape, "n/a", dtype=object)
    for r in rows:
        i, j = labels.index(label(r)), methods.index(r["method"])
        value = (r["metrics"] or {}).get(metric)
        if value is not None:
            ci = r["metrics"].get(f"{metric}_ci")
            table[i, j] = value
            text[i, j] = f"{value:+.2f}" + (f"\n[{ci[0]:+.2f}, {ci[1]:+.2f}]" if ci else "")
    title = f"{metric}, transfer - baseline [95% CI; none below 3 seeds a side]"
    return files("transfer_matrix", plot_matrix(table, labels, methods, metric, text=text,
                                                axis_labels=("pair", "method"), title=title, vector=None, style=figure))


def summary_aggregates(rows: list[dict], figure: FigureStyle = DEFAULT) -> dict[str, bytes]:
    """``aggregates.json``, ``aggregates.md`` and ``performance_profiles.png`` (drawn as ``figure`` says): each
    method against no transfer over the sweep's pairs and seeds, as rliable defines the aggregates
    (:mod:`drltg.analysis.aggregate`); nothing where no row has its runs' scores."""
    import json

    from drltg.analysis.aggregate import aggregates_table, sweep_aggregates
    from drltg.analysis.plot import files, plot_profiles

    entries = sweep_aggregates(rows)
    if not entries:
        return {}
    md = ("Aggregates over the sweep's pairs, each method against no transfer (rliable's definitions: IQM, "
          "median and mean of normalised per-seed mean returns, optimality gap, P(T > B); 95% stratified-bootstrap "
          "intervals, 2000 resamples, seed 0):\n\n" + aggregates_table(entries))
    return {"aggregates.json": (json.dumps(entries, indent=1) + "\n").encode(), "aggregates.md": md.encode(),
            **files("performance_profiles", plot_profiles(entries, style=figure))}
