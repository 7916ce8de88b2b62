import numpy as np
import pytest
import torch

from drltg.analysis import metrics as M
from drltg.analysis import order_stats, stats

# An uneven grid: steps of 10, 20 and 30 frames.
F = [0, 10, 30, 60]
Y = [0, 10, 10, 40]


def test_area_uses_the_real_frame_axis():
    # 10 * (0 + 10) / 2 + 20 * (10 + 10) / 2 + 30 * (10 + 40) / 2
    assert M.area_under_curve(F, Y) == pytest.approx(50 + 200 + 750)
    # a fixed dx of one evaluation would give 5 + 10 + 25 = 40
    assert M.area_under_curve(np.arange(4), Y) == pytest.approx(40)


def test_area_within_a_budget_interpolates_the_end_point():
    # y(45) = 10 + 15/30 * 30 = 25
    frames, values = M.truncate(F, Y, stop=45)
    assert frames.tolist() == [0, 10, 30, 45] and values.tolist() == pytest.approx([0, 10, 10, 25])
    assert M.area_under_curve(F, Y, stop=45) == pytest.approx(50 + 200 + 15 * (10 + 25) / 2)
    assert M.area_under_curve(F, Y, start=10, stop=30) == pytest.approx(200)


def test_area_never_extrapolates_past_the_last_evaluation():
    with pytest.raises(ValueError, match="not inside"):
        M.area_under_curve(F, Y, stop=61)
    with pytest.raises(ValueError, match="strictly increase"):
        M.area_under_curve([0, 10, 10], [1, 2, 3])


def test_area_accepts_torch_tensors():
    assert M.area_under_curve(torch.tensor(F), torch.tensor(Y, dtype=torch.float32)) == pytest.approx(1000)


def test_initial_and_final_performance():
    assert M.initial_performance(Y, k=1) == 0
    assert M.initial_performance(Y, k=2) == pytest.approx(5)
    with pytest.raises(ValueError):
        M.initial_performance(Y, k=5)
    # window = last half of [0, 60] = [30, 60]: evaluations 10 and 40
    assert M.final_performance(F, Y, fraction=0.5) == pytest.approx(25)
    # within a budget of 45 the window is [22.5, 45]: only the evaluation at 30
    assert M.final_performance(F, Y, stop=45, fraction=0.5) == pytest.approx(10)
    with pytest.raises(ValueError, match="no evaluation"):
        M.final_performance(F, Y, stop=59, fraction=0.1)


def test_time_to_threshold_and_censoring():
    assert M.time_to_threshold(F, Y, 10) == 10
    assert M.time_to_threshold(F, Y, 0) == 0
    assert M.time_to_threshold(F, Y, 40) == 60
    assert M.time_to_threshold(F, Y, 40, stop=45) is None  # reached only after the budget
    assert M.time_to_threshold(F, Y, 41) is None


def test_moving_average_is_trailing_with_a_short_start():
    np.testing.assert_allclose(M.moving_average([1, 2, 3, 4], 2), [1, 1.5, 2.5, 3.5])
    np.testing.assert_allclose(M.moving_average([1, 2, 3, 4], 3), [1, 1.5, 2, 3])
    np.testing.assert_allclose(M.moving_average([1, 2, 3], 1), [1, 2, 3])
    # smoothing delays a noisy spike's threshold crossing
    y = [0, 9, 0, 5, 6, 7]
    f = np.arange(6) * 100
    assert M.time_to_threshold(f, y, 5) == 100
    assert M.time_to_threshold(f, M.moving_average(y, 2), 5) == 400


def test_interquartile_mean():
    assert M.interquartile_mean([1, 2, 3, 4, 100, 5, 6, 7]) == pytest.approx(4.5)  # mean of 3..6
    assert M.interquartile_mean([1, 2, 30]) == pytest.approx(11)  # n < 4: plain mean
    np.testing.assert_allclose(M.interquartile_mean([[4, 1, 2, 3], [0, 0, 10, 0]], axis=-1), [2.5, 0])


def test_probability_of_improvement_counts_ties_as_half():
    # pairs (t, b): (2,1) win, (2,2) tie, (3,1) win, (3,2) win
    assert M.probability_of_improvement([1, 2], [2, 3]) == pytest.approx(3.5 / 4)
    assert M.probability_of_improvement([1, 2, 3], [0]) == 0
    assert M.probability_of_improvement([5], [5]) == 0.5
    a, b = np.array([3.0, 1.0, 4.0]), np.array([1.0, 5.0])
    assert M.probability_of_improvement(a, b) + M.probability_of_improvement(b, a) == pytest.approx(1)


