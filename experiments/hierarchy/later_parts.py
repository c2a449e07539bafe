"""H4–H6 of the hierarchy study (PROTOCOL.md, amendments of 2026-11-27): several mentors, the
largest world, and where options should carry over. Cells from the sweep records, the declared
tests with Holm's correction per family, the page's sections and one figure."""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from common import (
    METHODS,
    SCHEDULES,
    WORLDS,
    Test,
    adjust,
    cells_by,
    fmt_interval,
    km_text,
    load_runs,
    paired_tests,
    tests_table,
    values,
)
from scipy.stats import ttest_rel

from himit_torch.statistics import bca_interval, paired_comparison

#: H4's worlds, poor mentors and mentor cells (in the tables' order).
H4_WORLDS = ("exp2", "exp1")
H4_KINDS = ("noisy", "detour")
H4_CELLS = ("good", "noisy", "detour", "good + noisy", "good + detour")
#: H6c's agents: label → agent.
H6C_AGENTS = {
    "eq. 2, options only": "imitation_extended",
    "options only, no mentor": "options_extended",
    "eq. 1": "imitation_primitives",
}
H6C_CELLS = {"trial": "options_only_exp1", "trial + feasibility": "options_only_feasibility_exp1"}
#: The sweeps each part reads.
SWEEPS = {
    "H4": tuple(
        f"{s}_{w}" for w in H4_WORLDS for s in ("mentors_alone", "detour_alone", "mentors")
    ),
    "H5": ("largest_exp3",),
    "H6": ("partial_exp1", "other_goal_exp1", *H6C_CELLS.values()),
}
_METHOD_OF = {agent: label for label, agent in METHODS.items()}


def _rows(results: Path, part: str) -> list[dict] | None:
    paths = [results / s / "runs.csv" for s in SWEEPS[part]]
    if not all(p.exists() for p in paths):
        return None
    return [r for p in paths for r in load_runs(p)]


# ------------------------------------------------------------------------------------- H4
def h4_cells(results: Path) -> dict:
    """(world, schedule, mentor cell, method) → {seed: run}; empty if a record is absent."""
    rows = _rows(results, "H4")
    if rows is None:
        return {}

    def key(r):
        sweep, method = r["sweep"], _METHOD_OF.get(r["agent"])
        world = sweep.rsplit("_", 1)[1]
        if sweep.startswith("mentors_alone"):
            cell = "good" if float(r["mentor_noise"]) == 0 else "noisy"
        elif sweep.startswith("detour_alone"):
            cell = "detour"
        else:
            cell = f"good + {r['second_mentor']}"
        return (world, r["preset"], cell, method) if method else None

    return cells_by(rows, key)


def dragged_tests(cells: dict) -> list[Test]:
    """H4a: one-sided paired t-tests of (good + poor) − good alone on the greedy policy
    (alternative: less), Holm over the 16."""
    tests = []
    for w in H4_WORLDS:
        for schedule in SCHEDULES:
            for method in METHODS:
                for kind in H4_KINDS:
                    a, b = (
                        cells[w, schedule, f"good + {kind}", method],
                        cells[w, schedule, "good", method],
                    )
                    va, vb = values(a, "greedy"), values(b, "greedy")
                    r = paired_comparison(va, vb)
                    p = float(ttest_rel(va, vb, alternative="less").pvalue)
                    # (no spread in the differences, all zero: no sign of a drag)
                    p = 1.0 if math.isnan(p) else p
                    tests.append(Test("H4a", f"{method}: good + {kind} − good", w, "", schedule,
                                      f"good + {kind}", "good", "greedy", r.difference.estimate,
                                      r.difference.low, r.difference.high, p, r.wins,
                                      r.losses))  # fmt: skip
    return adjust(tests)


