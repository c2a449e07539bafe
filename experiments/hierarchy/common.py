"""What the hierarchy study's analysis scripts share: the worlds and schedules, the per-run
endpoints, the paired comparison of two cells and how a test is shown (PROTOCOL.md)."""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from himit_torch.statistics import (
    first_goal_sign_test,
    first_goal_survival,
    holm,
    paired_comparison,
)

HERE = Path(__file__).resolve().parent
#: The worlds of the runs: sweep base → (label, budget in steps).
WORLDS = {
    "exp2": ("exp2, 40×40", 200_000),
    "exp1": ("exp1, 80×80", 300_000),
    "exp3": ("exp3, 120×120", 130_000),
}
#: Schedule presets, in the order the tables show them.
SCHEDULES = {"paper": "ε per decision (paper)", "explore-goals": "ε held until 10 goals"}
ENDPOINTS = {
    "greedy": "greedy policy at the end, % of the mentor's rate",
    "first_goal": "first goal (sign test on who reached it first)",
    "goals": "goals over the whole run",
}
#: Eq. 2 and eq. 1 by agent.
METHODS = {"eq. 2": "imitation", "eq. 1": "imitation_primitives"}


@dataclass
class Test:
    family: str
    name: str
    world: str
    condition: str
    schedule: str
    a: str
    b: str
    endpoint: str
    difference: float
    low: float
    high: float
    p: float
    wins: int
    losses: int
    p_holm: float = math.nan


def load_runs(path: Path) -> list[dict]:
    with path.open() as f:
        return list(csv.DictReader(f))


def values(cell: dict, endpoint: str) -> np.ndarray:
    seeds = sorted(cell)
    if endpoint == "greedy":
        return np.array([float(cell[s]["greedy_percent_of_mentor"]) for s in seeds])
    if endpoint == "goals":
        return np.array([float(cell[s]["total_goals"]) for s in seeds])
    return np.array([int(float(cell[s]["first_goal_step"])) for s in seeds])


def compare(a: dict, b: dict, endpoint: str) -> tuple[float, float, float, float, int, int]:
    if sorted(a) != sorted(b):
        raise ValueError("the cells' seeds differ: the comparison is paired by seed")
    return compare_values(values(a, endpoint), values(b, endpoint), endpoint)


def compare_values(a, b, endpoint: str) -> tuple[float, float, float, float, int, int]:
    """``a − b`` paired by position on ``endpoint``: (difference, low, high, p, wins, losses);
    the first goal by the sign test (no interval), the others by the paired comparison's t."""
    if endpoint == "first_goal":
        r = first_goal_sign_test(a, b)
        return r.difference.estimate, math.nan, math.nan, r.sign_p, r.wins, r.losses
    r = paired_comparison(a, b)
    return r.difference.estimate, r.difference.low, r.difference.high, r.t_p, r.wins, r.losses


def fmt_interval(iv) -> str:
    return f"{iv.estimate:.1f} [{iv.low:.1f}, {iv.high:.1f}]"


def km_text(cell: dict, budget: int) -> str:
    s = first_goal_survival(values(cell, "first_goal"), budget)
    median = "never" if math.isinf(s.median.estimate) else f"{s.median.estimate / 1000:.1f}k"
    return median + (f"; {s.never}/{s.runs} never" if s.never else "")


def verdict(t: Test) -> str:
    if math.isnan(t.p_holm):
        return "(outside the family)"
    if t.p_holm < 0.05:
        return "**better**" if t.difference > 0 else "**worse**"
    return "n.s."


def show_test(t: Test) -> str:
    if t.endpoint in ("first_goal", "first opening"):
        when = "sooner" if t.difference >= 0 else "later"
        diff = f"median {abs(t.difference) / 1000:.1f}k steps {when}; {t.wins}–{t.losses}"
    elif t.endpoint == "value gap":
        diff = f"{t.difference:+.4f} [{t.low:+.4f}, {t.high:+.4f}]; {t.wins}–{t.losses}"
    else:
        diff = f"{t.difference:+.1f} [{t.low:+.1f}, {t.high:+.1f}]; {t.wins}–{t.losses}"
    p_holm = "" if math.isnan(t.p_holm) else f"{t.p_holm:.3g}"
    return f"{diff} | {t.p:.3g} | {p_holm} | {verdict(t)}"


