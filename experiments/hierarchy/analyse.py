"""The hierarchy study's tables, tests and figure, as PROTOCOL.md declared them.

    python experiments/hierarchy/analyse.py [--results experiments/results/hierarchy]

Reads each part's sweep records (``<results>/<sweep>/runs.csv``); writes
``<results>/results.md``, ``<results>/tests.csv`` and one figure per part. A part whose records
are absent is left out, and the page says so.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import subprocess
from collections import defaultdict
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import later_parts as later  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from common import (  # noqa: E402
    ENDPOINTS,
    HERE,
    SCHEDULES,
    WORLDS,
    Test,
    compare,
    distinct_comparisons,
    fmt_interval,
    km_text,
    load_runs,
    show_test,
    values,
)

from himit_torch.statistics import (  # noqa: E402
    bca_interval,
    first_goal_sign_test,
    holm,
    paired_comparison,
)

#: H1's worlds.
SEGMENT_WORLDS = ("exp2", "exp1")
#: H1's methods: label → (agent, segments).
SEGMENT_METHODS = {
    "eq. 2": ("imitation", False),
    "eq. 2 + segments": ("imitation", True),
    "eq. 1": ("imitation_primitives", False),
    "eq. 1 + segments": ("imitation_primitives", True),
}
#: H1's family: (name, a, b), each a − b.
SEGMENT_TESTS = (
    ("H1b", "eq. 2 + segments", "eq. 2"),
    ("H1c", "eq. 1 + segments", "eq. 1"),
    ("H1d", "eq. 2 + segments", "eq. 1 + segments"),
)
#: Reported beside the family, not in it (PROTOCOL.md: "also reported").
SEGMENT_ALSO = (("H1d′", "eq. 2 + segments", "eq. 1"),)
TARGET = 95.0  # H1a: % of the mentor's rate
#: H3's cells: label → (sweep, the rows' mentor_trial value or None: every row of the sweep).
TRIAL_CELLS = {
    "off": ("trial_exp1", "False"),
    "trial": ("trial_exp1", "True"),
    "trial + feasibility": ("trial_feasibility_exp1", None),
}
TRIAL_AGENTS = {"eq. 2": "imitation", "eq. 1": "imitation_primitives"}
#: H2's cells (``puzzlebox_<cell>/summary.json``), labels.
BOX_CELLS = {"off": "off", "trial": "trial", "trial_feasibility": "trial + feasibility"}


def trial_cells(results: Path) -> dict:
    """(schedule, cell, method) → {seed: run} for H3 (empty if its records are absent)."""
    cells: dict = defaultdict(dict)
    for cell, (sweep, trial) in TRIAL_CELLS.items():
        path = results / sweep / "runs.csv"
        if not path.exists():
            return {}
        for r in load_runs(path):
            if trial is not None and r["learner.mentor_trial"] != trial:
                continue
            for method, agent in TRIAL_AGENTS.items():
                if r["agent"] == agent:
                    cells[r["preset"], cell, method][int(r["seed"])] = r
    return cells


def trial_tests(cells: dict) -> list[Test]:
    tests = []
    for schedule in SCHEDULES:
        pairs = [
            (f"{m}: {c} − off", (c, m), ("off", m))
            for m in TRIAL_AGENTS
            for c in ("trial", "trial + feasibility")
        ] + [(f"{c}: eq. 2 − eq. 1", (c, "eq. 2"), (c, "eq. 1")) for c in TRIAL_CELLS]
        for name, a, b in pairs:
            for e in ENDPOINTS:
                d, lo, hi, p, w, l_ = compare(cells[(schedule, *a)], cells[(schedule, *b)], e)
                tests.append(Test("H3", name, "exp1", "", schedule, " ".join(a), " ".join(b),
                                  e, d, lo, hi, p, w, l_))  # fmt: skip
    for t, p in zip(tests, holm([t.p for t in tests])):
        t.p_holm = p
    return tests


def trial_lines(cells: dict, tests: list[Test]) -> list[str]:
    lines = [
        "## H3, mismatched skills: trial and feasibility on exp1",
        "",
        "exp1 (80×80, 300k steps): the mentor's corner skills are not the learner's. Greedy "
        "policy at the end (% of the mentor's rate, mean [95 % BCa]), first goal (Kaplan–Meier "
        "median), goals over the whole run (mean); 20 seeds per cell.",
        "",
        "| method | cell | schedule | greedy, % of mentor | first goal | goals |",
        "|---|---|---|---|---|---|",
    ]
    for schedule, title in SCHEDULES.items():
        for cell in TRIAL_CELLS:
            for method in TRIAL_AGENTS:
                c = cells[schedule, cell, method]
                lines.append(
                    f"| {method} | {cell} | {title} | "
                    f"{fmt_interval(bca_interval(values(c, 'greedy')))} | "
                    f"{km_text(c, WORLDS['exp1'][1])} | "
                    f"{bca_interval(values(c, 'goals')).estimate:.0f} |"
                )
    lines += [
        "",
        "### Paired tests (family H3: Holm over its 42 p-values)",
        "",
        "| comparison | schedule | endpoint | difference | p | Holm p | |",
        "|---|---|---|---|---|---|---|",
    ]
    for t in tests:
        lines.append(f"| {t.name} | {SCHEDULES[t.schedule]} | {t.endpoint} | {show_test(t)} |")
    return lines + [""]


def box_cells(results: Path) -> dict:
    """cell → batch → {seed: run} for H2 (empty if its records are absent)."""
    out: dict = {}
    for cell in BOX_CELLS:
        path = results / f"puzzlebox_{cell}" / "summary.json"
        if not path.exists():
            return {}
        summary = json.loads(path.read_text())
        out[cell] = {
            b["batch"]: {int(r["seed"]): {**r, "value_star": b["value_star"]} for r in b["runs"]}
            for b in summary["batches"]
        }
    return out


def cells_equal(a: dict, b: dict) -> bool:
    """Whether two batches' runs (seed → run) are the same runs: every recorded endpoint."""
    keys = ("openings", "first_opening", "greedy_value", "stuck_at", "organisation")
    return sorted(a) == sorted(b) and all(a[s].get(k) == b[s].get(k) for s in a for k in keys)


