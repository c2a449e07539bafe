"""himit_torch.statistics: each function on a hand-solved case, and the Kaplan–Meier estimate
against the product-limit formula computed by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from himit_torch.statistics import (
    average_ranks,
    bca_interval,
    first_goal_sign_test,
    first_goal_survival,
    holm,
    mean_half_width,
    paired_comparison,
    paired_difference,
    paired_t_p,
    share_interval,
    t_interval,
    wilson_interval,
)


def test_t_interval_hand_solved():
    # mean 2, sd 1, n 3: half-width t(0.975, 2) · 1/√3 = 4.3027 · 0.57735 = 2.4841
    ci = t_interval([1.0, 2.0, 3.0])
    assert ci.estimate == 2.0
    assert ci.low == pytest.approx(2 - 2.4841, abs=1e-4)
    assert ci.high == pytest.approx(2 + 2.4841, abs=1e-4)
    assert "t-interval" in ci.what
    assert t_interval([5.0, 5.0]).low == 5.0  # no spread: the mean itself


def test_bca_interval_brackets_the_mean_and_is_reproducible():
    x = np.random.default_rng(1).exponential(10, size=20)
    a, b = bca_interval(x, seed=3), bca_interval(x, seed=3)
    assert a == b and a.low < x.mean() < a.high and "BCa" in a.what
    # a skewed count: BCa's interval is not symmetric about the mean, as a t-interval is
    assert (a.high - a.estimate) != pytest.approx(a.estimate - a.low, rel=0.02)


def test_paired_comparison_counts_and_tests():
    a = [5, 6, 7, 8, 9, 10]
    b = [4, 6, 5, 9, 6, 7]  # differences 1, 0, 2, −1, 3, 3
    c = paired_comparison(a, b)
    assert (c.wins, c.losses, c.ties) == (4, 1, 1)
    assert c.sign_p == pytest.approx(stats.binomtest(4, 5).pvalue)  # = 0.375
    assert c.sign_p == pytest.approx(0.375)
    assert c.t_p == pytest.approx(stats.ttest_1samp([1, 0, 2, -1, 3, 3], 0).pvalue)
    assert c.difference.estimate == pytest.approx(8 / 6)
    with pytest.raises(ValueError, match="equally long"):
        paired_comparison([1, 2], [1, 2, 3])


def test_paired_comparison_without_spread():
    c = paired_comparison([3, 4, 5], [1, 2, 3])
    assert c.difference.estimate == 2.0 and c.difference.low == 2.0 and c.t_p == 0.0
    assert c.sign_p == pytest.approx(0.25)  # 3 of 3: 2 · 0.5³


def test_kaplan_meier_hand_solved():
    # runs reaching the goal at 2, 4 and 6 steps, one never (censored at 10):
    # S(2) = 3/4, S(4) = 3/4 · 2/3 = 1/2 → the median is 4; S(6) = 1/2 · 1/2 = 1/4
    s = first_goal_survival([2, 4, -1, 6], budget=10)
    assert s.median.estimate == 4.0 and s.never == 1 and s.runs == 4
    assert list(s.times) == [2, 4, 6, 10]
    assert s.survival[:3] == pytest.approx([0.75, 0.5, 0.25])


def test_kaplan_meier_never_reaching_half():
    s = first_goal_survival([3, -1, -1, -1], budget=100)
    assert s.median.estimate == math.inf and s.never == 3


def test_kaplan_meier_equals_the_product_limit_formula():
    rng = np.random.default_rng(0)
    steps = rng.integers(1, 30, size=40)
    steps[rng.random(40) < 0.3] = -1  # never
    s = first_goal_survival(steps.tolist(), budget=30)
    survival = 1.0
    for t, p in zip(s.times, s.survival):
        if t == 30:
            break
        at_risk = np.sum((steps >= t) | (steps < 0))
        events = np.sum(steps == t)
        survival *= 1 - events / at_risk
        assert p == pytest.approx(survival)


def test_first_goal_sign_test():
    a = [10, 20, -1, 5, -1]
    b = [15, 10, 30, -1, -1]  # a first, b first, b first, a first, tie (neither)
    c = first_goal_sign_test(a, b)
    assert (c.wins, c.losses, c.ties) == (2, 2, 1) and c.sign_p == pytest.approx(1.0)


def test_share_interval_hand_solved():
    ci = share_interval(0, 20)
    assert ci.estimate == 0 and ci.low == 0
    assert ci.high == pytest.approx(1 - 0.025 ** (1 / 20), abs=1e-6)  # 0.1684


def test_holm_hand_solved():
    # sorted 0.01, 0.03, 0.04: ×3 = 0.03, ×2 = 0.06, ×1 = 0.04 → monotone 0.06
    assert holm([0.01, 0.04, 0.03]) == pytest.approx([0.03, 0.06, 0.06])
    out = holm([0.01, float("nan"), 0.04])
    assert math.isnan(out[1]) and out[0] == pytest.approx(0.02) and out[2] == pytest.approx(0.04)


def test_holm_is_statsmodels_bit_for_bit():
    """The step-down in NumPy gives statsmodels' numbers exactly, ties and NaNs included."""
    multitest = pytest.importorskip("statsmodels.stats.multitest")
    rng = np.random.default_rng(0)
    for n in range(1, 40):
        p = rng.random(n) ** rng.integers(1, 6)
        if n % 3 == 0:
            p = np.round(p, 2)  # ties
        assert holm(p) == multitest.multipletests(p, method="holm")[1].tolist()
    p = [0.01, math.nan, 0.04, 0.3]
    made = multitest.multipletests([0.01, 0.04, 0.3], method="holm")[1].tolist()
    assert [x for x in holm(p) if not math.isnan(x)] == made


