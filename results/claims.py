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

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "results"
if str(ROOT) not in sys.path:  # drltg, and results.regions
    sys.path.insert(0, str(ROOT))

from drltg.analysis import claims as cl  # noqa: E402
from results.regions import lift, manipulation, reference, seed_tasks, sweeps  # noqa: E402

FOUR_METHODS = ["model-reuse", "value-shaping", "policy-reuse", "reward-shaping"]
"""The FourRooms sweeps' methods, in the order their verdicts are read."""
REGIONS = {
    "results/README.md": {
        "graded-table": lambda: sweeps.sweep_table(sweeps.GRADED),
        "graded-verdicts": lambda: sweeps.sweep_verdicts(sweeps.GRADED, FOUR_METHODS),
        "graded-thresholds": lambda: sweeps.threshold_lines(sweeps.GRADED, "baseline") + sweeps.threshold_lines(
            sweeps.GRADED, "transfer", ["model-reuse", "value-shaping"]),
        "grid-table": lambda: sweeps.sweep_table(RESULTS / "sweep-gridrooms"),
        "grid-verdicts": lambda: sweeps.sweep_verdicts(RESULTS / "sweep-gridrooms", FOUR_METHODS),
        "grid-thresholds": lambda: sweeps.threshold_lines(RESULTS / "sweep-gridrooms", "baseline"),
        "options-table": sweeps.options_table,
        "options-verdicts": sweeps.options_verdicts,
        "options-sources": sweeps.options_sources,
        "lift-variants": lift.lift_variants,
        "lift-dense-verdicts": lift.lift_dense_verdicts,
        "lift-demonstrations-table": lift.lift_demonstrations_table,
        "demo": lift.demo_sentence,
        "lift-demonstrations-verdicts": lift.lift_demonstrations_verdicts,
        "lift-to-place-table": lift.lift_to_place_table,
        "lift-to-place-verdicts": lift.lift_to_place_verdicts,
        "pendulum-heavier": sweeps.pendulum_heavier,
    },
    "README.md": {"demo": lift.demo_sentence},
    "docs/tasks.md": {
        "tasks": lambda: reference.tasks_table("rooms"),
        "tasks-robosuite": lambda: reference.tasks_table("robosuite"),
        "tasks-gym": lambda: reference.tasks_table("gym"),
        "lift-summary": lift.readme_lift,
    },
    "docs/training.md": {"config": reference.config_table},
    "docs/methods.md": {"methods": reference.methods_table},
    "docs/results.md": {
        "results-table": sweeps.results_table,
        "results-verdicts": lambda: sweeps.sweep_verdicts(sweeps.GRADED, FOUR_METHODS),
        "results-others": sweeps.readme_others,
        "seed-rows": seed_tasks.seed_rows,
    },
    "results/seed-tasks/README.md": {"seed-rows": seed_tasks.seed_rows},
    "results/manipulation/README.md": {
        "manipulation-rows": manipulation.manipulation_rows,
        "manipulation-earlier": manipulation.manipulation_earlier,
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
