"""The hierarchy study's analysis (``experiments/hierarchy/``): each pair of runs counted once,
and hierarchy's effect on imitation as the difference of the two imitation effects, checked on
hand-made records."""

import sys
from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).resolve().parents[1] / "experiments" / "hierarchy"


@pytest.fixture(scope="module")
def analysis():
    sys.path.insert(0, str(HERE))
    try:
        import common
        import where_pays

        yield common, where_pays
    finally:
        sys.path.remove(str(HERE))


def _test(common, name, world="exp1", schedule="paper", endpoint="greedy", difference=-1.0):
    return common.Test("F", name, world, "", schedule, "a", "b", endpoint, difference, -2.0, 0.0,
                       0.01, 3, 17)  # fmt: skip


def test_a_comparison_of_the_same_runs_is_counted_once(analysis):
    common, _ = analysis
    first = [_test(common, "trial"), _test(common, "trial", endpoint="goals", difference=5.0)]
    same = [_test(common, "trial + feasibility"),
            _test(common, "trial + feasibility", endpoint="goals", difference=5.0)]  # fmt: skip
    other_world = [_test(common, "trial", world="exp2"),
                   _test(common, "trial", world="exp2", endpoint="goals", difference=5.0)]  # fmt: skip
    other_numbers = [_test(common, "off"), _test(common, "off", endpoint="goals", difference=6.0)]
    kept, repeats = common.distinct_comparisons(first + same + other_world + other_numbers)
    assert repeats == [("trial + feasibility", "exp1", "", "paper")]
    assert kept == first + other_world + other_numbers


def test_hierarchys_effect_is_the_difference_of_the_imitation_effects(analysis):
    """Hand-solved: per seed (eq. 2 − options only) − (eq. 1 − primitives only) on the greedy
    policy is (50 − 10) − (20 − 20) = 40, (60 − 30) − (25 − 15) = 20, (70 − 20) − (30 − 10) = 30:
    mean 30; eq. 2 − eq. 1 is 30, 35, 40: mean 35."""
    _, wp = analysis
    values = {"imitation": [50, 60, 70], "options": [10, 30, 20],
              "imitation_primitives": [20, 25, 30], "primitives": [20, 15, 10]}  # fmt: skip
    arrays = {a: np.array(v, dtype=float) for a, v in values.items()}
    cell = wp.Cell("taxi", "paper", 1000, "abc", (0, 1, 2), arrays,
                   {a: np.array([10, -1, 30]) for a in values}, arrays, 250)  # fmt: skip
    tests = {(t.name, t.endpoint): t for t in wp.cell_tests("Q1", cell)}
    assert tests[wp.HIERARCHY, "greedy"].difference == pytest.approx(30.0)
    assert (tests[wp.HIERARCHY, "greedy"].wins, tests[wp.HIERARCHY, "greedy"].losses) == (3, 0)
    assert tests[wp.DIRECT, "greedy"].difference == pytest.approx(35.0)
    own = "options' own effect (options only − primitives only)"
    assert tests[own, "greedy"].difference == pytest.approx(np.mean([-10, 15, 10]))
    # the same first goals for every learner: no speed-up differs, every sign test is a tie
    assert tests[wp.HIERARCHY, "first_goal"].difference == 0.0
    assert tests[wp.HIERARCHY, "first_goal"].p == 1.0


def test_the_budget_rule_is_the_least_multiple_of_10k_by_which_half_have_reached_the_goal(
    analysis,
):
    """Hand-solved: of four runs, two must have reached the goal; the 2nd smallest first goal
    decides (12,001 → 20k; 10,000 → 10k; a run that never did counts as never)."""
    common, _ = analysis
    assert common.budget_by_rule([30_000, 12_001, 5, None]) == 20_000
    assert common.budget_by_rule([10_000, 3, -1, -1]) == 10_000
    assert common.budget_by_rule([49, 225]) == 10_000  # at least one step of 10k
    assert common.budget_by_rule([7, None, None]) is None  # 1 of 3 reached: fewer than half
    assert common.budget_by_rule([25_000, 41_000, None, None], step=20_000) == 60_000


def _cell(wp, greedy, first_goal, goals, seeds=(0, 1, 2)):
    return wp.Cell("taxi", "paper", 1000, "abc", seeds, {wp.EQ2: np.array(greedy, dtype=float)},
                   {wp.EQ2: np.array(first_goal)}, {wp.EQ2: np.array(goals, dtype=float)},
                   250)  # fmt: skip


def test_feasibility_is_compared_with_trial_alone_paired_by_seed(analysis):
    """Hand-solved: greedy 40, 50, 60 with feasibility against 30, 50, 70 with trial alone:
    differences +10, 0, −10 (mean 0, one seed won, one lost); first goals 5, 20, never against
    10, 20, 30: one sooner, one tie, one later (never loses)."""
    _, wp = analysis
    trial = _cell(wp, [30, 50, 70], [10, 20, 30], [1, 2, 3])
    feasible = _cell(wp, [40, 50, 60], [5, 20, -1], [2, 4, 6])
    tests = {t.endpoint: t for t in wp.f_tests(trial, feasible, 1)}
    assert tests["greedy"].name == "N = 1 − trial alone"
    assert tests["greedy"].difference == pytest.approx(0.0)
    assert (tests["greedy"].wins, tests["greedy"].losses) == (1, 1)
    assert (tests["first_goal"].wins, tests["first_goal"].losses) == (1, 1)
    assert tests["goals_q1"].difference == pytest.approx(2.0)
    with pytest.raises(ValueError, match="seeds differ"):
        wp.f_tests(trial, _cell(wp, [1, 2], [1, 2], [1, 2], seeds=(0, 1)), 3)


def test_a_run_is_changed_where_any_window_of_its_record_differs(analysis):
    _, wp = analysis
    base = {("imitation", 0): (("2000", "5"),), ("imitation", 1): (("2000", "7"),)}
    same_and_one_window_differs = {("imitation", 0): (("2000", "5"),),
                                   ("imitation", 1): (("2000", "8"),)}  # fmt: skip
    assert wp.runs_changed(base, base) == (0, 2)
    assert wp.runs_changed(base, same_and_one_window_differs) == (1, 2)
    with pytest.raises(ValueError, match="seeds"):
        wp.runs_changed(base, {("imitation", 0): (("2000", "5"),)})
