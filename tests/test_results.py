"""The committed reference results are re-analysable: their curves give back their reports."""
import json
import math
from pathlib import Path

import pytest

from drltg.analysis.report import transfer_report

RESULTS = Path(__file__).resolve().parents[1] / "results"
GRADED = RESULTS / "sweep-fourrooms-graded" / "fourrooms-near" / "sac"
GRID = RESULTS / "sweep-gridrooms" / "gridrooms-far" / "sac"


def same(a, b) -> bool:
    """Equal, floats to 12 significant digits: numpy's sums may round the last bits differently on
    another CPU (vector width), nothing more."""
    if isinstance(a, float) or isinstance(b, float):
        return a is not None and b is not None and math.isclose(a, b, rel_tol=1e-12, abs_tol=1e-12)
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    return a == b


@pytest.mark.parametrize("experiment, method", [(GRADED, "model-reuse"), (GRADED, "policy-reuse"),
                                                (GRADED, "value-shaping"), (GRID, "model-reuse")])
def test_a_committed_report_is_reproduced_from_its_committed_curves(experiment, method, tmp_path):
    committed = json.loads((experiment / method / "report" / "transfer_metrics.json").read_text())
    result = transfer_report(experiment / "baseline", experiment / method / "transfer", tmp_path,
                             threshold=committed["settings"]["threshold"],
                             baseline_label="no transfer", transfer_label=method)
    assert same(result["metrics"], committed["metrics"])
    rebuilt = json.loads((tmp_path / "transfer_metrics.json").read_text())["per_seed"]

    def scores(per_seed):  # every per-seed number; "source" is the path the curve was read from
        return {side: [{k: v for k, v in row.items() if k != "source"} for row in rows]
                for side, rows in per_seed.items()}

    assert same(scores(rebuilt), scores(committed["per_seed"]))


@pytest.mark.parametrize("folder, count", [
    ("sweep-fourrooms-graded", 130),  # 5 sources, 25 baselines, 4 methods x 25 transfers
    ("sweep-gridrooms", 55),  # 5 sources, 10 baselines, 4 methods x 10 transfers
    ("sweep-options", 50),  # per K: 5 sources, 10 baselines, 10 transfers
    ("sweep-lift-demonstrations", 12),  # 3 baselines, 3 methods x 3 transfers
    ("sweep-lift-to-place", 12),  # per target: 3 baselines, 3 transfers
    ("lift-dense", 2),  # 2 seeds
    ("lift-dense-study", 8),  # 6 variants, 2 of them on 2 seeds
    ("demo", 13),  # `drltg demo`: 1 source, 6 baselines, 6 transfers
])
def test_every_committed_run_keeps_its_curve_and_config(folder, count):
    runs = [p.parent for p in (RESULTS / folder).glob("**/summary.json")]
    assert len(runs) == count
    for run in runs:
        assert (run / "eval.csv").is_file() and (run / "config.yaml").is_file()


def test_the_seed_tasks_progress_table_is_generated_from_its_kept_curves():
    import importlib.util

    spec = importlib.util.spec_from_file_location("progress", RESULTS / "seed-tasks" / "progress.py")
    progress = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(progress)
    text = (RESULTS / "seed-tasks" / "README.md").read_text()
    assert progress.filled(text) == text, "run python results/seed-tasks/progress.py"
    assert "earlier SAC (1 run)" in text and "| 10,000 |" in text
