"""Aggregates over task pairs are rliable's, on the same scores; the committed sweep's follow from its reports."""
import json
from pathlib import Path

import numpy as np
import pytest
from rliable import library as rly
from rliable import metrics

from drltg.analysis import aggregate

ROOT = Path(__file__).resolve().parents[1]


def test_the_vectorised_definitions_are_rliable_s():
    rng = np.random.default_rng(0)
    x, y = rng.integers(0, 4, (6, 3)).astype(float), rng.integers(0, 4, (5, 3)).astype(float)  # ties on purpose
    assert aggregate.probability_of_improvement(x, y) == pytest.approx(metrics.probability_of_improvement(x, y))
    assert aggregate.probability_of_improvement(x, x) == 0.5
    np.testing.assert_allclose(aggregate.profile(x / 4), rly.score_distributions(x / 4, aggregate.TAUS))


def test_aggregates_by_hand():
    """Two pairs of 4 runs: the IQM is the mean of the middle 4 of the 8 scores, the optimality gap how far
    the scores capped at 1 fall short of 1, P(T > B) each pair's share of wins, averaged."""
    b = np.array([[0.0, 0.2], [0.1, 0.4], [0.3, 0.6], [0.9, 1.0]])
    t = b + 0.5  # every transfer run beats every baseline run below it by 0.5
    out = aggregate.aggregates(b, t, reps=200)
    assert out["baseline"]["iqm"][0] == pytest.approx(np.mean([0.2, 0.3, 0.4, 0.6]))
    assert out["baseline"]["optimality_gap"][0] == pytest.approx(1 - b.mean())
    assert out["transfer"]["optimality_gap"][0] == pytest.approx(1 - np.minimum(t, 1).mean())
    assert out["difference"]["mean"][0] == pytest.approx(0.5)
    # pair 0: T = 0.5, 0.6, 0.8, 1.4 against B = 0, 0.1, 0.3, 0.9: 3 + 3 + 3 + 4 = 13 wins of 16; pair 1:
    # 0.7, 0.9, 1.1, 1.5 against 0.2, 0.4, 0.6, 1.0: 3 + 3 + 4 + 4 = 14 of 16
    assert out["probability_of_improvement"][0] == pytest.approx((13 + 14) / 32)
    for part in ("baseline", "transfer", "difference"):
        for value, (low, high) in out[part].values():
            assert low <= value <= high
    state = np.random.get_state()
    assert aggregate.aggregates(b, t, reps=200) == out  # seeded, and numpy's global generator given back
    assert all(np.array_equal(x, y) for x, y in zip(np.random.get_state(), state))


def test_a_sweep_s_groups_normalise_by_each_pair_s_range_and_use_the_fewest_runs():
    def row(pair, method, b, t, value_range):
        return {"pair": pair, "algo": "sac", "variant": "", "method": method, "value_range": value_range,
                "per_seed": {"baseline": [{"mean_return": v} for v in b], "transfer": [{"mean_return": v} for v in t]}}

    rows = [row("a", "m", [0, 10, 20], [10, 20, 30], (0, 100)), row("b", "m", [-1.0, 0.0], [0.0, 1.0], (-1, 1)),
            {"pair": "c", "algo": "sac", "variant": "", "method": "m", "metrics": None}]  # no report yet
    (entry,) = aggregate.sweep_aggregates(rows, reps=100)
    assert entry["pairs"] == ["a", "b"] and entry["runs_per_pair"] == 2 and entry["normalised"]
    # normalised means: a 0.05 -> 0.15 (first 2 runs), b 0.25 -> 0.75
    assert entry["baseline"]["mean"][0] == pytest.approx((0.05 + 0.25) / 2)
    assert entry["difference"]["mean"][0] == pytest.approx((0.1 + 0.5) / 2)


def test_the_committed_graded_sweep_s_aggregates_follow_from_its_reports():
    folder = ROOT / "results" / "sweep-fourrooms-graded"
    committed = {e["method"]: e for e in json.loads((folder / "aggregates.json").read_text())}
    rows = []
    for path in sorted(folder.glob("*/sac/model-reuse/report/transfer_metrics.json")):
        report = json.loads(path.read_text())
        rows.append({"pair": path.parts[-5], "algo": "sac", "variant": "", "method": "model-reuse",
                     "per_seed": report["per_seed"], "value_range": report["settings"]["value_range"]})
    (entry,) = aggregate.sweep_aggregates(rows)
    assert entry == committed["model-reuse"]
    value, (low, high) = entry["difference"]["iqm"]
    assert high < 0 and entry["probability_of_improvement"][1][1] < 0.5  # model reuse is below no transfer
