"""The verdicts' tests keep their level on every null shape and have power where effects are real."""
import itertools

import numpy as np
import pytest

from drltg.analysis import operating, sequential, stats


def test_the_vectorised_sign_flip_test_is_the_report_s_test():
    rng = np.random.default_rng(3)
    for n in (6, 9):
        b, t = rng.normal(size=(5, n)), rng.normal(0.4, 1.0, size=(5, n))
        got = operating.sign_flip_p(t - b, rng)
        expected = [stats.permutation_test(x, y, paired=True) for x, y in zip(b, t)]
        np.testing.assert_allclose(got, expected, rtol=1e-12)


def test_the_sign_flip_level_on_learn_or_not_pairs_is_at_most_alpha_exactly():
    """Learn-or-not under no effect: each pair's difference is -1, 0 or +1 with probabilities 1/4, 1/2, 1/4.
    Summing the chance of every outcome the test rejects gives its exact false-claim rate at 6 and 10 pairs,
    with no simulation: at most 0.05, and above 0 from 6 pairs (the test can say yes)."""
    prob = {-1.0: 0.25, 0.0: 0.5, 1.0: 0.25}
    rng = np.random.default_rng(0)
    for n in (6, 10):
        outcomes = np.array(list(itertools.product(prob, repeat=n)))
        chance = np.prod(np.vectorize(prob.get)(outcomes), axis=1)
        level = float(chance[operating.sign_flip_p(outcomes, rng) < 0.05].sum())
        assert 0 < level <= 0.05, (n, level)


@pytest.mark.parametrize("shape", sorted(operating.NULLS))
def test_no_test_of_a_verdict_claims_too_often_on_a_null_shape(shape):
    draw, value_range = operating.NULLS[shape]
    se = np.sqrt(0.05 * 0.95 / 600)
    for n in (6, 10):
        r = operating.rates(draw, value_range, n, reps=600, alpha=0.05, seed=n)
        assert r["sign-flip"] <= 0.05 + 3 * se and r["sequential"] <= 0.05 + 3 * se, (n, r)


def test_the_sign_flip_test_has_power_where_the_sweeps_effects_are():
    """A gain of 1.5 sd (the FourRooms sweep's): decided in most experiments of 10 pairs, where the betting
    test, bounded by a range alone, decides returns on [0, 500] at -22 +- 25 in none."""
    normal, _ = operating.EFFECTS["normal, gain/sd 1.5"]
    assert operating.rates(normal, None, 10, reps=300, alpha=0.05, seed=1)["sign-flip"] > 0.9
    wide, value_range = operating.EFFECTS["returns on [0, 500], -22 +- 25"]
    r = operating.rates(wide, value_range, 10, reps=200, alpha=0.05, seed=2)
    assert r["sign-flip"] > 0.5 and r["betting"] == 0.0


def test_the_committed_table_is_the_module_s_output():
    import json
    from pathlib import Path

    committed = json.loads((Path(__file__).parents[1] / "results" / "verdicts" / "operating.json").read_text())
    assert set(committed["level"]) == set(operating.NULLS) and set(committed["power"]) == set(operating.EFFECTS)
    for shape, by_n in committed["level"].items():
        for n, r in by_n.items():
            assert r["sign-flip"] <= 0.05 + 3 * np.sqrt(0.05 * 0.95 / committed["reps"]), (shape, n)
            assert r["sequential"] <= 0.05 + 3 * np.sqrt(0.05 * 0.95 / committed["reps"]), (shape, n)
    assert committed["power"]["normal, gain/sd 1.5"]["10"]["sign-flip"] > 0.95


def test_the_sequential_plan_looks_at_8_then_every_4_at_an_equal_share():
    assert sequential.looks(20) == [sequential.Look(n, 0.0125) for n in (8, 12, 16, 20)]
    assert sequential.looks(10) == [sequential.Look(8, 0.025), sequential.Look(10, 0.025)]
    assert sequential.looks(5) == [sequential.Look(5, 0.05)]
    plan = sequential.looks(20)
    decided = sequential.record(plan, [0.2, 0.004])
    assert decided["stopped"] == "decided" and decided["pairs"] == 12 and len(decided["taken"]) == 2
    capped = sequential.record(plan, [0.2, 0.1, 0.05, 0.02])
    assert capped["stopped"] == "cap" and capped["pairs"] == 20
    with pytest.raises(ValueError):
        sequential.record(plan, [0.2, 0.1])  # stopped early without deciding