def h4_tests(cells: dict) -> list[Test]:
    """H4's two-sided family: pairs against each mentor alone, and eq. 2 − eq. 1 per cell."""
    tests = []
    for w in H4_WORLDS:
        pairs = []
        for schedule in SCHEDULES:
            for method in METHODS:
                for kind in H4_KINDS:
                    pair = (w, schedule, f"good + {kind}", method)
                    for alone in ("good", kind):
                        pairs.append((f"{method}: good + {kind} − {alone}", schedule, pair,
                                      (w, schedule, alone, method)))  # fmt: skip
            for cell in H4_CELLS:
                pairs.append((f"{cell}: eq. 2 − eq. 1", schedule, (w, schedule, cell, "eq. 2"),
                              (w, schedule, cell, "eq. 1")))  # fmt: skip
        tests += paired_tests("H4", pairs, cells, world=w)
    return adjust(tests)


def _cell_rows(cells, keys, budget) -> list[str]:
    lines = []
    for label, key in keys:
        c = cells[key]
        lines.append(
            f"| {label} | {fmt_interval(bca_interval(values(c, 'greedy')))} | "
            f"{km_text(c, budget)} | {bca_interval(values(c, 'goals')).estimate:.0f} |"
        )
    return lines


_CELL_HEADER = [
    "| cell | greedy, % of mentor | first goal | goals |",
    "|---|---|---|---|",
]
_CELL_NOTE = (
    "Greedy policy at the end (% of the mentor's rate: mean of 20 seeds [95 % BCa interval of "
    "the mean]); first goal (Kaplan–Meier median, with the runs that never found it); goals "
    "over the whole run (mean)."
)


def h4_lines(cells: dict, dragged: list[Test], tests: list[Test]) -> list[str]:
    lines = [
        "## H4, several mentors",
        "",
        "The good mentor (the paper's), a noisy one (erring with probability 0.5) and one taking "
        "a needless detour, each alone and the good one with each poor one "
        "(`LearnerConfig.mentors = 2`: eq. 2 takes the larger mentor term). " + _CELL_NOTE,
        "",
    ]
    for w in H4_WORLDS:
        for schedule, title in SCHEDULES.items():
            lines += [f"**{WORLDS[w][0]}, {title}**", "", *_CELL_HEADER]
            keys = [(f"{m}, {cell}", (w, schedule, cell, m)) for m in METHODS for cell in H4_CELLS]
            lines += _cell_rows(cells, keys, WORLDS[w][1]) + [""]
    lines += [
        "### H4a: does a poor second mentor drag the learner below the good mentor alone?",
        "",
        "One-sided paired t-test of (good + poor) − good alone on the greedy policy "
        "(alternative: less), Holm over these 16; the difference with its 95 % BCa interval.",
        "",
        "| comparison | world | schedule | difference | one-sided p | Holm p | dragged |",
        "|---|---|---|---|---|---|---|",
    ]
    for t in dragged:
        lines.append(
            f"| {t.name} | {WORLDS[t.world][0]} | {SCHEDULES[t.schedule]} | "
            f"{t.difference:+.1f} [{t.low:+.1f}, {t.high:+.1f}]; {t.wins}–{t.losses} | "
            f"{t.p:.3g} | {t.p_holm:.3g} | {'**yes**' if t.p_holm < 0.05 else 'no'} |"
        )
    lines.append("")
    return lines + tests_table(tests, "Paired tests (family H4: Holm over its 156 p-values)")


