"""The benchmark's tables and figures, as PROTOCOL.md declared (the fair factorial of
2026-11-26): one leaderboard per exploration schedule (average ranks for ties, every method
against implicit imitation under the same schedule, Holm over both tables), "Does the hierarchy
help?" (eq. 2 − eq. 1 within each schedule × fading cell, Holm over that family), each method
under both schedules side by side, and one figure per stress axis.

    python experiments/benchmark/analyse.py [--results experiments/results]

Reads the factorial's records (``<results>/benchmark/<preset>/{exp1,exp2,exp3,gymnasium}`` for
the presets ``paper``, ``mentor-fade``, ``explore-goals``, ``recommended``, and
``<results>/benchmark/puzzlebox/<agent>_<preset>.{json,csv}``), the claims' runs (for the
batch-independence check), the stress sweep (``<results>/benchmark/stress_exp2``) and
MiniGrid's tasks (``<results>/benchmark/minigrid/<preset>/``, amendment of 2026-11-29: their
own tables, added to both pages and written alone to ``minigrid.md``); writes
``<results>/benchmark/leaderboard.md``, ``hierarchy.md``, ``minigrid.md``, ``leaderboard.csv``,
``hierarchy.png`` and ``stress_<axis>.png``.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

# Run as a script, the repository's root goes on the path (as the benchmarks' scripts do), so the
# claims' loader and tests are imported from their module like any other name
# (experiments/claims/analyse.py; experiments/ is a namespace package).
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from experiments.claims import analyse as claims  # noqa: E402
from experiments.claims.analyse import (  # noqa: E402
    Test,
    World,
    adjust,
    compare,
    km_text,
    load_dir,
)
from himit_torch.statistics import average_ranks, bca_interval, first_goal_survival  # noqa: E402

#: The nine worlds of the runs, then the puzzle box (ranked, but not in the mean rank; left
#: out, and said so, while its records are absent).
WORLDS: tuple[str, ...] = (*claims.WORLDS, "puzzlebox")
NINE = claims.WORLDS
#: Schedule → (preset without fading, preset with fading): the factorial's cells.
SCHEDULES = {"decision": ("paper", "mentor-fade"), "goals": ("explore-goals", "recommended")}
SCHEDULE_TITLES = {
    "decision": "ε per decision (the paper's: 0.75, × 0.999 per decision after the first goal, "
    "floor 0.01)",
    "goals": "ε 0.75 until the run's 10th goal, then 0.01 (the recommended schedule)",
}
#: The rows of each schedule's table: label → (agent, with mentor fading).
METHODS = {
    "eq. 2": ("imitation", False),
    "eq. 2, fading": ("imitation", True),
    "eq. 1 (implicit imitation)": ("imitation_primitives", False),
    "eq. 1, fading": ("imitation_primitives", True),
    "PBRS": ("pbrs", False),
    "PBRS, primitives": ("pbrs_primitives", False),
    "BCO": ("bco", False),
    "options only": ("options", False),
    "primitives only": ("primitives", False),
}
REFERENCE = "eq. 1 (implicit imitation)"
#: Eq. 2 − eq. 1 pairs of the hierarchy family: fading → (eq. 2's row, eq. 1's row).
HIERARCHY = {
    False: ("eq. 2", "eq. 1 (implicit imitation)"),
    True: ("eq. 2, fading", "eq. 1, fading"),
}
ENDPOINTS = ("greedy", "first_goal", "early", "late")
ENDPOINT_TITLES = {
    "greedy": "The greedy policy at the end: % of optimal (puzzle box: value gap "
    "V*(start) − V^π(start), 0 = optimal), mean of 20 seeds",
    "first_goal": "Steps to the first goal (Kaplan–Meier median; 'never': the curve does not "
    "fall to ½)",
    "early": "Goals in the first 50k steps (mean of 20 seeds)",
    "late": "Goals in the last 50k steps (mean of 20 seeds)",
}
EARLY_STEPS = LATE_STEPS = 50_000
#: The stress axes of stress_exp2.toml: setting → (label, its default).
AXES = {
    "mentor_episodes": ("demonstrations per seed", 20),
    "mentor_noise": ("mentor noise (probability of a random primitive)", 0.0),
    "mentor_detour": ("the mentor's detour", False),
    "observation_stride": ("observation stride (every k-th mentor state)", 1),
    "slip": ("slip", 0.1),
    "layout": ("layout", "open"),
}
STRESS_AGENTS = ("imitation", "imitation_primitives", "pbrs", "bco", "options")


def preset_of(schedule: str, faded: bool) -> str:
    return SCHEDULES[schedule][faded]


# ------------------------------------------------------------------------------------ loading
def load_puzzlebox(folder: Path, agent: str, preset: str) -> World:
    """The puzzle box's runs of one cell (``puzzle_box_benchmark.py``'s records) as a World:
    first opening, openings in the first and last 50k steps, and the greedy value gap."""
    record = json.loads((folder / f"{agent}_{preset}.json").read_text())
    budget = int(record["steps"])
    early: dict = defaultdict(int)
    late: dict = defaultdict(int)
    with open(folder / f"{agent}_{preset}.csv") as f:
        for row in csv.DictReader(f):
            step, seed, n = int(row["step"]), int(row["seed"]), int(row["openings"])
            early[seed] += n if step <= EARLY_STEPS else 0
            late[seed] += n if step > budget - LATE_STEPS else 0
    world = World("puzzlebox", budget)
    for run in record["runs"]:
        seed = run["seed"]
        world.runs[agent, seed] = {
            "first_goal": int(run["first_opening"]),
            "early": early[seed],
            "late": late[seed],
            "greedy_gap": record["value_star"] - run["greedy_value"],
        }
    return world


def load(results: Path) -> dict:
    """preset → world → World (each World holding every agent of that preset's runs)."""
    root = results / "benchmark"
    data: dict = {}
    for schedule in SCHEDULES:
        for faded in (False, True):
            preset = preset_of(schedule, faded)
            worlds = load_dir(root / preset)
            box = World("puzzlebox", 0)
            for agent in {a for a, f in METHODS.values() if f == faded or not faded}:
                if (root / "puzzlebox" / f"{agent}_{preset}.json").exists():
                    cell = load_puzzlebox(root / "puzzlebox", agent, preset)
                    box.budget = cell.budget
                    box.runs.update(cell.runs)
            worlds["puzzlebox"] = box
            for world in worlds.values():  # one greedy endpoint, higher is better everywhere
                for run in world.runs.values():
                    run["greedy"] = run.get("greedy_optimal", -run.get("greedy_gap", math.nan))
            data[preset] = worlds
    return data


def method_world(data: dict, schedule: str, method: str, world: str) -> World:
    """The runs of ``method`` under ``schedule`` on ``world``, as agent ``method``."""
    agent, faded = METHODS[method]
    source = data[preset_of(schedule, faded)][world]
    out = World(world, source.budget)
    for (a, seed), run in source.runs.items():
        if a == agent:
            out.runs[method, seed] = run
    return out


def merged(data: dict, schedule: str, world: str, methods=None) -> World:
    out = World(world, data[preset_of(schedule, False)][world].budget)
    for m in methods or METHODS:
        out.runs.update(method_world(data, schedule, m, world).runs)
    return out


# -------------------------------------------------------------------------------------- tests
def leaderboard_tests(
    data: dict, worlds=None, methods=None, family: str = "leaderboard"
) -> list[Test]:
    """Every method against implicit imitation under the same schedule (PROTOCOL.md, test 1);
    ``worlds``, ``methods``: those of the nine worlds' tables unless given (MiniGrid's)."""
    tests = []
    for schedule in SCHEDULES:
        for world in worlds or WORLDS:
            runs = merged(data, schedule, world, methods)
            for m in methods or METHODS:
                if m == REFERENCE:
                    continue
                for e in ENDPOINTS:
                    result = compare(runs, m, REFERENCE, e)
                    tests.append(Test(family, schedule, world, f"{m} − {REFERENCE}", e,
                                      "random", result))  # fmt: skip
    adjust(tests)
    return tests


def hierarchy_tests(data: dict, worlds=None, family: str = "hierarchy") -> list[Test]:
    """Eq. 2 − eq. 1 within each schedule × fading cell (PROTOCOL.md, test 2)."""
    tests = []
    for schedule in SCHEDULES:
        for faded, (a, b) in HIERARCHY.items():
            for world in worlds or WORLDS:
                runs = merged(data, schedule, world)
                for e in ENDPOINTS:
                    cell = f"{schedule}, {'fading' if faded else 'no fading'}"
                    tests.append(Test(family, cell, world, f"{a} − {b}", e, "random",
                                      compare(runs, a, b, e)))  # fmt: skip
    adjust(tests)
    return tests


def significant(t: Test) -> str:
    """▲ / ▼ where the Holm-adjusted p (the smaller of t-test and sign test) is < 0.05."""
    p = min((x for x in t.p_holm.values() if not math.isnan(x)), default=math.nan)
    if not p < 0.05:
        return ""
    r = t.result
    better = r.wins > r.losses if t.endpoint == "first_goal" else r.difference.estimate > 0
    return " ▲" if better else " ▼"


# ------------------------------------------------------------------------------------ tables
def score(world: World, method: str, endpoint: str) -> float:
    """The number a table shows and ranks by (first goal: the KM median, lower is better)."""
    if endpoint == "first_goal":
        return first_goal_survival(world.values(method, "first_goal"), world.budget).median.estimate
    return float(np.mean(world.values(method, endpoint)))


def show(world: str, endpoint: str, value: float) -> str:
    if endpoint == "first_goal":
        return "never" if math.isinf(value) else f"{value / 1000:.1f}k"
    if endpoint == "greedy":
        return f"{-value:.3f}" if world == "puzzlebox" else f"{value:.1f}"
    return f"{value:.0f}"


def ranks_of(data: dict, schedule: str, endpoint: str, worlds=None, methods=None) -> dict:
    """world → method → average rank (1 = best; exact ties share the mean of their ranks)."""
    out = {}
    for world in worlds or WORLDS:
        runs = merged(data, schedule, world, methods)
        scores = {m: score(runs, m, endpoint) for m in methods or METHODS}
        out[world] = average_ranks(scores, higher_is_better=endpoint != "first_goal")
    return out


def leaderboard_lines(
    data: dict, tests: list[Test], worlds=None, methods=None, label: str = "nine worlds", level=2
) -> tuple[list[str], dict]:
    """Each schedule's tables (``level``: its headings' level); the mean rank over ``worlds``
    (default: over the nine worlds, with the puzzle box ranked but not in the mean)."""
    by = {(t.claim, t.world, t.comparison, t.endpoint): t for t in tests}
    lines, mean_ranks = [], {}
    shown, ranked, methods = worlds or WORLDS, worlds or NINE, methods or METHODS
    for schedule in SCHEDULES:
        lines += [f"{'#' * level} Schedule: {SCHEDULE_TITLES[schedule]}", ""]
        for endpoint in ENDPOINTS:
            ranks = ranks_of(data, schedule, endpoint, shown, methods)
            lines += [
                f"{'#' * (level + 1)} {ENDPOINT_TITLES[endpoint]}",
                "",
                "| method | " + " | ".join(shown) + f" | mean rank ({label}) |",
                "|---|" + "---|" * (len(shown) + 1),
            ]
            for m in methods:
                cells = []
                for world in shown:
                    runs = merged(data, schedule, world, methods)
                    text = show(world, endpoint, score(runs, m, endpoint))
                    if m != REFERENCE:
                        text += significant(by[schedule, world, f"{m} − {REFERENCE}", endpoint])
                    cells.append(f"{text} ({ranks[world][m]:g})")
                mean = float(np.mean([ranks[w][m] for w in ranked]))
                mean_ranks[schedule, endpoint, m] = mean
                lines.append(f"| {m} | " + " | ".join(cells) + f" | {mean:.2f} |")
            lines.append("")
    return lines, mean_ranks


def mean_rank_lines(mean_ranks: dict, methods=None, label: str = "the nine worlds") -> list[str]:
    methods = methods or METHODS
    lines = []
    for schedule in SCHEDULES:
        lines += [
            f"**{SCHEDULE_TITLES[schedule]}** — mean rank of {len(methods)} over {label} (1 = "
            "best; ties share their average rank):",
            "",
            "| method | greedy policy at the end | first goal | goals, first 50k steps | goals, "
            "last 50k steps |",
            "|---|---|---|---|---|",
        ]
        for m in sorted(methods, key=lambda m: mean_ranks[schedule, "greedy", m]):
            lines.append(
                f"| {m} | "
                + " | ".join(f"{mean_ranks[schedule, e, m]:.2f}" for e in ENDPOINTS)
                + " |"
            )
        lines.append("")
    return lines


def hierarchy_lines(data: dict, tests: list[Test], worlds=None, level: int = 2) -> list[str]:
    by = {(t.claim, t.world, t.endpoint): t for t in tests}
    lines = []
    for endpoint in ENDPOINTS:
        what = {
            "greedy": "greedy policy at the end, eq. 2 − eq. 1 in points of % of optimal "
            "(puzzle box: eq. 1's value gap − eq. 2's, > 0 = eq. 2 nearer the optimum)",
            "first_goal": "first goal: seeds where eq. 2 found it first – seeds where eq. 1 did "
            "(ties: neither or the same window), and the KM medians eq. 2 / eq. 1",
            "early": "goals in the first 50k steps, eq. 2 − eq. 1",
            "late": "goals in the last 50k steps, eq. 2 − eq. 1",
        }[endpoint]
        cells = [f"{s}, {'fading' if f else 'no fading'}" for s in SCHEDULES for f in (False, True)]
        lines += [
            f"{'#' * level} {what}",
            "",
            "| world | " + " | ".join(cells) + " |",
            "|---|" + "---|" * len(cells),
        ]
        for world in worlds or WORLDS:
            row = []
            for cell in cells:
                t = by[cell, world, endpoint]
                r = t.result
                if endpoint == "first_goal":
                    schedule, fading = cell.split(", ")
                    runs = merged(data, schedule, world)
                    a, b = HIERARCHY[fading == "fading"]
                    ka, kb = score(runs, a, endpoint), score(runs, b, endpoint)
                    text = f"{r.wins}–{r.losses} ({show(world, endpoint, ka)} / " + (
                        f"{show(world, endpoint, kb)})"
                    )
                else:
                    digits = (
                        3
                        if (world == "puzzlebox" and endpoint == "greedy")
                        else (1 if endpoint == "greedy" else 0)
                    )
                    text = f"{r.difference.format(digits)} ({r.wins}–{r.losses})"
                row.append(text + significant(t))
            lines.append(f"| {world} | " + " | ".join(row) + " |")
        lines.append("")
    return lines


def exploration_lines(data: dict, worlds=None, methods=None, level: int = 3) -> list[str]:
    """Each method under both schedules (descriptive): decision → goals."""
    lines, worlds = [], worlds or WORLDS
    for endpoint in ("greedy", "early"):
        lines += [
            f"{'#' * level} {ENDPOINT_TITLES[endpoint]}: ε per decision → ε goals",
            "",
            "| method | " + " | ".join(worlds) + " |",
            "|---|" + "---|" * len(worlds),
        ]
        for m in methods or METHODS:
            cells = []
            for world in worlds:
                before = score(method_world(data, "decision", m, world), m, endpoint)
                after = score(method_world(data, "goals", m, world), m, endpoint)
                cells.append(f"{show(world, endpoint, before)} → {show(world, endpoint, after)}")
            lines.append(f"| {m} | " + " | ".join(cells) + " |")
        lines.append("")
    return lines


def batch_check(results: Path, data: dict) -> str:
    """Whether the cells the claims' runs also hold give the committed runs, run by run."""
    same = total = 0
    for preset, folder in (("paper", "paper-random"), ("recommended", "recommended-random")):
        theirs = load_dir(results / folder)
        for world in NINE:
            for (agent, seed), run in data[preset][world].runs.items():
                if (agent, seed) in theirs[world].runs:
                    total += 1
                    mine = {k: v for k, v in run.items() if k in theirs[world].runs[agent, seed]}
                    same += mine == theirs[world].runs[agent, seed]
    return (
        f"Batch independence: the factorial's runs that the claims' runs also hold (eq. 2, "
        f"options and primitives under `paper` and `recommended`) equal them in {same} of "
        f"{total} runs (every endpoint)."
    )


def hierarchy_figure(tests: list[Test], out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(15, 4.5))
    cells = [f"{s}, {'fading' if f else 'no fading'}" for s in SCHEDULES for f in (False, True)]
    by = {(t.claim, t.world, t.endpoint): t for t in tests}
    for ax, endpoint in zip(axes, ("greedy", "early", "late")):
        for i, cell in enumerate(cells):
            d = [by[cell, w, endpoint].result.difference for w in NINE]
            x = np.arange(len(NINE)) + (i - 1.5) * 0.18
            ax.errorbar(
                x,
                [v.estimate for v in d],
                yerr=[[v.estimate - v.low for v in d], [v.high - v.estimate for v in d]],
                fmt="o",
                capsize=2,
                markersize=4,
                label=cell,
            )
        ax.axhline(0, color="grey", linewidth=0.8)
        ax.set_xticks(np.arange(len(NINE)), NINE, rotation=45, ha="right")
        ax.set_title(
            {
                "greedy": "greedy policy at the end, points of % of optimal",
                "early": "goals in the first 50k steps",
                "late": "goals in the last 50k steps",
            }[endpoint]
        )
    axes[0].set_ylabel("eq. 2 − eq. 1 (mean over 20 paired seeds, 95 % BCa)")
    axes[0].legend(fontsize=8, title="schedule, mentor fading")
    fig.suptitle("Does the hierarchy help? Eq. 2 (options) − eq. 1 (primitives), same settings")
    fig.tight_layout()
    fig.savefig(out / "hierarchy.png", dpi=90)
    plt.close(fig)


# ----------------------------------------------------------------------------------- stresses
def stress_figures(results: Path, out: Path) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sweep = results / "benchmark" / "stress_exp2"
    rows = list(csv.DictReader((sweep / "runs.csv").open()))
    steps = json.loads((sweep / "sweep.json").read_text())["cells"][0]["config"]["steps"]

    def level_of(row: dict, axis: str):
        cell = row["cell"]
        for other in AXES:
            if cell.startswith(f"{other}="):
                return cell.split("=", 1)[1] if other == axis else None
        return str(AXES[axis][1])  # the baseline cell: every axis at its default

    for axis, (label, default) in AXES.items():
        levels: dict = defaultdict(lambda: defaultdict(list))
        for r in rows:
            level = level_of(r, axis)
            if level is not None:
                levels[level][r["agent"]].append(r)

        order = sorted(levels, key=lambda level, d=str(default): _level_key(level, d))
        fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4))
        for agent in STRESS_AGENTS:
            g, f = [], []
            for level in order:
                rs = levels[level][agent]
                g.append(bca_interval([float(r["greedy_percent_of_optimal"]) for r in rs]))
                f.append(first_goal_survival([int(r["first_goal_step"]) for r in rs], steps).median)
            x = np.arange(len(order))
            ax1.errorbar(
                x,
                [i.estimate for i in g],
                yerr=[[i.estimate - i.low for i in g], [i.high - i.estimate for i in g]],
                marker="o",
                capsize=3,
                label=agent,
            )
            fin = [min(i.estimate, steps) / 1000 for i in f]
            lo = [min(i.low, steps) / 1000 for i in f]
            hi = [min(i.high, steps) / 1000 for i in f]
            ax2.errorbar(
                x,
                fin,
                yerr=[np.subtract(fin, lo), np.subtract(hi, fin)],
                marker="o",
                capsize=3,
                label=agent,
            )
        for ax in (ax1, ax2):
            ax.set_xticks(np.arange(len(order)), order)
            ax.set_xlabel(label)
        ax1.set_ylabel("greedy policy at the end, % of optimal\n(mean, 95 % BCa)")
        ax2.set_ylabel("first goal, thousands of steps\n(KM median, 95 % interval; top: never)")
        ax1.legend(fontsize=8)
        fig.suptitle(f"Experiment 2 (40×40), 20 seeds per point: {label}")
        fig.tight_layout()
        fig.savefig(out / f"stress_{axis}.png", dpi=90)
        plt.close(fig)
    return _stress_table(rows, steps)


