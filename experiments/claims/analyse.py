"""The paper's claims under both tie rules, and the recommended preset on every world: the
endpoints and tests that PROTOCOL.md declared before the runs, computed from the committed run
records (``worlds/*.json``, ``tasks/*.json`` and ``curves.csv`` of each run directory).

    python experiments/claims/analyse.py [--results experiments/results] [--out experiments/results/claims]

Reads ``<results>/<preset>-<ties>/{exp1,exp2,exp3,gymnasium}`` for the presets ``paper`` and
``recommended`` and the tie rules ``random`` and ``first``; writes ``claims.md``, ``claims.csv``
(every test with its raw and Holm-adjusted p-value) and the Kaplan–Meier figures
``first_goal_km_<preset>.png`` into ``--out``.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from himit_torch.statistics import (
    Interval,
    PairedComparison,
    bca_interval,
    first_goal_sign_test,
    first_goal_survival,
    holm,
    paired_comparison,
    share_interval,
)

PRESETS = ("paper", "recommended")
TIES = ("random", "first")
#: Steps of the "early" and "late" endpoints (PROTOCOL.md).
EARLY_STEPS = LATE_STEPS = 50_000
EXP3_SIZES = (64, 80, 96, 120)
GYM_TASKS = ("taxi", "cliffwalking", "frozenlake8x8")


@dataclass
class World:
    """The runs of one world of one run directory: per (agent, seed) the endpoints."""

    name: str
    budget: int
    runs: dict = field(default_factory=dict)  # (agent, seed) → {endpoint: value}

    def agents(self) -> list[str]:
        return list(dict.fromkeys(a for a, _ in self.runs))

    def values(self, agent: str, endpoint: str) -> list:
        """``endpoint`` of ``agent``'s runs, in seed order."""
        seeds = sorted(s for a, s in self.runs if a == agent)
        return [self.runs[agent, s][endpoint] for s in seeds]


def _window_goals(path: Path, key: str, goals: str) -> dict:
    """(world or task, agent, seed) → [(step, goals in the window), …] from a curves.csv."""
    out: dict = defaultdict(list)
    with open(path) as f:
        for row in csv.DictReader(f):
            out[row[key], row["agent"], int(row["seed"])].append(
                (int(row["step"]), int(row[goals]))
            )
    return out


def _world(name: str, record: dict, windows: dict, key: str, total: str) -> World:
    budget = int(record["steps"])
    world = World(name, budget)
    window = None
    for b, (agent, seed) in enumerate(zip(record["agents"], record["seeds"])):
        series = windows[key, agent, seed]
        window = window or series[0][0]
        optimal_total = record["optimal_goals_per_window"] * budget / window
        world.runs[agent, seed] = {
            "first_goal": int(record["first_goal_step"][b]),
            "early": sum(g for step, g in series if step <= EARLY_STEPS),
            "late": sum(g for step, g in series if step > budget - LATE_STEPS),
            "greedy_optimal": float(record["greedy_percent_of_optimal"][b]),
            "greedy_mentor": float(record["greedy_percent_of_mentor"][b]),
            "percent_of_optimal": 100.0 * int(record[total][b]) / optimal_total,
        }
    return world


def load(results: Path, preset: str, ties: str) -> dict[str, World]:
    """World name (exp1, exp2, exp3_64, …, taxi, …) → its runs, of one preset and tie rule."""
    return load_dir(results / f"{preset}-{ties}")


def load_dir(root: Path) -> dict[str, World]:
    """World name → its runs, from a folder holding ``exp1``, ``exp2``, ``exp3`` and
    ``gymnasium`` as ``collect_results.py`` copies them."""
    worlds = {}
    for exp in ("exp1", "exp2", "exp3"):
        windows = _window_goals(root / exp / "curves.csv", "world", "goals_in_window")
        for path in sorted((root / exp / "worlds").glob("world*.json")):
            record = json.loads(path.read_text())
            size = record["size"]
            name = exp if exp != "exp3" else f"exp3_{size}"
            worlds[name] = _world(name, record, windows, str(size), "goals")
    windows = _window_goals(root / "gymnasium" / "curves.csv", "task", "goals")
    for task in GYM_TASKS:
        record = json.loads((root / "gymnasium" / "tasks" / f"{task}.json").read_text())
        worlds[task] = _world(task, record, windows, task, "total_goals")
    return worlds