def _fisher(a: int, b: int, n: int) -> float:
    from scipy.stats import fisher_exact

    return float(fisher_exact([[a, n - a], [b, n - b]]).pvalue)


def box_tests(cells: dict) -> list[Test]:
    tests = []
    off = cells["off"]["speed_imitation"]
    seeds = sorted(off)
    n = len(seeds)
    for cell in ("trial", "trial_feasibility"):
        runs = cells[cell]["speed_imitation"]
        for endpoint, count in (
            ("stuck plans", lambda rs: sum(rs[s]["stuck_at"] is not None for s in seeds)),
            ("watched organisation followed",
             lambda rs: sum(rs[s]["organisation"] == rs[s]["watched"] for s in seeds)),
        ):  # fmt: skip
            a, b = count(runs), count(off)
            tests.append(Test("H2", f"{BOX_CELLS[cell]} − off", "puzzlebox", "", "paper",
                              cell, "off", endpoint, a - b, math.nan, math.nan,
                              _fisher(a, b, n), a, b))  # fmt: skip
        gap = [runs[s]["value_star"] - runs[s]["greedy_value"] for s in seeds]
        gap_off = [off[s]["value_star"] - off[s]["greedy_value"] for s in seeds]
        r = paired_comparison(gap, gap_off)
        tests.append(Test("H2", f"{BOX_CELLS[cell]} − off", "puzzlebox", "", "paper", cell,
                          "off", "value gap", r.difference.estimate, r.difference.low,
                          r.difference.high, r.t_p, r.wins, r.losses))  # fmt: skip
        never = 10**9
        first = [runs[s]["first_opening"] if runs[s]["first_opening"] >= 0 else never
                 for s in seeds]  # fmt: skip
        first_off = [off[s]["first_opening"] if off[s]["first_opening"] >= 0 else never
                     for s in seeds]  # fmt: skip
        r = first_goal_sign_test(first, first_off)
        tests.append(Test("H2", f"{BOX_CELLS[cell]} − off", "puzzlebox", "", "paper", cell,
                          "off", "first opening", r.difference.estimate, math.nan, math.nan,
                          r.sign_p, r.wins, r.losses))  # fmt: skip
    for t, p in zip(tests, holm([t.p for t in tests])):
        t.p_holm = p
    return tests