def _level_key(level: str, default: str) -> tuple:
    """Numbers in order; words (open/maze, False/True) with the default first."""
    try:
        return (0, float(level), "")
    except ValueError:
        return (1, float(level != default), level)


def _stress_table(rows: list[dict], steps: int) -> list[str]:
    """Every stress cell: per agent the greedy % of optimal [BCa], the KM first goal, and the
    runs whose greedy policy never reaches the goal (0 % of optimal)."""
    cells = list(dict.fromkeys(r["cell"] for r in rows))
    lines = [
        "| cell | " + " | ".join(STRESS_AGENTS) + " |",
        "|---|" + "---|" * len(STRESS_AGENTS),
    ]
    for cell in cells:
        out = []
        for agent in STRESS_AGENTS:
            rs = [r for r in rows if r["cell"] == cell and r["agent"] == agent]
            greedy = [float(r["greedy_percent_of_optimal"]) for r in rs]
            g = bca_interval(greedy)
            f = first_goal_survival([int(r["first_goal_step"]) for r in rs], steps).median
            stuck = sum(x == 0.0 for x in greedy)
            out.append(
                f"{g.format(1)}; {km_text(f).split(' [')[0]}"
                + (f"; {stuck}/{len(rs)} stuck" if stuck else "")
            )
        lines.append(f"| {cell} | " + " | ".join(out) + " |")
    return lines


