"""The statistics every result of the library states: intervals, paired tests, first-goal
survival and the correction for many tests — one function per idea, each a thin, named call of
the library made for it.

* :func:`t_interval` — a mean and its Student-t interval (``scipy.stats.t``): *the* interval of
  a mean, in every study's tables and figures;
* :func:`bca_interval` — a mean and its bias-corrected and accelerated bootstrap interval
  (``scipy.stats.bootstrap``, ``method="BCa"``), for skewed counts where a t-interval can leave
  the possible range;
* :func:`share_interval` — a share and its exact Clopper–Pearson interval: *the* interval of a
  share (its coverage is never below ``level``, which matters at the 0/20 and 20/20 that seeds
  give);
* :func:`paired_comparison` — two samples paired by seed (common random numbers): the mean
  difference with its interval (BCa or t, named in it), the paired t-test, the Wilcoxon
  signed-rank test and the sign test, each p-value under its test's name, and the wins, losses
  and ties;
* :func:`first_goal_survival` — steps to the first goal with "never" right-censored at the budget:
  the Kaplan–Meier curve and median with its interval (``scipy.stats.ecdf`` on
  ``scipy.stats.CensoredData``);
* :func:`first_goal_sign_test` — who reached the goal first, paired by seed;
* :func:`holm` — Holm's correction of a family of p-values (the step-down of
  ``statsmodels.stats.multitest.multipletests(method="holm")``, bit for bit, in NumPy: the
  puzzle-box report needs it without the ``analysis`` extra);
* :func:`average_ranks` — ranks of a table's rows with exact ties sharing the mean of the ranks
  they span (``scipy.stats.rankdata``, ``method="average"``), so no row gains from its place in
  the listing.

Every interval is two-sided at ``level`` (default 95 %) and says what it is where it is printed.

**Bad input is refused, never answered with NaN.** A sample must hold numbers, all finite: a NaN
(a value not measured) or an infinity is refused with a ``ValueError`` naming the argument and
the item, and so is an empty sample — a caller with values it did not measure leaves them out
itself, where it can say so. A ``level`` must be a number strictly between 0 and 1; counts must
be whole numbers with ``0 ≤ count ≤ total`` and ``total ≥ 1``. The one NaN this module answers
with is an interval that one value cannot give: :func:`t_interval` of a single value has NaN
bounds (no spread can be measured from one value). :func:`holm` alone reads NaN in its input, as
"test not made".

``mean_half_width``, ``wilson_interval``, ``paired_difference`` and ``paired_t_p`` are deprecated
aliases (a ``DeprecationWarning``) of the functions above, kept for one version.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Literal

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
    "PAIRED_T",
    "WILCOXON",
    "SIGN",
    "t_interval",
    "bca_interval",
    "share_interval",
    "paired_comparison",
    "first_goal_survival",
    "first_goal_sign_test",
    "holm",
    "average_ranks",
]

#: Bootstrap resamples of :func:`bca_interval` and :func:`paired_comparison`.
RESAMPLES = 9999

#: The paired t-test's name in :attr:`PairedComparison.tests`.
PAIRED_T = "paired t-test"
#: The Wilcoxon signed-rank test's name in :attr:`PairedComparison.tests`.
WILCOXON = "Wilcoxon signed-rank test"
#: The sign test's name in :attr:`PairedComparison.tests`.
SIGN = "sign test"


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
        raise ValueError(
            f"{where}[{i}]={float(x[i])!r} must be a finite number (leave out a value not "
            "measured before asking for a statistic)"
        )
    return x


def _level(where: str, level: float) -> float:
    """``level`` as a float strictly between 0 and 1 (``ValueError`` naming ``where``)."""
    if (
        isinstance(level, (bool, np.bool_))
        or not isinstance(level, (int, float, np.integer, np.floating))
        or not 0 < level < 1  # NaN fails too
    ):
        raise ValueError(
            f"{where}: level={level!r} must be a confidence level strictly between 0 and 1 "
            "(0.95 for a 95 % interval)"
        )
    return float(level)


def _whole(where: str, name: str, value, low: int, high: float = math.inf) -> int:
    """``value`` as an int in ``low … high`` (``ValueError`` naming ``where`` and ``name``)."""
    if (
        isinstance(value, (bool, np.bool_))
        or not isinstance(value, (int, float, np.integer, np.floating))
        or not math.isfinite(value)
        or value != int(value)
        or not low <= value <= high
    ):
        bound = f"≤ {high:g}" if math.isfinite(high) else "(no upper bound)"
        raise ValueError(f"{where}: {name}={value!r} must be a whole number ≥ {low} and {bound}")
    return int(value)


@dataclass(frozen=True)
class Interval:
    """An estimate and its two-sided interval; ``what`` names the interval."""

    estimate: float
    low: float
    high: float
    what: str

    @property
    def half_width(self) -> float:
        """Half the interval's width: the "±" of a symmetric (t) interval; NaN where the
        interval has no bounds."""
        return (self.high - self.low) / 2

    def format(self, digits: int = 1) -> str:
        """``estimate [low, high]`` with ``digits`` decimals."""
        return f"{self.estimate:.{digits}f} [{self.low:.{digits}f}, {self.high:.{digits}f}]"

    def plus_minus(self, digits: int = 1, sign: str = "") -> str:
        """``estimate ± half-width`` with ``digits`` decimals (``sign``: a format flag of the
        estimate, ``"+"`` or ``","``); the estimate alone where the interval has no bounds (one
        value)."""
        mean = f"{self.estimate:{sign}.{digits}f}"
        if not math.isfinite(self.half_width):
            return mean
        return f"{mean} ± {self.half_width:{sign.replace('+', '')}.{digits}f}"


def t_interval(values: Sequence[float], level: float = 0.95) -> Interval:
    """The mean of ``values`` and its Student-t interval: mean ± ``t_{(1+level)/2, n−1}·s/√n``
    (``s`` the sample standard deviation, n − 1 degrees of freedom). Values all equal: the
    interval is the mean itself (no spread); one value: its bounds are NaN (no spread can be
    measured from one value).

    Raises:
        ValueError: no values, a value that is not a finite number (a value not measured is left
            out by the caller), or a ``level`` not strictly between 0 and 1.
    """
    level = _level("t_interval", level)
    x = _sample("t_interval: values", values)
    mean, n = float(x.mean()), len(x)
    what = f"{level:.0%} t-interval of the mean"
    if n == 1:
        return Interval(mean, math.nan, math.nan, what + " (one value: no interval)")
    half = float(_stats().t.ppf(0.5 + level / 2, n - 1) * x.std(ddof=1) / math.sqrt(n))
    return Interval(mean, mean - half, mean + half, what)


def bca_interval(values: Sequence[float], level: float = 0.95, seed: int = 0) -> Interval:
    """The mean of ``values`` and its BCa bootstrap interval (``RESAMPLES`` resamples drawn
    from ``seed``). One value, or values all equal (up to round-off): the interval is the mean
    itself.

    Raises:
        ValueError: no values, a value that is not a finite number, or a ``level`` not strictly
            between 0 and 1.
    """
    level = _level("bca_interval", level)
    x = _sample("bca_interval: values", values)
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


def share_interval(count: int, total: int, level: float = 0.95) -> Interval:
    """``count / total`` and its exact Clopper–Pearson interval
    (``scipy.stats.binomtest(count, total).proportion_ci(method="exact")``).

    Raises:
        ValueError: ``total`` not a whole number ≥ 1, ``count`` not a whole number in
            ``0 … total``, or a ``level`` not strictly between 0 and 1.
    """
    level = _level("share_interval", level)
    total = _whole("share_interval", "total", total, 1)
    count = _whole("share_interval", "count", count, 0, total)
    ci = _stats().binomtest(count, total).proportion_ci(level, method="exact")
    return Interval(
        count / total, float(ci.low), float(ci.high), f"exact {level:.0%} Clopper–Pearson"
    )


@dataclass(frozen=True)
class PairedComparison:
    """``a − b`` paired by seed: the mean difference and its interval (``difference.what``
    names it), each test's two-sided p-value under the test's name (``tests``: the keys are
    :data:`PAIRED_T`, :data:`WILCOXON`, :data:`SIGN`; :func:`first_goal_sign_test` makes only the
    sign test), and how many pairs ``a`` won, lost and tied."""

    difference: Interval
    tests: dict[str, float] = field(default_factory=dict)
    wins: int = 0
    losses: int = 0
    ties: int = 0

    @property
    def t_p(self) -> float:
        """The paired t-test's p (NaN where it was not made)."""
        return self.tests.get(PAIRED_T, math.nan)

    @property
    def wilcoxon_p(self) -> float:
        """The Wilcoxon signed-rank test's p (NaN where it was not made)."""
        return self.tests.get(WILCOXON, math.nan)

    @property
    def sign_p(self) -> float:
        """The sign test's p."""
        return self.tests.get(SIGN, math.nan)


