"""Bad input to ``himit_torch.statistics`` is refused with a ``ValueError`` naming the function,
the argument and what would be right — never answered with an undocumented NaN (issue 52).

Each case is generated from a valid call by spoiling one argument: the bad call must raise
naming the function and the argument, and the valid call beside it must answer. Without the
check, each bad call would answer (a NaN interval, a p of NaN) or fail inside SciPy with
another message, so every case fails when its check is removed.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from himit_torch.statistics import (
    bca_interval,
    first_goal_sign_test,
    first_goal_survival,
    paired_comparison,
    share_interval,
    t_interval,
)

#: (id, the bad call, the valid call beside it, words the message must hold)
CASES: list = []


def case(name: str, bad, good, *words: str) -> None:
    CASES.append(pytest.param(bad, good, words, id=name))


# ============================================================ the confidence level, everywhere
_SAMPLE = [1.0, 2.0, 4.0, 8.0]
_LEVEL_USERS = {
    "t_interval": lambda level: t_interval(_SAMPLE, level),
    "bca_interval": lambda level: bca_interval(_SAMPLE, level),
    "share_interval": lambda level: share_interval(3, 10, level),
    "paired_comparison": lambda level: paired_comparison(_SAMPLE, [0, 1, 1, 2], level),
    "paired_comparison(t)": lambda level: paired_comparison(
        _SAMPLE, [0, 1, 1, 2], level, interval="t"
    ),
    "first_goal_survival": lambda level: first_goal_survival([3, 5, -1], 10, level),
}
for _user, _call in _LEVEL_USERS.items():
    for _level in [math.nan, 0, 1, 0.0, 1.0, -0.5, 1.5, math.inf, True, "0.95", None]:
        case(
            f"{_user}-level={_level!r}",
            lambda call=_call, level=_level: call(level),
            lambda call=_call: call(0.9),
            _user.removesuffix("(t)"),
            "level",
            "between 0 and 1",
        )

# ================================================================== a sample of a mean
_NOT_FINITE = [[], [math.nan], [1.0, math.nan], [1.0, math.inf], [-math.inf], [[1.0, 2.0]]]
for _name, _fn in (("t_interval", t_interval), ("bca_interval", bca_interval)):
    for _values, _words in [(v, ()) for v in _NOT_FINITE] + [
        (["a", "b"], ("number",)),
        ([None, 1.0], ("number",)),
    ]:
        case(
            f"{_name}-values={_values!r}",
            lambda fn=_fn, v=_values: fn(v),
            lambda fn=_fn: fn([1.0, 2.0]),
            _name,
            "values",
            *_words,
        )

# ===================================================================== the counts of a share
for _count, _total, _field in [
    (-1, 10, "count"),
    (11, 10, "count"),
    (2.5, 10, "count"),
    (math.nan, 10, "count"),
    (True, 10, "count"),
    ("3", 10, "count"),
    (None, 10, "count"),
    (0, 0, "total"),
    (0, -5, "total"),
    (1, 2.5, "total"),
    (1, math.nan, "total"),
    (1, math.inf, "total"),
    (1, "10", "total"),
]:
    case(
        f"share_interval-count={_count!r}-total={_total!r}",
        lambda k=_count, n=_total: share_interval(k, n),
        lambda: share_interval(3, 10),
        "share_interval",
        _field,
        "whole number",
    )

# ======================================================================= paired samples
for _a, _b, _words in [
    ([1.0, 2.0], [1.0, 2.0, 3.0], ("equally long",)),
    ([1.0], [2.0], ("≥ 2",)),
    ([], [], ("≥ 2",)),
    ([1.0, math.nan, 3.0], [1.0, 2.0, 3.0], ("a[1]", "finite")),
    ([1.0, 2.0, 3.0], [1.0, math.inf, 3.0], ("b[1]", "finite")),
    ([1.0, 2.0, 3.0], [-math.inf, 2.0, 3.0], ("b[0]", "finite")),
]:
    case(
        f"paired_comparison-a={_a!r}-b={_b!r}",
        lambda a=_a, b=_b: paired_comparison(a, b),
        lambda: paired_comparison([1.0, 2.0, 4.0], [1.0, 1.0, 2.0]),
        "paired_comparison",
        *_words,
    )
for _interval in ["BCa", "student", None]:
    case(
        f"paired_comparison-interval={_interval!r}",
        lambda i=_interval: paired_comparison([1.0, 2.0, 4.0], [1.0, 1.0, 2.0], interval=i),
        lambda: paired_comparison([1.0, 2.0, 4.0], [1.0, 1.0, 2.0], interval="t"),
        "paired_comparison",
        "interval",
    )

# ========================================================== who reached the goal first
for _a, _b, _words in [
    ([], [], ("a", "at least 1")),
    ([3, math.nan], [4, 5], ("a[1]", "finite")),
    ([3, 4], [4, -2], ("b[1]", "−1")),
    ([3, 2.5], [4, 5], ("a[1]", "whole number")),
    ([3, 4, 5], [4, 5], ("equally long",)),
]:
    case(
        f"first_goal_sign_test-a={_a!r}-b={_b!r}",
        lambda a=_a, b=_b: first_goal_sign_test(a, b),
        lambda: first_goal_sign_test([3, -1], [4, 5]),
        "first_goal_sign_test",
        *_words,
    )


def test_the_cases_are_over_sixty():
    assert len(CASES) >= 60, len(CASES)


@pytest.mark.parametrize("bad, good, words", CASES)
def test_bad_input_is_refused_naming_it_and_its_valid_neighbour_answers(bad, good, words):
    with pytest.raises(ValueError) as caught:
        bad()
    for word in words:
        assert word in str(caught.value), str(caught.value)
    answer = good()
    numbers = [
        x
        for x in (
            getattr(answer, "estimate", None),
            getattr(getattr(answer, "difference", None), "estimate", None),
            getattr(getattr(answer, "median", None), "estimate", None),
        )
        if x is not None
    ]
    assert numbers and all(not np.isnan(x) for x in numbers)
