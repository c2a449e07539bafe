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
