"""Planning pairs from a pilot: the paired t test's power by the noncentral t, and a plan that uses the
upper confidence bound of the pilot's spread rather than replaying the pilot."""
import math

import pytest
from scipy import stats

from drltg.analysis.planning import paired_t_power, pairs_for_power


def test_paired_t_power_matches_the_textbook_plan():
    """Cohen's table: a standardised effect of 0.5 needs 34 pairs for 80% power at 0.05 two-sided (33 give less)."""
    assert paired_t_power(0.5, 34) >= 0.8 > paired_t_power(0.5, 33)
    assert paired_t_power(0.0, 20) == pytest.approx(0.05)  # no effect: the test's level


def test_a_plan_uses_the_spread_s_upper_bound_and_never_fewer_pairs_than_the_exact_test_needs():
    d = [1.0, 2.0, 0.5, 1.5, 1.0, 0.8]
    n, mean, sd = len(d), sum(d) / len(d), stats.tstd(d)
    upper = sd * math.sqrt((n - 1) / stats.chi2.ppf(0.2, n - 1))
    t_plan = next(k for k in range(3, 1000) if paired_t_power(mean / upper, k) >= 0.8)
    assert pairs_for_power(d) == max(6, t_plan)  # the sign-flip test needs 6 pairs to reach 0.05 at all
    wide = [1.0, 3.0, -0.5, 2.5, 0.0, 1.8]
    mean, upper = sum(wide) / 6, stats.tstd(wide) * math.sqrt(5 / stats.chi2.ppf(0.2, 5))
    planned = pairs_for_power(wide)
    assert planned > 6 and paired_t_power(mean / upper, planned) >= 0.8 > paired_t_power(mean / upper, planned - 1)
    assert pairs_for_power([5.0, 5.0, 5.0]) == 6  # no spread: the exact test's floor
    assert pairs_for_power([0.1, -0.2, 0.05]) is None  # more than 1000
    assert pairs_for_power([1.0, 2.0]) is None  # too few to estimate a spread
    # a replay of the pilot (its sd taken as the truth) would plan fewer pairs than the honest plan
    noisy = [0.3, -0.1, 0.5, 0.2, -0.2, 0.4, 0.1, 0.0]
    replay = next(k for k in range(3, 1000)
                  if paired_t_power(abs(sum(noisy) / 8) / stats.tstd(noisy), k) >= 0.8)
    assert pairs_for_power(noisy) > replay
