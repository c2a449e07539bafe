"""Where hierarchy pays (PROTOCOL.md, amendment of 2026-11-29): each question's tables and
paired tests, every gain split into the options' own effect and imitation's.

    python experiments/hierarchy/where_pays.py [--results experiments/results/hierarchy]

Reads the records of the round's runs (Q1 on a Gymnasium task: ``<results>/q1_<task>_<schedule>/``,
a ``himit run gymnasium`` run directory's ``config.json`` and ``tasks/<task>.{json,csv}``; Q2's
sweeps and MiniGrid cells; Q3's transfer cells ``<results>/q3_<task>_iv<value>_<schedule>/``;
F's cells; the puzzle box's ``q1_puzzlebox4_<schedule>``, ``f_puzzlebox4_<schedule>_n<N>`` and
``q3_puzzlebox5_iv<value>_<schedule>``, ``puzzle_box_round.py``'s per-learner batches);
writes ``<results>/where_pays.md`` and ``<results>/where_pays_tests.csv``. A cell whose records
are absent is left out, and the page says so.

The split (the protocol's "controls"): per seed, the options' own effect is options-only −
primitives-only; eq. 2's imitation effect is eq. 2 − options-only, eq. 1's is eq. 1 −
primitives-only; hierarchy's effect on imitation is the difference of the two imitation
effects. Endpoints: the greedy policy at the end as an exact % of the optimum; the first goal
(the sign test on who reached it first, "never" losing to any finite step; for hierarchy's
effect, the sign of the difference of the two speed-ups, "never" censored at the budget);
goals in the first quarter of the budget (the windows that end within it). Q3 adds, in its
family, each imitator's imitation effect at initial value 0 − at −1 (the inert-mentor
mechanism) and its transfer's cost (the moved goal's mentor − its own task's, Q1's cell).
"""

from __future__ import annotations

import argparse
import csv
import json
import re
import subprocess
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import fifth_skewer
import numpy as np
from common import (
    HERE,
    SCHEDULES,
    Test,
    adjust,
    compare_values,
    distinct_comparisons,
    load_runs,
    show_test,
)

from himit_torch.statistics import (
    bca_interval,
    first_goal_survival,
    paired_comparison,
)

#: Q1's Gymnasium tasks: the task's name in ``himit run gymnasium`` → its label.
Q1_TASKS = {
    "taxi": "Taxi",
    "doorkey5x5": "DoorKey 5×5",
    "doorkey6x6": "DoorKey 6×6",
    "unlock": "Unlock",
    "doorkey8x8": "DoorKey 8×8",
    "keycorridors3r1": "KeyCorridor S3R1",
    "multiroomn4s5": "MultiRoom N4S5",
}
#: Q2's worlds (sweep bases) and observations: label → (the imitators' sweep, its stride or
#: None); the no-mentor controls are ``q2_controls_<world>``, shared by the observations.
Q2_WORLDS = {"exp2": ("exp2, 40×40", 200_000), "exp1": ("exp1, 80×80", 300_000)}
Q2_OBSERVATIONS = {
    "option ends": ("q2_ends", None),
    "stride 10": ("q2_stride", "10"),
    "stride 20": ("q2_stride", "20"),
}
#: Q2 on MiniGrid: Q1's tasks, the cells' observation names → labels (controls: Q1's cells).
Q2_MINIGRID = ("doorkey5x5", "doorkey6x6", "unlock")
Q2_MINIGRID_OBSERVATIONS = {"ends": "option ends", "stride10": "stride 10", "stride20": "stride 20"}
#: Q3's transfer tasks (``himit run minigrid``'s): the registered task → (the learner's task,
#: whose Q1 cell is the same task's mentor, or None; its label); its initial values → labels.
Q3_TASKS = {
    "doorkey5x5_transfer": ("doorkey5x5", "DoorKey 5×5, mentor's goal (3, 2)"),
    "doorkey6x6_transfer": ("doorkey6x6", "DoorKey 6×6, mentor's goal (4, 2)"),
    "doorkey8x8_transfer": ("doorkey8x8", "DoorKey 8×8, mentor's goal (6, 1)"),
}
Q3_VALUES = {"-1": "initial value −1", "0": "initial value 0"}
#: Q3 on the multi-room world (amendment "Q3 (transfer) on the multi-room world"): the sweep →
#: (its cells' task name, label, budget, the sweep whose trial-on imitators watched the
#: learner's own task: transfer's cost).
Q3_SWEEPS = {
    "q3_multirooms_exp1": (
        "exp1_top_right",
        "exp1, 80×80, mentor's goal the top-right corner",
        300_000,
        "trial_exp1",
    ),
}
#: Q3 with options discovered from the mentor's states (amendment "Q3 on the multi-room world with
#: options discovered from the mentor's states"): the cells' task name → (label, budget, each
#: ``himit run discovery`` record's name before ``_iv<value>_<schedule>``). The discovered learners
#: take the places of eq. 2 and options only; eq. 1 and primitives only are the same study's runs.
Q3_DISCOVERED = {
    "exp1_top_right_discovered": (
        "exp1, 80×80, mentor's goal the top-right corner, discovered options",
        300_000,
        "q3_discovered_exp1",
    ),
}
#: A discovery record's learners → the places they take in a cell.
DISCOVERED_AGENTS = {
    "discovered_imitation": "imitation",
    "discovered_options": "options",
    "imitation_primitives": "imitation_primitives",
    "primitives": "primitives",
}
#: Each Q3 task's own-task cell's name (its mentor demonstrating the learner's own task).
Q3_OWN_TASK = {
    **{transfer: task for transfer, (task, _) in Q3_TASKS.items()},
    **{task: f"{own}_own" for task, _, _, own in Q3_SWEEPS.values()},
}
#: The puzzle box's cells (amendment "Q1 and Q3 on the puzzle box", ``puzzle_box_round.py``):
#: task → label; Q1's is the 4-skewer box, Q3's the 5-skewer box watching the 4-skewer mentor.
#: Their endpoint 1 is ``V^π(start) − V*(start)`` in value units, not a % of the optimum (the
#: amendment says why): shown to 4 decimals, left out of the figure.
BOX_TASKS = {
    "puzzlebox4": "Puzzle box, 4 skewers",
    "puzzlebox5": "Puzzle box, 5 skewers, the 4-skewer mentor mapped in (plain)",
}
BOX_Q1, BOX_Q3 = "puzzlebox4", "puzzlebox5"
#: The box's endpoint 1, as the tables name it.
BOX_GREEDY = "greedy policy at the end, V^π(start) − V*(start)"
#: The box's cells whose runs have H2's settings (``puzzlebox_trial``): cell → {agent: H2's
#: batch} (the check the amendment names).
BOX_H2_CHECKS = {
    "q1_puzzlebox4_paper": {
        "imitation": "speed_imitation",
        "options": "speed_options",
        "primitives": "speed_primitives",
    },
    "q3_puzzlebox5_iv-1_paper": {"imitation": "transfer_plain", "options": "transfer_options"},
}
#: F's tries (``mentor_feasibility``), each against Q1's eq. 2 cell (trial alone).
F_TRIES = (1, 3)
#: The per-window columns that make a run's record (a decision that differs changes them).
RECORD_COLUMNS = ("step", "goals", "episodes", "epsilon", "value_gap", "mentor_term_wins")
#: The four learners of every cell: eq. 2, its no-mentor control, eq. 1, its no-mentor control.
EQ2, OPTIONS, EQ1, PRIMITIVES = "imitation", "options", "imitation_primitives", "primitives"
#: Each imitator's no-mentor control (the same options, no mentor).
CONTROL = {EQ2: OPTIONS, EQ1: PRIMITIVES}
AGENT_LABELS = {
    EQ2: "eq. 2",
    OPTIONS: "options only",
    EQ1: "eq. 1",
    PRIMITIVES: "primitives only",
}
ENDPOINTS = {
    "greedy": "greedy policy at the end, % of the optimum",
    "first_goal": "first goal",
    "goals_q1": "goals in the first quarter of the budget",
}


@dataclass(frozen=True)
class Cell:
    """One task × schedule: per agent, per-seed endpoint arrays (seeds in the same order)."""

    task: str
    schedule: str
    budget: int
    commit: str
    seeds: tuple[int, ...]
    greedy: dict[str, np.ndarray]
    first_goal: dict[str, np.ndarray]  # steps, −1 for a run that never reached the goal
    goals_q1: dict[str, np.ndarray]
    quarter_steps: int  # the steps the first-quarter goals cover (whole windows)
    condition: str = ""  # Q2's observation ("" for Q1)