def box_lines(cells: dict, tests: list[Test], committed: Path) -> list[str]:
    lines = [
        "## H2, the puzzle box: trial and feasibility",
        "",
        "The 4-skewer box's speed condition, imitators (eq. 2) watching a mentor of one "
        "organisation per seed (skewer by skewer for even seeds, step by step for odd), 20 "
        "seeds, 100k steps, the paper's ε. Stuck: the greedy plan loops or stops where the run "
        "tried nothing. Value gap: V*(start) − V^π(start) of the frozen greedy policy (0 = "
        "optimal), mean [95 % BCa].",
        "",
        "| cell | stuck plans | watched organisation followed | value gap | first opening "
        "(median) |",
        "|---|---|---|---|---|",
    ]
    for cell, label in BOX_CELLS.items():
        runs = cells[cell]["speed_imitation"]
        seeds = sorted(runs)
        stuck = [s for s in seeds if runs[s]["stuck_at"] is not None]
        follows = sum(runs[s]["organisation"] == runs[s]["watched"] for s in seeds)
        gap = [runs[s]["value_star"] - runs[s]["greedy_value"] for s in seeds]
        first = [runs[s]["first_opening"] for s in seeds if runs[s]["first_opening"] >= 0]
        where = f" (seeds {', '.join(map(str, stuck))})" if stuck else ""
        lines.append(
            f"| {label} | {len(stuck)}/{len(seeds)}{where} | {follows}/{len(seeds)} | "
            f"{bca_interval(gap).format(4)} | {np.median(first):,.0f} |"
        )
    lines += [
        "",
        "### Paired tests (family H2: Holm over its 8 p-values)",
        "",
        "Shares: Fisher's exact test (difference = count − the off count); value gap: paired "
        "t-test (difference [95 % BCa], lower is better; seeds where it is higher – lower); "
        "first opening: sign test (seeds sooner – later).",
        "",
        "| comparison | endpoint | difference | p | Holm p | |",
        "|---|---|---|---|---|---|",
    ]
    for t in tests:
        if t.endpoint in ("stuck plans", "watched organisation followed"):
            diff = f"{t.difference:+.0f} ({t.wins} vs {t.losses})"
            lines.append(f"| {t.name} | {t.endpoint} | {diff} | {t.p:.3g} | {t.p_holm:.3g} | "
                         f"{'**differs**' if t.p_holm < 0.05 else 'n.s.'} |")  # fmt: skip
        else:
            lines.append(f"| {t.name} | {t.endpoint} | {show_test(t)} |")
    # the check: learning unchanged since the committed run (its openings per seed)
    if (committed / "summary.json").exists():
        old = json.loads((committed / "summary.json").read_text())
        old_runs = {b["batch"]: b["runs"] for b in old["batches"]}
        same = all(
            [r["openings"] for r in old_runs[batch]]
            == [cells["off"][batch][int(r["seed"])]["openings"] for r in old_runs[batch]]
            for batch in cells["off"]
            if batch in old_runs
        )
        lines += [
            "",
            f"Check: the **off** run's openings per seed {'equal' if same else '**differ from**'}"
            " the committed puzzle-box run's in every batch they share "
            "(`../puzzlebox/summary.json`).",
        ]
    return lines + [""]


def segment_cells(rows: list[dict]) -> dict:
    """(world, stride, schedule, method) → {seed: run}."""
    cells: dict = defaultdict(dict)
    for r in rows:
        segments = r["learner.mentor_segments"] == "True"
        for method, (agent, seg) in SEGMENT_METHODS.items():
            if r["agent"] == agent and segments == seg:
                key = (r["sweep"].split("_")[-1], int(r["observation_stride"]), r["preset"], method)
                cells[key][int(r["seed"])] = r
    return cells


def segment_tests(cells: dict, worlds: list[str]) -> tuple[list[Test], list[Test]]:
    family, also = [], []
    for world in worlds:
        for stride in (2, 5):
            for schedule in SCHEDULES:
                for group, out in ((SEGMENT_TESTS, family), (SEGMENT_ALSO, also)):
                    for name, a, b in group:
                        for e in ENDPOINTS:
                            d, lo, hi, p, w, l_ = compare(
                                cells[world, stride, schedule, a],
                                cells[world, stride, schedule, b],
                                e,
                            )
                            out.append(Test("H1", name, world, f"stride {stride}", schedule,
                                            a, b, e, d, lo, hi, p, w, l_))  # fmt: skip
    for t, p in zip(family, holm([t.p for t in family])):
        t.p_holm = p
    return family, also


# ------------------------------------------------------------------------------------ output