@dataclass
class Test:
    """One row of a table: a comparison on an endpoint, and its p-values (raw, then Holm's)."""

    table: str
    claim: str
    world: str
    comparison: str
    endpoint: str
    ties: str
    result: PairedComparison
    p_holm: dict = field(default_factory=dict)

    def effect(self) -> str:
        d = self.result.difference
        if math.isnan(d.low):
            return f"{self.result.wins}–{self.result.losses} (tie {self.result.ties})"
        return f"{d.format(1)} ({self.result.wins}–{self.result.losses})"


def compare(world: World, a: str, b: str, endpoint: str) -> PairedComparison:
    if endpoint == "first_goal":
        return first_goal_sign_test(world.values(a, endpoint), world.values(b, endpoint))
    return paired_comparison(world.values(a, endpoint), world.values(b, endpoint))


ENDPOINT_NAMES = {
    "first_goal": "first goal (sign test: seeds a first – b first)",
    "early": "goals in the first 50k steps",
    "greedy_optimal": "greedy policy at the end, % of optimal",
    "late": "goals in the last 50k steps",
    "slope": "exp3: slope of (imitation − options) % of optimal per cell",
    "percent_of_optimal": "total goals, % of optimal (the paper's measure)",
}


def claims_tests(data: dict) -> list[Test]:
    """The claims table of PROTOCOL.md, for the paper preset, both tie rules."""
    tests = []
    for ties in TIES:
        worlds = data["paper", ties]
        for a, b in (
            ("imitation", "options"),
            ("imitation", "primitives"),
            ("options", "primitives"),
        ):
            for e in ("first_goal", "early", "greedy_optimal"):
                r = compare(worlds["exp1"], a, b, e)
                tests.append(Test("claims", "1", "exp1", f"{a} − {b}", e, ties, r))
        for a, b in (("imitation", "options"), ("imitation", "primitives")):
            for e in ("first_goal", "early", "greedy_optimal"):
                r = compare(worlds["exp2"], a, b, e)
                tests.append(Test("claims", "2", "exp2", f"{a} − {b}", e, ties, r))
        diffs = np.array(
            [
                np.subtract(
                    worlds[f"exp3_{n}"].values("imitation", "percent_of_optimal"),
                    worlds[f"exp3_{n}"].values("options", "percent_of_optimal"),
                )
                for n in EXP3_SIZES
            ]
        )  # [size, seed]
        slopes = np.polyfit(np.array(EXP3_SIZES, dtype=float), diffs, 1)[0]
        r = paired_comparison(slopes, np.zeros_like(slopes))
        tests.append(Test("claims", "3", "exp3", "imitation − options", "slope", ties, r))
        for n in EXP3_SIZES:
            r = compare(worlds[f"exp3_{n}"], "imitation", "options", "percent_of_optimal")
            tests.append(
                Test(
                    "claims", "3", f"exp3_{n}", "imitation − options", "percent_of_optimal", ties, r
                )
            )
    return tests


WORLDS = ("exp1", "exp2", *(f"exp3_{n}" for n in EXP3_SIZES), *GYM_TASKS)
NON_IMITATORS = ("options", "primitives")


def recommended_tests(data: dict) -> list[Test]:
    tests = []
    for name in WORLDS:
        world = data["recommended", "random"][name]
        for b in NON_IMITATORS:
            for e in ("first_goal", "late"):
                r = compare(world, "imitation", b, e)
                tests.append(Test("recommended", "", name, f"imitation − {b}", e, "random", r))
    return tests


def adjust(tests: list[Test]) -> None:
    """Holm over every p-value of the table (t-tests and sign tests together)."""
    raw = [p for t in tests for p in (t.result.t_p, t.result.sign_p)]
    adjusted = holm(raw)
    for i, t in enumerate(tests):
        t.p_holm = {"t": adjusted[2 * i], "sign": adjusted[2 * i + 1]}


def _p(p: float) -> str:
    if math.isnan(p):
        return "–"
    return "< 0.001" if p < 0.001 else f"{p:.3f}"


def _km(world: World, agent: str) -> Interval:
    return first_goal_survival(world.values(agent, "first_goal"), world.budget).median


def km_text(ci: Interval) -> str:
    """A Kaplan–Meier median and its interval in thousands of steps ("never": the curve never
    falls to ½), as the claims' and the benchmark's pages print them."""

    def k(x: float) -> str:
        return "never" if math.isinf(x) else f"{x / 1000:.1f}k"

    return f"{k(ci.estimate)} [{k(ci.low)}, {k(ci.high)}]"


