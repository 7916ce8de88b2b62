"""The committed reference results are re-analysable (their curves give back their reports), and the committed
prose quotes them: ``results/claims.py --check`` finds a quoted number that moved."""
import importlib.util
import json
import math
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from drltg.analysis.claims import headline
from drltg.cli import report

ROOT = Path(__file__).resolve().parents[1]
DEMO = ROOT / "results" / "demo"
GRADED = ROOT / "results" / "sweep-fourrooms-graded" / "fourrooms-near" / "sac"
GRID = ROOT / "results" / "sweep-gridrooms" / "gridrooms-far" / "sac"
CASES = [(DEMO, DEMO, "model-reuse"), *[(e, e / m, m) for e, m in (
    (GRADED, "model-reuse"), (GRADED, "policy-reuse"), (GRADED, "value-shaping"), (GRID, "model-reuse"))]]


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


@pytest.mark.parametrize("experiment, method_dir, method", CASES, ids=lambda x: getattr(x, "name", x))
def test_a_committed_report_is_reproduced_from_its_committed_curves(experiment, method_dir, method, tmp_path, capsys):
    """``drltg report`` on the committed curves gives back the committed numbers and prints the quoted headline."""
    committed = json.loads((method_dir / "report" / "transfer_metrics.json").read_text())
    assert report.main(["--baseline", str(experiment / "baseline"), "--transfer", str(method_dir / "transfer"),
                        "--threshold", str(committed["settings"]["threshold"]), "--baseline-label", "no transfer",
                        "--transfer-label", method, "--out", str(tmp_path / "rep")]) == 0
    assert headline(committed) in capsys.readouterr().out
    rebuilt = json.loads((tmp_path / "rep" / "transfer_metrics.json").read_text())
    assert same(rebuilt["metrics"], committed["metrics"])

    def scores(per_seed):  # every per-seed number; "source" is the path the curve was read from
        return {side: [{k: v for k, v in row.items() if k != "source"} for row in rows]
                for side, rows in per_seed.items()}
    assert same(scores(rebuilt["per_seed"]), scores(committed["per_seed"]))


def test_the_committed_prose_quotes_the_committed_reports(tmp_path, monkeypatch):
    """results/claims.py --check exits 0 on the committed files, and 1 once a quoted report's number moves."""
    check = [sys.executable, str(ROOT / "results" / "claims.py"), "--check"]
    assert subprocess.run(check, capture_output=True).returncode == 0, "run python results/claims.py"
    spec = importlib.util.spec_from_file_location("results_claims", ROOT / "results" / "claims.py")
    g = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(g)
    shutil.copy(ROOT / "README.md", tmp_path / "README.md")
    shutil.copytree(DEMO / "report", tmp_path / "results" / "demo" / "report")
    monkeypatch.setattr(g, "ROOT", tmp_path)
    monkeypatch.setattr(g, "REGIONS", {"README.md": g.REGIONS["README.md"]})
    assert g.main(["--check"]) == 0
    metrics = tmp_path / "results" / "demo" / "report" / "transfer_metrics.json"
    data = json.loads(metrics.read_text())
    data["metrics"]["mean_return_gain"] += 0.01
    metrics.write_text(json.dumps(data))
    assert g.main(["--check"]) == 1
    assert g.main([]) == 0 and g.main(["--check"]) == 0  # rewritten
    with pytest.raises(ValueError, match="no region 'demo'"):
        g.fill("no markers\n", {"demo": "x"})