def h4_answer(dragged: list[Test], tests: list[Test]) -> list[str]:
    n_dragged = sum(t.p_holm < 0.05 for t in dragged)
    lifted = [t for t in tests if t.endpoint == "greedy" and "eq. 2 − eq. 1" not in t.name
              and not t.name.endswith("− good")]  # fmt: skip
    better = sum(t.p_holm < 0.05 and t.difference > 0 for t in lifted)
    diffs = [t.difference for t in dragged]
    slower = [t for t in tests if t.endpoint == "goals" and t.name.endswith("− good")]
    n_slower = sum(t.p_holm < 0.05 and t.difference < 0 for t in slower)
    flat = [t for t in tests if "eq. 2 − eq. 1" in t.name]
    helps, worse = hierarchy_verdicts(flat)
    cells = {(t.name, t.world, t.condition, t.schedule) for t in flat}
    return [
        f"- **H4, several mentors: a poor second mentor dragged the learner below the good "
        f"mentor alone in {n_dragged} of {len(dragged)}** world × schedule × method × poor-mentor "
        f"conditions (one-sided, Holm); (good + poor) − good alone on the greedy policy ranged "
        f"from {min(diffs):+.1f} to {max(diffs):+.1f} points ({sum(d < 0 for d in diffs)} of "
        f"{len(diffs)} below 0). On goals over the run (learning speed) it is significantly "
        f"lower in {n_slower} of {len(slower)} (family H4). The good mentor lifted the "
        f"learner above the poor mentor alone in {better} of {len(lifted)} (Holm, greedy "
        f"policy). Hierarchy helps (eq. 2 − eq. 1 by the protocol's rule) in {len(helps)} of "
        f"{len(cells)} mentor cells; eq. 2 is significantly worse "
        f"on the greedy policy in {len(worse)}."
    ]


# ------------------------------------------------------------------------------------- H5
def h5_cells(results: Path) -> dict:
    """(schedule, trial, method) → {seed: run}; empty if the record is absent."""
    rows = _rows(results, "H5")
    if rows is None:
        return {}
    return cells_by(
        rows,
        lambda r: (
            (r["preset"], r["learner.mentor_trial"] == "True", _METHOD_OF[r["agent"]])
            if r["agent"] in _METHOD_OF
            else None
        ),
    )


def h5_tests(cells: dict) -> list[Test]:
    pairs = []
    for schedule in SCHEDULES:
        for method in METHODS:
            pairs.append((f"{method}: trial − off", schedule, (schedule, True, method),
                          (schedule, False, method)))  # fmt: skip
        for trial in (False, True):
            label = "trial" if trial else "off"
            pairs.append((f"{label}: eq. 2 − eq. 1", schedule, (schedule, trial, "eq. 2"),
                          (schedule, trial, "eq. 1")))  # fmt: skip
    return adjust(paired_tests("H5", pairs, cells, world="exp3"))


def h5_lines(cells: dict, tests: list[Test]) -> list[str]:
    lines = ["## H5, the largest world: exp3 at 120×120", "", _CELL_NOTE, ""]
    for schedule, title in SCHEDULES.items():
        lines += [f"**{title}**", "", *_CELL_HEADER]
        keys = [(f"{m}, {'trial' if t else 'off'}", (schedule, t, m))
                for m in METHODS for t in (False, True)]  # fmt: skip
        lines += _cell_rows(cells, keys, WORLDS["exp3"][1]) + [""]
    return lines + tests_table(tests, "Paired tests (family H5: Holm over its 24 p-values)")


def h5_answer(cells: dict, tests: list[Test]) -> list[str]:
    helps, worse = hierarchy_verdicts([t for t in tests if "eq. 2 − eq. 1" in t.name])
    means = {k: values(cells[k], "greedy").mean() for k in cells}
    trial = [t for t in tests if t.name == "eq. 2: trial − off" and t.endpoint == "greedy"]
    return [
        f"- **H5, exp3 at 120×120: hierarchy helps in {len(helps)} of 4** (trial off / on × "
        f"schedule); eq. 2 significantly worse on the greedy policy in {len(worse)}. Greedy "
        "policy (% of the mentor's rate), paper ε / held ε: eq. 2 "
        f"{means['paper', False, 'eq. 2']:.1f} / {means['explore-goals', False, 'eq. 2']:.1f}, "
        f"with trial {means['paper', True, 'eq. 2']:.1f} / "
        f"{means['explore-goals', True, 'eq. 2']:.1f}; eq. 1 "
        f"{means['paper', False, 'eq. 1']:.1f} / {means['explore-goals', False, 'eq. 1']:.1f}. "
        "Trial changes eq. 2 significantly under "
        f"{sum(t.p_holm < 0.05 for t in trial)} of 2 schedules."
    ]