def km_figure(data: dict, preset: str, out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 3, figsize=(13, 7), sharey=True)
    for ax, name in zip(axes.flat, ("exp1", "exp2", *(f"exp3_{n}" for n in EXP3_SIZES))):
        for ties, style in zip(TIES, ("-", "--")):
            world = data[preset, ties][name]
            for agent, color in zip(("imitation", "options", "primitives"), "C0 C1 C2".split()):
                s = first_goal_survival(world.values(agent, "first_goal"), world.budget)
                ax.step(
                    np.r_[0, s.times] / 1000,
                    1 - np.r_[1, s.survival],
                    where="post",
                    color=color,
                    linestyle=style,
                    label=f"{agent}, {ties} ties",
                )
        ax.set_title(name)
        ax.set_xlabel("steps (thousands)")
    axes[0, 0].set_ylabel("share of runs that found the goal")
    axes[1, 0].set_ylabel("share of runs that found the goal")
    axes[0, 0].legend(fontsize=7)
    fig.suptitle(
        f"First goal, Kaplan–Meier (1 − S(t); 'never' censored at the budget), preset "
        f"{preset}, 20 seeds per line"
    )
    fig.tight_layout()
    fig.savefig(out / f"first_goal_km_{preset}.png", dpi=90)
    plt.close(fig)


def record_commits(results: Path) -> str:
    """The commits the claims' run records hold, each with what it ran."""
    found: dict = defaultdict(set)
    for preset in PRESETS:
        for ties in TIES:
            root = results / f"{preset}-{ties}"
            for path in root.glob("exp*/worlds/*.json"):
                found[json.loads(path.read_text()).get("commit")].add("exp1–exp3")
            for path in root.glob("gymnasium/tasks/*.json"):
                found[json.loads(path.read_text()).get("commit")].add("Gymnasium")
    return (
        ", ".join(
            f"`{c}` ({' and '.join(sorted(w))})" for c, w in sorted(found.items(), key=str) if c
        )
        or "not recorded"
    )


