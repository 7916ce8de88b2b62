"""Result sentences follow fixed rules (the committed prose that quotes them: tests/test_results.py)."""
import numpy as np
import pytest

from drltg.analysis import claims as cl
from drltg.analysis import stats


def report(times=(1000.0, None, 3000.0), crossing="sustained", value=0.4, ci=(0.1, 0.7), p_adjusted=0.01, **st):
    """A hand-made transfer_metrics.json: three transfer seeds with the given threshold times."""
    per_seed = [{"seed": 100 * i, "mean_return": 0.5 + i, "time_to_threshold": t} for i, t in enumerate(times)]
    return {
        "metrics": {"n_seeds_baseline": len(times), "n_seeds_transfer": len(times), "mean_return_gain": value,
                    "mean_return_gain_ci": list(ci) if ci else None, "mean_return_gain_p_adjusted": p_adjusted,
                    "time_to_threshold_transfer": None},
        "settings": {"threshold": 0.5, "crossing": crossing, "sustain": None, "sustain_after": 2, "paired": True,
                     "budget": 20000, "transfer_label": "model-reuse", "baseline_label": "no transfer",
                     "family": {"size": 3}, **st},
        "per_seed": {"transfer": per_seed, "baseline": per_seed},
    }


# ------------------------------------------------------------------------------------------ rules
@pytest.mark.parametrize("value, ci, p_adjusted, expected", [
    (0.3, (0.1, 0.5), None, 1), (-0.3, (-0.5, -0.1), None, -1), (0.2, (-0.1, 0.5), None, 0), (0.0, None, None, 0),
    (0.3, (0.1, 0.5), 0.2, 0),  # no exact test: the interval excludes 0 alone, not after Holm: no verdict
    (0.3, (0.1, 0.5), 0.049, 1),
])
def test_without_an_exact_test_the_interval_decides(value, ci, p_adjusted, expected):
    assert cl.direction(value, ci, p_adjusted) == expected


@pytest.mark.parametrize("value, ci, p_adjusted, expected", [
    (0.3, (0.1, 0.5), cl.Adjusted(0.01, 0.03), 1),
    (0.3, (0.1, 0.5), cl.Adjusted(0.01, 0.25), 0),   # the interval excludes 0, the exact test does not decide
    (0.3, (-0.9, 1.5), cl.Adjusted(0.9, 0.03), 1),   # a range-bounded interval holds 0, the exact test decides
    (-0.3, None, cl.Adjusted(None, 0.002), -1),      # no interval at all: the test still decides
    (0.0, (-0.1, 0.1), cl.Adjusted(0.9, 0.01), 0),   # no direction to give
])
def test_the_exact_test_decides_and_the_interval_does_not(value, ci, p_adjusted, expected):
    assert cl.direction(value, ci, p_adjusted) == expected


def test_verdicts_read_higher_lower_or_no_evidence():
    assert cl.verdict(1.08, (0.91, 1.24)) == "+1.08 [+0.91, +1.24], higher with transfer"
    assert cl.verdict(-0.41, (-0.6, -0.21)) == "\u22120.41 [\u22120.60, \u22120.21], lower with transfer"
    assert cl.verdict(0.25, (-0.03, 0.53)) == "+0.25 [\u22120.03, +0.53]: no evidence of a difference at this budget"
    assert cl.verdict(0.0, None) == "+0.00: no evidence of a difference at this budget"
    # the same +0.89 in every pair: no interval, and neither "higher" nor "no evidence"
    assert cl.verdict(0.895, None) == "+0.90: no interval, so no verdict"
    assert cl.verdict(0.004, None) == "+0.00: no evidence of a difference at this budget"
    held_back = cl.verdict(-0.32, (-0.51, -0.13), p_adjusted=0.079, family=20)
    assert held_back == ("\u22120.32 [\u22120.51, \u22120.13]: no evidence of a difference at this budget after Holm's "
                         "adjustment (adjusted p = 0.079 of 20)")