# ------------------------------------------------------------------------------------- H6
def h6_cells(results: Path) -> dict:
    """(condition, schedule, method) → {seed: run}; empty if a record is absent. Conditions:
    ``partial``, ``other goal``, and the H6c cells (``trial``, ``trial + feasibility``)."""
    rows = _rows(results, "H6")
    if rows is None:
        return {}
    h6c = {sweep: cell for cell, sweep in H6C_CELLS.items()}
    agents_c = {agent: label for label, agent in H6C_AGENTS.items()}

    def key(r):
        sweep = r["sweep"]
        if sweep in h6c:
            label = agents_c.get(r["agent"])
            return (h6c[sweep], r["preset"], label) if label else None
        condition = "partial" if sweep.startswith("partial") else "other goal"
        method = _METHOD_OF.get(r["agent"])
        return (condition, r["preset"], method) if method else None

    return cells_by(rows, key)


def h6_tests(cells: dict) -> list[Test]:
    pairs = []
    ext, plain, flat = H6C_AGENTS
    for schedule in SCHEDULES:
        for condition in ("partial", "other goal"):
            pairs.append((f"{condition}: eq. 2 − eq. 1", schedule, (condition, schedule, "eq. 2"),
                          (condition, schedule, "eq. 1")))  # fmt: skip
        for cell in H6C_CELLS:
            for other in (flat, plain):
                pairs.append((f"options only, {cell}: {ext} − {other}", schedule,
                              (cell, schedule, ext), (cell, schedule, other)))  # fmt: skip
        pairs.append((f"{ext}: trial + feasibility − trial", schedule,
                      ("trial + feasibility", schedule, ext), ("trial", schedule, ext)))  # fmt: skip
    return adjust(paired_tests("H6", pairs, cells, world="exp1"))


def h6_lines(cells: dict, tests: list[Test]) -> list[str]:
    lines = [
        "## H6, where options should carry over (exp1, 80×80)",
        "",
        "Demonstrations of the first half of each route (`mentor_coverage = 0.5`); a mentor "
        "demonstrating its walk to the top-right corner, not the learner's goal (`mentor_goal`);"
        " learners acting through options only (`imitation_extended`, `options_extended`). "
        "Every imitator with trial of untried options. " + _CELL_NOTE,
        "",
    ]
    for schedule, title in SCHEDULES.items():
        lines += [f"**{title}**", "", *_CELL_HEADER]
        keys = [(f"{cond}: {m}", (cond, schedule, m))
                for cond in ("partial", "other goal") for m in METHODS]  # fmt: skip
        keys += [(f"options only, {cell}: {a}", (cell, schedule, a))
                 for cell in H6C_CELLS for a in H6C_AGENTS]  # fmt: skip
        lines += _cell_rows(cells, keys, WORLDS["exp1"][1]) + [""]
    return lines + tests_table(tests, "Paired tests (family H6: Holm over its 42 p-values)")


def h6_answer(cells: dict, tests: list[Test]) -> list[str]:
    ext = next(iter(H6C_AGENTS))

    def verdicts(prefix):
        return hierarchy_verdicts([t for t in tests if t.name.startswith(prefix)
                                   and (t.name.endswith("− eq. 1"))])  # fmt: skip

    out = []
    for cond in ("partial", "other goal"):
        helps, worse = verdicts(f"{cond}:")
        out.append(f"{cond}: helps in {len(helps)} of 2 schedules, worse in {len(worse)}")
    helps, worse = verdicts("options only")
    out.append(f"options only: helps in {len(helps)} of 4, worse in {len(worse)}")
    watched = [t for t in tests if t.name.endswith("− options only, no mentor")
               and t.endpoint == "greedy"]  # fmt: skip
    feas = [t for t in tests if "feasibility − trial" in t.name]
    same = all(
        values(cells["trial", s, ext], e).tolist()
        == values(cells["trial + feasibility", s, ext], e).tolist()
        for s in SCHEDULES
        for e in ("greedy", "goals", "first_goal")
    )
    return [
        "- **H6, where options should carry over (exp1):** hierarchy (eq. 2 − eq. 1 by the "
        "protocol's rule) — " + "; ".join(out) + ". Watching the mentor changed the options-only "
        "learner's greedy policy significantly in "
        f"{sum(t.p_holm < 0.05 for t in watched)} of {len(watched)} cells × schedules. "
        + (
            "Feasibility testing changed no options-only run."
            if same
            else "Feasibility testing changed the options-only runs: significantly on "
            f"{sum(t.p_holm < 0.05 for t in feas)} of {len(feas)} endpoint × schedule tests."
        )
    ]


