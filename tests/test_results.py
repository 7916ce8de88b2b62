"""The committed reference results are re-analysable: their curves give back their reports."""
import json
from pathlib import Path

import pytest

from drltg.report import transfer_report

RESULTS = Path(__file__).resolve().parents[1] / "results"
EXPERIMENT = RESULTS / "sweep-fourrooms-graded" / "fourrooms-near" / "sac"


@pytest.mark.parametrize("method", ["model-reuse", "policy-reuse", "value-shaping"])
def test_a_committed_report_is_reproduced_from_its_committed_curves(method, tmp_path):
    committed = json.loads((EXPERIMENT / method / "report" / "transfer_metrics.json").read_text())
    result = transfer_report(EXPERIMENT / "baseline", EXPERIMENT / method / "transfer", tmp_path,
                             threshold=committed["settings"]["threshold"],
                             baseline_label="no transfer", transfer_label=method)
    assert result["metrics"] == committed["metrics"]
    rebuilt = json.loads((tmp_path / "transfer_metrics.json").read_text())["per_seed"]

    def scores(per_seed):  # every per-seed number; "source" is the path the curve was read from
        return {side: [{k: v for k, v in row.items() if k != "source"} for row in rows]
                for side, rows in per_seed.items()}

    assert scores(rebuilt) == scores(committed["per_seed"])


def test_every_committed_run_keeps_its_curve_and_config():
    runs = [p.parent for p in RESULTS.glob("sweep-fourrooms-graded/**/summary.json")]
    assert len(runs) == 130  # 5 sources, 25 baselines, 4 methods x 25 transfers
    for run in runs:
        assert (run / "eval.csv").is_file() and (run / "config.yaml").is_file()
