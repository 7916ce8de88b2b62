"""The seed's tasks (``results/seed-tasks/``): one sentence per complete row."""
from __future__ import annotations

from drltg.analysis import claims as cl
from results.regions.common import PRIMARY, RESULTS, ends, load, said, whole_family

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
        gains = "; ".join(f"{tag}{'' if tag == 'return' else ' rate'} {said(r, PRIMARY, adjusted.get(tag))}{ends(r)}"
                          for tag, r in reports.items())
        size = next(iter(adjusted.values())).size if adjusted else 0
        gains += f" (Holm over all {size} test{'s' if size != 1 else ''} of its {len(reports)} report" \
                 f"{'s' if len(reports) > 1 else ''})"
        lines.append(f"- `{row}` ({st['task']}, {st['transfer_label']} against {st['baseline_label']}, "
                     f"{m['n_seeds_transfer']} paired seeds × {cl.frames(st['budget'])} frames), mean gain in {gains}.")
    left = len(SEED_ROWS) - len(lines)
    if not lines:
        return f"No row of the {len(SEED_ROWS)} is reported yet: the table above shows their runs so far.\n"
    return "\n".join(lines) + "\n" + (
        f"{left} of the {len(SEED_ROWS)} rows {'is' if left == 1 else 'are'} not reported yet.\n" if left else "")