# --------------------------------------------------------------------------------- shared
def hierarchy_verdicts(tests: list[Test]) -> tuple[list, list]:
    """The conditions (name, world, condition, schedule) of hierarchical − flat ``tests`` where the
    hierarchy helps by PROTOCOL.md's rule (significantly better on the greedy policy or goals,
    not significantly worse on the greedy policy), and where it is significantly worse on the
    greedy policy."""
    by: dict = {}
    for t in tests:
        by.setdefault((t.name, t.world, t.condition, t.schedule), {})[t.endpoint] = t
    helps, worse = [], []
    for key, ts in by.items():
        better = any(ts[e].p_holm < 0.05 and ts[e].difference > 0 for e in ("greedy", "goals"))
        bad = ts["greedy"].p_holm < 0.05 and ts["greedy"].difference < 0
        if bad:
            worse.append(key)
        elif better:
            helps.append(key)
    return helps, worse


def figure(h4: dict, h5: dict, h6: dict, out: Path) -> None:
    """Greedy policy at the end (mean, 95 % BCa) of every H4–H6 cell, eq. 2 against eq. 1."""
    panels = []
    if h4:
        for w in H4_WORLDS:
            panels.append((f"H4, {WORLDS[w][0]}", [
                (cell, {m: (w, s, cell, m) for m in METHODS}) for cell in H4_CELLS
                for s in ("paper",)
            ]))  # fmt: skip
    if h5:
        panels.append(("H5, exp3 at 120×120", [
            ("off" if not t else "trial", {m: ("paper", t, m) for m in METHODS})
            for t in (False, True)
        ]))  # fmt: skip
    if h6:
        groups = [(c, {m: (c, "paper", m) for m in METHODS}) for c in ("partial", "other goal")]
        groups += [(f"options only\n{cell}", {"eq. 2": (cell, "paper", next(iter(H6C_AGENTS))),
                                              "eq. 1": (cell, "paper", "eq. 1")})
                   for cell in H6C_CELLS]  # fmt: skip
        panels.append(("H6, exp1", groups))
    if not panels:
        return
    cells = {**h4, **h5, **h6}
    fig, axes = plt.subplots(1, len(panels), figsize=(5 * len(panels), 4), squeeze=False)
    colours = {"eq. 2": "#08519c", "eq. 1": "#a63603"}
    for ax, (title, groups) in zip(axes[0], panels):
        for i, method in enumerate(METHODS):
            ivs = [bca_interval(values(cells[g[method]], "greedy")) for _, g in groups]
            x = np.arange(len(groups)) + (i - 0.5) * 0.35
            ax.bar(x, [iv.estimate for iv in ivs], 0.35, color=colours[method], label=method,
                   yerr=[[iv.estimate - iv.low for iv in ivs], [iv.high - iv.estimate for iv in ivs]],
                   capsize=2)  # fmt: skip
        ax.set_xticks(np.arange(len(groups)))
        ax.set_xticklabels([label for label, _ in groups], fontsize=7)
        ax.set_ylim(0, 115)
        ax.set_title(title)
        ax.set_ylabel("greedy policy at the end, % of the mentor's rate")
    axes[0][0].legend(loc="lower left", fontsize=8)
    fig.suptitle("H4–H6 under the paper's ε (20 seeds, mean with 95 % BCa; eq. 2 in the H6 "
                 "options-only groups: imitation_extended)", fontsize=9)  # fmt: skip
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)