def adjust(tests: list[Test]) -> list[Test]:
    """Holm's correction over ``tests`` (one family), in place; returns them."""
    for t, p in zip(tests, holm([t.p for t in tests])):
        t.p_holm = p
    return tests


def cells_by(rows: list[dict], key) -> dict:
    """``key(row)`` → {seed: run} over ``rows`` (rows whose key is ``None`` left out)."""
    cells: dict = {}
    for r in rows:
        k = key(r)
        if k is not None:
            cells.setdefault(k, {})[int(r["seed"])] = r
    return cells


def paired_tests(family: str, pairs, cells: dict, world: str = "", condition: str = "") -> list:
    """``Test`` rows of a family: for each ``(name, schedule, a, b)`` of ``pairs`` (``a``, ``b``
    keys of ``cells``), a − b on every endpoint."""
    out = []
    for name, schedule, a, b in pairs:
        for e in ENDPOINTS:
            d, lo, hi, p, w, l_ = compare(cells[a], cells[b], e)
            out.append(Test(family, name, world, condition, schedule, str(a), str(b), e, d, lo,
                            hi, p, w, l_))  # fmt: skip
    return out


def tests_table(tests: list[Test], title: str) -> list[str]:
    """A family's tests as a markdown table under ``title``."""
    lines = [
        f"### {title}",
        "",
        "Each row: a − b paired by seed (mean difference [95 % BCa], wins–losses of a), the "
        "paired t-test's p (greedy, goals) or the sign test's (first goal), Holm's p.",
        "",
        "| comparison | world | schedule | endpoint | difference | p | Holm p | |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for t in tests:
        world = WORLDS[t.world][0] if t.world in WORLDS else t.world
        lines.append(
            f"| {t.name} | {world} | {SCHEDULES[t.schedule]} | {t.endpoint} | {show_test(t)} |"
        )
    return lines + [""]


def distinct_comparisons(tests: list[Test]) -> tuple[list[Test], list[tuple]]:
    """``tests`` without the comparisons that repeat an earlier one, and the keys (name, world,
    condition, schedule) of those left out. Two comparisons are the same pair of runs when they
    are on the same world and schedule and every endpoint's test has the same numbers (the
    difference, its interval, p and the seeds won and lost): a feasibility cell whose runs
    feasibility never changed, or a cell of one part that is another part's cell. Counting such a
    pair twice would count one result twice."""
    by: dict = {}
    for t in tests:
        by.setdefault((t.name, t.world, t.condition, t.schedule), []).append(t)
    seen: set = set()
    kept: list[Test] = []
    repeats: list[tuple] = []
    for key, ts in by.items():
        numbers = tuple(
            sorted((t.endpoint, t.difference, t.low, t.high, t.p, t.wins, t.losses) for t in ts)
        )
        identity = (key[1], key[3], numbers)
        if identity in seen:
            repeats.append(key)
            continue
        seen.add(identity)
        kept += ts
    return kept, repeats


def budget_by_rule(first_goals, step: int = 10_000) -> int | None:
    """A MiniGrid task's budget by the protocol's rule (amendment "Q1 on MiniGrid, and F"): the
    least multiple of ``step`` at which at least half of the held-out runs have reached the goal,
    from each run's first-goal step (``None`` or negative: never). ``None`` where fewer than half
    reached it at all (the run's cap is then too short)."""
    reached = sorted(s for s in first_goals if s is not None and s >= 0)
    needed = math.ceil(len(first_goals) / 2)
    if needed == 0 or len(reached) < needed:
        return None
    return max(step, math.ceil(reached[needed - 1] / step) * step)