# ----------------------------------------------------------------------------------- MiniGrid
#: MiniGrid's tasks (PROTOCOL.md, amendment of 2026-11-29), in their running order
#: (``minigrid_benchmark.py``); a task enters the tables once its cells are all recorded.
MINIGRID_TASKS = ("multiroomn2s4", "keycorridors3r1", "doorkey5x5", "unlock", "fourrooms",
                  "multiroomn4s5", "doorkey6x6")  # fmt: skip
MINIGRID_PRESETS = tuple(p for pair in SCHEDULES.values() for p in pair)


def load_minigrid_task(folder: Path, task: str, meta: dict) -> World | None:
    """One task's runs of one preset (``<task>.json``/``.csv``, BCO's ``<task>.bco.*``), or
    None where its main cell is not recorded: first goal (exact: every terminal state is a
    success), goals in the first and last 50k steps, the greedy policy's % of optimal. The
    records' commits and wall times are added to ``meta``."""
    if not (folder / f"{task}.json").exists():
        return None
    world = World(task, 0)
    for stem in (task, f"{task}.bco"):
        if not (folder / f"{stem}.json").exists():
            continue
        record = json.loads((folder / f"{stem}.json").read_text())
        world.budget = budget = int(record["steps"])
        meta["commits"].add(record["commit"])
        meta["seconds"] += float(record["wall_seconds"])
        goals: dict = defaultdict(list)
        with open(folder / f"{stem}.csv") as f:
            for row in csv.DictReader(f):
                goals[row["agent"], int(row["seed"])].append((int(row["step"]), int(row["goals"])))
        for b, (agent, seed) in enumerate(zip(record["agents"], record["seeds"])):
            series = goals[agent, seed]
            world.runs[agent, seed] = {
                "first_goal": int(record["first_goal_step"][b]),
                "early": sum(g for step, g in series if step <= EARLY_STEPS),
                "late": sum(g for step, g in series if step > budget - LATE_STEPS),
                "greedy": float(record["greedy_percent_of_optimal"][b]),
            }
    return world