def test_mean_half_width_by_hand():
    mean, half, n = mean_half_width([1.0, 2.0, 3.0])  # t(0.975, 2) = 4.302653, sd = 1
    assert (mean, n) == (2.0, 3) and half == pytest.approx(4.302653 / np.sqrt(3), rel=1e-6)
    assert mean_half_width([5.0])[:1] == (5.0,) and np.isnan(mean_half_width([5.0])[1])
    assert mean_half_width([])[2] == 0 and np.isnan(mean_half_width([])[0])
    # None, NaN and inf are left out; values all equal: no spread
    assert mean_half_width([1.0, None, math.nan, math.inf, 3.0])[::2] == (2.0, 2)
    assert mean_half_width([4.0, 4.0, 4.0])[:2] == (4.0, 0.0)
    # the same interval as t_interval's, up to round-off
    ci = t_interval([1.0, 2.0, 4.0, 8.0])
    assert mean_half_width([1.0, 2.0, 4.0, 8.0])[1] == pytest.approx(ci.high - ci.estimate)


def test_wilson_interval_and_paired_difference_by_hand():
    share, low, high = wilson_interval(8, 10)
    assert share == 0.8 and low == pytest.approx(0.4902, abs=1e-4)
    assert high == pytest.approx(0.9433, abs=1e-4)
    assert all(math.isnan(x) for x in wilson_interval(0, 0))
    mean, half, p = paired_difference([3.0, 5.0, 4.0, 9.0], [1.0, 1.0, 2.0, 2.0])
    assert mean == pytest.approx(3.75)
    assert half == pytest.approx(stats.t.ppf(0.975, 3) * stats.sem([2, 4, 2, 7]))
    assert p == pytest.approx(stats.wilcoxon([2, 4, 2, 7]).pvalue)
    assert paired_difference([1, 2], [1, 2])[2] == 1.0


def test_paired_t_p_by_hand():
    d = np.array([1.0, 3.0, -0.5, 2.0])
    assert paired_t_p(d) == pytest.approx(stats.ttest_1samp(d, 0.0).pvalue)
    assert paired_t_p(d) == pytest.approx(stats.ttest_rel(d, np.zeros(4)).pvalue)
    assert paired_t_p([0.0, 0.0, 0.0]) == 1.0 and paired_t_p([2.0]) == 1.0
    assert paired_t_p([2.0, 2.0]) == 0.0  # no spread: the difference is exact


def test_round_off_is_no_spread():
    """20 values equal up to round-off: the BCa interval is the mean (scipy's would be NaN)."""
    x = 76.5 + np.random.default_rng(0).normal(0, 1e-13, 20)
    ci = bca_interval(x)
    assert ci.low == ci.high == ci.estimate and math.isfinite(ci.low)


def test_average_ranks_share_the_ranks_of_planted_ties():
    # CliffWalking's greedy column as it was: three methods at 100.0, three at 76.47, two below.
    # Listing order must not matter: the three at 100 share ranks 1-3 (2.0 each), the three
    # at 76.47 share 4-6 (5.0 each), then 7 and 8.
    scores = {"a": 76.47, "b": 100.0, "c": 50.0, "d": 100.0, "e": 76.47, "f": 100.0}
    scores |= {"g": 76.47, "h": 10.0}
    ranks = average_ranks(scores)
    assert ranks == {"b": 2.0, "d": 2.0, "f": 2.0, "a": 5.0, "e": 5.0, "g": 5.0, "c": 7.0, "h": 8.0}
    assert sum(ranks.values()) == sum(range(1, 9))  # average ranks keep the total
    reordered = average_ranks(dict(reversed(list(scores.items()))))
    assert reordered == ranks


def test_average_ranks_lower_is_better_and_never_ties_with_never():
    # first goals in steps, lower is better; two runs that never found it share the last ranks
    steps = {"x": 5000.0, "y": math.inf, "z": 800.0, "w": math.inf}
    assert average_ranks(steps, higher_is_better=False) == {"z": 1.0, "x": 2.0, "y": 3.5, "w": 3.5}
    with pytest.raises(ValueError, match="score of 'q' is NaN"):
        average_ranks({"p": 1.0, "q": math.nan})
