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
* :func:`holm` — Holm's correction of a family of p-values
  (``statsmodels.stats.multitest.multipletests``);
* :func:`average_ranks` — ranks of a table's rows with exact ties sharing the mean of the ranks
  they span (``scipy.stats.rankdata``, ``method="average"``), so no row gains from its place in
  the listing.

Every interval is two-sided at ``level`` (default 95 %) and says what it is where it is printed.
Input that has no answer is refused with a ``ValueError`` naming the argument, never answered
with NaN: an empty or NaN sample, a p-value outside ``[0, 1]``, a first goal after the budget.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
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
    """Holm-adjusted p-values of a family (NaN entries, tests not made, stay NaN and are not
    counted in the family).

    Raises:
        ValueError: a p-value outside ``[0, 1]`` (or infinite), naming it.
    """
    try:
        from statsmodels.stats.multitest import multipletests
    except ImportError:
        raise ImportError(
            "himit_torch.statistics.holm needs statsmodels: pip install 'himit_torch[analysis]'"
        ) from None

    p = _sample("holm: p_values", p_values, minimum=0, nan=True)
    outside = np.flatnonzero(~np.isnan(p) & ((p < 0) | (p > 1)))
    if outside.size:
        i = int(outside[0])
        raise ValueError(
            f"holm: p_values[{i}]={float(p[i])!r} is not a p-value; each must lie in [0, 1] (NaN: a "
            "test not made)"
        )
    out = np.full_like(p, np.nan)
    made = ~np.isnan(p)
    if made.any():
        out[made] = multipletests(p[made], method="holm")[1]
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
