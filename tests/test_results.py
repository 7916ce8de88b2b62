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