def load_minigrid(results: Path) -> tuple[dict, tuple[str, ...], dict, dict]:
    """preset → task → World; the tasks whose every cell but BCO's is recorded; the rows of
    the tables (BCO's only where its cells are recorded on every one of those tasks); task →
    the commits its records name and their wall seconds."""
    root = results / "benchmark" / "minigrid"
    data: dict = {preset: {} for preset in MINIGRID_PRESETS}
    meta: dict = {task: {"commits": set(), "seconds": 0.0} for task in MINIGRID_TASKS}
    for preset in MINIGRID_PRESETS:
        for task in MINIGRID_TASKS:
            world = load_minigrid_task(root / preset, task, meta[task])
            if world is not None:
                data[preset][task] = world
    tasks = tuple(t for t in MINIGRID_TASKS if all(t in data[p] for p in MINIGRID_PRESETS))
    with_bco = all(("bco", 0) in data[p][t].runs for t in tasks for p in ("paper", "explore-goals"))
    methods = {m: v for m, v in METHODS.items() if with_bco or v[0] != "bco"}
    return data, tasks, methods, meta


def minigrid_sections(results: Path) -> tuple[list[str], list[str], list[Test]] | None:
    """The MiniGrid tables: the leaderboards' section, "Does the hierarchy help?"'s section and
    their tests (own Holm families: ``minigrid leaderboard``, ``minigrid hierarchy``); None
    while no task is complete."""
    data, tasks, methods, by_task = load_minigrid(results)
    if not tasks:
        return None
    commits = sorted({c for t in tasks for c in by_task[t]["commits"]})
    minutes = sum(by_task[t]["seconds"] for t in tasks) / 60
    missing = [t for t in MINIGRID_TASKS if t not in tasks]
    tests = leaderboard_tests(data, tasks, methods, "minigrid leaderboard")
    family = hierarchy_tests(data, tasks, "minigrid hierarchy")
    board, mean_ranks = leaderboard_lines(data, tests, tasks, methods, "MiniGrid tasks", 3)
    budgets = ", ".join(f"{t} {data['paper'][t].budget // 1000}k" for t in tasks)
    about = (
        f"MiniGrid's key-and-door tasks (`experiments/benchmark/PROTOCOL.md`, amendment of "
        f"2026-11-29): {len(tasks)} tasks ({budgets} steps per run), seeds 0–19, random ties, "
        'the learner\'s options the primitives and its "go to and face X" skills, the MiniGrid '
        "mentor (optimal for its own right-handed skills). "
        + (
            "Not run yet: " + ", ".join(missing) + " (`python experiments/benchmark/"
            "run_benchmark.py --parts minigrid` runs what is missing). "
            if missing
            else ""
        )
        + (
            ""
            if len(methods) == len(METHODS)
            else "BCO's cells are not run yet on every task: its row is left out. "
        )
        + f"Runs recorded at commit {', '.join(f'`{c[:12]}`' for c in commits)} (their batches "
        f"took {minutes:.1f} min in all on the shared 2-core CPU); regenerated from the "
        "committed records (`experiments/results/benchmark/minigrid/`) by `python "
        "experiments/benchmark/analyse.py`. Its own Holm families (not mixed with the nine "
        "worlds'); ▲ / ▼ as above."
    )
    leaderboard = [
        "## MiniGrid's tasks",
        "",
        about,
        "",
        *mean_rank_lines(mean_ranks, methods, "the MiniGrid tasks"),
        *board,
        "### Each method under both schedules (descriptive)",
        "",
        *exploration_lines(data, tasks, methods, 4),
    ]
    hierarchy = ["## MiniGrid's tasks", "", about, "", *hierarchy_lines(data, family, tasks, 3)]
    return leaderboard, hierarchy, tests + family