def segment_lines(cells: dict, worlds: list[str], family: list[Test], also: list[Test]) -> list:
    lines = ["## H1, coarse observation: the segment term", ""]
    # H1a
    lines += [
        "### H1a: does eq. 2 with segments reach 95 % of the mentor's rate?",
        "",
        "| world | stride | eq. 2 (paper / held ε) | eq. 2 + segments (paper / held ε) | met |",
        "|---|---|---|---|---|",
    ]
    for world in worlds:
        for stride in (2, 5):
            plain = [values(cells[world, stride, s, "eq. 2"], "greedy").mean() for s in SCHEDULES]
            seg = [
                values(cells[world, stride, s, "eq. 2 + segments"], "greedy").mean()
                for s in SCHEDULES
            ]
            met = max(seg) >= TARGET and min(plain) < TARGET
            lines.append(
                f"| {WORLDS[world][0]} | {stride} | {plain[0]:.1f} / {plain[1]:.1f} | "
                f"{seg[0]:.1f} / {seg[1]:.1f} | {'yes' if met else 'no'} |"
            )
    lines += [
        "",
        "Mean greedy policy at the end over 20 seeds, % of the mentor's goal rate.",
        "",
        "### Every cell",
        "",
        "Greedy policy at the end (% of the mentor's rate: mean of 20 seeds [95 % BCa interval of "
        "the mean]); first goal (Kaplan–Meier median, with the runs that never found it); goals "
        "over the whole run (mean [95 % BCa]).",
        "",
    ]
    for world in worlds:
        budget = WORLDS[world][1]
        for stride in (2, 5):
            lines += [
                f"**{WORLDS[world][0]}, stride {stride}**",
                "",
                "| method | schedule | greedy, % of mentor | first goal | goals |",
                "|---|---|---|---|---|",
            ]
            for schedule, title in SCHEDULES.items():
                for method in SEGMENT_METHODS:
                    cell = cells[world, stride, schedule, method]
                    lines.append(
                        f"| {method} | {title} | "
                        f"{fmt_interval(bca_interval(values(cell, 'greedy')))} | "
                        f"{km_text(cell, budget)} | "
                        f"{bca_interval(values(cell, 'goals')).estimate:.0f} |"
                    )
            lines.append("")
    lines += [
        "### Paired tests (family H1: Holm over its 72 p-values)",
        "",
        "Each row: a − b paired by seed (mean difference [95 % BCa], wins–losses of a), the "
        "paired t-test's p (greedy, goals) or the sign test's (first goal), Holm's p.",
        "",
        "| test | world | stride | schedule | a − b | endpoint | difference | p | Holm p | |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for t in family + also:
        lines.append(
            f"| {t.name} | {WORLDS[t.world][0]} | {t.condition} | {SCHEDULES[t.schedule]} | "
            f"{t.a} − {t.b} | {t.endpoint} | {show_test(t)} |"
        )
    lines.append("")
    return lines


def hierarchy_helps(family: list[Test]) -> list[tuple]:
    """The H1d conditions where eq. 2 + segments beats eq. 1 + segments by PROTOCOL.md's rule."""
    by_condition: dict = defaultdict(dict)
    for t in family:
        if t.name == "H1d":
            by_condition[t.world, t.condition, t.schedule][t.endpoint] = t
    helped = []
    for key, tests in by_condition.items():
        better = any(
            tests[e].p_holm < 0.05 and tests[e].difference > 0 for e in ("greedy", "goals")
        )
        worse = tests["greedy"].p_holm < 0.05 and tests["greedy"].difference < 0
        if better and not worse:
            helped.append(key)
    return helped


def segment_figure(cells: dict, worlds: list[str], out: Path) -> None:
    fig, axes = plt.subplots(1, len(worlds), figsize=(6 * len(worlds), 4), squeeze=False)
    colours = {"eq. 2": "#9ecae1", "eq. 2 + segments": "#08519c", "eq. 1": "#fdae6b",
               "eq. 1 + segments": "#a63603"}  # fmt: skip
    for ax, world in zip(axes[0], worlds):
        groups = [(stride, s) for stride in (2, 5) for s in SCHEDULES]
        width = 0.2
        for i, method in enumerate(SEGMENT_METHODS):
            means, lows, highs = [], [], []
            for stride, schedule in groups:
                iv = bca_interval(values(cells[world, stride, schedule, method], "greedy"))
                means.append(iv.estimate)
                lows.append(iv.estimate - iv.low)
                highs.append(iv.high - iv.estimate)
            x = np.arange(len(groups)) + (i - 1.5) * width
            ax.bar(x, means, width, yerr=[lows, highs], label=method, color=colours[method],
                   capsize=2)  # fmt: skip
        ax.axhline(TARGET, color="grey", lw=0.8, ls="--")
        ax.set_xticks(np.arange(len(groups)))
        ax.set_xticklabels(
            [f"stride {k}\n{'paper ε' if s == 'paper' else 'held ε'}" for k, s in groups]
        )
        ax.set_ylim(0, 110)
        ax.set_title(WORLDS[world][0])
        ax.set_ylabel("greedy policy at the end, % of the mentor's rate")
    axes[0][0].legend(loc="lower left", fontsize=8)
    fig.suptitle("Coarse observation: one-step term vs segment term (20 seeds, 95 % BCa)")
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def provenance(results: Path, sweeps: list[str]) -> str:
    commits = set()
    for name in sweeps:
        about = json.loads((results / name / "sweep.json").read_text())
        run_commits = about.get("commit") or ["?"]
        commits.update(
            str(c)[:7] for c in (run_commits if isinstance(run_commits, list) else [run_commits])
        )
    head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                          text=True, cwd=HERE).stdout.strip()  # fmt: skip
    return (
        f"*Runs at commit {', '.join(sorted(commits))}; this page written at {head} by "
        "`python experiments/hierarchy/analyse.py` from the committed records; rerun with "
        "`python experiments/hierarchy/run_hierarchy.py`.*"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--results", default=str(HERE.parent / "results" / "hierarchy"))
    args = parser.parse_args()
    results = Path(args.results)
    sweeps = [
        f"segments_{w}" for w in SEGMENT_WORLDS if (results / f"segments_{w}" / "runs.csv").exists()
    ]
    rows = [r for name in sweeps for r in load_runs(results / name / "runs.csv")]
    worlds = [w for w in SEGMENT_WORLDS if f"segments_{w}" in sweeps]
    cells = segment_cells(rows)
    family, also = segment_tests(cells, worlds)
    helped = hierarchy_helps(family)
    h3 = trial_cells(results)
    h3_tests = trial_tests(h3) if h3 else []
    h2 = box_cells(results)
    h2_tests = box_tests(h2) if h2 else []
    recorded = sweeps + [n for n in ("trial_exp1", "trial_feasibility_exp1") if h3]
    h4, h5, h6 = later.h4_cells(results), later.h5_cells(results), later.h6_cells(results)
    dragged, h4_tests = (later.dragged_tests(h4), later.h4_tests(h4)) if h4 else ([], [])
    h5_tests = later.h5_tests(h5) if h5 else []
    h6_tests = later.h6_tests(h6) if h6 else []
    for part, cells_ in (("H4", h4), ("H5", h5), ("H6", h6)):
        recorded += list(later.SWEEPS[part]) if cells_ else []

    lines = ["# Where does hierarchy help imitation?", "", provenance(results, recorded), ""]
    lines += answer_lines(worlds, family, helped, h3, h3_tests, h2, h2_tests)
    later_answers = (
        (later.h4_answer(dragged, h4_tests) if h4 else [])
        + (later.h5_answer(h5, h5_tests) if h5 else [])
        + (later.h6_answer(h6, h6_tests) if h6 else [])
    )
    overall = overall_answer(family, h3_tests, h4_tests + h5_tests + h6_tests)
    at = lines.index("![Greedy policy at the end under coarse observation](segments.png)") - 1
    lines[at:at] = later_answers + overall
    lines += segment_lines(cells, worlds, family, also)
    lines += box_lines(h2, h2_tests, results.parent / "puzzlebox") if h2 else []
    lines += trial_lines(h3, h3_tests) if h3 else []
    lines += later.h4_lines(h4, dragged, h4_tests) if h4 else []
    lines += later.h5_lines(h5, h5_tests) if h5 else []
    lines += later.h6_lines(h6, h6_tests) if h6 else []
    if h4 or h5 or h6:
        later.figure(h4, h5, h6, results / "later.png")
        lines += ["![H4–H6: greedy policy at the end](later.png)", ""]
    missing = [f"segments_{w}" for w in SEGMENT_WORLDS if w not in worlds]
    missing += [] if h3 else ["H3 (trial_exp1, trial_feasibility_exp1)"]
    missing += [] if h2 else ["H2 (puzzlebox_*)"]
    missing += [f"{part} ({', '.join(later.SWEEPS[part])})"
                for part, c in (("H4", h4), ("H5", h5), ("H6", h6)) if not c]  # fmt: skip
    if missing:
        lines += [f"*Records absent, left out: {', '.join(missing)}.*", ""]
    segment_figure(cells, worlds, results / "segments.png")
    (results / "results.md").write_text("\n".join(lines))
    with (results / "tests.csv").open("w", newline="") as f:
        writer = csv.writer(f)
        fields = list(Test.__dataclass_fields__)
        writer.writerow(fields)
        for t in family + also + h2_tests + h3_tests + dragged + h4_tests + h5_tests + h6_tests:
            writer.writerow([getattr(t, k) for k in fields])
    print(f"wrote {results / 'results.md'}")


def overall_answer(h1: list[Test], h3: list[Test], later_tests: list[Test]) -> list[str]:
    """The issue's target, over every hierarchical − flat comparison of the study: where the
    hierarchy helps by the protocol's rule, and where it is significantly worse on the greedy
    policy."""
    h1_pairs = [t for t in h1 if t.name == "H1d"]  # (one per world × stride × schedule)
    flat = [t for t in h3 + later_tests if t.name.endswith("− eq. 1")]
    distinct, repeats = distinct_comparisons(h1_pairs + flat)
    helps, worse = later.hierarchy_verdicts(distinct)
    total = len({(t.name, t.world, t.condition, t.schedule) for t in distinct})
    met = len(helps) >= 3 and not worse

    def where(keys):
        return "; ".join(
            f"{name} ({WORLDS[w][0] if w in WORLDS else w}{', ' + c if c else ''}, {SCHEDULES[s]})"
            for name, w, c, s in keys
        )

    return [
        f"- **Overall: hierarchy helps in {len(helps)} of {total} distinct hierarchical − flat "
        f"comparisons** (world × condition × schedule, by the protocol's rule; "
        f"{len(repeats)} more compare runs whose every per-seed result equals one of these, and "
        f"are counted once: {where(repeats)})"
        + (f": {where(helps)}" if helps else "")
        + f"; the hierarchical imitator is significantly worse on the greedy policy in "
        f"{len(worse)}" + (f": {where(worse)}" if worse else "") + ". The issue's target "
        "(better in at least 3, never significantly worse) is "
        + ("**met**." if met else "**not met**: the recommended imitator stays flat.")
    ]


def h3_answer(cells: dict, tests: list[Test]) -> str:
    """H3's bullet: what trial and feasibility did to each imitator, and eq. 2 against eq. 1."""

    def test(name, schedule, endpoint="greedy"):
        (t,) = [
            t for t in tests if t.name == name and t.schedule == schedule and t.endpoint == endpoint
        ]
        sig = "significant" if t.p_holm < 0.05 else "not significant"
        return f"{t.difference:+.1f} points [{t.low:+.1f}, {t.high:+.1f}] ({sig})"

    def mean(schedule, cell, method):
        return values(cells[schedule, cell, method], "greedy").mean()

    same = all(
        values(cells[sch, "trial", m], e).tolist()
        == values(cells[sch, "trial + feasibility", m], e).tolist()
        for sch in SCHEDULES
        for m in TRIAL_AGENTS
        for e in ENDPOINTS
    )
    p, g = "paper", "explore-goals"
    hierarchy_wins = [
        t
        for t in tests
        if "eq. 2 − eq. 1" in t.name and t.endpoint != "first_goal" and t.p_holm < 0.05
        and t.difference > 0
    ]  # fmt: skip
    verdict = (
        "flat imitation still ends at least as well"
        if not hierarchy_wins
        else f"eq. 2 beats eq. 1 in {len(hierarchy_wins)} comparisons"
    )
    return (
        f"- **H3, exp1 (the learner lacks the mentor's corner skills): {verdict}.** Trial "
        "changes eq. 2's greedy policy (% of the mentor's rate) by "
        f"{test('eq. 2: trial − off', p)} under the paper's ε and "
        f"{test('eq. 2: trial − off', g)} under held ε (Holm), to {mean(p, 'trial', 'eq. 2'):.1f} "
        f"and {mean(g, 'trial', 'eq. 2'):.1f} %; eq. 1's moves by "
        f"{test('eq. 1: trial − off', p)} and {test('eq. 1: trial − off', g)}. Eq. 2 − eq. 1: "
        f"without trial {test('off: eq. 2 − eq. 1', p)} (paper ε) and "
        f"{test('off: eq. 2 − eq. 1', g)} (held ε); with trial "
        f"{test('trial: eq. 2 − eq. 1', p)} and {test('trial: eq. 2 − eq. 1', g)}. "
        + (
            "Feasibility testing changed no run: trial + feasibility equals trial on every "
            "endpoint of every run (on this world every mentor move is one primitive step, "
            "which the learner's primitives reproduce, so no mentor term fails the test)."
            if same
            else "Feasibility testing changed some runs (tables below)."
        )
    )


def answer_lines(
    worlds: list[str],
    family: list[Test],
    helped: list,
    h3: dict,
    h3_tests: list[Test],
    h2: dict,
    h2_tests: list[Test],
) -> list[str]:
    """The page's opening: what each hypothesis found, in words, from the tests."""

    def count(tests, name, sign, endpoint="greedy"):
        return sum(
            1
            for t in tests
            if t.name == name and t.endpoint == endpoint and t.p_holm < 0.05
            and (t.difference > 0) == (sign > 0)
        )  # fmt: skip

    n_conditions = len(worlds) * 2 * len(SCHEDULES)
    lines = [
        "## The answer",
        "",
        f"- **H1, coarse observation: the segment term.** On the greedy policy at the end it "
        f"improves eq. 2 significantly in "
        f"{count(family, 'H1b', 1)} of {n_conditions} world × stride × schedule conditions and "
        f"eq. 1 in {count(family, 'H1c', 1)} (Holm over the family); worse in "
        f"{count(family, 'H1b', -1)} and {count(family, 'H1c', -1)}.",
        f"- **H1: hierarchy helps in {len(helped)} of {n_conditions} conditions** by the "
        "protocol's rule (eq. 2 + segments significantly better than eq. 1 + segments on the "
        "greedy policy or on goals, and not significantly worse on the greedy policy)"
        + (
            ": " + "; ".join(f"{WORLDS[w][0]}, {c}, {SCHEDULES[s]}" for w, c, s in helped)
            if helped
            else "."
        )  # fmt: skip
        + " Eq. 2 + segments is significantly worse than eq. 1 + segments on the greedy "
        f"policy in {count(family, 'H1d', -1)} of them.",
    ]
    if h2:
        runs = {c: h2[c]["speed_imitation"] for c in BOX_CELLS}
        stuck = {c: sum(r["stuck_at"] is not None for r in runs[c].values()) for c in runs}
        follows = {c: sum(r["organisation"] == r["watched"] for r in runs[c].values())
                   for c in runs}  # fmt: skip
        n = len(runs["off"])
        differs = [t for t in h2_tests if t.p_holm < 0.05]
        same = all(
            cells_equal(h2["trial"][batch], h2["trial_feasibility"][batch]) for batch in h2["trial"]
        )
        lines.append(
            f"- **H2, the puzzle box:** stuck greedy plans {stuck['off']}/{n} without either "
            f"setting, {stuck['trial']}/{n} with trial, {stuck['trial_feasibility']}/{n} with "
            f"trial and feasibility (target 0); the watched organisation followed "
            f"{follows['off']}/{n}, {follows['trial']}/{n} and {follows['trial_feasibility']}/{n}"
            f" (target ≥ 13). {len(differs)} of H2's {len(h2_tests)} tests differ after Holm"
            + (": " + "; ".join(f"{t.name}, {t.endpoint}" for t in differs) if differs else "")
            + " (with 20 seeds, 3 stuck plans against 0 cannot reach significance)."
            + (
                " Feasibility testing changed no run: every batch with it equals the batch "
                "with trial alone."
                if same
                else ""
            )
        )
    if h3_tests:
        lines.append(h3_answer(h3, h3_tests))
    lines += [
        "",
        "![Greedy policy at the end under coarse observation](segments.png)",
        "",
        "*H1: the greedy policy at the end as a % of the mentor's goal rate, mean of 20 seeds "
        "with its 95 % BCa interval; the dashed line is H1a's 95 %.*",
        "",
    ]
    return lines


if __name__ == "__main__":
    main()