def test_jumpstart_and_asymptotic_are_differences_of_locations():
    assert M.jumpstart([0, 2], [4, 6]) == pytest.approx(4)
    assert M.jumpstart(1.0, 3.5) == pytest.approx(2.5)
    assert M.asymptotic_performance([1, 2, 3, 4, 100], [1, 2, 3, 4, 5]) == pytest.approx(-19)
    # interquartile mean drops the outlier: IQM([1,2,3,4,100]) = 3, IQM([1..5]) = 3
    assert M.asymptotic_performance([1, 2, 3, 4, 100], [1, 2, 3, 4, 5], location=M.interquartile_mean) == 0


def test_transfer_ratio_against_the_plain_ratio():
    assert M.transfer_ratio(100, 125) == pytest.approx(125 / 100 - 1)
    # negative areas: less negative is better, the ratio stays positive while the plain ratio is 0.5
    assert M.transfer_ratio(-100, -50) == pytest.approx(0.5)
    assert M.transfer_ratio(-100, -150) == pytest.approx(-0.5)
    assert M.transfer_ratio([100, 300], [250, 350]) == pytest.approx((300 - 200) / 200)
    # near-zero baseline area relative to the possible area: undefined
    assert M.transfer_ratio(0.5, 80, scale=1000, eps=0.01) is None
    assert M.transfer_ratio(20, 80, scale=1000, eps=0.01) == pytest.approx(3)
    assert M.transfer_ratio(0.0, 5.0) is None


def test_censored_median():
    assert M.censored_median([5]) == 5
    assert M.censored_median([None]) is None
    assert M.censored_median([10, None, 30]) == 30
    assert M.censored_median([10, None]) is None  # half the seeds never reach it
    assert M.censored_median([10, 20, 30, None]) == 25
    assert M.censored_median([10, 20, None, None]) is None


def test_sustained_time_to_threshold():
    f, y = np.arange(6) * 100, [0, 9, 0, 5, 6, 7]
    assert M.sustained_time_to_threshold(f, y, 5) == 300  # the spike at 100 is followed by a 0
    assert M.time_to_threshold(f, y, 5) == 100
    with pytest.raises(ValueError, match="sustain must be >= 2"):
        M.sustained_time_to_threshold(f, y, 5, sustain=1)  # a first crossing is never sustained
    assert M.sustained_time_to_threshold(f, y, 5, sustain=2) == 300
    # until the budget needs SUSTAIN_AFTER = 2 later evaluations: at 300 only 400 follows within 450
    assert M.sustained_time_to_threshold(f, y, 5, stop=450) is None
    assert M.sustained_time_to_threshold(f, y, 5, stop=450, after=1) == 300
    assert M.sustained_time_to_threshold(f, y, 5, stop=400, sustain=3) is None  # only 300, 400 inside
    assert M.sustained_time_to_threshold(f, y, 8) is None
    assert M.sustained_time_to_threshold(f, y, 6) is None  # 6 and 7 at the last two: not yet shown to hold
    assert M.sustained_time_to_threshold(f, y, 6, after=1) == 400


def test_upper_median_is_one_of_the_frames():
    assert M.censored_median([10, 20, 30, None], upper=True) == 30
    assert M.censored_median([10, 20], upper=True) == 20
    assert M.censored_median([10, None], upper=True) is None
    assert M.censored_median([30, 10, 20], upper=True) == 20


def test_t_quantiles():
    assert stats.t_quantile(0.975, 1) == pytest.approx(12.7062047, abs=1e-6)
    assert stats.t_quantile(0.975, 4) == pytest.approx(2.7764451, abs=1e-6)
    assert stats.t_quantile(0.95, 10) == pytest.approx(1.8124611, abs=1e-6)
    assert stats.t_quantile(0.975, 1e6) == pytest.approx(1.959966, abs=1e-5)
    np.testing.assert_allclose(stats.t_quantile(0.975, np.array([[4.0], [1.0]])), [[2.7764451], [12.7062047]],
                               atol=1e-6)