def load_gymnasium_cell(directory: Path, task: str, schedule: str) -> Cell:
    """A ``himit run gymnasium`` run directory's records of ``task`` as a :class:`Cell`."""
    config = json.loads((directory / "config.json").read_text())
    summary = json.loads((directory / "tasks" / f"{task}.json").read_text())
    budget = int(summary["steps"])
    window = int(config["window"])
    quarter = (budget // 4) // window * window
    runs = list(zip(summary["agents"], summary["seeds"]))
    seeds = tuple(sorted({int(s) for _, s in runs}))

    def per_agent(values) -> dict[str, np.ndarray]:
        out: dict[str, dict[int, float]] = {}
        for (agent, seed), v in zip(runs, values):
            out.setdefault(agent, {})[int(seed)] = float(v)
        return {a: np.array([by[s] for s in seeds]) for a, by in out.items()}

    first = [
        -1 if step is None or (isinstance(step, float) and not np.isfinite(step)) else step
        for step in summary["first_goal_step"]
    ]
    goals: dict[tuple[str, int], float] = {}
    with (directory / "tasks" / f"{task}.csv").open() as f:
        for row in csv.DictReader(f):
            if int(row["step"]) <= quarter:
                key = (row["agent"], int(row["seed"]))
                goals[key] = goals.get(key, 0.0) + float(row["goals"])
    return Cell(
        task=task,
        schedule=schedule,
        budget=budget,
        commit=str(summary.get("commit", "?"))[:7],
        seeds=seeds,
        greedy=per_agent(summary["greedy_percent_of_optimal"]),
        first_goal=per_agent(first),
        goals_q1=per_agent([goals.get((a, int(s)), 0.0) for a, s in runs]),
        quarter_steps=quarter,
    )


def load_box_cell(directory: Path, task: str, schedule: str, condition: str = "") -> Cell:
    """A puzzle-box cell (``puzzle_box_round.py``'s records: ``config.json``, ``commit.txt``, per
    learner ``batches/<agent>.json`` and ``.csv``) as a :class:`Cell`: endpoint 1 each run's final
    greedy value minus the box's ``V*(start)``; first openings (−1: never); openings in the
    windows that end within the first quarter of the budget.

    Raises:
        ValueError: the learners' seeds or budgets differ."""
    window = int(json.loads((directory / "config.json").read_text())["window"])
    commit_path = directory / "commit.txt"
    commit = commit_path.read_text().strip()[:7] if commit_path.exists() else "?"
    paths = sorted((directory / "batches").glob("*.json"))
    batches = {p.stem: json.loads(p.read_text()) for p in paths}
    budgets = {int(b["steps"]) for b in batches.values()}
    seed_lists = {tuple(int(r["seed"]) for r in b["runs"]) for b in batches.values()}
    if len(budgets) != 1 or len(seed_lists) != 1:
        raise ValueError(f"load_box_cell: {directory}: the learners' seeds or budgets differ")
    (budget,), (seeds,) = budgets, seed_lists
    quarter = (budget // 4) // window * window
    greedy, first, goals = {}, {}, {}
    for agent, batch in batches.items():
        runs = batch["runs"]
        greedy[agent] = np.array([float(r["greedy_value"]) - batch["value_star"] for r in runs])
        first[agent] = np.array([int(r["first_opening"]) for r in runs])
        early = dict.fromkeys(seeds, 0.0)
        with (directory / "batches" / f"{agent}.csv").open() as f:
            for row in csv.DictReader(f):
                if int(row["step"]) <= quarter:
                    early[int(row["seed"])] += float(row["openings"])
        goals[agent] = np.array([early[s] for s in seeds])
    return Cell(task, schedule, budget, commit, seeds, greedy, first, goals, quarter, condition)


def box_cell_complete(directory: Path, agents=tuple(AGENT_LABELS)) -> bool:
    """Whether a box cell's records hold every one of ``agents``' batches (a cell still running
    has only some)."""
    return all((directory / "batches" / f"{a}.json").exists() for a in agents)


def box_window_records(directory: Path) -> dict[tuple[str, int], tuple]:
    """Each box run's record by (agent, seed): its windows' (step, openings, ε) as written, then
    its final greedy value and first opening (a decision that differs changes them)."""
    out: dict[tuple[str, int], list] = {}
    for path in sorted((directory / "batches").glob("*.csv")):
        with path.open() as f:
            for row in csv.DictReader(f):
                key = (path.stem, int(row["seed"]))
                out.setdefault(key, []).append((row["step"], row["openings"], row["epsilon"]))
        for run in json.loads(path.with_suffix(".json").read_text())["runs"]:
            out[path.stem, int(run["seed"])].append((run["greedy_value"], run["first_opening"]))
    return {k: tuple(v) for k, v in out.items()}


def box_h2_check(results: Path, name: str) -> list[tuple[str, int, int]]:
    """The amendment's check of a box cell against H2's ``puzzlebox_trial`` record: per agent
    of :data:`BOX_H2_CHECKS`, the seeds whose first opening, openings and final greedy value are
    equal, of those compared (``[]`` where either record is absent)."""
    h2_path = results / "puzzlebox_trial" / "summary.json"
    if name not in BOX_H2_CHECKS or not h2_path.exists():
        return []
    h2 = {b["batch"]: b for b in json.loads(h2_path.read_text())["batches"]}
    out = []
    for agent, tag in BOX_H2_CHECKS[name].items():
        path = results / name / "batches" / f"{agent}.json"
        if not path.exists() or tag not in h2:
            continue
        theirs = {r["seed"]: r for r in h2[tag]["runs"]}
        keys = ("first_opening", "openings", "greedy_value")
        mine = json.loads(path.read_text())["runs"]
        equal = sum(all(r[k] == theirs[r["seed"]][k] for k in keys) for r in mine)
        out.append((agent, equal, len(mine)))
    return out


def digits(world: str) -> int:
    """How many decimals endpoint 1 is shown with: 4 on the box (value units), else 1."""
    return 4 if world in BOX_TASKS else 1


def endpoint_name(world: str, endpoint: str) -> str:
    """An endpoint's name in a table (the box's endpoint 1 is its value, not a %)."""
    return BOX_GREEDY if world in BOX_TASKS and endpoint == "greedy" else ENDPOINTS[endpoint]


def label(world: str, condition: str = "") -> str:
    """A condition's name on the page: the task or world, and Q2's observation or Q3's initial
    value."""
    if world in BOX_TASKS:
        name = BOX_TASKS[world]
    elif world in Q1_TASKS:
        name = Q1_TASKS[world]
    elif world in Q3_TASKS:
        name = Q3_TASKS[world][1]
    elif world in {task for task, *_ in Q3_SWEEPS.values()}:
        (name,) = [name for task, name, *_ in Q3_SWEEPS.values() if task == world]
    elif world in Q3_DISCOVERED:
        name = Q3_DISCOVERED[world][0]
    else:
        name = Q2_WORLDS[world][0]
    return f"{name}, {condition}" if condition else name


def sweep_cell(runs: list[dict], windows: list[dict], world: str, schedule: str,
               condition: str, budget: int, commit: str) -> Cell:  # fmt: skip
    """A Q2 cell from sweep records: ``runs`` (``runs.csv`` rows) and ``windows``
    (``results.csv`` rows) of the four learners, one world, schedule and observation.

    Raises:
        ValueError: a learner's seeds differ from the others'."""
    by = {(r["agent"], int(r["seed"])): r for r in runs}
    seeds = tuple(sorted({s for _, s in by}))
    if len(by) != len(seeds) * len({a for a, _ in by}):
        raise ValueError(f"sweep_cell: {world} {condition} {schedule}: the learners' seeds differ")
    goals: dict[tuple[str, int], float] = {}
    for row in windows:
        if int(row["step"]) <= budget // 4:
            key = (row["agent"], int(row["seed"]))
            goals[key] = goals.get(key, 0.0) + float(row["goals_in_window"])
    agents = sorted({a for a, _ in by})

    def per_agent(value) -> dict[str, np.ndarray]:
        return {a: np.array([value(a, s) for s in seeds]) for a in agents}

    return Cell(
        task=world,
        schedule=schedule,
        budget=budget,
        commit=commit,
        seeds=seeds,
        greedy=per_agent(lambda a, s: float(by[a, s]["greedy_percent_of_optimal"])),
        first_goal=per_agent(lambda a, s: int(float(by[a, s]["first_goal_step"]))),
        goals_q1=per_agent(lambda a, s: goals.get((a, s), 0.0)),
        quarter_steps=budget // 4,
        condition=condition,
    )


def read_sweep(results: Path, name: str, missing: list[str]):
    """A committed sweep's ``(runs, windows, commits)``: its ``runs.csv`` and ``results.csv``
    rows and its trials' distinct commits, short; ``None`` (its name added to ``missing``)
    where its records are absent."""
    directory = results / name
    if not (directory / "runs.csv").exists():
        missing.append(name)
        return None
    with (directory / "runs.csv").open() as f:
        runs = list(csv.DictReader(f))
    with (directory / "results.csv").open() as f:
        windows = list(csv.DictReader(f))
    commit = json.loads((directory / "sweep.json").read_text()).get("commit", "?")
    # a sweep's record lists its trials' commits: the distinct ones, short
    commits = commit if isinstance(commit, list) else [commit]
    return runs, windows, ", ".join(sorted({str(c)[:7] for c in commits}))


def load_q2_cells(results: Path) -> tuple[list[Cell], list[str]]:
    """Q2's cells from the committed sweeps (those present), and the sweeps absent."""
    cells: list[Cell] = []
    missing: list[str] = []

    for world, (_, budget) in Q2_WORLDS.items():
        controls = read_sweep(results, f"q2_controls_{world}", missing)
        for observation, (sweep, stride) in Q2_OBSERVATIONS.items():
            imitators = read_sweep(results, f"{sweep}_{world}", missing)
            if controls is None or imitators is None:
                continue
            for schedule in SCHEDULES:

                def keep(row, stride_of_cell, schedule=schedule):
                    return row["preset"] == schedule and (
                        stride_of_cell is None or row["observation_stride"] == stride_of_cell
                    )

                cells.append(
                    sweep_cell(
                        [r for r in imitators[0] if keep(r, stride)]
                        + [r for r in controls[0] if keep(r, None)],
                        [r for r in imitators[1] if keep(r, stride)]
                        + [r for r in controls[1] if keep(r, None)],
                        world,
                        schedule,
                        observation,
                        budget,
                        imitators[2],
                    )
                )
    for task in Q2_MINIGRID:
        for short, observation in Q2_MINIGRID_OBSERVATIONS.items():
            for schedule in SCHEDULES:
                name = f"q2_{task}_{short}_{schedule}"
                directory, controls = results / name, results / f"q1_{task}_{schedule}"
                if not (directory / "tasks" / f"{task}.json").exists():
                    missing.append(name)
                    continue
                cell = load_gymnasium_cell(directory, task, schedule)
                base = load_gymnasium_cell(controls, task, schedule)
                if cell.seeds != base.seeds or cell.budget != base.budget:
                    raise ValueError(f"{name}: its seeds or budget differ from Q1's controls")

                def merged(field, cell=cell, base=base):
                    imitators = getattr(cell, field)
                    return {**{a: getattr(base, field)[a] for a in (OPTIONS, PRIMITIVES)},
                            **{a: imitators[a] for a in (EQ2, EQ1)}}  # fmt: skip

                cells.append(
                    replace(
                        cell,
                        greedy=merged("greedy"),
                        first_goal=merged("first_goal"),
                        goals_q1=merged("goals_q1"),
                        condition=observation,
                    )
                )
    return cells, sorted(set(missing))


#: The protocol's five contrasts: name → (a, b), each a function of the cell's per-agent arrays
#: giving per-seed values; the test is a − b paired by seed.
Contrast = tuple[Callable[[dict], np.ndarray], Callable[[dict], np.ndarray]]
CONTRASTS: dict[str, Contrast] = {
    "options' own effect (options only − primitives only)": (
        lambda v: v[OPTIONS],
        lambda v: v[PRIMITIVES],
    ),
    "eq. 2's imitation effect (eq. 2 − options only)": (lambda v: v[EQ2], lambda v: v[OPTIONS]),
    "eq. 1's imitation effect (eq. 1 − primitives only)": (
        lambda v: v[EQ1],
        lambda v: v[PRIMITIVES],
    ),
    "hierarchy's effect on imitation (eq. 2's − eq. 1's)": (
        lambda v: v[EQ2] - v[OPTIONS],
        lambda v: v[EQ1] - v[PRIMITIVES],
    ),
    "eq. 2 − eq. 1": (lambda v: v[EQ2], lambda v: v[EQ1]),
}
HIERARCHY = "hierarchy's effect on imitation (eq. 2's − eq. 1's)"
#: The endings of Q3's two other contrasts' names (after the imitator's label).
MECHANISM = "imitation effect, initial value 0 − −1"
COST = "moved goal's mentor − its own task's (Q1)"
OWN = "options' own effect (options only − primitives only)"
DIRECT = "eq. 2 − eq. 1"


def speed_ups(cell: Cell, agent: str) -> np.ndarray:
    """Per seed, how many steps sooner ``agent`` reached its first goal than its no-mentor
    control (:data:`CONTROL`), "never" counted at the budget (so that differences exist)."""
    censored = {a: np.where(x < 0, cell.budget, x) for a, x in cell.first_goal.items()}
    return censored[CONTROL[agent]] - censored[agent]


def compare_speed_ups(a: np.ndarray, b: np.ndarray) -> tuple[float, float, float, float, int, int]:
    """Two samples of speed-ups (:func:`speed_ups`) paired by seed: the mean difference with its
    95 % BCa interval, the sign test's p on the differences, the seeds won and lost by ``a``."""
    r = paired_comparison(a, b)
    return (r.difference.estimate, r.difference.low, r.difference.high, r.sign_p, r.wins,
            r.losses)  # fmt: skip


def cell_tests(family: str, cell: Cell) -> list[Test]:
    """The five contrasts × three endpoints of one cell, as unadjusted :class:`Test` rows."""
    out = []
    for name, (a, b) in CONTRASTS.items():
        for endpoint in ENDPOINTS:
            if endpoint == "first_goal":
                if name == HIERARCHY:
                    # speed-ups (positive: sooner); their difference's sign, paired by seed
                    result = compare_speed_ups(speed_ups(cell, EQ2), speed_ups(cell, EQ1))
                else:
                    result = compare_values(a(cell.first_goal), b(cell.first_goal), endpoint)
            else:
                values = getattr(cell, endpoint)
                result = compare_values(a(values), b(values), endpoint)
            out.append(Test(family, name, cell.task, cell.condition, cell.schedule, "", "",
                            endpoint, *result))  # fmt: skip
    return out


def helps(tests: list[Test], task: str, schedule: str, condition: str = "") -> tuple[bool, bool]:
    """(hierarchy helps imitation, eq. 2 significantly worse than eq. 1 on the greedy policy) at
    one condition, by the protocol's rule."""

    def find(name, endpoint):
        (t,) = [
            t
            for t in tests
            if (t.name, t.world, t.condition, t.schedule, t.endpoint)
            == (name, task, condition, schedule, endpoint)
        ]
        return t

    better = any(
        find(HIERARCHY, e).p_holm < 0.05 and find(HIERARCHY, e).difference > 0
        for e in ("greedy", "goals_q1")
    )
    worse = find(DIRECT, "greedy").p_holm < 0.05 and find(DIRECT, "greedy").difference < 0
    return better and not worse, worse


#: The learners' names in a discovered-options cell's table (:data:`DISCOVERED_AGENTS`).
DISCOVERED_LABELS = {
    EQ2: "eq. 2, discovered options",
    OPTIONS: "discovered options only",
    EQ1: "eq. 1",
    PRIMITIVES: "primitives only",
}


def agents_table(cells: list[Cell], label: str, names: dict[str, str] = AGENT_LABELS) -> list[str]:
    box = cells[0].task in BOX_TASKS
    lines = [
        f"### {label}: the four learners",
        "",
        "Mean of the seeds [95 % BCa interval of the mean]; first goal: Kaplan–Meier median "
        "('never': the curve does not fall to ½), and how many runs never reached the goal.",
        "",
        "| schedule | learner | greedy policy, "
        + ("V^π(start) − V*(start)" if box else "% of optimum")
        + " | first goal | goals, first quarter |",
        "|---|---|---|---|---|",
    ]
    for cell in cells:
        for agent, name in names.items():
            greedy = bca_interval(cell.greedy[agent]).format(digits(cell.task))
            goals = bca_interval(cell.goals_q1[agent]).format(0)
            s = first_goal_survival(cell.first_goal[agent], cell.budget)
            median = (
                "never"
                if not np.isfinite(s.median.estimate)
                else f"{s.median.estimate / 1000:.1f}k"
            )
            never = f"; {s.never}/{s.runs} never" if s.never else ""
            lines.append(
                f"| {SCHEDULES[cell.schedule]} | {name} | {greedy} | {median}{never} | {goals} |"
            )
    return lines + [""]


def tests_table(tests: list[Test], title: str, by_task: bool = False) -> list[str]:
    lines = [
        f"### {title}",
        "",
        "Each row: a − b paired by seed (mean difference [95 % BCa], seeds a won–lost), the "
        "paired t-test's p (greedy policy, goals) or the sign test's (first goal), Holm's p "
        "over the family.",
        "",
        "| contrast | schedule | endpoint | difference | p | Holm p | |",
        "|---|---|---|---|---|---|---|",
    ]
    if by_task:
        lines[-2:] = ["| contrast | task | schedule | endpoint | difference | p | Holm p | |",
                      "|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for t in tests:
        box_value = t.world in BOX_TASKS and t.endpoint == "greedy"
        shown = show_test(replace(t, endpoint="value gap") if box_value else t)
        if t.endpoint == "first_goal" and (t.name == HIERARCHY or MECHANISM in t.name):
            # the mean of the seeds' differences of speed-ups (not a median of first goals)
            shown = shown.replace("median", "mean").replace("sooner", "more speed-up")
            shown = shown.replace("later", "less speed-up")
        task = f" {label(t.world, t.condition)} |" if by_task else ""
        lines.append(
            f"| {t.name} |{task} {SCHEDULES[t.schedule]} | {endpoint_name(t.world, t.endpoint)} "
            f"| {shown} |"
        )
    return lines + [""]


def window_records(directory: Path, task: str) -> dict[tuple[str, int], tuple]:
    """Each run's per-window record (:data:`RECORD_COLUMNS`, as written) by (agent, seed)."""
    out: dict[tuple[str, int], list] = {}
    with (directory / "tasks" / f"{task}.csv").open() as f:
        for row in csv.DictReader(f):
            key = (row["agent"], int(row["seed"]))
            out.setdefault(key, []).append(tuple(row[c] for c in RECORD_COLUMNS))
    return {k: tuple(v) for k, v in out.items()}


def runs_changed(a: dict, b: dict, agent: str = EQ2) -> tuple[int, int]:
    """(the runs of ``agent`` whose per-window record differs between the records ``a`` and
    ``b``, the runs compared), paired by seed.

    Raises:
        ValueError: the two records hold ``agent``'s runs for different seeds."""
    seeds = sorted(s for g, s in a if g == agent)
    if seeds != sorted(s for g, s in b if g == agent):
        raise ValueError(f"runs_changed: the records' seeds of {agent!r} differ")
    return sum(a[agent, s] != b[agent, s] for s in seeds), len(seeds)


def f_tests(trial: Cell, feasibility: Cell, tries: int) -> list[Test]:
    """F's contrasts at one task × schedule: eq. 2 with feasibility at ``tries`` − eq. 2 with
    trial alone (Q1's cell), paired by seed, × the three endpoints, unadjusted.

    Raises:
        ValueError: the two cells' seeds differ."""
    if trial.seeds != feasibility.seeds:
        raise ValueError("f_tests: the feasibility cell's seeds differ from the trial cell's")
    out = []
    for endpoint in ENDPOINTS:
        a, b = getattr(feasibility, endpoint)[EQ2], getattr(trial, endpoint)[EQ2]
        out.append(Test("F", f"N = {tries} − trial alone", trial.task, trial.condition,
                        trial.schedule, "", "", endpoint, *compare_values(a, b, endpoint)))  # fmt: skip
    return out


def box_f_section(results: Path, cell: Cell) -> tuple[list[Test], list[str], list[str]]:
    """F on a box's Q1 cell: each N's tests against Q1's eq. 2 (trial alone), its row of changed
    runs (no batch check: on the box each learner runs in a batch of its own), the cells absent."""
    tests, rows, missing = [], [], []
    base = box_window_records(results / f"q1_{cell.task}_{cell.schedule}")
    for tries in F_TRIES:
        directory = results / f"f_{cell.task}_{cell.schedule}_n{tries}"
        if not box_cell_complete(directory, (EQ2,)):
            missing.append(directory.name)
            continue
        tests += f_tests(cell, load_box_cell(directory, cell.task, cell.schedule), tries)
        changed, n = runs_changed(base, box_window_records(directory))
        rows.append(
            f"| {label(cell.task)} | {SCHEDULES[cell.schedule]} | N = {tries} | {changed} of {n} "
            "| – (a batch of its own) |"
        )
    return tests, rows, missing


def load_q3_cells(results: Path) -> tuple[list[Cell], list[str]]:
    """Q3's cells (``q3_<task>_iv<value>_<schedule>``, those present; their condition the
    initial value's label) and the cells absent."""
    cells, missing = [], []
    for transfer, (task, _) in Q3_TASKS.items():
        for value, condition in Q3_VALUES.items():
            for schedule in SCHEDULES:
                directory = results / f"q3_{task}_iv{value}_{schedule}"
                if not (directory / "tasks" / f"{transfer}.json").exists():
                    missing.append(directory.name)
                    continue
                cell = load_gymnasium_cell(directory, transfer, schedule)
                cells.append(replace(cell, condition=condition))
    for value, condition in Q3_VALUES.items():  # the puzzle box's transfer
        for schedule in SCHEDULES:
            directory = results / f"q3_{BOX_Q3}_iv{value}_{schedule}"
            if not box_cell_complete(directory):
                missing.append(directory.name)
                continue
            cells.append(load_box_cell(directory, BOX_Q3, schedule, condition))
    return cells, missing


def load_q3_sweep_cells(results: Path) -> tuple[list[Cell], list[Cell], list[str]]:
    """Q3's cells from its sweeps (:data:`Q3_SWEEPS`, those present): per initial value and
    schedule the four learners; the own-task cells their transfer's cost is measured against
    (the trial-on imitators of the sweep named there, task ``<sweep>_own``); the sweeps absent."""
    cells, own_cells, missing = [], [], []
    for name, (task, _, budget, own) in Q3_SWEEPS.items():
        found = read_sweep(results, name, missing)
        if found is None:
            continue
        runs, windows, commit = found
        for value, condition in Q3_VALUES.items():
            for schedule in SCHEDULES:

                def keep(row, value=value, schedule=schedule):
                    initial = float(row["learner.initial_value"])
                    return row["preset"] == schedule and initial == float(value)

                cells.append(
                    sweep_cell(
                        [r for r in runs if keep(r)],
                        [r for r in windows if keep(r)],
                        task,
                        schedule,
                        condition,
                        budget,
                        commit,
                    )  # fmt: skip
                )
        found = read_sweep(results, own, missing)
        if found is None:
            continue
        runs, windows, commit = found
        for schedule in SCHEDULES:

            def trial(row, schedule=schedule):
                return row["preset"] == schedule and row["learner.mentor_trial"] == "True"

            own_cells.append(
                sweep_cell(
                    [r for r in runs if trial(r)],
                    [r for r in windows if trial(r)],
                    f"{own}_own",
                    schedule,
                    "",
                    budget,
                    commit,
                )  # fmt: skip
            )
    return cells, own_cells, missing


def discovery_commit(directory: Path) -> str:
    """The commit a ``himit run discovery`` record's page names ("Runs recorded at commit …"),
    short; ``?`` where it names none."""
    page = directory / "results.md"
    text = page.read_text() if page.exists() else ""
    found = re.search(r"Runs recorded at commit `([0-9a-f]+)", text)
    return found.group(1)[:7] if found else "?"


def discovered_cell(directory: Path, task: str, schedule: str, condition: str,
                    budget: int) -> Cell:  # fmt: skip
    """A Q3 cell from a ``himit run discovery`` record (``runs.csv``, ``curves.csv``): its
    discovered learners in the places of eq. 2 and options only (:data:`DISCOVERED_AGENTS`),
    its primitives-only runs in eq. 1's and primitives only's."""

    def renamed(rows):
        return [{**r, "agent": DISCOVERED_AGENTS[r["agent"]]} for r in rows
                if r["agent"] in DISCOVERED_AGENTS]  # fmt: skip

    runs, windows = (renamed(load_runs(directory / f)) for f in ("runs.csv", "curves.csv"))
    return sweep_cell(runs, windows, task, schedule, condition, budget,
                      discovery_commit(directory))  # fmt: skip


def load_q3_discovered_cells(results: Path) -> tuple[list[Cell], list[str]]:
    """Q3's discovered-options cells (:data:`Q3_DISCOVERED`, those present) and those absent."""
    cells, missing = [], []
    for task, (_, budget, prefix) in Q3_DISCOVERED.items():
        for value, condition in Q3_VALUES.items():
            for schedule in SCHEDULES:
                directory = results / f"{prefix}_iv{value}_{schedule}"
                if not (directory / "runs.csv").exists():
                    missing.append(directory.name)
                    continue
                cells.append(discovered_cell(directory, task, schedule, condition, budget))
    return cells, missing


def summaries_equal(results: Path, name: str, sweep: str, agents: tuple[str, ...],
                    value: str, schedule: str) -> tuple[int, int]:  # fmt: skip
    """Of a discovery record's runs of ``agents`` (its primitives-only learners), how many have
    the same first goal, total goals and greedy policy's % of the optimum (to 4 decimals) as the
    same agent's and seed's run at ``value`` and ``schedule`` in the committed ``sweep``, and of
    how many the sweep holds (a check that a run does not depend on the study it ran in)."""
    ignored: list[str] = []
    theirs = read_sweep(results, sweep, ignored)
    mine = results / name / "runs.csv"
    if theirs is None or not mine.exists():
        return 0, 0
    by = {
        (r["agent"], int(r["seed"])): r
        for r in theirs[0]
        if r["preset"] == schedule and float(r["learner.initial_value"]) == float(value)
    }
    pairs = [(r, by[r["agent"], int(r["seed"])]) for r in load_runs(mine)
             if r["agent"] in agents and (r["agent"], int(r["seed"])) in by]  # fmt: skip
    equal = sum(
        int(a["first_goal_step"]) == int(float(b["first_goal_step"]))
        and int(a["total_goals"]) == int(float(b["total_goals"]))
        and round(float(a["greedy_percent_of_optimal"]), 4)
        == round(float(b["greedy_percent_of_optimal"]), 4)
        for a, b in pairs
    )
    return equal, len(pairs)


def imitation_effect(cell: Cell, agent: str, endpoint: str) -> np.ndarray:
    """Per seed, the imitator ``agent``'s imitation effect on ``endpoint``: ``agent`` − its
    no-mentor control; on the first goal, its speed-up (:func:`speed_ups`)."""
    if endpoint == "first_goal":
        return speed_ups(cell, agent)
    values = getattr(cell, endpoint)
    return values[agent] - values[CONTROL[agent]]


def mechanism_tests(cells: list[Cell]) -> list[Test]:
    """Q3's test of the inert-mentor mechanism, unadjusted: per task × schedule × imitator, its
    imitation effect at initial value 0 − at −1, paired by seed, on each endpoint (the first
    goal: the sign test on the difference of the two speed-ups).

    Raises:
        ValueError: the two initial values' cells hold different seeds."""
    by = {(c.task, c.condition, c.schedule): c for c in cells}
    out = []
    for (task, condition, schedule), zero in by.items():
        minus = by.get((task, Q3_VALUES["-1"], schedule))
        if condition != Q3_VALUES["0"] or minus is None:
            continue
        if zero.seeds != minus.seeds:
            raise ValueError(f"mechanism_tests: {task} {schedule}: the cells' seeds differ")
        for agent in CONTROL:
            for endpoint in ENDPOINTS:
                a, b = (
                    imitation_effect(zero, agent, endpoint),
                    imitation_effect(minus, agent, endpoint),
                )
                if endpoint == "first_goal":
                    result = compare_speed_ups(a, b)
                else:
                    result = compare_values(a, b, endpoint)
                out.append(Test("Q3", f"{AGENT_LABELS[agent]}'s {MECHANISM}", task, "",
                                schedule, "", "", endpoint, *result))  # fmt: skip
    return out


def transfer_cost_tests(cells: list[Cell], same_task: list[Cell]) -> list[Test]:
    """Q3's transfer's cost, unadjusted: per task with a Q1 cell × schedule × imitator, the
    imitator watching the moved goal's mentor (initial value −1) − the same imitator watching
    its own task's mentor (Q1's cell), paired by seed, on each endpoint.

    Raises:
        ValueError: a Q3 cell's seeds or budget differ from its Q1 cell's."""
    q1 = {(c.task, c.schedule): c for c in same_task}
    out = []
    for cell in cells:
        base = q1.get((Q3_OWN_TASK.get(cell.task, ""), cell.schedule))
        if cell.condition != Q3_VALUES["-1"] or base is None:
            continue
        if cell.seeds != base.seeds or cell.budget != base.budget:
            raise ValueError(f"transfer_cost_tests: {cell.task}: seeds or budget differ from Q1's")
        for agent in CONTROL:
            for endpoint in ENDPOINTS:
                result = compare_values(
                    getattr(cell, endpoint)[agent], getattr(base, endpoint)[agent], endpoint
                )
                out.append(Test("Q3", f"{AGENT_LABELS[agent]}: {COST}", cell.task, "",
                                cell.schedule, "", "", endpoint, *result))  # fmt: skip
    return out


def first_goals_equal(cell: Cell, agent: str) -> int:
    """The seeds at which the imitator ``agent`` reached its first goal at the same step as its
    no-mentor control (both never counts as equal): what an inert mentor predicts."""
    return int((cell.first_goal[agent] == cell.first_goal[CONTROL[agent]]).sum())


def figure(panels: list[tuple[str, list[Test], list[str]]], path: Path) -> None:
    """The greedy endpoint's paired differences with their 95 % BCa intervals, one panel per
    ``(title, tests, contrast names)``: Q1's and Q2's split per condition, F's N − trial alone."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    def key(t):
        return (t.world, t.condition, t.schedule)

    rows = max(len({key(t) for t in tests}) for _, tests, _ in panels)
    fig, axes = plt.subplots(
        1, len(panels), figsize=(6.5 * len(panels), 2.5 + 0.8 * rows), squeeze=False
    )
    for ax, (title, tests, names) in zip(axes[0], panels):
        greedy = [t for t in tests if t.endpoint == "greedy" and t.world not in BOX_TASKS]
        conditions = list(dict.fromkeys(key(t) for t in greedy))
        for k, name in enumerate(names):
            by = {key(t): t for t in greedy if t.name == name}
            offset = (k - (len(names) - 1) / 2) * 0.16
            ys = [i + offset for i, c in enumerate(conditions) if c in by]
            ts = [by[c] for c in conditions if c in by]
            ax.errorbar(
                [t.difference for t in ts],
                ys,
                xerr=[[t.difference - t.low for t in ts], [t.high - t.difference for t in ts]],
                fmt="o",
                ms=4,
                capsize=2,
                label=name,
            )
        ax.axvline(0, color="grey", lw=0.8)
        ax.set_yticks(range(len(conditions)))
        ax.set_yticklabels([f"{label(w, c)}, {s}" for w, c, s in conditions], fontsize=8)
        ax.invert_yaxis()
        ax.set_xlabel("difference in the greedy policy's % of the optimum (95 % BCa)")
        ax.set_title(title, fontsize=10)
        ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.12))
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def budget_line(rule: dict, task: str) -> str:
    """How the rule picked a MiniGrid task's budget (from ``q1_budget_rule.json``)."""
    r = rule[task]
    first = sorted(s for s in r["first_goal_step"] if s is not None)
    return (
        f" The budget is the rule's (options only, the paper's schedule, held-out seeds "
        f"{r['seeds'][0]}–{r['seeds'][-1]}, one run per seed at a cap of {r['cap']:,} steps): "
        f"{len(first)} of {len(r['seeds'])} reached the goal, the 10th at step {first[9]:,} "
        f"(first goals {first[0]:,}–{first[-1]:,}), so {r['budget']:,} steps, by which "
        f"{r['reached_by_budget']} of {len(r['seeds'])} had reached it."
    )


def verdict_lines(tests: list[Test], cells: list[Cell], question: str) -> list[str]:
    """One line per condition: the protocol's verdict and the split on the greedy policy."""
    lines = []
    for c in cells:
        h, w = helps(tests, c.task, c.schedule, c.condition)
        split = {
            t.name: t
            for t in tests
            if (t.world, t.condition, t.schedule, t.endpoint)
            == (c.task, c.condition, c.schedule, "greedy")
        }
        own, d = split[OWN], digits(c.task)
        box = "value, V^π(start) − V*(start)"
        unit = box if c.task in BOX_TASKS else "points of % of the optimum"
        lines.append(
            f"- **{question}, {label(c.task, c.condition)}, {SCHEDULES[c.schedule]}:** hierarchy "
            + ("**helps** imitation" if h else "does not help imitation")
            + " by the protocol's rule"
            + (" (eq. 2 significantly worse than eq. 1 on the greedy policy)" if w else "")
            + f". On the greedy policy ({unit}, mean [95 % BCa]): the "
            f"options' own effect {own.difference:+.{d}f} [{own.low:+.{d}f}, {own.high:+.{d}f}], "
            f"eq. 2's imitation effect {split[list(CONTRASTS)[1]].difference:+.{d}f}, eq. 1's "
            f"{split[list(CONTRASTS)[2]].difference:+.{d}f}, hierarchy's effect on imitation "
            f"{split[HIERARCHY].difference:+.{d}f} [{split[HIERARCHY].low:+.{d}f}, "
            f"{split[HIERARCHY].high:+.{d}f}]; eq. 2 − eq. 1 {split[DIRECT].difference:+.{d}f}."
        )
    return lines


#: The subgoal-mentor preset's own runs on seeds 0–19 (amendment "the preset": it fades, so its
#: results are its own runs): condition → (its record, stride or None, the (task, condition) of
#: the Q1 / Q2 cell shown beside it, paper's ε).
SUBGOAL_MENTOR = {
    "exp2, option ends": ("subgoal_mentor_ends_exp2", None, ("exp2", "option ends")),
    "exp2, stride 10": ("subgoal_mentor_stride_exp2", "10", ("exp2", "stride 10")),
    "exp2, stride 20": ("subgoal_mentor_stride_exp2", "20", ("exp2", "stride 20")),
    "exp1, option ends": ("subgoal_mentor_ends_exp1", None, ("exp1", "option ends")),
    "Taxi, every state": ("subgoal_mentor_taxi", None, ("taxi", "")),
}


def subgoal_mentor_lines(results: Path, cells: list[Cell]) -> list[str]:
    """The preset's results section: eq. 2 under ``subgoal-mentor`` on seeds 0–19 beside the
    same condition's committed cell (paper's ε: eq. 2 and eq. 1 with trial, and the segment
    term on Q2's worlds; options only). Empty where no record is there yet."""
    rows = []
    by = {(c.task, c.condition, c.schedule): c for c in cells}
    for condition, (name, stride, (task, observation)) in SUBGOAL_MENTOR.items():
        directory = results / name
        base = by.get((task, observation, "paper"))
        if base is None:
            continue
        if (directory / "runs.csv").exists():
            runs, windows = (load_runs(directory / f) for f in ("runs.csv", "results.csv"))
            if stride is not None:
                runs, windows = ([r for r in rows_ if r["observation_stride"] == stride]
                                 for rows_ in (runs, windows))  # fmt: skip
            cell = sweep_cell(runs, windows, task, "paper", observation, base.budget, "")
        elif (directory / "tasks" / f"{task}.json").exists():
            cell = load_gymnasium_cell(directory, task, "paper")
        else:
            continue
        if cell.seeds != base.seeds:
            raise ValueError(f"{name}: its seeds differ from the committed cell's")

        def shown(c: Cell, agent: str) -> str:
            return (f"{bca_interval(c.greedy[agent]).format(1)} "
                    f"({bca_interval(c.goals_q1[agent]).estimate:.0f})")  # fmt: skip

        rows.append(f"| {condition} | {shown(cell, EQ2)} | {shown(base, EQ2)} | "
                    f"{shown(base, EQ1)} | {shown(base, OPTIONS)} |")  # fmt: skip
    if not rows:
        return []
    return [
        "## The preset `subgoal-mentor` on seeds 0–19",
        "",
        "Chosen on held-out seeds 5000–5019 (`preset_choice.md`): the mentor-fade preset "
        "(`mentor_fade = 20`, the paper's ε) with the segment term and trial. It fades, so its "
        "results are its own runs on seeds 0–19 (eq. 2 alone), shown beside the committed cell "
        "of the same condition under the paper's ε (eq. 2 and eq. 1 with trial, with the "
        "segment term on exp2 and exp1; options only, no mentor). Greedy policy, % of the "
        "optimum, mean [95 % BCa]; in brackets the goals in the first quarter of the budget. "
        "A description: the amendment declared no test of the preset against these cells, and "
        "eq. 1 was not run with fading. Run: `python experiments/hierarchy/run_hierarchy.py "
        "--parts subgoal-mentor`.",
        "",
        "| condition | eq. 2, `subgoal-mentor` | eq. 2, no fading | eq. 1, no fading | "
        "options only |",
        "|---|---|---|---|---|",
        *rows,
        "",
    ]


def f_section(results: Path, cells: list[Cell]) -> tuple[list[Test], list[str], list[str]]:
    """F's tests (unadjusted), its table of changed runs, and its cells absent."""
    tests: list[Test] = []
    rows: list[str] = []
    missing: list[str] = []
    for cell in cells:
        q1_dir = results / f"q1_{cell.task}_{cell.schedule}"
        if cell.task in BOX_TASKS:
            box = box_f_section(results, cell)
            tests, rows, missing = tests + box[0], rows + box[1], missing + box[2]
            continue
        check = results / f"f_{cell.task}_{cell.schedule}_trial"
        if not (check / "tasks" / f"{cell.task}.json").exists():
            missing += [check.name, *(f"f_{cell.task}_{cell.schedule}_n{n}" for n in F_TRIES)]
            continue
        base = window_records(q1_dir, cell.task)
        changed_check, n_check = runs_changed(base, window_records(check, cell.task))
        for tries in F_TRIES:
            directory = results / f"f_{cell.task}_{cell.schedule}_n{tries}"
            if not (directory / "tasks" / f"{cell.task}.json").exists():
                missing.append(directory.name)
                continue
            tests += f_tests(cell, load_gymnasium_cell(directory, cell.task, cell.schedule), tries)
            changed, n = runs_changed(base, window_records(directory, cell.task))
            rows.append(
                f"| {label(cell.task)} | {SCHEDULES[cell.schedule]} | N = {tries} | "
                f"{changed} of {n} | {n_check - changed_check} of {n_check} |"
            )
    return tests, rows, missing


#: F on Q2's conditions (amendments "F on Q2's conditions", "F at Q2's strides 10 and 20"): on
#: Q2's sweep worlds eq. 2 with feasibility is the sweep ``f_<imitators' sweep>_<world>`` (trial
#: alone: Q2's ``<imitators' sweep>_<world>``, :data:`Q2_OBSERVATIONS`); on MiniGrid the cells
#: ``f_q2_<task>_<observation>_<schedule>_n<N>`` (trial alone: ``q2_<task>_<observation>_<schedule>``).
F_Q2_MINIGRID = {label: short for short, label in Q2_MINIGRID_OBSERVATIONS.items()}
#: The per-window columns of a sweep's ``results.csv`` that make a run's record.
SWEEP_RECORD_COLUMNS = ("step", "goals_in_window", "epsilon", "episodes", "backups", "decisions",
                        "mentor_term_wins")  # fmt: skip


def sweep_window_records(rows: list[dict]) -> dict[tuple[str, int], tuple]:
    """Each run's per-window record (:data:`SWEEP_RECORD_COLUMNS`, as written) by (agent, seed),
    from a sweep's ``results.csv`` rows of one cell."""
    out: dict[tuple[str, int], list] = {}
    for row in rows:
        out.setdefault((row["agent"], int(row["seed"])), []).append(
            tuple(row[c] for c in SWEEP_RECORD_COLUMNS)
        )
    return {k: tuple(v) for k, v in out.items()}


#: Why feasibility changed what it did at Q2's conditions: a reading of its mechanism, written
#: after the runs (not a test), shown under F's table of Q2's cells.
F_Q2_WHY = [
    "*Why* (a reading of the mechanism, not a test): the test drops the mentor term at a state "
    "only once every own option has been tried there N times without reaching the observed "
    "successor. At the option ends each observed move is one of the mentor's options, several "
    "primitive steps that no primitive makes, but on the rooms the learner's doorway (and "
    "corner) options end where the mentor's do, and they slip (10 % of moves): at N = 1 one "
    "missed try of each own option at a state drops the term, which happened in a few runs; at "
    "N = 3 it never did. On MiniGrid's tasks, which do not slip, no run changed at either N: "
    "either an own option reaches the observed state, or not every own option was tried there "
    "N times within the 10k steps; these runs do not tell the two apart. At a stride each "
    "observed move joins states up to 10 or 20 steps apart, where no primitive and, but by "
    "chance, no own option ends, so the mentor term leads eq. 2 toward moves it cannot make; "
    "the test drops those terms, and nearly every run changes (fewer on MiniGrid at stride 10, "
    "whose short episodes put more of the observed states one option apart). That is where "
    "feasibility pays, the stronger the sparser the observation: the segment term already "
    "scores a stride's move by its duration, but does not tell eq. 2 that its own options "
    "cannot make it.",
]


def f_q2_description(cells: list[Cell], f: list[Test]) -> list[str]:
    """Table rows: per Q2 condition × schedule with F's cells, the greedy policy's mean % of the
    optimum for eq. 2 with trial alone, with feasibility N = 1 and 3 (trial alone's mean + F's
    paired mean difference, the same seeds), eq. 1 and options only (Q2's cell): a description
    beside F's tests, no test of its own."""
    rows = []
    for cell in cells:
        by = {t.name: t.difference for t in f if (t.world, t.condition, t.schedule, t.endpoint)
              == (cell.task, cell.condition, cell.schedule, "greedy")}  # fmt: skip
        if not by:
            continue
        trial = float(np.mean(cell.greedy[EQ2]))
        with_n = [f"{trial + by[f'N = {n} − trial alone']:.1f}" for n in F_TRIES]
        rows.append(
            f"| {label(cell.task, cell.condition)} | {SCHEDULES[cell.schedule]} | {trial:.1f} | "
            + " | ".join(with_n)
            + f" | {np.mean(cell.greedy[EQ1]):.1f} | {np.mean(cell.greedy[OPTIONS]):.1f} |"
        )
    return rows


def f_q2_section(results: Path, cells: list[Cell]) -> tuple[list[Test], list[str], list[str]]:
    """F's tests on Q2's conditions (unadjusted), their table rows of changed runs, and the
    records absent."""
    tests: list[Test] = []
    rows: list[str] = []
    missing: list[str] = []
    for cell in cells:
        for tries in F_TRIES:
            if cell.task in Q2_WORLDS:
                prefix, stride = Q2_OBSERVATIONS[cell.condition]
                found = read_sweep(results, f"f_{prefix}_{cell.task}", missing)
                trial = read_sweep(results, f"{prefix}_{cell.task}", missing)
                if found is None or trial is None:
                    break

                def keep(row, tries=None, stride=stride, schedule=cell.schedule):
                    n = row.get("learner.mentor_feasibility", "")
                    return (row["preset"] == schedule and row["agent"] == EQ2
                            and (tries is None or n == str(tries))
                            and (stride is None or row["observation_stride"] == stride))  # fmt: skip

                runs, windows = ([r for r in rows_ if keep(r, tries)] for rows_ in found[:2])
                feasible = sweep_cell(runs, windows, cell.task, cell.schedule, cell.condition,
                                      cell.budget, found[2])  # fmt: skip
                base = [r for r in trial[1] if keep(r)]
                changed, n = runs_changed(sweep_window_records(base),
                                          sweep_window_records(windows))  # fmt: skip
            else:
                short = F_Q2_MINIGRID[cell.condition]
                name = f"f_q2_{cell.task}_{short}_{cell.schedule}_n{tries}"
                directory = results / name
                if not (directory / "tasks" / f"{cell.task}.json").exists():
                    missing.append(name)
                    continue
                feasible = load_gymnasium_cell(directory, cell.task, cell.schedule)
                trial_dir = results / f"q2_{cell.task}_{short}_{cell.schedule}"
                changed, n = runs_changed(window_records(trial_dir, cell.task),
                                          window_records(directory, cell.task))  # fmt: skip
            tests += f_tests(cell, feasible, tries)
            rows.append(
                f"| {label(cell.task, cell.condition)} | {SCHEDULES[cell.schedule]} | "
                f"N = {tries} | {changed} of {n} |"
            )
    return tests, rows, sorted(set(missing))


def q3_answer_lines(q3: list[Test], cells: list[Cell]) -> list[str]:
    """The answers' lines on Q3 beyond each condition's verdict: the mechanism (first goals equal
    to the control's; imitation effects at 0 − at −1) and transfer's cost."""
    if not cells:
        return []

    def shown(t: Test) -> str:
        mark = " (significant)" if t.p_holm < 0.05 else ""
        if t.endpoint == "first_goal":
            return f"{t.difference:+.0f} steps of speed-up, {t.wins}–{t.losses}{mark}"
        d = digits(t.world) if t.endpoint == "greedy" else 1
        return f"{t.difference:+.{d}f}{mark}"

    equal = "; ".join(
        f"{label(c.task, c.condition)}, {SCHEDULES[c.schedule]}: eq. 2 "
        f"{first_goals_equal(c, EQ2)}, eq. 1 {first_goals_equal(c, EQ1)}"
        for c in cells
    )
    mechanism = [t for t in q3 if MECHANISM in t.name]
    cost = [t for t in q3 if COST in t.name]

    def greedy(name: str) -> list[Test]:
        return [t for t in q3 if t.name == name and t.endpoint == "greedy"]

    n_helps = sum(helps(q3, c.task, c.schedule, c.condition)[0] for c in cells)
    direct = [t for t in greedy(DIRECT) if t.p_holm < 0.05 and t.difference > 0]
    own = {(t.world, t.condition, t.schedule): t for t in greedy(OWN)}
    eq2 = [t for t in greedy(list(CONTRASTS)[1]) if t.p_holm < 0.05]
    lines = [
        f"- **Q3 in short:** hierarchy helps imitation at {n_helps} of {len(cells)} transfer "
        f"conditions. Eq. 2 − eq. 1 on the greedy policy is significantly positive at "
        f"{len(direct)} of them"
        + (
            " ("
            + "; ".join(
                f"{label(t.world, t.condition)}, {SCHEDULES[t.schedule]}: "
                f"{t.difference:+.{digits(t.world)}f}, the options' own effect there "
                f"{own[t.world, t.condition, t.schedule].difference:+.{digits(t.world)}f}"
                for t in direct
            )
            + "): compare each with the options' own effect, which needs no mentor"
            if direct
            else ""
        )
        + f". Eq. 2's own imitation effect on the greedy policy is significant at {len(eq2)} of "
        f"{len(cells)}.",
        "- **Q3, the inert-mentor mechanism, counted:** imitators whose first goal came at the "
        f"same step as their no-mentor control's, of {len(cells[0].seeds)} seeds — {equal}.",
    ]
    if mechanism:
        lines.append(
            "- **Q3, the mechanism tested** (each imitator's imitation effect at initial value 0 "
            "− at −1, paired by seed; greedy policy in points, value units on the puzzle box; "
            "first goal in steps of speed-up; Holm over family Q3): "
            + "; ".join(
                f"{label(t.world)}, {SCHEDULES[t.schedule]}, {t.name.split(chr(39))[0]}: "
                f"greedy {shown(t)}"
                + "".join(
                    f", {ENDPOINTS[u.endpoint]} {shown(u)}"
                    for u in mechanism
                    if (u.world, u.schedule, u.name) == (t.world, t.schedule, t.name)
                    and u.endpoint != "greedy"
                )
                for t in mechanism
                if t.endpoint == "greedy"
            )
            + f". {sum(t.p_holm < 0.05 for t in mechanism)} of {len(mechanism)} significant."
        )
    if cost:
        lines.append(
            "- **Q3, transfer's cost** (an imitator watching the moved goal's mentor − the same "
            "imitator watching its own task's mentor, Q1's cell; initial value −1; greedy "
            "policy, points): "
            + "; ".join(
                f"{label(t.world)}, {SCHEDULES[t.schedule]}, {t.name.split(':')[0]} {shown(t)}"
                for t in cost
                if t.endpoint == "greedy"
            )
            + f". {sum(t.p_holm < 0.05 for t in cost)} of {len(cost)} contrasts (all endpoints) "
            "significant."
        )
    return lines


#: What a sweep's per-run summary says of a run (the columns compared by Q3's checks).
SUMMARY_COLUMNS = (
    "total_goals",
    "final_window_goals",
    "late_goals",
    "first_goal_step",
    "value_start",
    "mentor_term_wins",
    "greedy_percent_of_optimal",
    "greedy_value_start",
)


def same_runs(results: Path, sweep: str, other: str, agents: tuple[str, ...],
              keep: Callable[[dict], bool]) -> tuple[int, int]:  # fmt: skip
    """Of ``sweep``'s runs of ``agents`` that ``keep`` selects, how many have a per-run summary
    equal to the same agent's, seed's and schedule's in the sweep ``other``, and of how many
    that ``other`` has (a check that a run does not depend on the sweep it ran in)."""
    ignored: list[str] = []
    mine, theirs = read_sweep(results, sweep, ignored), read_sweep(results, other, ignored)
    if mine is None or theirs is None:
        return 0, 0
    by = {(r["agent"], r["seed"], r["preset"]): r for r in theirs[0] if r["agent"] in agents}
    pairs = [
        (r, by[r["agent"], r["seed"], r["preset"]])
        for r in mine[0]
        if r["agent"] in agents and keep(r) and (r["agent"], r["seed"], r["preset"]) in by
    ]
    equal = sum(all(a[c] == b[c] for c in SUMMARY_COLUMNS) for a, b in pairs)
    return equal, len(pairs)


def q3_sweep_paragraphs(results: Path, cells: list[Cell]) -> list[str]:
    """What Q3's multi-room cells are, and their checks against the earlier runs the amendment
    names (at initial value −1: the imitators H6b's, the controls Q2's)."""
    lines = []
    for sweep, (task, name, budget, own) in Q3_SWEEPS.items():
        if not any(c.task == task for c in cells):
            continue
        minus_one = lambda row: float(row["learner.initial_value"]) == -1.0  # noqa: E731
        imitators = same_runs(results, sweep, "other_goal_exp1", (EQ2, EQ1), minus_one)
        controls = same_runs(results, sweep, "q2_controls_exp1", (OPTIONS, PRIMITIVES), minus_one)
        lines += [
            f'**{name}** (amendment "Q3 (transfer) on the multi-room world"): the learner is '
            "rewarded at exp1's goal (the bottom-right corner); its mentor demonstrates its walk "
            "to the top-right corner cell (`mentor_goal`, H6's setting), which is no goal of the "
            "learner's. Four learners (eq. 2 and eq. 1 with trial; options only and primitives "
            f"only, no mentor), 20 seeds (0–19), {budget:,} steps a run, initial value −1 or 0 "
            f"for all four, both schedules. Transfer's cost is measured against H3's `{own}` "
            "cell with trial on (the mentor demonstrating the learner's own task). Run: `python "
            "experiments/hierarchy/run_hierarchy.py --parts q3mr`.",
            "",
            "*Check* (not a test), at initial value −1, each run's summary (goals, first goal, "
            "values, the greedy policy) against the same run in an earlier sweep: the imitators "
            f"against H6b's `other_goal_exp1`, {imitators[0]} of {imitators[1]} equal; the "
            f"controls against Q2's `q2_controls_exp1`, {controls[0]} of {controls[1]} equal.",
            "",
        ]
    return lines


def check_text(checks: list[tuple[str, int, int]]) -> str:
    """The box's check against H2's record, as a sentence's end."""
    return "; ".join(f"{AGENT_LABELS[a]} {equal} of {n}" for a, equal, n in checks)


def box_q1_lines(results: Path, cells: list[Cell], q1: list[Test]) -> list[str]:
    """Q1's puzzle-box section: the setting, the check against H2's record, the learners and
    the split."""
    if not cells:
        return []
    name = BOX_TASKS[BOX_Q1]
    checks = box_h2_check(results, f"q1_{BOX_Q1}_paper")
    return [
        f"{name} (`himit run puzzlebox`'s first finding, amendment \"Q1 and Q3 on the puzzle "
        'box"): '
        f"{len(cells[0].seeds)} seeds ({cells[0].seeds[0]}–{cells[0].seeds[-1]}; even seeds watch "
        "the skewer-by-skewer mentor, odd ones the step-by-step mentor, 20 episodes each) per "
        f"learner and schedule, {cells[0].budget:,} steps a run, each learner in a batch of its "
        "own (the study's `run_box_batch`); trial on for both imitators. Eq. 1 watches the same "
        "episodes: every mentor move is one step of the box, with the pinch grip, one of the "
        "learner's primitives. Endpoint 1 is the greedy policy's V^π(start) − V*(start) (value "
        "units: 0 is optimal; not a % of the optimum, the amendment says why; left out of the "
        f"figure); goals (openings) in the first quarter over the first {cells[0].quarter_steps:,} "
        "steps. Run: `python experiments/hierarchy/run_hierarchy.py --parts q1box`.",
        "",
        *(
            [
                "*Check* (not a test): under the paper's ε, the runs whose first opening, "
                "openings and final greedy value equal H2's `puzzlebox_trial` record (the same "
                f"settings): {check_text(checks)}.",
                "",
            ]
            if checks
            else []
        ),
        *agents_table(cells, name),
        *tests_table([t for t in q1 if t.world == BOX_Q1], f"{name}: the split, paired by seed"),
    ]


def box_q3_paragraphs(results: Path, cells: list[Cell]) -> list[str]:
    """What Q3's puzzle-box cells are, and their check against H2's record."""
    box = [c for c in cells if c.task == BOX_Q3]
    if not box:
        return []
    checks = box_h2_check(results, f"q3_{BOX_Q3}_iv-1_paper")
    return [
        '**The puzzle box** (amendment "Q1 and Q3 on the puzzle box"): the learner is rewarded '
        "when it opens the 5-skewer box; its mentor's episodes are Q1's 4-skewer episodes mapped "
        "in by the study's `plain` mapping (skewers 1–4 in place, skewer 5 stays in), so the "
        "mentor never shows a state where the learner's box is open. Four learners (eq. 2 and "
        "eq. 1 with trial; options only and primitives only, no mentor), each in a batch of its "
        f"own, 20 seeds (0–19), {box[0].budget:,} steps a run (the study's transfer budget), "
        "initial value −1 or 0 for all four, both schedules; endpoint 1 is the greedy policy's "
        "V^π(start) − V*(start) (value units, not a % of the optimum); goals in the first quarter "
        f"counted over the first {box[0].quarter_steps:,} steps. No transfer's cost: no cell has "
        "a mentor demonstrating the 5-skewer box. Run: `python "
        "experiments/hierarchy/run_hierarchy.py --parts q3box`.",
        "",
        *(
            [
                "*Check* (not a test): at initial value −1 under the paper's ε, the runs whose "
                "first opening, openings and final greedy value equal H2's `puzzlebox_trial` "
                f"record (`transfer_plain`, `transfer_options`: the same settings): {check_text(checks)}.",
                "",
            ]
            if checks
            else []
        ),
    ]


def q3_discovered_paragraphs(results: Path, cells: list[Cell]) -> list[str]:
    """What Q3's discovered-options cells are, the subgoals and options found, and the check of
    their primitives-only runs against the committed multi-room cells'."""
    lines = []
    for task, (name, budget, prefix) in Q3_DISCOVERED.items():
        mine = [c for c in cells if c.task == task]
        if not mine:
            continue
        checks, found, options = [], [], []
        for c in mine:
            value = next(v for v, text in Q3_VALUES.items() if text == c.condition)
            record = f"{prefix}_iv{value}_{c.schedule}"
            eq1 = summaries_equal(results, record, "q3_multirooms_exp1", (EQ1,), value, c.schedule)
            prims = summaries_equal(results, record, "q3_multirooms_exp1", (PRIMITIVES,), value,
                                    c.schedule)  # fmt: skip
            checks.append(
                f"{c.condition}, {SCHEDULES[c.schedule]}: eq. 1 {eq1[0]} of {eq1[1]}, "
                f"primitives only {prims[0]} of {prims[1]}"
            )
            found += load_runs(results / record / "subgoals.csv")
            options += [int(r["discovered_options"]) for r in load_runs(results / record /
                        "runs.csv") if r["discovered_options"]]  # fmt: skip
        per_seed = {int(r["seed"]): r for r in found}  # (the same episodes in every cell)
        precision = [float(r["precision"]) for r in per_seed.values()]
        recall = [float(r["recall_visited"]) for r in per_seed.values()]
        subgoals = [int(r["found"]) for r in per_seed.values()]
        lines += [
            f'**{name}** (amendment "Q3 on the multi-room world with options discovered from the '
            "mentor's states\"): the multi-room transfer above, its eq. 2 and options-only "
            "control given options discovered from each seed's demonstrations of the mentor's "
            "walk to the top-right corner (`himit run discovery --mentor-goal top-right`): each "
            "is its seed's primitives-only run (eq. 1's, primitives only's) up to the warm-up "
            "(20,000 steps), then the same run continued with the primitives and options to the "
            "subgoals found, built once from the run's own one-step counts. Trial on for the "
            f"imitators, 20 seeds (0–19), {budget:,} steps a run, initial value −1 or 0 for all "
            "four, both schedules. Run: `python experiments/hierarchy/run_hierarchy.py --parts "
            "q3disc`.",
            "",
            f"Subgoals found per seed: {np.mean(subgoals):.1f} (of {min(subgoals)}–"
            f"{max(subgoals)}), precision {np.mean(precision):.2f} and recall "
            f"{np.mean(recall):.2f} against the doorways the mentor passed (means over the 20 "
            f"seeds); options built per run at the warm-up: {np.mean(options):.1f} "
            f"({min(options)}–{max(options)}; an option is built where its subgoal lies within "
            "2 × 7 expected steps of some state in the run's own model).",
            "",
            "*Check* (not a test): each of the study's primitives-only runs against the same "
            "seed's run in the committed multi-room cells (`q3_multirooms_exp1`: the same world, "
            "mentor's goal, schedule, initial value, trial, seeds and budget), runs whose first "
            "goal, total goals and greedy policy's % of the optimum are equal — "
            + "; ".join(checks)
            + ". Where all are, eq. 1's imitation effect in these cells is the committed cells' "
            "pair of runs again.",
            "",
        ]
    return lines


def q3_section(results: Path, q3: list[Test], cells: list[Cell]) -> list[str]:
    """Q3's section: the setting, the check of its controls against Q1's, each task × initial
    value's learners and split, the mechanism's and transfer's cost's tests."""
    lines = [
        "## Q3, transfer to a task the mentor never showed",
        "",
        "The learner is rewarded on MiniGrid's DoorKey task (its goal in the bottom-right "
        "corner); its mentor demonstrates the same layout with the goal moved (5×5 to (3, 2) "
        "and 6×6 to (4, 2): one cell past the door, on the learner's way; 8×8 to (6, 1): one "
        "cell past the door the other way). The two tasks share the key and the door; the "
        "mentor never enters a state where the learner is rewarded. Four learners per task, "
        "initial value and schedule (eq. 2 and eq. 1 with trial; options only and primitives "
        "only, no mentor), 20 seeds (0–19), each task's Q1 budget by the rule; the initial value "
        "−1 (the runner's neutral value) or 0 for all four. Run: `python "
        "experiments/hierarchy/run_hierarchy.py --parts q3`.",
        "",
    ]
    rows = []
    for cell in cells:
        if cell.task not in Q3_TASKS:
            continue  # (the multi-room world's cells: checked below)
        task = Q3_TASKS[cell.task][0]
        q1_dir = results / f"q1_{task}_{cell.schedule}"
        q3_dir = results / f"q3_{task}_iv-1_{cell.schedule}"
        if cell.condition != Q3_VALUES["-1"] or not (q1_dir / "tasks").exists():
            continue
        base, mine = window_records(q1_dir, task), window_records(q3_dir, cell.task)
        counts = [runs_changed(base, mine, agent) for agent in (OPTIONS, PRIMITIVES)]
        rows.append(
            f"| {label(cell.task)} | {SCHEDULES[cell.schedule]} | "
            + " | ".join(f"{n - changed} of {n}" for changed, n in counts)
            + " |"
        )
    if rows:
        lines += [
            "*Check* (not a test): the no-mentor controls at initial value −1 against Q1's "
            "controls of the same task and schedule (same world, seeds, budget and settings), "
            "runs whose per-window record is equal. Where all are, the options' own effect there "
            "is Q1's pair of runs again (a repeat in the tally).",
            "",
            "| task | schedule | options only equal | primitives only equal |",
            "|---|---|---|---|",
            *rows,
            "",
        ]
    lines += q3_sweep_paragraphs(results, cells)
    lines += box_q3_paragraphs(results, cells)
    lines += q3_discovered_paragraphs(results, cells)
    for world, condition in dict.fromkeys((c.task, c.condition) for c in cells):
        group = [c for c in cells if (c.task, c.condition) == (world, condition)]
        name = label(world, condition)
        lines += agents_table(
            group, name, DISCOVERED_LABELS if world in Q3_DISCOVERED else AGENT_LABELS
        )
        lines += tests_table(
            [t for t in q3 if (t.world, t.condition) == (world, condition)],
            f"{name}: the split, paired by seed",
        )
    mechanism = [t for t in q3 if MECHANISM in t.name]
    if mechanism:
        lines += tests_table(
            mechanism,
            "Q3, the mechanism: imitation effect at initial value 0 − at −1",
            by_task=True,
        )
    cost = [t for t in q3 if COST in t.name]
    if cost:
        lines += tests_table(
            cost, "Q3, transfer's cost: the moved goal's mentor − the task's own (Q1)", by_task=True
        )
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--results", default=str(HERE.parent / "results" / "hierarchy"))
    args = parser.parse_args()
    results = Path(args.results)
    rule_path = results / "q1_budget_rule.json"
    rule = json.loads(rule_path.read_text()) if rule_path.exists() else {}
    cells, missing = [], []
    for task in Q1_TASKS:
        for schedule in SCHEDULES:
            directory = results / f"q1_{task}_{schedule}"
            if (directory / "tasks" / f"{task}.json").exists():
                cells.append(load_gymnasium_cell(directory, task, schedule))
            else:
                missing.append(directory.name)
    for schedule in SCHEDULES:  # the puzzle box's Q1 cells
        directory = results / f"q1_{BOX_Q1}_{schedule}"
        if box_cell_complete(directory):
            cells.append(load_box_cell(directory, BOX_Q1, schedule))
        else:
            missing.append(directory.name)
    q1 = adjust([t for cell in cells for t in cell_tests("Q1", cell)])
    q2_cells, q2_missing = load_q2_cells(results)
    missing += q2_missing
    q2 = adjust([t for cell in q2_cells for t in cell_tests("Q2", cell)])
    f_raw, f_rows, f_missing = f_section(results, cells)
    f_q2_raw, f_q2_rows, f_q2_missing = f_q2_section(results, q2_cells)
    missing += f_missing + f_q2_missing
    f = adjust(f_raw + f_q2_raw)
    q3_cells, q3_missing = load_q3_cells(results)
    q3_sweep_cells, q3_own_cells, q3_sweeps_missing = load_q3_sweep_cells(results)
    q3_discovered_cells, q3_discovered_missing = load_q3_discovered_cells(results)
    q3_cells += q3_sweep_cells + q3_discovered_cells
    missing += q3_missing + q3_sweeps_missing + q3_discovered_missing
    q3_split = [t for cell in q3_cells for t in cell_tests("Q3", cell)]
    # the discovered options' mechanism for their imitator only: eq. 1's runs there are the
    # study's primitives-only runs (checked against the committed cells' on the page)
    mechanism = [t for t in mechanism_tests(q3_cells)
                 if t.world not in Q3_DISCOVERED or t.name.startswith(AGENT_LABELS[EQ2])]  # fmt: skip
    q3 = adjust(q3_split + mechanism + transfer_cost_tests(q3_cells, cells + q3_own_cells))
    q4_cells, q4_raw, q4_missing = fifth_skewer.family(results)  # Q4: its own module
    q4 = adjust(q4_raw)
    missing += q4_missing
    every = q1 + q2 + q3_split
    verdicts = [helps(every, c.task, c.schedule, c.condition) for c in cells + q2_cells + q3_cells]
    distinct, repeats = distinct_comparisons([t for t in every if t.name == HIERARCHY])
    n_conditions = len({(t.world, t.condition, t.schedule) for t in distinct})
    n_helps = sum(h for h, _ in verdicts)
    n_worse = sum(w for _, w in verdicts)
    head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                          text=True, cwd=HERE).stdout.strip()  # fmt: skip
    every_cell = cells + q2_cells + q3_cells
    commits = ", ".join(sorted({x for c in every_cell for x in c.commit.split(", ")})) or "–"
    lines = [
        "# Where does hierarchy pay? Subgoal tasks, subgoal observation, transfer",
        "",
        f"*Runs at commit {commits}; this page written at {head} by `python "
        "experiments/hierarchy/where_pays.py` from the committed records, as the protocol's "
        "amendments of 2026-11-29 declared them before the runs.*",
        "",
        "## The answers so far",
        "",
        *verdict_lines(q1, cells, "Q1"),
        *verdict_lines(q2, q2_cells, "Q2"),
        *verdict_lines(q3, q3_cells, "Q3"),
        *q3_answer_lines(q3, q3_cells),
        *fifth_skewer.answer_lines(q4, q4_cells),
        f"- **Tally so far:** hierarchy helps imitation in {n_helps} of {n_conditions} distinct "
        f"conditions (each pair of runs counted once; {len(repeats)} repeats), and eq. 2 is "
        f"significantly worse than eq. 1 on the greedy policy in {n_worse}. The protocol's goal "
        "needs ≥ 3 with none worse"
        + (
            ": not met."
            if n_helps < 3
            else (
                ": met, on the conditions run so far (the round is not finished: below)."
                if n_worse == 0
                else ": not met (eq. 2 worse somewhere)."
            )
        ),
    ]
    helped = [c for c, (h, _) in zip(every_cell, verdicts) if h]
    if helped:

        def effect(c, name):
            (t,) = [t for t in every if (t.name, t.world, t.condition, t.schedule, t.endpoint)
                    == (name, c.task, c.condition, c.schedule, "greedy")]  # fmt: skip
            mark = "" if t.p_holm >= 0.05 else (" (significant)")
            return f"{t.difference:+.{digits(t.world)}f}{mark}"

        lines.append(
            "- **Where hierarchy helps, whose effect it is** (greedy policy: points of %, value "
            "units on the puzzle box; Holm): "
            + "; ".join(
                f"{label(c.task, c.condition)}, {SCHEDULES[c.schedule]}: eq. 2's imitation "
                f"effect {effect(c, list(CONTRASTS)[1])}, eq. 1's {effect(c, list(CONTRASTS)[2])}"
                for c in helped
            )
            + ". Where eq. 1's imitation effect is negative, much of hierarchy's effect is flat "
            "imitation losing ground to its own no-mentor control, not eq. 2 gaining over its "
            "own."
        )
    own_eq2 = [t for t in q2 if t.name == list(CONTRASTS)[1] and t.endpoint == "greedy"]
    if own_eq2:
        by_observation: dict[tuple[str, str], list[str]] = {}
        for t in own_eq2:
            mark = "*" if t.p_holm < 0.05 else ""
            by_observation.setdefault((t.world, t.schedule), []).append(
                f"{t.condition} {t.difference:+.1f}{mark}"
            )
        ends = [t for t in own_eq2 if t.condition == "option ends"]
        strides = [t for t in own_eq2 if t.condition != "option ends"]
        lines.append(
            "- **Q2, eq. 2's own imitation effect by what it sees** (eq. 2 − options only, "
            "greedy policy, points; * Holm-significant): "
            + "; ".join(
                f"{label(w)}, {SCHEDULES[s]}: " + ", ".join(v)
                for (w, s), v in by_observation.items()
            )
            + f". Below zero at {sum(t.difference < 0 for t in ends)} of {len(ends)} option-ends "
            f"conditions and at {sum(t.difference < 0 for t in strides)} of {len(strides)} "
            "stride conditions. Hierarchy's effect is the difference of the two imitation "
            'effects: where both are negative, a "helps" means eq. 1 lost more than eq. 2.'
        )
    hurt = [t for t in every if t.name == HIERARCHY and t.p_holm < 0.05 and t.difference < 0]
    own = {
        (t.world, t.schedule)
        for t in q1 + q2
        if t.name == OWN and t.p_holm < 0.05 and t.difference > 0
    }
    n_own = len({(c.task, c.schedule) for c in cells + q2_cells})
    lines += [
        "- **Where hierarchy hurts imitation:** hierarchy's effect on imitation is significantly "
        "negative (Holm) at "
        + (
            "; ".join(
                f"{t.family}, {label(t.world, t.condition)}, {SCHEDULES[t.schedule]}, "
                f"{endpoint_name(t.world, t.endpoint)} "
                f"({t.difference:+.{digits(t.world) if t.endpoint == 'greedy' else 1}f})"
                for t in hurt
            )  # fmt: skip
            if hurt
            else "no condition"
        )
        + ".",
        f"- **The options' own effect** (options only − primitives only, no mentor) is "
        f"significantly positive (Holm) on some endpoint at {len(own)} of {n_own} distinct "
        "task × schedule pairs of Q1 and Q2: where it is, the options pay with or without a "
        "mentor.",
    ]
    if f:
        significant = [t for t in f if t.p_holm < 0.05]
        counts = [re.search(r"\| (\d+) of (\d+) \|", row) for row in f_rows + f_q2_rows]
        changed = [(int(m.group(1)), int(m.group(2))) for m in counts if m]
        q2_changed = changed[len(f_rows) :]
        where: dict[tuple[str, str], list[float]] = {}
        for t in significant:
            where.setdefault((t.world, t.condition), []).append(t.difference)
        lines.append(
            f"- **F, feasibility:** {len(significant)} of {len(f)} contrasts (N − trial alone) "
            "significant after Holm"
            + (
                f", {sum(t.difference > 0 for t in significant)} of them in feasibility's favour: "
                + "; ".join(
                    f"{label(w, c)} ({len(d)}, {min(d):+.1f} to {max(d):+.1f})"
                    for (w, c), d in where.items()
                )
                + " (contrasts, and their differences: points of the greedy policy or early goals)"
                if significant
                else ""
            )
            + f". Runs changed from trial alone's: {sum(c for c, _ in changed[: len(f_rows)])} "
            f"of {sum(n for _, n in changed[: len(f_rows)])} on Q1's conditions"
            + (
                f", {sum(c for c, _ in q2_changed)} of {sum(n for _, n in q2_changed)} on Q2's "
                f"conditions ({sum(c > 0 for c, _ in q2_changed)} of {len(q2_changed)} cells "
                "with any change)"
                if q2_changed
                else ""
            )
            + "; each cell in F's section below."
        )
    choice_path = results / "preset_choice.json"
    choice = json.loads(choice_path.read_text()) if choice_path.exists() else None
    if choice is not None:
        won = choice["candidates"][choice["winner"]]
        lines.append(
            f'- **The preset** (amendment "the preset"): of the '
            f"{len(choice['candidates'])} candidates run on held-out seeds {choice['seeds']} at "
            f"{len(choice['conditions'])} conditions, `{choice['winner']}` (base preset "
            f"`{won['base_preset']}`, the segment term and trial) has "
            + (
                "the highest minimum"
                if sum(c["tied_with_best"] for c in choice["candidates"].values()) == 1
                else "a minimum within 1 point of the best and the most early goals"
            )
            + f" of the greedy policy's % of the optimum ({won['minimum']:.1f}, at {won['at']}; "
            "`preset_choice.md`). "
            + (
                f"Registered as the learner preset `{choice['registered_as']}`: its amendment "
                "registers it if the tally holds (≥ 3 conditions, none worse) when the choice is "
                "made, with the cells it names"
                + (
                    ", and it still holds."
                    if n_helps >= 3 and n_worse == 0
                    else "; it held then. Since then the tally no longer holds: eq. 2 is "
                    "significantly worse than eq. 1 on the greedy policy at "
                    + "; ".join(
                        label(c.task, c.condition) + f", {SCHEDULES[c.schedule]}"
                        for c, (_, w) in zip(every_cell, verdicts)
                        if w
                    )  # fmt: skip
                    + (
                        " (transfer, where the mentor's goal is not the learner's: a condition "
                        "of another kind than those the preset was chosen at)"
                        if all(
                            any(c is q for q in q3_cells)
                            for c, (_, w) in zip(every_cell, verdicts)
                            if w
                        )
                        else ""
                    )
                    + ". The preset stays as its amendment's rule decided it; the round's goal "
                    "is not met."
                )
                if choice.get("registered_as")
                else "Not registered: the tally did not hold when the choice was made."
            )
        )
    lines += [
        "- **Not run yet:** "
        + ("; ".join(sorted(set(missing))) + " (records absent); " if missing else "")
        + "Q1 on MiniGrid's UnlockPickup, FourRooms and MultiRoom N2S4 "
        "(registered for himit run minigrid, left out of the amendment that added three tasks, "
        "by cost and for having no subgoal or only one: PROTOCOL.md), F on Q3's conditions, "
        "Q3's other transfers (options discovered from the mentor's states on MiniGrid's tasks "
        "and the puzzle box, a key moved)"
        + ("" if q4_cells else ", Q4 (the fifth skewer)")
        + ": their cells follow in amendments before their runs, as the settings and worlds "
        "land. Declared out by cost in the puzzle box's amendment: F on Q3's puzzle-box cells, "
        "and the `any` mapping of the mentor's episodes into the 5-skewer box. "
        + (
            ""
            if choice is not None
            else "A preset is due by the protocol (eq. 2 with segments and trial, where the "
            "mentor is seen at its subgoals), chosen on held-out seeds 5000–5019 by the presets' "
            "rule: not run yet."
            if n_helps >= 3 and n_worse == 0
            else "No preset: nothing has won at ≥ 3 conditions."
        ),
        "",
        "![The greedy endpoint's paired differences](where_pays.png)",
        "",
        "## Q1, subgoal tasks",
        "",
    ]
    for task, name in Q1_TASKS.items():
        task_cells = [c for c in cells if c.task == task]
        if not task_cells:
            continue
        c0 = task_cells[0]
        lines += [
            f"{name}: {len(c0.seeds)} seeds ({c0.seeds[0]}–{c0.seeds[-1]}) per learner and "
            f"schedule, {c0.budget:,} steps a run; trial of untried own options on for both "
            f"imitators; goals in the first quarter counted over the first {c0.quarter_steps:,} "
            "steps (the whole windows within it). Both schedules hold ε at its start until a "
            "run's first goal, so the first-goal rows of the two schedules are the same runs'."
            + (budget_line(rule, task) if task in rule else "")
            + f" Run: `python experiments/hierarchy/run_hierarchy.py --parts q1 --tasks {task}`.",
            "",
        ]
        lines += agents_table(task_cells, name)
        lines += tests_table(
            [t for t in q1 if t.world == task], f"{name}: the split, paired by seed"
        )
    lines += box_q1_lines(results, [c for c in cells if c.task == BOX_Q1], q1)
    if q2_cells:
        lines += [
            "## Q2, a mentor seen only at its subgoals",
            "",
            "Eq. 2 and eq. 1 watch the mentor only where its options end (with each episode's "
            "first and last state), or every 10th or 20th state; the segment term and trial on "
            "for both; the no-mentor controls (options only, primitives only) watch nothing, so "
            "one pair of control cells per world and schedule serves the three observations (on "
            "MiniGrid: Q1's cells). 20 seeds (0–19), each world's budget (MiniGrid: Q1's); goals "
            "in the first quarter: the windows that end within it. Run: `python "
            "experiments/hierarchy/run_hierarchy.py --parts q2 q2mg`.",
            "",
        ]
        for world, observation in dict.fromkeys((c.task, c.condition) for c in q2_cells):
            group = [c for c in q2_cells if (c.task, c.condition) == (world, observation)]
            name = label(world, observation)
            lines += agents_table(group, name)
            lines += tests_table(
                [t for t in q2 if (t.world, t.condition) == (world, observation)],
                f"{name}: the split, paired by seed",
            )
    lines += subgoal_mentor_lines(results, cells + q2_cells)
    if q3_cells:
        lines += q3_section(results, q3, q3_cells)
    lines += fifth_skewer.section_lines(results, q4_cells, q4)
    if f:
        lines += [
            "## F, feasibility at N = 1 and N = 3",
            "",
            "Eq. 2 with trial and `mentor_feasibility` N against eq. 2 with trial alone (Q1's "
            "cell), paired by seed. *Changed*: the runs whose per-window record (goals, "
            "episodes, ε, value gap, mentor-term wins) differs from trial alone's. *Check*: eq. "
            "2 with trial alone run by itself in a batch, runs equal to Q1's cell (so that a "
            "change is the setting's, not the batch's). Run: `python "
            "experiments/hierarchy/run_hierarchy.py --parts f`.",
            "",
            "| task | schedule | feasibility | runs changed | check: trial alone equal |",
            "|---|---|---|---|---|",
            *f_rows,
            "",
        ]
        moves_path = results / "f_mentor_moves.json"
        if moves_path.exists():
            moves = json.loads(moves_path.read_text())
            lines += [
                "*Why* (counted, `f_mentor_moves.json`): of the mentor's observed moves (each "
                "seed's 20 episodes, as the runs record them), the share one of the learner's "
                "own primitives makes — "
                + ", ".join(
                    f"{label(t)} {m['made_by_a_primitive']:,} of {m['moves']:,}"
                    for t, m in moves.items()
                )
                + ". The test drops the mentor term at a state only once every own option has "
                "been tried there N times and none reached the mentor's successor; where a "
                "primitive makes the mentor's move in a deterministic world, its tries always "
                "reach it, so on these tasks the test cannot drop a term, and no decision "
                "changes. Feasibility has work to do only where the mentor's observed moves are "
                "ones no own option makes (missing skills, H3/H6; at Q2's option ends the "
                "learner's own options end where the mentor's do: below).",
                "",
            ]
        if any(BOX_TASKS[BOX_Q1] in row for row in f_rows):
            lines += [
                "*Why, on the puzzle box* (a reading of the mechanism, not a test): each of the "
                "mentor's observed moves is one step of the box with the pinch grip, which is one "
                "of the learner's primitives, but a movement fails 10 % of the time, so a try of "
                "the right primitive can miss the mentor's successor. The test drops the term at "
                "a state only once every own option usable there has been tried N times and none "
                "reached it: possible at N = 1 after one unlucky try, far rarer at N = 3. Its "
                "rows above are each learner's own batch (no batch check needed).",
                "",
            ]
        if all(" | 0 of " in row for row in f_rows):
            lines += [
                "No run changed: each of F's comparisons so far is a run against itself, the "
                "same pair of runs, so by the protocol's counting F has no distinct comparison "
                "on these tasks (its tests, below, are all ties).",
                "",
            ]
        if f_q2_rows:
            lines += [
                "### F on Q2's conditions: the mentor seen at its option ends or every 10th / "
                "20th state",
                "",
                'Amendments "F on Q2\'s conditions" and "F at Q2\'s strides 10 and 20": eq. 2 '
                "watching the mentor only where its options end, or every 10th or 20th state, "
                "the segment term and trial on, with `mentor_feasibility` N, against Q2's "
                "committed eq. 2 cell of the same world, observation and schedule (trial alone; "
                "not run again in a batch of its own: the checks above and Q3's found no run "
                "that depends on its batch). 20 seeds, each world's Q2 budget. *Changed*: the "
                "runs whose per-window record differs from trial alone's (MiniGrid: goals, "
                "episodes, ε, value gap, mentor-term wins; exp2 and exp1: goals, ε, episodes, "
                "backups, decisions, mentor-term wins). Run: `python "
                "experiments/hierarchy/run_hierarchy.py --parts fq2 fq2s`.",
                "",
                "| world, observation | schedule | feasibility | runs changed |",
                "|---|---|---|---|",
                *f_q2_rows,
                "",
                *F_Q2_WHY,
                "",
                "*Beside Q2's learners* (a description, no test was declared for it): the greedy "
                "policy's mean % of the optimum of eq. 2 with trial alone and with feasibility "
                "(trial alone's mean + F's paired difference), and of Q2's eq. 1 (segments and "
                "trial, no feasibility: not run with it) and options only (no mentor).",
                "",
                "| world, observation | schedule | eq. 2, trial alone | eq. 2, N = 1 | eq. 2, "
                "N = 3 | eq. 1 | options only |",
                "|---|---|---|---|---|---|---|",
                *f_q2_description(q2_cells, f),
                "",
            ]
        lines += tests_table(f, "F: feasibility − trial alone, paired by seed", by_task=True)
    panels = [("Q1: the split (eq. 2 and eq. 1 with trial)", q1, list(CONTRASTS))]
    if q2:
        panels.append(("Q2: the split (segments and trial on)", q2, list(CONTRASTS)))
    if q3_split:
        panels.append(("Q3: the split (transfer, trial on)", q3_split, list(CONTRASTS)))
    if f:
        panels.append(("F: feasibility − trial alone (eq. 2)", f, sorted({t.name for t in f})))
    figure(panels, results / "where_pays.png")
    (results / "where_pays.md").write_text("\n".join(lines))
    with (results / "where_pays_tests.csv").open("w", newline="") as out:
        writer = csv.writer(out)
        fields = list(Test.__dataclass_fields__)
        writer.writerow(fields)
        for t in q1 + q2 + q3 + f + q4:
            writer.writerow([getattr(t, k) for k in fields])
    print(f"wrote {results / 'where_pays.md'}")


if __name__ == "__main__":
    main()