def minigrid_page(sections: tuple[list[str], list[str], list[Test]]) -> str:
    """``minigrid.md``: the two MiniGrid sections alone."""
    leaderboard, hierarchy, _ = sections
    return "\n".join([
        "# The benchmark on MiniGrid's tasks (generated by `experiments/benchmark/analyse.py`)",
        "",
        "The MiniGrid sections of `leaderboard.md` and `hierarchy.md` on one page.",
        "",
        "## The leaderboards",
        "",
        *leaderboard[2:],
        "## Does the hierarchy help? Eq. 2 − eq. 1 under the same settings",
        "",
        *hierarchy[2:],
    ]) + "\n"  # fmt: skip


# --------------------------------------------------------------------------------------- main
def write_csv(path: Path, tests: list[Test]) -> None:
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["family", "cell", "world", "comparison", "endpoint", *claims.RESULT_COLUMNS])
        for t in tests:
            w.writerow([t.table, t.claim, t.world, t.comparison, t.endpoint,
                        *claims.result_cells(t)])  # fmt: skip


def provenance(results: Path) -> str:
    root = results / "benchmark"
    commits = set()
    for preset in {p for pair in SCHEDULES.values() for p in pair}:
        for path in (root / preset).glob("*/worlds/*.json"):
            commits.add(json.loads(path.read_text()).get("commit"))
        for path in (root / preset).glob("gymnasium/tasks/*.json"):
            commits.add(json.loads(path.read_text()).get("commit"))
    if (root / "puzzlebox" / "commit.txt").exists():
        commits.add((root / "puzzlebox" / "commit.txt").read_text().strip())
    timing_path = root / "timing.json"
    timing = json.loads(timing_path.read_text()) if timing_path.exists() else {}
    time_text = (
        "Wall time of `python experiments/benchmark/run_benchmark.py` on a 2-core CPU, by part: "
        + ", ".join(f"{part} {seconds / 60:.1f} min" for part, seconds in sorted(timing.items()))
        + f" (in all {sum(timing.values()) / 60:.1f} min)."
        if timing
        else ""
    )
    named = ", ".join(f"`{c[:12]}`" for c in sorted(c for c in commits if c)) or "not recorded"
    return (
        f"Runs recorded at commit {named}; regenerated from the committed records by `python "
        f"experiments/benchmark/analyse.py`; the runs by `python "
        f"experiments/benchmark/run_benchmark.py`. {time_text}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--results", default="experiments/results")
    args = parser.parse_args()
    results = Path(args.results)
    out = results / "benchmark"
    data = load(results)
    global WORLDS
    if not data["paper"]["puzzlebox"].runs:
        print("no puzzle-box records: the tables leave it out", file=sys.stderr)
        WORLDS = NINE
    tests = leaderboard_tests(data)
    family = hierarchy_tests(data)
    board, mean_ranks = leaderboard_lines(data, tests)
    stress = stress_figures(results, out)
    hierarchy_figure(family, out)
    header = [
        "Every method under each exploration schedule, with the same seeds (0–19), mentor "
        "episodes and random numbers, random ties, the endpoints of "
        "`experiments/benchmark/PROTOCOL.md` (amendment of 2026-11-26). The greedy policy: "
        "ε = 0, ties random, and at a state where the run tried none of its options a uniform "
        "choice among its available options (the rule `uniform`, as the learner acts). "
        + provenance(results),
        "",
    ]
    lines = [
        "# The leaderboards, one per exploration schedule (generated by "
        "`experiments/benchmark/analyse.py`)",
        "",
        *header,
        "Each cell: the value, then its **average rank** among the nine rows on that world "
        "(exact ties share the mean of the ranks they span). **▲ / ▼**: better / worse than "
        "implicit imitation (eq. 1, no fading) under the same schedule, paired by seed, "
        "Holm-adjusted p < 0.05 (the smaller of the t-test's and the sign test's; Holm over "
        "every comparison of both schedules' tables; every test with its raw and adjusted p: "
        "`leaderboard.csv`). " + batch_check(results, data),
        "",
        *mean_rank_lines(mean_ranks),
        *board,
        "## Each method under both schedules (descriptive)",
        "",
        *exploration_lines(data),
        "## Stresses on experiment 2 (40×40, the paper preset for every agent): the greedy "
        "policy at the end, % of optimal (mean [95 % BCa]); the first goal (KM median); runs "
        "whose greedy policy is stuck (0 %)",
        "",
        "20 seeds per cell; one setting changed at a time from the baseline (the defaults). "
        "Figures: `stress_<setting>.png`.",
        "",
        *stress,
        "",
    ]
    hierarchy = [
        "# Does the hierarchy help? Eq. 2 against eq. 1 under the same settings (generated by "
        "`experiments/benchmark/analyse.py`)",
        "",
        *header,
        "Eq. 2 (`imitation`: the learner's options, the mentor term in the max) against eq. 1 "
        "(`imitation_primitives`: primitives, Price & Boutilier's implicit imitation), within "
        "each cell of schedule × mentor fading, paired by seed. Each cell: the mean difference "
        "[95 % BCa interval] (seeds where eq. 2 is higher – lower); first goal: seeds where "
        "eq. 2 found it first – where eq. 1 did, and the two KM medians. **▲ / ▼**: eq. 2 "
        "better / worse, Holm-adjusted p < 0.05 over this family (every p-value of this page: "
        "`leaderboard.csv`, family `hierarchy`). Figure: `hierarchy.png`.",
        "",
        *hierarchy_lines(data, family),
    ]
    minigrid = minigrid_sections(results)
    if minigrid is not None:  # (MiniGrid's tables after the nine worlds', amendment 2026-11-29)
        lines += ["", *minigrid[0]]
        hierarchy += ["", *minigrid[1]]
        (out / "minigrid.md").write_text(minigrid_page(minigrid))
    (out / "leaderboard.md").write_text("\n".join(lines) + "\n")
    (out / "hierarchy.md").write_text("\n".join(hierarchy) + "\n")
    write_csv(out / "leaderboard.csv", tests + family + (minigrid[2] if minigrid else []))
    print((out / "leaderboard.md").read_text())
    print((out / "hierarchy.md").read_text())


if __name__ == "__main__":
    main()
