"""The manipulation study (``results/manipulation/``): its rows, beside the earlier implementation's."""
from __future__ import annotations

from pathlib import Path

from drltg.analysis import claims as cl
from drltg.analysis.tables import estimate, render
from results.regions.common import (
    PRIMARY,
    RESULTS,
    ends,
    load,
    said,
    tuned,
    whole_family,
)

MANIP = RESULTS / "manipulation"
ROWS = ("lift-shaping", "pi-reuse-place", "pi-reuse-barrier", "model-reuse-place", "soc-model-reuse-place",
        "demonstrations-place", "demonstrations-barrier", "combined-place", "combined-barrier",
        "demonstrations-reference-place", "demonstrations-reference-barrier")
"""The study's rows in queue.sh's order."""








EARLIER = MANIP / "earlier"


def _row_report(row: str, tag: str = "success") -> dict | None:
    """The study's report of ``row`` on ``tag`` (``results/manipulation/ROW/PAIR/ALGO/METHOD/report-TAG/``)."""
    found = sorted((MANIP / row).glob(f"*/*/*/report-{tag}/transfer_metrics.json"))
    return load(found[0]) if found else None


def manipulation_rows() -> str:
    """One line per reported row, in the queue's order: the transfer side's gain over no transfer in mean
    success rate over the budget (the area under the curve per frame, paired by seed), and on the placing
    targets in lifted rate; the gains are read in the family of every test of the row's reports, Holm-adjusted
    (:func:`whole_family`). Where any seed holds the
    report's success threshold to the end (its sustained rule), how many on each side do."""
    lines, queue = [], ROWS
    for row in queue:
        reports = {tag: r for tag in ("success", "lifted") if (r := _row_report(row, tag)) is not None}
        if "success" not in reports:
            continue
        adjusted = whole_family(reports)
        m, st = reports["success"]["metrics"], reports["success"]["settings"]
        gains = "; ".join(f"{tag} rate {said(r, PRIMARY, adjusted.get(tag))}{ends(r)}"
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
        gains += tuned(row, reports["success"])
        lines.append(f"- `{row}` ({st['task']}, {st['transfer_label']} against {st['baseline_label']}, "
                     f"{m['n_seeds_transfer']} paired seeds × {cl.frames(st['budget'])} frames), mean gain in {gains}.")
    if not lines:
        return "No row of the queue is complete yet (the runs finished so far are below).\n"
    left = len(queue) - len(lines)
    return "\n".join(lines) + "\n" + (f"{left} of the queue's {len(queue)} rows are not complete yet (the runs "
                                     "finished so far are below).\n" if left else "")


def manipulation_earlier() -> str:
    """The earlier implementation's rows (one run a side, its own reward) beside the study's (3 paired seeds)."""
    out = [("row", "earlier runs: no transfer → transfer", "frames", "final return, B / T", "mean return gain",
            "gain at 100k frames", "drltg: mean success-rate gain, 3 paired seeds")]
    order = list(ROWS)
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