def write(data: dict, claims: list[Test], recommended: list[Test], out: Path) -> None:
    lines = [
        "# The paper's claims under both tie rules, and the recommended preset on every world",
        "",
        f"Runs recorded at commit(s) {record_commits(out.parent)} (the `commit` of every "
        "`worlds/*.json` and `tasks/*.json` of `experiments/results/<preset>-<ties>/`); this page: "
        "`python experiments/claims/analyse.py` (from those committed records); the runs: "
        "`python experiments/claims/run_claims.py`.",
        "",
        "Endpoints and tests as `PROTOCOL.md` declared before the runs; 20 seeds (0–19) per "
        "agent, paired by seed (common random numbers). Made by "
        "`python experiments/claims/analyse.py` from `experiments/results/<preset>-<ties>/`. "
        "**Effects**: the paired mean difference a − b with its **95 % BCa bootstrap interval** "
        "(9999 resamples) and, in brackets after it, the seeds where a was higher – lower; for "
        "the first goal, the seeds where a reached the goal first – later (ties: neither did). "
        "**p**: two-sided, **Holm-adjusted over the whole table** (`claims.csv` has the raw "
        "ones): the paired t-test, and beside it the sign test. KM: Kaplan–Meier median of the "
        "steps to the first goal, 'never' censored at the budget, with its 95 % interval from "
        "the log–log band ('never': the curve does not fall to ½ within the budget).",
        "",
        "## Claims (the paper preset)",
        "",
        "| claim | world | a − b | endpoint | random ties: effect | p (t) | p (sign) | "
        "first-index ties: effect | p (t) | p (sign) |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    by_key = {(t.claim, t.world, t.comparison, t.endpoint, t.ties): t for t in claims}
    for t in claims:
        if t.ties != "random":
            continue
        f = by_key[t.claim, t.world, t.comparison, t.endpoint, "first"]
        lines.append(
            f"| {t.claim} | {t.world} | {t.comparison} | {ENDPOINT_NAMES[t.endpoint]} | "
            f"{t.effect()} | {_p(t.p_holm['t'])} | {_p(t.p_holm['sign'])} | {f.effect()} | "
            f"{_p(f.p_holm['t'])} | {_p(f.p_holm['sign'])} |"
        )
    lines += [
        "",
        "### First goal and failures per agent (the paper preset)",
        "",
        "| world | agent | random ties: KM median | never (share, exact 95 % CI) | first-index "
        "ties: KM median | never |",
        "|---|---|---|---|---|---|",
    ]
    for name in ("exp1", "exp2", *(f"exp3_{n}" for n in EXP3_SIZES)):
        for agent in data["paper", "random"][name].agents():
            cells = []
            for ties in TIES:
                world = data["paper", ties][name]
                s = first_goal_survival(world.values(agent, "first_goal"), world.budget)
                share = share_interval(s.never, s.runs)
                cells.append(
                    f"{km_text(s.median)} | {s.never}/{s.runs} [{share.low:.2f}, {share.high:.2f}]"
                )
            lines.append(f"| {name} | {agent} | {' | '.join(cells)} |")
    lines += _recommended_lines(data, recommended)
    lines += _presets_lines(data)
    (out / "claims.md").write_text("\n".join(lines) + "\n")
    with open(out / "claims.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["table", "claim", "world", "comparison", "endpoint", "ties", *RESULT_COLUMNS])
        for t in claims + recommended:
            w.writerow(
                [
                    t.table,
                    t.claim,
                    t.world,
                    t.comparison,
                    t.endpoint,
                    t.ties,
                    *result_cells(t),
                ]
            )


#: The columns of :func:`result_cells`.
RESULT_COLUMNS = [
    "difference", "low", "high", "wins", "losses", "ties_count", "p_t", "p_sign", "p_t_holm",
    "p_sign_holm",
]  # fmt: skip


def result_cells(t: Test) -> list:
    """A test's result as CSV cells (:data:`RESULT_COLUMNS`): the effect, its interval, the
    seeds won, lost and tied, and the raw and Holm-adjusted p-values."""
    r = t.result
    d = r.difference
    return [d.estimate, d.low, d.high, r.wins, r.losses, r.ties, r.t_p, r.sign_p,
            t.p_holm["t"], t.p_holm["sign"]]  # fmt: skip


def _recommended_lines(data: dict, tests: list[Test]) -> list[str]:
    lines = [
        "",
        "## The recommended preset on every world (random ties)",
        "",
        "Each world's non-imitators run under the same preset (the same ε schedule). **First "
        "goal**: the KM medians of the imitator and of the best non-imitator (the smaller KM "
        "median), their ratio (goal: ≥ 2), and the sign test. **Greedy**: the imitator's frozen "
        "greedy policy at the end, goals per window as a % of the mentor's own rate, mean [95 % "
        "BCa interval] (goal: ≥ 95 %). **Late**: goals in the last 50k steps, imitation − "
        "non-imitator, paired. p: Holm over this table. Gymnasium budgets: Taxi 60k, "
        "CliffWalking 30k, FrozenLake 8×8 100k steps, so on CliffWalking the 'last 50k steps' "
        "are the whole run.",
        "",
        "| world | imitator KM | best non-imitator KM | ratio | p (sign) | greedy, % of "
        "mentor | late − options | p (t / sign) | late − primitives | p (t / sign) |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    by = {(t.world, t.comparison, t.endpoint): t for t in tests}
    for name in WORLDS:
        world = data["recommended", "random"][name]
        mine = _km(world, "imitation")
        best = min(NON_IMITATORS, key=lambda b: _km(world, b).estimate)
        theirs = _km(world, best)
        ratio = theirs.estimate / mine.estimate if mine.estimate > 0 else math.nan
        ratio_text = "∞" if math.isinf(ratio) else f"{ratio:.2f}×"
        sign = by[name, f"imitation − {best}", "first_goal"]
        greedy = bca_interval(world.values("imitation", "greedy_mentor"))
        cells = [
            name,
            km_text(mine),
            f"{best}: {km_text(theirs)}",
            ratio_text,
            f"{_p(sign.p_holm['sign'])} ({sign.result.wins}–{sign.result.losses})",
            greedy.format(1),
        ]
        for b in NON_IMITATORS:
            t = by[name, f"imitation − {b}", "late"]
            cells += [t.effect(), f"{_p(t.p_holm['t'])} / {_p(t.p_holm['sign'])}"]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def _presets_lines(data: dict) -> list[str]:
    lines = [
        "",
        "## The two presets side by side (random ties; the imitator, and each world's best "
        "non-imitator by late goals)",
        "",
        "Means over 20 seeds with 95 % BCa intervals; KM medians as above. Under the "
        "recommended preset the non-imitators run with its ε schedule too.",
        "",
        "| world | preset | imitator: KM first goal | early goals | late goals | greedy, % of "
        "optimal | greedy, % of mentor | best non-imitator: late goals | its greedy, % of "
        "optimal |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for name in WORLDS:
        for preset in PRESETS:
            world = data[preset, "random"][name]
            best = max(NON_IMITATORS, key=lambda b: np.mean(world.values(b, "late")))
            cells = [
                name,
                preset,
                km_text(_km(world, "imitation")),
                bca_interval(world.values("imitation", "early")).format(0),
                bca_interval(world.values("imitation", "late")).format(0),
                bca_interval(world.values("imitation", "greedy_optimal")).format(1),
                bca_interval(world.values("imitation", "greedy_mentor")).format(1),
                f"{best}: " + bca_interval(world.values(best, "late")).format(0),
                bca_interval(world.values(best, "greedy_optimal")).format(1),
            ]
            lines.append("| " + " | ".join(cells) + " |")
    return lines


def untried_rule_lines(results: Path, data: dict) -> list[str]:
    """Plain eq. 2 on exp1 (paper preset, random ties) under both rules for states where the
    frozen greedy policy has no tried option (``himit_torch.exact.greedy_evaluation``): read
    from the benchmark factorial's runs of the same seeds, which record both (empty if absent)."""
    path = results / "benchmark" / "paper" / "exp1" / "worlds" / "world80.json"
    if not path.exists():
        return []
    record = json.loads(path.read_text())
    if "greedy_percent_of_optimal_stuck" not in record:
        return []
    runs = sorted((s, b) for b, (a, s) in enumerate(zip(record["agents"], record["seeds"]))
                  if a == "imitation")  # fmt: skip
    uniform = [float(record["greedy_percent_of_optimal"][b]) for _, b in runs]
    stuck = [float(record["greedy_percent_of_optimal_stuck"][b]) for _, b in runs]
    ours = data["paper", "random"]["exp1"].values("imitation", "greedy_optimal")
    same = sum(abs(u - o) < 1e-6 for u, o in zip(uniform, ours))
    differ = sum(u != s for u, s in zip(uniform, stuck))
    return [
        "",
        "## The greedy policy at states it never tried: both rules (plain eq. 2, exp1)",
        "",
        "Every greedy column above uses the rule `uniform`: at a state where the run tried none "
        "of its own options, the frozen policy chooses uniformly among the options available "
        "there, as the learner itself acts. Under the rule `stuck` such a state is never left, "
        "so a policy that can reach one scores 0 (`docs/reproducing.md`, 'States the run has "
        "not tried'). On the grid worlds slip (0.1) can carry any policy into a state its run "
        "never tried, so under `stuck` every run of every agent there scores 0 — the rule "
        "measures whether a run has tried every option of every reachable state, not how good "
        "its policy is; `uniform` is the rule the results use. Plain eq. 2 on exp1 (paper preset, random ties), greedy policy at the "
        "end, % of optimal, mean [95 % BCa] over seeds 0–19: "
        f"**uniform {bca_interval(uniform).format(1)}**, **stuck "
        f"{bca_interval(stuck).format(1)}**; the rules differ on {differ} of {len(runs)} "
        "seeds. (From the benchmark factorial's runs of the same seeds, commit "
        f"`{record.get('commit', 'unknown')}`, which record both rules; their `uniform` values "
        f"equal this page's runs on {same} of {len(ours)} seeds.)",
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--results", default="experiments/results")
    parser.add_argument("--out", default="experiments/results/claims")
    args = parser.parse_args()
    results, out = Path(args.results), Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    data = {(p, t): load(results, p, t) for p in PRESETS for t in TIES}
    claims, recommended = claims_tests(data), recommended_tests(data)
    adjust(claims)
    adjust(recommended)
    write(data, claims, recommended, out)
    extra = untried_rule_lines(results, data)
    if extra:
        with open(out / "claims.md", "a") as f:
            f.write("\n".join(extra) + "\n")
    for preset in PRESETS:
        km_figure(data, preset, out)
    print((out / "claims.md").read_text())


if __name__ == "__main__":
    main()