def test_t_interval_by_hand():
    b, t = np.array([1.0, 2.0, 3.0]), np.array([2.0, 4.0, 6.0])
    # paired: d = 1, 2, 3; mean 2, s_d = 1, t_{0.975, 2} = 4.302653
    lo, hi = stats.t_interval(b, t, paired=True)
    assert (lo, hi) == pytest.approx((2 - 4.302653 / np.sqrt(3), 2 + 4.302653 / np.sqrt(3)), abs=1e-6)
    # unpaired: se = sqrt(1/3 + 4/3); Hsu df 2; Welch df = (5/3)^2 / ((1/3)^2/2 + (4/3)^2/2) = 2.941
    lo, hi = stats.t_interval(b, t)
    assert hi - 2 == pytest.approx(4.302653 * np.sqrt(5 / 3), abs=1e-6)
    lo_w, hi_w = stats.welch_interval(b, t)
    assert hi_w - 2 == pytest.approx(stats.t_quantile(0.975, (5 / 3) ** 2 / ((1 / 9 + 16 / 9) / 2)) * np.sqrt(5 / 3))
    assert hi_w < hi
    # no spread: no interval
    assert np.isnan(stats.t_interval([1.0, 1.0, 1.0], [2.0, 2.0, 2.0])[0])
    assert np.isnan(stats.t_interval([1.0, 2.0, 3.0], [2.0, 3.0, 4.0], paired=True)[0])
    # nor where the spread is only round-off: success rates logged in float32 and averaged over
    # different evaluations give the same difference to within ~1e-9
    f32 = [float(np.float32(x)) for x in (0.8, 0.9)]  # 0.800000011920929, 0.8999999761581421
    zero, same = np.zeros(3), np.array([f32[1], (f32[0] + 1.0) / 2, 0.9])
    assert 0 < np.ptp(same) < 1e-7
    assert np.isnan(stats.t_interval(zero, same, paired=True)[0]) and np.isnan(stats.t_test(zero, same, paired=True))
    assert np.isnan(stats.t_interval(np.full(3, 0.3), 0.1 + np.array([0.2, 0.2, 0.1 + 0.1]))[0])
    # a spread of 1e-5 in 0.9 is a spread
    assert np.isfinite(stats.t_interval(np.zeros(3), 0.9 + np.array([0, 1e-5, 2e-5]), paired=True)[0])
    # vectorised over experiments
    lo, hi = stats.t_interval(np.zeros((4, 3)) + b, np.zeros((4, 3)) + t, paired=True)
    assert lo.shape == (4,)


def test_bootstrap_candidates_are_seeded_and_bracket_the_estimate():
    b, t = np.array([1.0, 2.0, 4.0, 3.0, 2.5]), np.array([3.0, 5.0, 4.0, 6.0, 7.0])
    for method in ("bca", "studentized", "percentile"):
        fn = stats.INTERVALS[method]
        lo, hi = fn(b, t, seed=3)
        assert (lo, hi) == fn(b, t, seed=3)
        assert lo < t.mean() - b.mean() < hi


def test_fieller_ratio_interval():
    b, t = np.array([10.0, 11.0, 12.0, 10.5]), np.array([20.0, 23.0, 21.0, 22.0])
    lo, hi = stats.fieller_interval(b, t)
    q2 = stats.t_quantile(0.975, 3) ** 2
    vb, vt = b.var(ddof=1) / 4, t.var(ddof=1) / 4
    for rho in (lo, hi):  # the bounds solve (t - rho b)^2 = q^2 (v_t + rho^2 v_b)
        assert (t.mean() - rho * b.mean()) ** 2 == pytest.approx(q2 * (vt + rho ** 2 * vb))
    assert lo < t.mean() / b.mean() < hi
    r_lo, r_hi = stats.ratio_interval(b, t)
    assert (r_lo, r_hi) == pytest.approx((lo - 1, hi - 1))
    # negative areas: r = -(rho - 1), so the interval flips
    assert stats.ratio_interval(-b, -t) == pytest.approx((1 - hi, 1 - lo))
    # the baseline mean's interval contains 0: no bounded interval
    assert np.isnan(stats.ratio_interval([-1.0, 0.5, 1.0], [2.0, 3.0, 4.0])[0])