def _sign_p(wins: int, losses: int) -> float:
    """The sign test's two-sided p on ``wins`` against ``losses`` (ties left out; 1 for none)."""
    return float(_stats().binomtest(wins, wins + losses).pvalue) if wins + losses else 1.0


def paired_comparison(
    a: Sequence[float] | np.ndarray,
    b: Sequence[float] | np.ndarray,
    level: float = 0.95,
    seed: int = 0,
    interval: Literal["bca", "t"] = "bca",
) -> PairedComparison:
    """Compare ``a`` with ``b``, the i-th of each from the same seed: the mean of ``a − b`` with
    its ``interval`` (:func:`bca_interval` from ``seed``, for skewed counts, or
    :func:`t_interval`), the paired t-test (``scipy.stats.ttest_rel``), the Wilcoxon
    signed-rank test (``scipy.stats.wilcoxon``) and the sign test (``scipy.stats.binomtest`` on
    the non-zero differences). Differences without spread beyond round-off: the t-test's p is 1
    when they are 0 and 0 otherwise (the difference is exact); every difference 0: the
    Wilcoxon p is 1.

    Raises:
        ValueError: sequences of different lengths or of fewer than 2 pairs, a value that is not
            a finite number (a NaN would count as neither a win nor a loss: leave the pair out),
            a ``level`` not strictly between 0 and 1, or an unknown ``interval``.
    """
    level = _level("paired_comparison", level)
    if interval not in ("bca", "t"):
        raise ValueError(f"paired_comparison: interval={interval!r} must be 'bca' or 't'")
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
        t_p = 1.0 if d[0] == 0 else 0.0
    else:
        t_p = float(_stats().ttest_rel(x, y).pvalue)
    wilcoxon_p = 1.0 if not np.any(d) else float(_stats().wilcoxon(d).pvalue)
    tests = {PAIRED_T: t_p, WILCOXON: wilcoxon_p, SIGN: _sign_p(wins, losses)}
    diff = bca_interval(d, level, seed) if interval == "bca" else t_interval(d, level)
    return PairedComparison(diff, tests, wins, losses, len(d) - wins - losses)


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
    level = _level("first_goal_survival", level)
    budget = _whole("first_goal_survival", "budget", budget, 1)
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
    (so positive: ``a`` sooner); its interval is left empty (NaN) — the sign test, the one test
    in ``tests``, is the test.

    Raises:
        ValueError: sequences of different lengths or empty, or a first-goal step that is not a
            whole number ≥ −1.
    """
    x = _sample("first_goal_sign_test: a", a)
    y = _sample("first_goal_sign_test: b", b)
    if x.shape != y.shape:
        raise ValueError(
            f"first_goal_sign_test: a and b must be equally long (one per seed), got "
            f"{len(x)} and {len(y)}"
        )
    for name, v in (("a", x), ("b", y)):
        bad = np.flatnonzero((v != np.round(v)) | (v < -1))
        if bad.size:
            i = int(bad[0])
            raise ValueError(
                f"first_goal_sign_test: {name}[{i}]={v[i]:g} must be a whole number of steps "
                "≥ 0, or −1 for a run that never reached the goal"
            )
    late = max(x.max(), y.max()) + 1
    x, y = np.where(x < 0, late, x), np.where(y < 0, late, y)
    wins, losses = int((x < y).sum()), int((x > y).sum())
    median = float(np.median(y - x))
    return PairedComparison(
        Interval(median, math.nan, math.nan, "median over seeds (no interval)"),
        {SIGN: _sign_p(wins, losses)},
        wins,
        losses,
        len(x) - wins - losses,
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


# ========================================================== deprecated aliases (for one version)
def _deprecated(old: str, new: str) -> None:
    warnings.warn(
        f"himit_torch.statistics.{old} is deprecated; use {new}", DeprecationWarning, stacklevel=3
    )


def mean_half_width(
    values: Iterable[float | None], level: float = 0.95
) -> tuple[float, float, int]:
    """Deprecated: :func:`t_interval` (``(estimate, half_width, n)`` of the finite values;
    ``(nan, nan, 0)`` for none)."""
    _deprecated("mean_half_width", "t_interval(values).half_width")
    v = [x for x in values if x is not None and math.isfinite(x)]
    if not v:
        return math.nan, math.nan, 0
    ci = t_interval(v, level)
    return ci.estimate, ci.half_width, len(v)


def wilson_interval(k: int, n: int, level: float = 0.95) -> tuple[float, float, float]:
    """Deprecated: :func:`share_interval` (Clopper–Pearson) is the library's share interval;
    this one is still Wilson's score interval, ``(nan, nan, nan)`` for ``n = 0``."""
    _deprecated("wilson_interval", "share_interval")
    if n == 0:
        return math.nan, math.nan, math.nan
    ci = _stats().binomtest(int(k), int(n)).proportion_ci(confidence_level=level, method="wilson")
    return k / n, float(ci.low), float(ci.high)


def paired_difference(
    a: Sequence[float] | np.ndarray, b: Sequence[float] | np.ndarray
) -> tuple[float, float, float]:
    """Deprecated: :func:`paired_comparison` with ``interval="t"`` (``(estimate, half_width,
    Wilcoxon p)``)."""
    _deprecated("paired_difference", 'paired_comparison(a, b, interval="t")')
    c = paired_comparison(a, b, interval="t")
    return c.difference.estimate, c.difference.half_width, c.wilcoxon_p


def paired_t_p(differences: Sequence[float] | np.ndarray) -> float:
    """Deprecated: :func:`paired_comparison`'s ``t_p`` (here on the differences against 0)."""
    _deprecated("paired_t_p", "paired_comparison(a, b).t_p")
    d = np.asarray(differences, dtype=float)
    return paired_comparison(d, np.zeros_like(d), interval="t").t_p if d.size >= 2 else 1.0