def test_a_verdict_names_the_exact_test_that_decided_it():
    assert cl.verdict(0.4, (0.1, 0.7), cl.Adjusted(0.01, 0.03)) == (
        "+0.40 [+0.10, +0.70], higher with transfer (exact test, p = 0.03)")
    assert cl.verdict(0.4, (-0.1, 0.7), cl.Adjusted(0.2, 0.03), design=(6, True)) == (
        "+0.40 [\u22120.10, +0.70], higher with transfer (exact sign-flip test, p = 0.03)")
    assert cl.verdict(0.4, (0.1, 0.7), cl.Adjusted(0.01, 0.2), design=(10, True)) == (
        "+0.40 [+0.10, +0.70]: undecided at 10 pairs (exact sign-flip test, p = 0.2)")
    # 3 pairs: the sign-flip test's smallest p is 2 / 2^3 = 0.25, so no data could decide
    assert cl.verdict(0.4, (0.1, 0.7), cl.Adjusted(0.01, 0.25), design=(3, True)) == (
        "+0.40 [+0.10, +0.70]: undecided at 3 pairs, which cannot decide (the exact sign-flip test gives no p below "
        "0.25; p = 0.25)")
    # 5 + 5 runs: the permutation test's smallest p is 2 / C(10, 5) = 0.0079, below 0.05 / 4
    assert cl.verdict(-0.4, (-0.7, -0.1), cl.Adjusted(0.02, 0.2, 4), design=(5, False)) == (
        "\u22120.40 [\u22120.70, \u22120.10]: undecided at 5 seeds a side (exact permutation test, p = 0.2 after Holm)")
    # 14 pairs: 2^14 = 16,384 sign patterns outnumber the 9,999 draws, so the p-value is drawn, not counted
    assert cl.verdict(0.4, (0.1, 0.7), cl.Adjusted(0.01, 0.002), design=(13, True)).endswith(
        "(exact sign-flip test, p = 0.002)")
    assert cl.verdict(0.4, (0.1, 0.7), cl.Adjusted(0.01, 0.002), design=(14, True)).endswith(
        "(sign-flip test (Monte Carlo, 9,999 draws), p = 0.002)")
    assert cl.test_words(7, False) == "exact permutation test"  # C(14, 7) = 3,432 relabellings
    assert cl.test_words(8, False) == "permutation test (Monte Carlo, 9,999 draws)"  # C(16, 8) = 12,870


def test_the_smallest_exact_p_is_the_two_extreme_arrangements():
    assert [cl.smallest_exact_p(n, True) for n in (3, 5, 6, 10)] == [0.25, 0.0625, 0.03125, 2 / 1024]
    assert cl.smallest_exact_p(4, False) == pytest.approx(2 / 70) and cl.smallest_exact_p(3, False, 5) == 2 / 56


def test_the_headline_concludes_or_says_there_is_no_evidence():
    assert cl.headline(report()) == ("Headline (model-reuse vs no transfer, 3 paired seeds, 20k frames): mean return "
                                     "gain +0.40 [+0.10, +0.70], higher with transfer.")
    assert cl.headline(report(ci=(-0.1, 0.9))).endswith(
        "+0.40 [\u22120.10, +0.90]: no evidence of a difference at this budget.")
    # a report of the success rate (drltg report --tag success_rate) names it
    assert cl.headline(report(tag="success_rate")).startswith(
        "Headline (model-reuse vs no transfer, 3 paired seeds, 20k frames): mean success rate gain +0.40")


def test_a_betting_p_value_by_hand():
    # x = 1, 1, 1 against m = 1/2: every bet is capped at c/m = 1.5 (the plug-in bets are above 3), so the
    # up-gambler's wealth is 1.75^3 and the down-gambler's falls; p = 1 / (max wealth / 2)
    assert stats.betting_p(np.ones((1, 3)), [0.5])[0, 0] == pytest.approx(2 / 1.75 ** 3)
    # the largest paired differences possible: 6 pairs cannot reach 0.05, 7 can
    for n, p in ((6, 2 / 1.75 ** 6), (7, 2 / 1.75 ** 7)):
        lo, hi, p0 = stats.betting_interval(np.zeros(n), np.ones(n), (0, 1), paired=True)
        assert p0 == pytest.approx(p) and (lo > 0) == (p < 0.05)