def test_probability_of_improvement_score_intervals():
    # Clopper-Pearson over pairs: 5 of 5 gives [0.025^(1/5), 1], which holds 1/2 (the sign test's p is 1/16)
    assert stats.poi_interval(1.0, 5, 5, paired=True) == pytest.approx((0.025 ** (1 / 5), 1.0), abs=1e-6)
    assert stats.poi_interval(1.0, 5, 5, paired=True)[0] < 0.5 and stats.sign_test([0] * 5, [1] * 5) == 0.0625
    assert stats.poi_interval(0.6, 5, 5, paired=True) == pytest.approx((0.1466, 0.9473), abs=1e-4)  # 3 of 5
    lo, hi = stats.poi_interval(0.5, 5, 5, paired=True)  # 2 wins and a tie: k = 2.5
    assert 0 < lo < 0.5 < hi < 1
    lo, hi = stats.poi_interval(1.0, 5, 5)
    assert 0.5 < lo < 1.0 and hi == 1.0  # never [1, 1]
    assert stats.paired_probability_of_improvement([1, 2, 3], [2, 2, 1]) == pytest.approx(1.5 / 3)


def test_trend_by_hand():
    slope, se, df = stats.trend([0, 1, 2, 3], [0, 1, 1, 3])
    # centred frames -1.5, -.5, .5, 1.5; slope 4.5 / 5; residuals .1, .2, -.7, .4
    assert (slope, se, df) == pytest.approx((0.9, np.sqrt(0.7 / 2 / 5), 2))
    assert stats.trend([0, 1, 2], [1, 1, 1]) == (0.0, 0.0, 1)


def test_newcombe_method_5_against_its_published_example():
    """Newcombe (2006), method 5: B = 20 20 26 25 22 23, T = 28 25 24 27 30 30 29 (6 and 7 seeds, ties
    counted half) give 0.9167 [0.5973, 0.9860]; N = (n + m)/2, not (n + m)/2 - 1."""
    b, t = [20, 20, 26, 25, 22, 23], [28, 25, 24, 27, 30, 30, 29]
    p = M.probability_of_improvement(b, t)
    assert p == pytest.approx(0.9167, abs=1e-4)
    assert stats.poi_interval(p, 6, 7) == pytest.approx((0.5973, 0.9860), abs=1e-4)


def test_probability_intervals_stay_in_their_range():
    for n in (2, 3, 5, 10):
        for k in np.arange(0, 2 * n + 1) / 2:
            for paired in (True, False):
                lo, hi = stats.poi_interval(k / n, n, n, paired)
                assert 0.0 <= lo <= k / n <= hi <= 1.0 and lo < hi


def test_exact_tests_by_hand():
    # 3 vs 3, completely separated: 2 of the C(6, 3) = 20 relabellings are as extreme
    assert stats.permutation_test([1, 2, 3], [4, 5, 6]) == pytest.approx(2 / 20)
    assert stats.permutation_test([1, 2, 3], [4, 5, 6], statistic="poi") == pytest.approx(2 / 20)
    # 4 pairs, all improving: 2 of the 2^4 sign patterns as extreme
    assert stats.permutation_test([0, 0, 0, 0], [1, 2, 3, 4], paired=True) == pytest.approx(2 / 16)
    assert stats.permutation_test([1, 1], [1, 1]) == 1.0
    assert stats.sign_test([0, 0, 0, 0, 0, 0], [1, 1, 1, 1, 1, 0]) == pytest.approx(2 / 32)  # the tie is dropped
    assert stats.sign_test([0, 0], [0, 0]) == 1.0


def test_t_test_is_the_interval_s_dual():
    rng = np.random.default_rng(3)
    b, t = rng.normal(0, 1, (200, 4)), rng.normal(1, 1, (200, 4))
    for paired in (True, False):
        lo, hi = stats.t_interval(b, t, paired)
        p = stats.t_test(b, t, paired)
        np.testing.assert_array_equal(p < 0.05, (lo > 0) | (hi < 0))
    # pairs (1, 2), (2, 4), (3, 6): d = 1, 2, 3, t = 2 / (1 / sqrt 3) = 3.4641 on 2 df: p = 0.07418
    assert stats.t_test([1, 2, 3], [2, 4, 6], paired=True) == pytest.approx(0.07418, abs=1e-5)


def test_holm_by_hand():
    # sorted 0.005, 0.01, 0.03, 0.04 (k = 4): 0.02, 0.03, 0.06, 0.06 (monotone)
    assert stats.holm([0.01, 0.04, None, 0.03, 0.005]) == pytest.approx([0.03, 0.06, None, 0.06, 0.02])
    assert stats.holm([0.5, 0.9]) == [1.0, 1.0]
    assert stats.holm([]) == []


