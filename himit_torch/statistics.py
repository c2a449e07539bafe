"""The statistics every result of the library states: intervals, paired tests, first-goal
survival and the correction for many tests — each a thin, named call of the library made for it.

* :func:`t_interval` — a mean and its Student-t interval (``scipy.stats.t``);
* :func:`bca_interval` — a mean and its bias-corrected and accelerated bootstrap interval
  (``scipy.stats.bootstrap``, ``method="BCa"``), for skewed counts where a t-interval can leave
  the possible range;
* :func:`paired_comparison` — two agents' values paired by seed (common random numbers): the mean
  difference with its BCa interval, the paired t-test (``scipy.stats.ttest_rel``) and beside it
  the sign test (``scipy.stats.binomtest`` on the non-zero differences);
* :func:`first_goal_survival` — steps to the first goal with "never" right-censored at the budget:
  the Kaplan–Meier curve and median with its interval (``scipy.stats.ecdf`` on
  ``scipy.stats.CensoredData``);
* :func:`first_goal_sign_test` — who reached the goal first, paired by seed;
* :func:`share_interval` — a share with its exact Clopper–Pearson interval;
* :func:`holm` — Holm's correction of a family of p-values (the step-down of
  ``statsmodels.stats.multitest.multipletests(method="holm")``, bit for bit, in NumPy: the
  puzzle-box report needs it without the ``analysis`` extra);
* :func:`average_ranks` — ranks of a table's rows with exact ties sharing the mean of the ranks
  they span (``scipy.stats.rankdata``, ``method="average"``), so no row gains from its place in
  the listing.

Every interval is two-sided at ``level`` (default 95 %) and says what it is where it is printed.
Input that has no answer is refused with a ``ValueError`` naming the argument, never answered
with NaN: an empty or NaN sample, a p-value outside ``[0, 1]``, a first goal after the budget.

The runners' tables and figures use four plainer helpers, which return tuples and answer a cell
that has nothing to show with NaN instead of refusing it (a figure's band over windows where
some runs have no value, a share of no runs):

* :func:`mean_half_width` — ``(mean, half-width of the Student-t interval, n)`` over the finite
  values (the "mean ± 95 % t" of the Gymnasium, discovery and puzzle-box pages). The same mean
  and interval as :func:`t_interval`, but its half-width is ``t·s/√n`` computed directly, which
  can differ from :func:`t_interval`'s ``high − mean`` in the last bits;
* :func:`wilson_interval` — a share with its Wilson score interval (the puzzle box's shares;
  :func:`share_interval` is the exact Clopper–Pearson one);
* :func:`paired_difference` — the mean of paired differences with its t half-width and the
  Wilcoxon signed-rank p (the puzzle box's paired tests; :func:`paired_comparison` gives a BCa
  interval, the paired t-test and the sign test);
* :func:`paired_t_p` — the paired t-test's p on the differences alone (the discovery page's),
  with its own rule for differences without spread.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np


def _stats():
    """``scipy.stats``, imported at first use: importing it takes ~0.7 s, and the command line
    imports this module (through the sweep's summary) to build its parser."""
    from scipy import stats

    return stats


__all__ = [
    "Interval",
    "PairedComparison",
    "Survival",
    "t_interval",
    "bca_interval",
    "paired_comparison",
    "first_goal_survival",
    "first_goal_sign_test",
    "share_interval",
    "holm",
    "average_ranks",
    "mean_half_width",
    "wilson_interval",
    "paired_difference",
    "paired_t_p",
]

#: Bootstrap resamples of :func:`bca_interval` and :func:`paired_comparison`.
RESAMPLES = 9999


def _sample(
    where: str, values: Sequence[float] | np.ndarray, minimum: int = 1, nan: bool = False
) -> np.ndarray:
    """``values`` as a 1-D float array of at least ``minimum`` finite numbers (``ValueError``
    naming ``where`` and the first bad item otherwise: a NaN has no place in a mean; ``nan``:
    NaN allowed, where it means "not made", as in :func:`holm`)."""
    try:
        x = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{where} must be a list of numbers, got {values!r}") from None
    if x.ndim != 1:
        raise ValueError(f"{where} must be a 1-D list of numbers, got shape {x.shape}")
    if len(x) < minimum:
        raise ValueError(
            f"{where} holds {len(x)} value(s); give at least {minimum} (a mean of nothing is "
            "undefined)"
        )
    bad = np.flatnonzero(~np.isfinite(x) & ~(nan & np.isnan(x)))
    if bad.size:
        i = int(bad[0])
        raise ValueError(f"{where}[{i}]={float(x[i])!r} must be a finite number")
    return x


@dataclass(frozen=True)
class Interval:
    """An estimate and its two-sided interval; ``what`` names the interval."""

    estimate: float
    low: float
    high: float
    what: str

    def format(self, digits: int = 1) -> str:
        return f"{self.estimate:.{digits}f} [{self.low:.{digits}f}, {self.high:.{digits}f}]"


def t_interval(values: Sequence[float], level: float = 0.95) -> Interval:
    """The mean of ``values`` and its Student-t interval (n − 1 degrees of freedom). One value,
    or values all equal: the interval is the mean itself (no spread to measure).

    Raises:
        ValueError: no values (a mean of nothing), or a value that is not finite.
    """
    x = _sample("t_interval: values", values)
    mean = float(x.mean())
    if len(x) < 2 or np.all(x == x[0]):
        return Interval(mean, mean, mean, f"{level:.0%} t-interval of the mean")
    low, high = _stats().t.interval(level, len(x) - 1, loc=mean, scale=_stats().sem(x))
    return Interval(mean, float(low), float(high), f"{level:.0%} t-interval of the mean")


def bca_interval(values: Sequence[float], level: float = 0.95, seed: int = 0) -> Interval:
    """The mean of ``values`` and its BCa bootstrap interval (``RESAMPLES`` resamples drawn
    from ``seed``). Values all equal: the interval is the mean itself."""
    x = np.asarray(values, dtype=float)
    mean = float(x.mean())
    what = f"{level:.0%} BCa bootstrap interval of the mean"
    # no spread beyond round-off (e.g. 20 greedy policies all at 76.5 %): the mean itself
    if len(x) < 2 or np.ptp(x) <= 1e-9 * max(1.0, abs(mean)):
        return Interval(mean, mean, mean, what)
    result = _stats().bootstrap(
        (x,),
        np.mean,
        confidence_level=level,
        n_resamples=RESAMPLES,
        method="BCa",
        rng=np.random.default_rng(seed),
    )
    low, high = result.confidence_interval
    return Interval(mean, float(low), float(high), what)


@dataclass(frozen=True)
class PairedComparison:
    """``a − b`` paired by seed: the mean difference and its BCa interval, the paired t-test's
    and the sign test's two-sided p-values, and how many pairs ``a`` won, lost and tied."""

    difference: Interval
    t_p: float
    sign_p: float
    wins: int
    losses: int
    ties: int


def paired_comparison(
    a: Sequence[float], b: Sequence[float], level: float = 0.95, seed: int = 0
) -> PairedComparison:
    """Compare ``a`` with ``b``, the i-th of each from the same seed.

    Raises:
        ValueError: sequences of different lengths or of fewer than 2 values, or a value that is
            not finite (a NaN would count as neither a win nor a loss).
    """
    x, y = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if x.shape != y.shape or x.ndim != 1 or len(x) < 2:
        raise ValueError(
            f"paired_comparison needs two equally long sequences of ≥ 2 values, got "
            f"{x.shape} and {y.shape}"
        )
    x, y = _sample("paired_comparison: a", x), _sample("paired_comparison: b", y)
    d = x - y
    wins, losses = int((d > 0).sum()), int((d < 0).sum())
    if np.ptp(d) <= 1e-9 * max(1.0, abs(float(d.mean()))):
        # no spread beyond round-off: a t-test is undefined, the difference is exact
        t_p = 1.0 if d[0] == 0 else 0.0
    else:
        t_p = float(_stats().ttest_rel(x, y).pvalue)
    sign_p = float(_stats().binomtest(wins, wins + losses).pvalue) if wins + losses else 1.0
    return PairedComparison(
        bca_interval(d, level, seed), t_p, sign_p, wins, losses, len(d) - wins - losses
    )


@dataclass(frozen=True)
class Survival:
    """Steps to the first goal of a group of runs, "never" right-censored at the budget: the
    Kaplan–Meier median with its interval (``math.inf`` where the curve never falls to ½),
    how many runs never reached the goal, and the curve itself (``times``, ``survival``)."""

    median: Interval
    never: int
    runs: int
    times: np.ndarray
    survival: np.ndarray


def first_goal_survival(
    first_goal_steps: Sequence[int], budget: int, level: float = 0.95
) -> Survival:
    """The Kaplan–Meier estimate of the steps to the first goal. ``first_goal_steps``: one per
    run, −1 for a run that never reached the goal within its ``budget`` of steps (censored
    there). The median's interval is where the pointwise log–log band of the curve crosses ½.

    Raises:
        ValueError: no runs, a ``budget`` that is not a whole number ≥ 1, or a first-goal step
            that is not a whole number in ``0 … budget`` or −1 (a goal after the budget was not
            within it: give the budget the runs had).
    """
    if (
        isinstance(budget, (bool, np.bool_))
        or not isinstance(budget, (int, np.integer, float, np.floating))
        or not math.isfinite(budget)
        or budget != int(budget)
        or budget < 1
    ):
        raise ValueError(
            f"first_goal_survival: budget={budget!r} must be a whole number of steps ≥ 1"
        )
    steps = _sample("first_goal_survival: first_goal_steps", first_goal_steps)
    bad = np.flatnonzero((steps != np.round(steps)) | (steps < -1) | (steps > budget))
    if bad.size:
        i = int(bad[0])
        raise ValueError(
            f"first_goal_survival: first_goal_steps[{i}]={steps[i]:g} must be a whole number of "
            f"steps in 0 … budget={budget:g}, or −1 for a run that never reached the goal"
        )
    found = steps >= 0
    data = _stats().CensoredData(uncensored=steps[found], right=np.full((~found).sum(), budget))
    sf = _stats().ecdf(data).sf
    with warnings.catch_warnings():
        # the log-log band is undefined where S(t) is 0 or 1 (scipy warns); those points are
        # NaN and never cross ½, which is what the median's interval reads
        warnings.simplefilter("ignore", RuntimeWarning)
        band = sf.confidence_interval(level, method="log-log")

    def crossing(curve) -> float:
        """The first time ``curve`` is at or below ½ (inf: never)."""
        below = np.nonzero(curve.probabilities <= 0.5)[0]
        return float(curve.quantiles[below[0]]) if len(below) else math.inf

    median = Interval(
        crossing(sf),
        crossing(band.low),
        crossing(band.high),
        f"Kaplan–Meier median, {level:.0%} interval from the log–log band",
    )
    return Survival(median, int((~found).sum()), len(steps), sf.quantiles, sf.probabilities)


def first_goal_sign_test(a: Sequence[int], b: Sequence[int]) -> PairedComparison:
    """Who reached the goal first, paired by seed (−1: never). A pair where neither did is a
    tie; one that never did loses to one that did. The "difference" is the median over seeds
    of ``b``'s first-goal step minus ``a``'s, "never" counted as just after the larger budget
    (so positive: ``a`` sooner); its interval is left empty (NaN) — the sign test is the test."""
    x, y = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if x.shape != y.shape or x.ndim != 1:
        raise ValueError(f"first_goal_sign_test: shapes {x.shape} and {y.shape} differ")
    late = max(x.max(), y.max()) + 1
    x, y = np.where(x < 0, late, x), np.where(y < 0, late, y)
    wins, losses = int((x < y).sum()), int((x > y).sum())
    sign_p = float(_stats().binomtest(wins, wins + losses).pvalue) if wins + losses else 1.0
    median = float(np.median(y - x))
    return PairedComparison(
        Interval(median, math.nan, math.nan, "median over seeds (no interval)"),
        math.nan,
        sign_p,
        wins,
        losses,
        len(x) - wins - losses,
    )


def share_interval(count: int, total: int, level: float = 0.95) -> Interval:
    """``count / total`` and its exact Clopper–Pearson interval."""
    ci = _stats().binomtest(count, total).proportion_ci(level, method="exact")
    return Interval(
        count / total, float(ci.low), float(ci.high), f"exact {level:.0%} Clopper–Pearson"
    )


def holm(p_values: Sequence[float]) -> list[float]:
    """Holm-adjusted p-values of a family, in the order given (NaN entries, tests not made, stay
    NaN and are not counted in the family). The ``i``-th smallest of ``m`` p-values (from 0) is
    multiplied by ``m − i``, the products made non-decreasing in that order and capped at 1:
    the numbers of ``statsmodels.stats.multitest.multipletests(p, method="holm")[1]``, bit for
    bit (tested against it), without needing statsmodels.

    Raises:
        ValueError: a p-value outside ``[0, 1]`` (or infinite), naming it.
    """
    p = _sample("holm: p_values", p_values, minimum=0, nan=True)
    outside = np.flatnonzero(~np.isnan(p) & ((p < 0) | (p > 1)))
    if outside.size:
        i = int(outside[0])
        raise ValueError(
            f"holm: p_values[{i}]={float(p[i])!r} is not a p-value; each must lie in [0, 1] (NaN: a "
            "test not made)"
        )
    out = np.full_like(p, np.nan)
    made = np.flatnonzero(~np.isnan(p))
    if made.size:
        order = made[np.argsort(p[made])]
        adjusted = np.maximum.accumulate(p[order] * np.arange(made.size, 0, -1))
        out[order] = np.minimum(adjusted, 1.0)
    return out.tolist()


def average_ranks(scores: dict[str, float], higher_is_better: bool = True) -> dict[str, float]:
    """Rank 1 for the best of ``scores`` (name → score); rows with exactly equal scores share
    the average of the ranks they span (three rows tied for 2nd–4th each get 3.0). Infinite
    scores rank like any other (a "never" first goal is tied with every other "never"); a NaN
    score is refused, as it has no place in an order.

    Raises:
        ValueError: a NaN score, naming its row.
    """
    for name, score in scores.items():
        if math.isnan(score):
            raise ValueError(f"average_ranks: the score of {name!r} is NaN; give every row a score")
    names = list(scores)
    keys = np.array([scores[n] for n in names], dtype=float)
    ranks = _stats().rankdata(-keys if higher_is_better else keys, method="average")
    return {n: float(r) for n, r in zip(names, ranks)}


# ============================================================= the runners' tables and figures
def mean_half_width(
    values: Iterable[float | None], level: float = 0.95
) -> tuple[float, float, int]:
    """``(mean, half-width, n)`` of the Student-t interval of the mean of ``values``: ``n`` the
    values that are numbers and finite (``None``, NaN and ±inf are left out), the half-width
    ``t_{(1+level)/2, n−1} · s / √n`` (``s`` the sample standard deviation). No such value:
    ``(nan, nan, 0)``; one: ``(value, nan, 1)``; values all equal: half-width 0."""
    v = np.asarray([x for x in values if x is not None and math.isfinite(x)], dtype=np.float64)
    n = v.size
    if n == 0:
        return math.nan, math.nan, 0
    if n == 1:
        return float(v[0]), math.nan, 1
    half = float(_stats().t.ppf(0.5 + level / 2, n - 1) * v.std(ddof=1) / math.sqrt(n))
    return float(v.mean()), half, n


def wilson_interval(k: int, n: int, level: float = 0.95) -> tuple[float, float, float]:
    """``(k/n, low, high)``: the share ``k`` of ``n`` with its Wilson score interval
    (``scipy.stats.binomtest(k, n).proportion_ci(method="wilson")``); ``(nan, nan, nan)`` for
    ``n = 0``."""
    if n == 0:
        return math.nan, math.nan, math.nan
    ci = _stats().binomtest(int(k), int(n)).proportion_ci(confidence_level=level, method="wilson")
    return k / n, float(ci.low), float(ci.high)


def paired_difference(
    a: Sequence[float] | np.ndarray, b: Sequence[float] | np.ndarray
) -> tuple[float, float, float]:
    """``(mean of a − b, half-width of its 95 % t interval, Wilcoxon signed-rank p)``, paired by
    position (:func:`mean_half_width` of the differences, so a non-finite difference is left
    out of the mean; ``scipy.stats.wilcoxon``, two-sided; p = 1 when every difference is 0)."""
    d = np.asarray(a, dtype=np.float64) - np.asarray(b, dtype=np.float64)
    mean, half, _ = mean_half_width(d)
    p = 1.0 if not np.any(d) else float(_stats().wilcoxon(d).pvalue)
    return mean, half, p


def paired_t_p(differences: Sequence[float] | np.ndarray) -> float:
    """The two-sided p of the paired t-test, from the paired ``differences`` alone (the
    one-sample t-test of their mean against 0, ``scipy.stats.ttest_1samp``): 1 when there are
    fewer than 2 or all are 0, 0 when all are equal and not 0 (no spread: the difference is
    exact). :func:`paired_comparison`'s ``t_p`` is the same test on the two samples
    (``scipy.stats.ttest_rel``), with round-off-sized spread counted as none."""
    diff = np.asarray(differences, dtype=np.float64)
    if diff.size < 2 or not np.any(diff):
        return 1.0
    if np.all(diff == diff[0]):
        return 0.0
    return float(_stats().ttest_1samp(diff, 0.0).pvalue)
