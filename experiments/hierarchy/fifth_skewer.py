"""Q4, the fifth skewer (PROTOCOL.md, amendment "Q4 (the fifth skewer)"): the records of
``q4_fifth_skewer.py``, Q4's endpoint, its family of tests and its section of the round's page
(``where_pays.py`` calls :func:`q4_section`).

Q4's endpoint: a run's greedy plan opens the 5-skewer box and fits skewer 5 into the
organisation its seed's mentor showed (:func:`follows_on_skewer_5`); shares compared by
Fisher's exact test. Beside it the round's endpoints 1–3 (the value gap, the first opening,
openings in the first quarter), with Q1's five contrasts in which eq. 2 with the skewer
routines takes eq. 2's place and eq. 2 with the given options eq. 1's.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
from common import SCHEDULES, Test, compare_values
from scipy.stats import fisher_exact

from himit_torch.statistics import bca_interval, first_goal_survival, paired_comparison

#: The cells (``q4_fifth_skewer.py``'s) → their labels on the page.
CELLS = {
    "relative_eq2": "eq. 2, skewer routines",
    "relative_options": "skewer routines only",
    "given_eq2": "eq. 2, given options",
    "given_options": "given options only",
}
R2, R0, G2, G0 = CELLS
#: Each cell's no-mentor control.
CONTROL = {R2: R0, G2: G0}
WORLD = "puzzle box, 5 skewers"
ENDPOINTS = {
    "value_gap": "value gap V*(start) − V^π(start) (lower is better)",
    "first_opening": "first opening",
    "goals_q1": "openings in the first quarter of the budget",
}
FOLLOWS = "follows the watched organisation on skewer 5"
EFFECT = "the routines' effect on imitation (the two imitation effects' difference)"
#: Q1's five contrasts, the routines in eq. 2's place and the given options in eq. 1's:
#: name → (a, b) of per-cell arrays; a − b paired by seed.
CONTRASTS = {
    "the routines' own effect (routines only − given options only)": (
        lambda v: v[R0],
        lambda v: v[G0],
    ),
    "imitation's effect with routines (eq. 2 − routines only)": (
        lambda v: v[R2],
        lambda v: v[R0],
    ),
    "imitation's effect with the given options (eq. 2 − given options only)": (
        lambda v: v[G2],
        lambda v: v[G0],
    ),
    EFFECT: (lambda v: v[R2] - v[R0], lambda v: v[G2] - v[G0]),
    "eq. 2 with routines − eq. 2 with the given options": (lambda v: v[R2], lambda v: v[G2]),
}
#: Fisher's exact tests on Q4's endpoint: name → (a, b).
FISHER = {
    "eq. 2: routines against the given options": (R2, G2),
    "imitation's, with routines (eq. 2 against routines only)": (R2, R0),
    "imitation's, with the given options (eq. 2 against given options only)": (G2, G0),
}


def follows_on_skewer_5(run: dict) -> bool:
    """Q4's endpoint for one run's record: its greedy plan opens the box and the last skewer's
    score for the organisation its seed's mentor showed (``watched``, or for a control the one
    its seed's imitator watched) is 1 — skewer by skewer: that skewer's steps in one unbroken
    run; step by step: each of its steps after the other skewers' lower steps and before their
    higher ones (``organisation_scores(…, focus)``)."""
    score = (run.get("focus_scores") or {}).get(run["watched"])
    return bool(run["opens"]) and score is not None and score == 1.0


def follows_overall(run: dict) -> bool:
    """The study's (c) endpoint: the greedy plan follows the watched organisation over every
    skewer."""
    return run["organisation"] == run["watched"]


def goals_in_quarter(run: dict, steps: int, window: int) -> int:
    """Openings in the windows that end within the first quarter of ``steps``."""
    return sum(run["window_openings"][: (steps // 4) // window])


def by_organisation(record: dict) -> str:
    """``"x/n · y/m"``: a cell's runs fitting skewer 5 among its skewer-by-skewer seeds and its
    step-by-step seeds."""
    runs = record["runs"]
    parts = []
    for organisation in ("skewer", "step"):
        mine = [r for r in runs if r["watched"] == organisation]
        parts.append(f"{sum(follows_on_skewer_5(r) for r in mine)}/{len(mine)}")
    return " · ".join(parts)


def load_q4(results: Path) -> tuple[dict[str, dict[str, dict]], list[str]]:
    """Per schedule whose four cells are all recorded, cell → record; and the records absent."""
    cells: dict[str, dict[str, dict]] = {}
    missing = []
    for schedule in SCHEDULES:
        found = {}
        for cell in CELLS:
            path = results / f"q4_{schedule}_{cell}.json"
            if path.exists():
                found[cell] = json.loads(path.read_text())
            else:
                missing.append(path.stem)
        if len(found) == len(CELLS):
            seeds = {c: [r["seed"] for r in rec["runs"]] for c, rec in found.items()}
            if len({tuple(s) for s in seeds.values()}) != 1:
                raise ValueError(f"Q4 {schedule}: the cells' seeds differ: {seeds}")
            cells[schedule] = found
    return cells, missing


def endpoint_arrays(cells: dict[str, dict]) -> dict[str, dict[str, np.ndarray]]:
    """Endpoint → cell → per-seed values (the first opening −1 for never)."""
    out: dict[str, dict[str, np.ndarray]] = {e: {} for e in ENDPOINTS}
    for cell, record in cells.items():
        runs = record["runs"]
        out["value_gap"][cell] = np.array([float(r["value_gap"]) for r in runs])
        out["first_opening"][cell] = np.array([int(r["first_opening"]) for r in runs])
        out["goals_q1"][cell] = np.array(
            [goals_in_quarter(r, record["steps"], record["window"]) for r in runs], dtype=float
        )
    return out


def speed_up(first: dict[str, np.ndarray], cell: str, budget: int) -> np.ndarray:
    """Per seed, how many steps sooner ``cell`` opened the box than its no-mentor control,
    "never" counted at the budget."""
    censored = {c: np.where(x < 0, budget, x) for c, x in first.items()}
    return censored[CONTROL[cell]] - censored[cell]


def fisher_test(name: str, schedule: str, a: list[bool], b: list[bool]) -> Test:
    """Fisher's exact test (two-sided) of two shares; ``difference`` in points of %, ``wins``
    and ``losses`` the runs of ``a`` and of ``b`` that follow."""
    ya, yb = sum(a), sum(b)
    _, p = fisher_exact([[ya, len(a) - ya], [yb, len(b) - yb]])
    difference = 100.0 * (ya / len(a) - yb / len(b))
    return Test("Q4", name, WORLD, FOLLOWS, schedule, f"{ya} of {len(a)}", f"{yb} of {len(b)}",
                "follows", difference, math.nan, math.nan, float(p), ya, yb)  # fmt: skip


def q4_tests(schedule: str, cells: dict[str, dict]) -> list[Test]:
    """One schedule's 18 tests of family Q4, unadjusted: 3 Fisher's, 5 contrasts × 3 endpoints."""
    follows = {c: [follows_on_skewer_5(r) for r in rec["runs"]] for c, rec in cells.items()}
    out = [fisher_test(name, schedule, follows[a], follows[b]) for name, (a, b) in FISHER.items()]
    values = endpoint_arrays(cells)
    budget = int(cells[R2]["steps"])
    for name, (a, b) in CONTRASTS.items():
        for endpoint in ENDPOINTS:
            v = values[endpoint]
            if endpoint == "first_opening" and name == EFFECT:
                first = values["first_opening"]
                r = paired_comparison(speed_up(first, R2, budget), speed_up(first, G2, budget))
                result = (r.difference.estimate, r.difference.low, r.difference.high, r.sign_p,
                          r.wins, r.losses)  # fmt: skip
            else:
                kind = "first_goal" if endpoint == "first_opening" else endpoint
                result = compare_values(a(v), b(v), kind)
            out.append(Test("Q4", name, WORLD, "", schedule, "", "", endpoint, *result))
    return out


def _verdict(t: Test) -> str:
    """Better / worse for ``a`` after Holm, by the endpoint's direction (a gap: lower)."""
    if math.isnan(t.p_holm) or t.p_holm >= 0.05:
        return "n.s."
    better = t.difference < 0 if t.endpoint == "value_gap" else t.difference > 0
    return "**better**" if better else "**worse**"