def test_equivalence_test_by_hand():
    # change 0.1 +- se 0.05 on 5 df, margin 0.3: max(P(T >= 8), P(T <= -4)) = P(T <= -4) on 5 df
    assert stats.equivalence_test(0.1, 0.05, 5, 0.3) == pytest.approx(0.0051617, abs=1e-6)
    assert stats.equivalence_test(0.0, 0.0, 5, 0.3) == 0.0 and stats.equivalence_test(0.4, 0.0, 5, 0.3) == 1.0
    assert stats.equivalence_test(0.1, 0.05, 5, 0.0) == 1.0  # no margin: never equivalent


def test_shape_of_per_seed_scores():
    assert stats.shape_of([1, 2, 3, 4, 5]) is None  # too few seeds to see a shape
    assert stats.shape_of([0, 0, 0, 0, 0, 0, 0, 0, 0, 10]) == "skewed"
    assert stats.shape_of([0, 0, 0, 0, 0, 10, 10, 10, 10, 10]) == "bimodal"
    assert stats.shape_of([-1.2, -0.8, -0.4, -0.2, 0.0, 0.1, 0.3, 0.5, 0.9, 1.1]) is None


def test_the_median_interval_by_hand():
    # 7 differences, sorted -1, 1, 2, 3, 4, 5, 9. P(Bin(7, 1/2) <= 0) = 1/128 (twice: 0.0156 <= 0.05) and
    # P(<= 1) = 8/128 (twice: 0.125 > 0.05), so rank k = 1: [d_(1), d_(7)] at 1 - 2/128
    assert order_stats.median_interval([3, -1, 4, 1, 5, 9, 2]) == pytest.approx((3.0, -1.0, 9.0, 1 - 2 / 128))
    # at 80%: P(<= 1) twice is 16/128 <= 0.2, P(<= 2) = 29/128 twice 0.45 > 0.2, so k = 2: [d_(2), d_(6)]
    assert order_stats.median_interval([3, -1, 4, 1, 5, 9, 2], 0.80) == pytest.approx((3.0, 1.0, 5.0, 1 - 16 / 128))
    # 10 pairs: P(<= 1) = 11/1024 (twice 0.021), P(<= 2) = 56/1024 (twice 0.109): k = 2, [d_(2), d_(9)]
    assert order_stats.median_interval(np.arange(10.0)) == pytest.approx((4.5, 1.0, 8.0, 1 - 22 / 1024))
    # 5 pairs: even [min, max] covers only 1 - 2/32 = 0.9375 < 0.95
    median, lo, hi, level = order_stats.median_interval([1, 2, 3, 4, 5])
    assert median == 3 and np.isnan([lo, hi, level]).all()


def test_the_median_interval_covers_skewed_and_learn_or_not_differences():
    """Distribution-free: at least its stated level for any shape (exponential differences, median log 2;
    learn-or-not, +1 with probability 0.6 else 0, median 1), 2,000 experiments of 10 pairs a shape."""
    rng = np.random.default_rng(0)
    for draw, median in ((lambda: rng.exponential(1.0, 10), np.log(2)),
                         (lambda: (rng.random(10) < 0.6).astype(float), 1.0)):
        hits = []
        for _ in range(2000):
            _, lo, hi, level = order_stats.median_interval(draw())
            hits.append(lo <= median <= hi)
        assert level == pytest.approx(1 - 22 / 1024)
        assert np.mean(hits) >= level - 3 * np.sqrt(level * (1 - level) / 2000)


def test_the_mann_whitney_counts_match_every_ordering():
    import itertools

    for m, n in ((1, 1), (2, 3), (3, 4), (4, 2)):
        counts = np.zeros(m * n + 1)
        for low in itertools.combinations(range(m + n), m):
            high = [v for v in range(m + n) if v not in low]
            counts[sum(x < y for x in low for y in high)] += 1
        assert order_stats._u_counts(m, n) == pytest.approx(counts)