def test_a_betting_interval_holds_0_and_says_how_many_seeds_would_decide():
    rows = {side: [{"seed": i, "mean_return": v} for i, v in enumerate(values)]
            for side, values in (("baseline", [0.0] * 3), ("transfer", [1.0] * 3))}
    ranged = {"metrics": {"n_seeds_baseline": 3, "n_seeds_transfer": 3, "mean_return_gain": 1.0,
                          "mean_return_gain_ci": [-0.2, 1.0], "mean_return_gain_p_exact": 0.25},
              "settings": {"paired": True, "interval_method": "auto", "value_range": [0, 1]}, "per_seed": rows}
    # 7 pairs like these reach p = 2 / 1.75^7 < 0.05 (and a sign-flip test of 7 pairs can: 2/128)
    assert cl.betting_seeds([0.0] * 3, [1.0] * 3, (0, 1), paired=True) == 7
    assert cl.verdict_of(ranged, "mean_return_gain") == (  # the exact test decides: 3 pairs cannot
        "+1.00 [\u22120.20, +1.00]: undecided at 3 pairs, which cannot decide (the exact sign-flip test gives no p "
        "below 0.25; p = 0.25)")
    no_exact = {**ranged, "metrics": {k: v for k, v in ranged["metrics"].items() if not k.endswith("_p_exact")}}
    assert cl.verdict_of(no_exact, "mean_return_gain") == (
        "+1.00 [\u22120.20, +1.00]: no verdict at 3 pairs; about 7 would decide it if further seeds scored like these "
        "(estimate)")
    unknown = {**no_exact, "metrics": {k: v for k, v in no_exact["metrics"].items() if not k.endswith("_ci")},
               "settings": {**ranged["settings"], "value_range": None}}
    assert cl.verdict_of(unknown, "mean_return_gain") == (
        "+1.00: no interval without the curves' range (--value-range), so no verdict")
    assert cl.betting_seeds([0.5] * 3, [0.5] * 3, (0, 1), paired=True) is None  # alike: no number decides



def test_a_labelled_report_names_what_each_interval_assumes():
    """The sentence states the exact test's verdict, then each magnitude with what it assumes, all read from the
    report's numbers and labels (``<key>_assumes``)."""
    m = {"n_seeds_baseline": 7, "n_seeds_transfer": 7, "mean_return_gain": 3.2857, "mean_return_gain_p_exact": 0.03,
         "mean_return_gain_ci": [-4.5, 11.0], "mean_return_gain_ci_assumes": cl.RANGE_ONLY,
         "mean_return_gain_t_interval": [0.37, 6.2], "mean_return_gain_t_interval_assumes": "normal differences",
         "mean_return_gain_median": 3.0, "mean_return_gain_median_interval": [-1.0, 9.0],
         "mean_return_gain_median_interval_level": 1 - 2 / 128, "mean_return_gain_median_interval_assumes":
         "independent pairs, any shape", "mean_return_gain_verdict": "higher"}
    labelled = {"metrics": m, "settings": {"paired": True, "confidence": 0.95, "value_range": [-20, 20],
                                           "interval_method": "auto"}, "per_seed": {}}
    assert cl.verdict_of(labelled, "mean_return_gain") == (
        "+3.29, higher with transfer (exact sign-flip test, p = 0.03); 95% intervals: mean [+0.37, +6.20] by paired "
        "t, assuming normal differences; median +3.00 [\u22121.00, +9.00] by order statistics (at 98.4%), assuming "
        "independent pairs, any shape; [\u22124.50, +11.00] as the worst case over the declared range [-20, 20]")
    # a number changed in the report changes the sentence
    changed = {**labelled, "metrics": {**m, "mean_return_gain_median_interval": [0.5, 8.0]}}
    assert "median +3.00 [+0.50, +8.00] by order statistics" in cl.verdict_of(changed, "mean_return_gain")
    # without labels (a report made before them) the sentence reads as it did
    bare = {**labelled, "metrics": {k: v for k, v in m.items() if not k.endswith("_assumes")}}
    assert cl.verdict_of(bare, "mean_return_gain") == (
        "+3.29 [\u22124.50, +11.00], higher with transfer (exact sign-flip test, p = 0.03)")