def _shown(t: Test) -> str:
    if t.endpoint == "follows":
        return f"{t.a} against {t.b} ({t.difference:+.0f} points)"
    if t.endpoint == "first_opening":
        if t.name == EFFECT:
            return f"mean {t.difference / 1000:+.1f}k steps more speed-up; {t.wins}–{t.losses}"
        when = "sooner" if t.difference >= 0 else "later"
        return f"median {abs(t.difference) / 1000:.1f}k steps {when}; {t.wins}–{t.losses}"
    if t.endpoint == "value_gap":
        return f"{t.difference:+.4f} [{t.low:+.4f}, {t.high:+.4f}]; {t.wins}–{t.losses}"
    return f"{t.difference:+.1f} [{t.low:+.1f}, {t.high:+.1f}]; {t.wins}–{t.losses}"


def learners_table(schedule: str, cells: dict[str, dict]) -> list[str]:
    """One schedule's learners: Q4's endpoint (by organisation watched), the study's (c)
    endpoint, the plans that open, and endpoints 1–3."""
    values = endpoint_arrays(cells)
    lines = [
        f"### {SCHEDULES[schedule]}: the four learners",
        "",
        "Greedy plans read without slips; skewer 5 fitted into the watched organisation (Q4's "
        "endpoint) among the skewer-by-skewer seeds (even) and the step-by-step seeds (odd); "
        "the plan following it over all five skewers (the study's (c) endpoint). Mean of the "
        "seeds [95 % BCa interval]; first opening: Kaplan–Meier median.",
        "",
        "| learner | options | skewer 5 fitted: skewer / step / all | all five skewers | plan opens "
        "| value gap | first opening | openings, first quarter |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for cell, name in CELLS.items():
        record = cells[cell]
        runs = record["runs"]
        survival = first_goal_survival(values["first_opening"][cell], int(record["steps"]))
        median = survival.median.estimate
        first = "never" if not np.isfinite(median) else f"{median / 1000:.1f}k"
        lines.append(
            f"| {name} | {record['runs'][0]['options']}/{record['runs'][1]['options']} "
            f"| {by_organisation(record)} · {sum(map(follows_on_skewer_5, runs))}/{len(runs)} "
            f"| {sum(follows_overall(r) for r in runs)}/{len(runs)} "
            f"| {sum(bool(r['opens']) for r in runs)}/{len(runs)} "
            f"| {bca_interval(values['value_gap'][cell]).format(3)} | {first} "
            f"| {bca_interval(values['goals_q1'][cell]).format(0)} |"
        )
    return lines + [""]


def tests_table(tests: list[Test]) -> list[str]:
    lines = [
        "### Family Q4: the tests",
        "",
        "Fisher's exact test (two-sided) on the runs following the watched organisation on "
        "skewer 5; then a − b paired by seed (mean difference [95 % BCa], seeds a above–below "
        "b), the paired t-test's p (value gap, openings) or the sign test's (first opening); "
        "Holm's p over the family. On the value gap, lower is better.",
        "",
        "| contrast | schedule | endpoint | difference | p | Holm p | |",
        "|---|---|---|---|---|---|---|",
    ]
    for t in tests:
        endpoint = FOLLOWS if t.endpoint == "follows" else ENDPOINTS[t.endpoint]
        lines.append(
            f"| {t.name} | {SCHEDULES[t.schedule]} | {endpoint} | {_shown(t)} | {t.p:.3g} "
            f"| {t.p_holm:.3g} | {_verdict(t)} |"
        )
    return lines + [""]


def study_check(results: Path, cells: dict[str, dict]) -> str:
    """The check the amendment declares: the paper schedule's given-options cells against the
    study's committed ``puzzlebox_trial`` transfer cells, seed by seed ("" where either is
    absent)."""
    path = results / "puzzlebox_trial" / "summary.json"
    if "paper" not in cells or not path.exists():
        return ""
    batches = {b["batch"]: b for b in json.loads(path.read_text())["batches"]}
    keys = ("first_opening", "openings", "greedy_value", "organisation", "subgoals")
    parts = []
    for cell, batch in ((G2, "transfer_any"), (G0, "transfer_options")):
        mine = {r["seed"]: r for r in cells["paper"][cell]["runs"]}
        theirs = {r["seed"]: r for r in batches[batch]["runs"]}
        equal = sum(all(mine[s][k] == theirs[s][k] for k in keys) for s in mine if s in theirs)
        parts.append(f"{CELLS[cell]} {equal} of {len(mine)} seeds equal to `{batch}`")
    return (
        "*Check* (declared): under the paper's ε the given-options cells against the study's "
        "committed `puzzlebox_trial` cells (first opening, openings, greedy value, plan): "
        + "; ".join(parts)
        + "."
    )


def answer_lines(tests: list[Test], cells: dict[str, dict[str, dict]]) -> list[str]:
    """The page's "answers so far" line for Q4, one per schedule run."""
    lines = []
    for schedule, group in cells.items():
        follows = {c: sum(follows_on_skewer_5(r) for r in rec["runs"]) for c, rec in group.items()}
        n = len(group[R2]["runs"])
        (main,) = [t for t in tests if t.schedule == schedule and t.name == list(FISHER)[0]]
        (own,) = [t for t in tests if t.schedule == schedule and t.name == list(FISHER)[1]]
        significant = main.p_holm < 0.05 and main.difference > 0
        lines.append(
            f"- **Q4, the fifth skewer, {SCHEDULES[schedule]}:** eq. 2 with skewer routines "
            "discovered from the mentor's 4-skewer episodes fits skewer 5 into the watched "
            f"organisation in {main.a} greedy plans, eq. 2 with the given options "
            f"in {main.b} (Fisher p = {main.p:.3g}, Holm {main.p_holm:.3g}): "
            + (
                "**significantly more often**."
                if significant
                else "**not significantly more often**"
                + (" (fewer)." if main.difference < 0 else ".")
            )
            + f" Routines without a mentor: {follows[R0]} of {n}; given options without one: "
            f"{follows[G0]} of {n} (eq. 2 with routines against routines only: Holm p = "
            f"{own.p_holm:.3g}). By the organisation watched, skewer by skewer / step by step: "
            + ", ".join(f"{CELLS[c]} {by_organisation(group[c])}" for c in CELLS)
            + "."
        )
    return lines


def family(results: Path) -> tuple[dict[str, dict[str, dict]], list[Test], list[str]]:
    """Q4's cells (per schedule whose four cells are recorded), its family of tests unadjusted
    (the caller applies Holm's correction over it), and the records absent."""
    cells, missing = load_q4(results)
    tests = [t for schedule, group in cells.items() for t in q4_tests(schedule, group)]
    return cells, tests, missing


def section_lines(results: Path, cells: dict[str, dict[str, dict]], tests: list[Test]) -> list[str]:
    """Q4's section of the page, from :func:`family`'s cells and its tests once adjusted."""
    if not cells:
        return []
    any_cells = next(iter(cells.values()))
    record = any_cells[R2]
    lines = [
        "## Q4, the fifth skewer",
        "",
        "Options discovered from watching, expressed relative to the skewer they act on, carried "
        "to a skewer the mentor never touched. Each seed's learner segments its own 20 mentor "
        "episodes on the 4-skewer box where the mentor's hand moves to another skewer and keeps "
        'each segment\'s net change as a routine, "the skewer at hand from level a to b" '
        "(`discover_skewer_routines`): a skewer-by-skewer mentor gives 0 → 4, a step-by-step "
        "one 0 → 1, …, 3 → 4. Each routine becomes an option on each of the 5 skewers, planned "
        "once in the one-skewer view with the learner's power grip and lifted "
        "(`skewer_routine_options`), beside the box's primitives. The mentor's episodes are "
        f'mapped into the {record["skewers"]}-skewer box with `"{record["mapping"]}"` (its '
        "4-skewer box seen in any 4 of the 5 skewers, the fifth at any level). "
        f"{len(record['runs'])} seeds (skewer-by-skewer mentors on even seeds, step by step on "
        f"odd), {record['steps']:,} steps a run, trial on for the imitators; options: the "
        "number of a skewer seed's / a step seed's. Runs at commit "
        + ", ".join(sorted({r["commit"] for g in cells.values() for r in g.values()}))
        + " (the library's code; each record's wall time in it). Run: `python "
        "experiments/hierarchy/q4_fifth_skewer.py`.",
        "",
    ]
    for schedule, group in cells.items():
        lines += learners_table(schedule, group)
    check = study_check(results, cells)
    if check:
        lines += [check, ""]
    lines += tests_table(tests)
    return lines