def test_the_shift_interval_by_hand():
    # 5 + 5 runs, T = B + 10: the 25 differences 10 + (j - i) sorted are 6, 7, 7, 8, 8, 8, ... 13, 13, 14. Of the
    # 252 orderings 1, 1, 2, 3, 5 give U = 0..4: 2 P(U <= 2) = 8/252 <= 0.05 < 2 P(U <= 3) = 14/252, so k = 3:
    # [D_(3), D_(23)] = [7, 13] at 1 - 8/252; the Hodges-Lehmann shift is the median difference, 10
    b = np.arange(5.0)
    assert order_stats.shift_interval(b, b + 10) == pytest.approx((10.0, 7.0, 13.0, 1 - 8 / 252))
    # 3 + 3 runs: even [D_(1), D_(9)] covers only 1 - 2/20 = 0.9
    shift, lo, hi, level = order_stats.shift_interval([0, 1, 2], [5, 6, 7])
    assert shift == 5 and np.isnan([lo, hi, level]).all()


def test_the_shift_interval_covers_a_skewed_shift():
    """Distribution-free: exponential runs shifted by 0.5, 2,000 experiments of 6 + 6 runs, cover 0.5 at least
    at the level they state."""
    rng = np.random.default_rng(0)
    hits = []
    for _ in range(2000):
        _, lo, hi, level = order_stats.shift_interval(rng.exponential(1.0, 6), rng.exponential(1.0, 6) + 0.5)
        hits.append(lo <= 0.5 <= hi)
    assert np.mean(hits) >= level - 3 * np.sqrt(level * (1 - level) / 2000)


def test_the_stratified_sign_flip_test_by_hand():
    # strata (3, 6, -3) and (2, 4): S = mean 2 + mean 3 = 5, the sum of terms d/n = 1, 2, -1 | 1, 2. Each of the
    # 2^5 = 32 sign patterns flips terms of size F in all (|terms| sum to 7): S* = 7 - 2F, so |S*| >= 5 where
    # F <= 1 (none flipped, or one of the three 1s: 4 patterns) or F >= 6 (the mirror images: 4); p = 8/32
    assert stats.stratified_sign_flip([[3, 6, -3], [2, 4]]) == pytest.approx((5.0, 8 / 32))
    # strata (1, 2, 3) and (-4, -5): S = 2 - 4.5 = -2.5; in sixths the |terms| are 2, 4, 6 | 12, 15 (sum 39) and
    # |39 - 2F| >= 15 where F <= 12: {}, {2}, {4}, {6}, {12}, {2, 4}, {2, 6}, {4, 6}, {2, 4, 6} (9), or F >= 27
    # (their 9 complements): p = 18/32. Pooled, the sum -3 of |d| 1..5 (15) is reached where F <= 6 (13 subsets)
    # or F >= 9 (13): 26/32; the stratified weights matter
    assert stats.stratified_sign_flip([[1, 2, 3], [-4, -5]]) == pytest.approx((-2.5, 18 / 32))
    assert stats.permutation_test([0] * 5, [1, 2, 3, -4, -5], paired=True) == pytest.approx(26 / 32)
    # every pair up: only the two extreme patterns of 2^5
    assert stats.stratified_sign_flip([[1, 2, 3], [4, 5]]) == pytest.approx((2 + 4.5, 2 / 32))
    assert stats.stratified_sign_flip([[1, -1], [2, -2]]) == (0.0, 1.0)
    with pytest.raises(ValueError, match="at least one"):
        stats.stratified_sign_flip([[1.0], []])


def test_one_stratum_is_the_paired_sign_flip_test_and_monte_carlo_agrees_with_the_count():
    rng = np.random.default_rng(1)
    d = rng.normal(0.5, 1.0, 11)
    assert stats.stratified_sign_flip([d])[1] == pytest.approx(stats.permutation_test(np.zeros(11), d, paired=True))
    strata = [rng.normal(0.3, 1.0, n) for n in (5, 7, 6)]
    exact = stats.stratified_sign_flip(strata)[1]
    statistic, p = stats.stratified_sign_flip(strata, exact_pairs=10, n_resamples=19999, seed=3)
    assert statistic == pytest.approx(sum(s.mean() for s in strata))
    assert round(p * 20000) == pytest.approx(p * 20000)  # (b + 1) / (m + 1)
    assert abs(p - exact) < 4 * np.sqrt(exact * (1 - exact) / 19999)
    assert stats.stratified_sign_flip(strata, exact_pairs=10, n_resamples=19999, seed=3)[1] == p  # seeded
