"""himit_torch.statistics: each function on a hand-solved case, and the Kaplan–Meier estimate
against the product-limit formula computed by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from himit_torch import statistics
from himit_torch.statistics import (
    PAIRED_T,
    SIGN,
    WILCOXON,
    average_ranks,
    bca_interval,
    first_goal_sign_test,
    first_goal_survival,
    holm,
    paired_comparison,
    share_interval,
    t_interval,
)


def test_t_interval_hand_solved():
    # mean 2, sd 1, n 3: half-width t(0.975, 2) · 1/√3 = 4.3027 · 0.57735 = 2.4841
    ci = t_interval([1.0, 2.0, 3.0])
    assert ci.estimate == 2.0
    assert ci.low == pytest.approx(2 - 2.4841, abs=1e-4)
    assert ci.high == pytest.approx(2 + 2.4841, abs=1e-4)
    assert "t-interval" in ci.what
    assert ci.half_width == pytest.approx(2.4841, abs=1e-4)
    assert ci.plus_minus(2) == "2.00 ± 2.48"
    assert t_interval([5.0, 5.0]).low == 5.0  # no spread: the mean itself
    assert t_interval([5.0, 5.0]).plus_minus() == "5.0 ± 0.0"
    one = t_interval([5.0])  # one value: no spread to measure, so no bounds
    assert one.estimate == 5.0 and math.isnan(one.low) and math.isnan(one.high)
    assert one.plus_minus() == "5.0" and "one value" in one.what


def test_t_interval_is_scipys_t_interval():
    """mean ± t·s/√n equals scipy.stats.t.interval around the mean with the standard error."""
    x = np.random.default_rng(4).normal(3.0, 2.0, 12)
    low, high = stats.t.interval(0.9, 11, loc=x.mean(), scale=stats.sem(x))
    ci = t_interval(x, level=0.9)
    assert (ci.low, ci.high) == pytest.approx((low, high), rel=1e-12)
    assert "90%" in ci.what


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
    assert set(c.tests) == {PAIRED_T, WILCOXON, SIGN}  # each p under its test's name
    assert c.sign_p == c.tests[SIGN] == pytest.approx(stats.binomtest(4, 5).pvalue)  # = 0.375
    assert c.sign_p == pytest.approx(0.375)
    assert c.t_p == c.tests[PAIRED_T]
    assert c.t_p == pytest.approx(stats.ttest_1samp([1, 0, 2, -1, 3, 3], 0).pvalue)
    assert c.wilcoxon_p == pytest.approx(stats.wilcoxon([1, 0, 2, -1, 3, 3]).pvalue)
    assert c.difference.estimate == pytest.approx(8 / 6) and "BCa" in c.difference.what
    with pytest.raises(ValueError, match="equally long"):
        paired_comparison([1, 2], [1, 2, 3])


def test_paired_comparison_with_a_t_interval():
    """interval="t": the difference's interval is t_interval of the differences, by hand."""
    c = paired_comparison([3.0, 5.0, 4.0, 9.0], [1.0, 1.0, 2.0, 2.0], interval="t")
    assert c.difference.estimate == pytest.approx(3.75) and "t-interval" in c.difference.what
    assert c.difference.half_width == pytest.approx(stats.t.ppf(0.975, 3) * stats.sem([2, 4, 2, 7]))
    assert c.wilcoxon_p == pytest.approx(stats.wilcoxon([2, 4, 2, 7]).pvalue)
    assert paired_comparison([1, 2], [1, 2], interval="t").wilcoxon_p == 1.0  # all 0


def test_paired_comparison_without_spread():
    c = paired_comparison([3, 4, 5], [1, 2, 3])
    assert c.difference.estimate == 2.0 and c.difference.low == 2.0 and c.t_p == 0.0
    assert c.sign_p == pytest.approx(0.25)  # 3 of 3: 2 · 0.5³
    assert paired_comparison([3, 4], [3, 4]).t_p == 1.0  # every difference 0


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
    assert list(c.tests) == [SIGN] and math.isnan(c.t_p)  # the one test it makes


def test_share_interval_hand_solved():
    ci = share_interval(0, 20)
    assert ci.estimate == 0 and ci.low == 0
    assert ci.high == pytest.approx(1 - 0.025 ** (1 / 20), abs=1e-6)  # 0.1684
    # 8 of 10: the Clopper–Pearson bounds are the beta quantiles, by definition
    ci = share_interval(8, 10)
    assert ci.low == pytest.approx(stats.beta.ppf(0.025, 8, 3))
    assert ci.high == pytest.approx(stats.beta.ppf(0.975, 9, 2))


def test_holm_hand_solved():
    # sorted 0.01, 0.03, 0.04: ×3 = 0.03, ×2 = 0.06, ×1 = 0.04 → monotone 0.06
    assert holm([0.01, 0.04, 0.03]) == pytest.approx([0.03, 0.06, 0.06])
    out = holm([0.01, float("nan"), 0.04])
    assert math.isnan(out[1]) and out[0] == pytest.approx(0.02) and out[2] == pytest.approx(0.04)


@pytest.mark.slow  # (importing statsmodels, ≈ 3 s: CI's; the hand-solved cases above are fast)
def test_holm_is_statsmodels_bit_for_bit():
    """The step-down in NumPy gives statsmodels' numbers exactly, ties and NaNs included."""
    multitest = pytest.importorskip("statsmodels.stats.multitest")
    rng = np.random.default_rng(0)
    for n in (1, 2, 3, 5, 8, 12, 21, 39):  # (≈ 80 ms a statsmodels call)
        p = rng.random(n) ** rng.integers(1, 6)
        if n % 3 == 0:
            p = np.round(p, 2)  # ties
        assert holm(p) == multitest.multipletests(p, method="holm")[1].tolist()
    p = [0.01, math.nan, 0.04, 0.3]
    made = multitest.multipletests([0.01, 0.04, 0.3], method="holm")[1].tolist()
    assert [x for x in holm(p) if not math.isnan(x)] == made


@pytest.mark.parametrize(
    "old, call, new",
    [
        ("mean_half_width", lambda f: f([1.0, None, 3.0]), lambda: t_interval([1.0, 3.0])),
        ("paired_difference", lambda f: f([3, 5, 4], [1, 1, 2]), None),
        ("paired_t_p", lambda f: f([2.0, 4.0, 2.0]), None),
        ("wilson_interval", lambda f: f(8, 10), None),
    ],
)
def test_the_deprecated_aliases_warn_and_answer_as_before(old, call, new):
    with pytest.warns(DeprecationWarning, match=old):
        answer = call(getattr(statistics, old))
    assert old not in statistics.__all__
    if old == "mean_half_width":
        assert answer == (2.0, new().half_width, 2)
    elif old == "paired_difference":
        c = paired_comparison([3, 5, 4], [1, 1, 2], interval="t")
        assert answer == (c.difference.estimate, c.difference.half_width, c.wilcoxon_p)
    elif old == "paired_t_p":
        assert answer == pytest.approx(stats.ttest_1samp([2.0, 4.0, 2.0], 0.0).pvalue)
    else:
        assert answer[0] == 0.8 and answer[1] == pytest.approx(0.4902, abs=1e-4)


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
