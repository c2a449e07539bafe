"""The hierarchy study's runs in one command (PROTOCOL.md): each part's sweeps, their records
copied into ``experiments/results/hierarchy/``, then ``analyse.py``.

    python experiments/hierarchy/run_hierarchy.py
        [--parts segments trial puzzlebox mentors largest carryover q1 f q2 q2mg q3 preset
                 subgoal-mentor q3mr q4 q1box fbox q3box fq2 q3disc fq2s]
        [--logdir runs/hierarchy] [--skip-runs]

Each part's wall time is written to ``experiments/results/hierarchy/timing.json``. The part ``q1``
(the amendments of 2026-11-29: Q1 on Gymnasium's Taxi and on MiniGrid's tasks) runs ``himit run
gymnasium`` per task and schedule instead of a sweep, each MiniGrid task at the budget its rule
picks on held-out seeds (``q1_budget_rule.json``); ``f`` (feasibility at N = 1 and 3 on Q1's cells)
runs eq. 2 alone the same way; ``where_pays.py`` writes their page. ``q3`` (transfer, amendment "Q3
on MiniGrid") runs the four learners per transfer task, initial value and schedule. ``preset``
(amendment "the preset") runs its candidates on held-out seeds and ``choose_preset.py`` picks one;
``subgoal-mentor`` runs the chosen preset on seeds 0–19 (its results, the amendment's rule for a
preset that fades); ``q3mr`` (amendment "Q3 (transfer) on the multi-room world") is one sweep; ``fq2`` (amendment "F
on Q2's conditions") two sweeps and ``himit run gymnasium`` per MiniGrid cell; ``q3disc``
(amendment "Q3 on the multi-room world with options discovered from the mentor's states") one
``himit run discovery`` per schedule and initial value; ``fq2s`` (amendment "F at Q2's strides 10
and 20") as ``fq2`` at the strides; ``q1box``, ``fbox`` and ``q3box`` (amendment "Q1 and Q3 on
the puzzle box") run ``puzzle_box_round.py``; ``q4`` (amendment "Q4 (the fifth skewer)") runs
``q4_fifth_skewer.py``.
``--tasks`` restricts ``q1``, ``f``, ``q2mg``, ``q3`` and ``fq2`` to some of their
tasks, ``--cells`` those parts and the box's to some of their cells (by name, e.g.
``f_unlock_paper_n1``), ``--sweeps`` a part to some of its sweeps; sweeps run in this process (``--no-ray``: Ray's start
times out on a loaded machine).
"""

import argparse
import json
import shutil
import subprocess
import sys
import time
from pathlib import Path

from common import budget_by_rule

HERE = Path(__file__).resolve().parent
RESULTS = HERE.parent / "results" / "hierarchy"
#: MiniGrid's task names (their Q1 budget comes from the rule).
MINIGRID = ("doorkey5x5", "doorkey6x6", "unlock")
#: Each part's sweep specs (``<name>.toml`` beside this script).
PARTS = {
    "segments": ("segments_exp2", "segments_exp1"),
    "trial": ("trial_exp1", "trial_feasibility_exp1"),
    "puzzlebox": (),  # (its own script, puzzle_box_h2.py)
    "mentors": (
        "mentors_alone_exp2",
        "detour_alone_exp2",
        "mentors_exp2",
        "mentors_alone_exp1",
        "detour_alone_exp1",
        "mentors_exp1",
    ),  # fmt: skip
    "largest": ("largest_exp3",),
    "carryover": (
        "partial_exp1",
        "other_goal_exp1",
        "options_only_exp1",
        "options_only_feasibility_exp1",
    ),
    "q1": (),  # (himit run gymnasium per task and schedule: run_q1)
    "f": (),  # (the same, eq. 2 alone with feasibility: run_f)
    "q2mg": (),  # (Q2 on MiniGrid's tasks, himit run gymnasium per cell: run_q2_minigrid)
    "q3": (),  # (transfer on MiniGrid, himit run gymnasium per cell: run_q3)
    "preset": ("preset_ends_exp2", "preset_stride_exp2", "preset_ends_exp1"),  # (+ run_preset)
    "subgoal-mentor": (  # the chosen preset on seeds 0–19 (+ its Taxi cell)
        "subgoal_mentor_ends_exp2",
        "subgoal_mentor_stride_exp2",
        "subgoal_mentor_ends_exp1",
    ),
    "q2": (
        "q2_controls_exp2",
        "q2_ends_exp2",
        "q2_stride_exp2",
        "q2_controls_exp1",
        "q2_ends_exp1",
        "q2_stride_exp1",
    ),
    "q3mr": ("q3_multirooms_exp1",),  # (transfer on the multi-room world)
    "q4": (),  # (the fifth skewer: its own script, q4_fifth_skewer.py)
    "q1box": (),  # (the puzzle box: puzzle_box_round.py)
    "fbox": (),
    "q3box": (),
    "fq2": ("f_q2_ends_exp2", "f_q2_ends_exp1"),  # (+ run_f_q2: its MiniGrid cells)
    "q3disc": (),  # (himit run discovery per schedule and initial value: run_q3_discovered)
    "fq2s": ("f_q2_stride_exp2", "f_q2_stride_exp1"),  # (+ run_f_q2: its MiniGrid cells)
}
#: The puzzle box's parts (amendment "Q1 and Q3 on the puzzle box"), run by puzzle_box_round.py.
BOX_PARTS = ("q1box", "fbox", "q3box")
#: What a sweep's record keeps in the repository: per-run summaries, per-window goals, its spec.
RECORDS = ("runs.csv", "results.csv", "sweep.json")
#: Q1's further MiniGrid tasks (amendment "Q1 on three more MiniGrid tasks").
Q1_MORE = ("doorkey8x8", "keycorridors3r1", "multiroomn4s5")
#: Q1's Gymnasium runs (PROTOCOL.md, amendments of 2026-11-29): per task and schedule one
#: ``himit run gymnasium`` of the four learners, trial on for the imitators, seeds 0–19.
Q1_TASKS = ("taxi", "doorkey5x5", "doorkey6x6", "unlock", *Q1_MORE)
Q1_SCHEDULES = ("paper", "explore-goals")
Q1_AGENTS = ("imitation", "imitation_primitives", "options", "primitives")
#: The MiniGrid tasks' budget rule: options only, the paper's schedule, the held-out seeds, one
#: run per task at a cap of ``RULE_CAP`` steps, extended by as much while the rule finds none.
HELD_OUT_FIRST, HELD_OUT_SEEDS, RULE_CAP = 5000, 20, 20_000
BUDGET_RULE = RESULTS / "q1_budget_rule.json"
#: F's settings: ``mentor_feasibility`` N, eq. 2 alone, with trial (its "trial alone" is Q1's cell).
F_TRIES = (1, 3)
#: Q3 (transfer): the learner's task → the registered task whose mentor shows it with the goal
#: moved; the initial values → their flags (−1: the runner's neutral value).
Q3_TASKS = {
    "doorkey5x5": "doorkey5x5_transfer",
    "doorkey6x6": "doorkey6x6_transfer",
    "doorkey8x8": "doorkey8x8_transfer",
}
Q3_INITIAL_VALUES = {"-1": [], "0": ["--no-neutral-initial-value", "--initial-value", "0"]}
#: The tasks whose budget the rule picks (Q1's MiniGrid tasks and Q3's learners' tasks).
RULE_TASKS = (*MINIGRID, *Q3_TASKS, *Q1_MORE)
#: ``--cells``: the only Gymnasium cells to run and copy (None: every cell of the parts run).
ONLY_CELLS: set[str] | None = None


def q1_budget(task: str, logdir: Path, skip_runs: bool) -> int | None:
    """The task's Q1 budget: ``None`` for a task with its own (Taxi's), else the rule's outcome
    on the held-out seeds, recorded in ``q1_budget_rule.json`` (read back when ``skip_runs``)."""
    if task not in RULE_TASKS:
        return None
    record = json.loads(BUDGET_RULE.read_text()) if BUDGET_RULE.exists() else {}
    if skip_runs or task in record:
        return int(record[task]["budget"])
    cap = RULE_CAP
    while True:
        name = f"q1_rule_{task}"
        run("-m", "himit_torch.cli", "run", "gymnasium", "--tasks", task, "--agents", "options",
            "--seeds", str(HELD_OUT_SEEDS), "--first-seed", str(HELD_OUT_FIRST), "--steps",
            str(cap), "--preset", "paper", "--name", name, "--logdir", str(logdir), "--quiet",
            "--force")  # fmt: skip
        summary = json.loads((logdir / name / "tasks" / f"{task}.json").read_text())
        first = [None if s is None or s < 0 else int(s) for s in summary["first_goal_step"]]
        budget = budget_by_rule(first)
        if budget is not None:
            break
        cap += RULE_CAP
    record[task] = {
        "rule": "least multiple of 10k steps >= the 10th smallest first goal of options only, "
        "paper schedule, held-out seeds 5000-5019",
        "cap": cap,
        "seeds": summary["seeds"],
        "first_goal_step": first,
        "reached_by_budget": sum(s is not None and s <= budget for s in first),
        "budget": budget,
        "commit": summary.get("commit"),
    }
    BUDGET_RULE.write_text(json.dumps(record, indent=2) + "\n")
    return budget


def gym_cell(name: str, task: str, agents, schedule: str, extra: list[str], steps: int | None,
             logdir: Path, skip_runs: bool) -> None:  # fmt: skip
    """One ``himit run gymnasium`` cell of 20 seeds (unless ``skip_runs``), then its records (the
    config, the task's summary and per-window curves) copied into the results; nothing for a
    cell that ``--cells`` leaves out."""
    if ONLY_CELLS is not None and name not in ONLY_CELLS:
        return
    if not skip_runs:
        budget = [] if steps is None else ["--steps", str(steps)]
        run("-m", "himit_torch.cli", "run", "gymnasium", "--tasks", task, "--agents", *agents,
            "--seeds", "20", "--preset", schedule, *budget, *extra, "--name", name,
            "--logdir", str(logdir), "--quiet", "--force")  # fmt: skip
    target = RESULTS / name / "tasks"
    target.mkdir(parents=True, exist_ok=True)
    shutil.copy(logdir / name / "config.json", RESULTS / name / "config.json")
    for suffix in (".json", ".csv"):
        shutil.copy(logdir / name / "tasks" / f"{task}{suffix}", target)


def run_q1(logdir: Path, skip_runs: bool, tasks=Q1_TASKS) -> None:
    """Q1's cells: per task and schedule the four learners, trial on."""
    for task in tasks:
        steps = q1_budget(task, logdir, skip_runs)
        for schedule in Q1_SCHEDULES:
            gym_cell(f"q1_{task}_{schedule}", task, Q1_AGENTS, schedule, ["--mentor-trial"],
                     steps, logdir, skip_runs)  # fmt: skip


MENTOR_MOVES = RESULTS / "f_mentor_moves.json"


def record_mentor_moves(tasks=Q1_TASKS) -> None:
    """Why feasibility may change nothing on Q1's tasks, counted rather than assumed: of the
    mentor's observed moves ``(s, s')`` (each seed's 20 episodes, as the runs record them), how
    many one of the learner's primitives can make (``s'`` a successor of ``s`` under some
    action with positive probability). Such a move is reproduced when that primitive is tried,
    so the test never drops its mentor term. Written to ``f_mentor_moves.json``."""
    import torch

    from himit_torch.mentor.policy import mentor_policy, record_demonstrations
    from himit_torch.options.builders import primitive_options
    from himit_torch.runs.gymnasium import TASKS

    record = json.loads(MENTOR_MOVES.read_text()) if MENTOR_MOVES.exists() else {}
    for task in tasks:
        spec = TASKS[task]
        world = spec.world(0.99)
        mentor = (
            spec.make_mentor(world)
            if spec.make_mentor is not None
            else mentor_policy(world, primitive_options(world), prefer_extended_within=0.0)
        )
        table = world.dynamics_table()
        possible = table.cdf.diff(dim=-1, prepend=torch.zeros_like(table.cdf[..., :1])) > 0
        moves = reproducible = 0
        for seed in range(20):
            demos = record_demonstrations(world, mentor, 20, seed=seed)
            for episode in demos.episodes:
                for s, t in zip(episode[:-1].tolist(), episode[1:].tolist()):
                    moves += 1
                    reproducible += bool(((table.successors[s] == t) & possible[s]).any())
        record[task] = {"moves": moves, "made_by_a_primitive": reproducible}
    MENTOR_MOVES.write_text(json.dumps(record, indent=2) + "\n")


def run_f(logdir: Path, skip_runs: bool, tasks=Q1_TASKS) -> None:
    """F's cells: eq. 2 with trial and feasibility at N tries, per task and schedule; first the
    check that eq. 2 with trial alone, by itself in a batch, is Q1's cell seed by seed; and the
    count of the mentor's moves a primitive can make (:func:`record_mentor_moves`)."""
    if not skip_runs:
        record_mentor_moves(tasks)
    for task in tasks:
        steps = q1_budget(task, logdir, skip_runs)
        for schedule in Q1_SCHEDULES:
            gym_cell(f"f_{task}_{schedule}_trial", task, ("imitation",), schedule,
                     ["--mentor-trial"], steps, logdir, skip_runs)  # fmt: skip
            for tries in F_TRIES:
                gym_cell(f"f_{task}_{schedule}_n{tries}", task, ("imitation",), schedule,
                         ["--mentor-trial", "--mentor-feasibility", str(tries)], steps, logdir,
                         skip_runs)  # fmt: skip


def run_f_q2(logdir: Path, skip_runs: bool, tasks=MINIGRID, observations=("ends",)) -> None:
    """F's cells on Q2's MiniGrid conditions: eq. 2 at each of ``observations``
    (:data:`Q2_OBSERVATIONS`), segments and trial on, feasibility at N tries, per task and
    schedule, at the task's Q1 budget."""
    for task in [t for t in tasks if t in MINIGRID]:
        steps = q1_budget(task, logdir, skip_runs)
        for observation in observations:
            for schedule in Q1_SCHEDULES:
                for tries in F_TRIES:
                    gym_cell(f"f_q2_{task}_{observation}_{schedule}_n{tries}", task,
                             ("imitation",), schedule,
                             ["--mentor-segments", "--mentor-trial", *Q2_OBSERVATIONS[observation],
                              "--mentor-feasibility", str(tries)], steps, logdir, skip_runs)  # fmt: skip


#: Q2 on MiniGrid: observation → its flags (the controls are Q1's cells).
Q2_OBSERVATIONS = {
    "ends": ["--observation", "option-ends"],
    "stride10": ["--observation-stride", "10"],
    "stride20": ["--observation-stride", "20"],
}


def run_q2_minigrid(logdir: Path, skip_runs: bool, tasks=MINIGRID) -> None:
    """Q2's MiniGrid cells: eq. 2 and eq. 1, segments and trial on, per task, observation and
    schedule, at the task's Q1 budget."""
    for task in [t for t in tasks if t in MINIGRID]:
        steps = q1_budget(task, logdir, skip_runs)
        for observation, flags in Q2_OBSERVATIONS.items():
            for schedule in Q1_SCHEDULES:
                gym_cell(f"q2_{task}_{observation}_{schedule}", task,
                         ("imitation", "imitation_primitives"), schedule,
                         ["--mentor-segments", "--mentor-trial", *flags], steps, logdir,
                         skip_runs)  # fmt: skip


def run_q3(logdir: Path, skip_runs: bool, tasks=tuple(Q3_TASKS)) -> None:
    """Q3's cells: per learner's task, initial value and schedule the four learners, trial on,
    watching the mentor of the task with its goal moved, at the learner's task's budget."""
    for task in tasks:
        steps = q1_budget(task, logdir, skip_runs)
        for value, flags in Q3_INITIAL_VALUES.items():
            for schedule in Q1_SCHEDULES:
                gym_cell(f"q3_{task}_iv{value}_{schedule}", Q3_TASKS[task], Q1_AGENTS, schedule,
                         ["--mentor-trial", *flags], steps, logdir, skip_runs)  # fmt: skip


#: Q3 with discovered options: what each ``himit run discovery`` cell keeps in the results.
DISCOVERY_RECORDS = ("config.json", "runs.csv", "curves.csv", "subgoals.csv", "results.md")


def run_q3_discovered(logdir: Path, skip_runs: bool) -> None:
    """Q3's discovered-options cells on exp1, the mentor's goal the top-right corner: per initial
    value and schedule one ``himit run discovery`` (seeds 0–19, trial on, the study's defaults
    otherwise), its records copied into the results."""
    for value in Q3_INITIAL_VALUES:
        for schedule in Q1_SCHEDULES:
            name = f"q3_discovered_exp1_iv{value}_{schedule}"
            if ONLY_CELLS is not None and name not in ONLY_CELLS:
                continue
            if not skip_runs:
                run("-m", "himit_torch.cli", "run", "discovery", "--worlds", "exp1", "--seeds",
                    "20", "--mentor-goal", "top-right", "--mentor-trial", "--preset", schedule,
                    f"--initial-value={value}", "--name", name, "--logdir", str(logdir),
                    "--quiet", "--force")  # fmt: skip
            (RESULTS / name).mkdir(parents=True, exist_ok=True)
            for record in DISCOVERY_RECORDS:
                shutil.copy(logdir / name / record, RESULTS / name / record)


#: The preset's candidates (amendment "the preset"): eq. 2 with segments and trial under each of
#: these base presets, on held-out seeds; on Taxi one ``himit run gymnasium`` cell each.
PRESET_CANDIDATES = ("paper", "explore-goals", "mentor-fade", "recommended")


def run_preset(logdir: Path, skip_runs: bool) -> None:
    """The preset's Taxi cells: eq. 2 alone, segments and trial on, per candidate's base preset,
    held-out seeds 5000–5019, Taxi's own budget (its exp2 and exp1 cells are the part's sweeps;
    ``choose_preset.py`` applies the rule)."""
    for base in PRESET_CANDIDATES:
        gym_cell(f"preset_taxi_{base}", "taxi", ("imitation",), base,
                 ["--mentor-segments", "--mentor-trial", "--first-seed", str(HELD_OUT_FIRST)],
                 None, logdir, skip_runs)  # fmt: skip


def run(*argv: str) -> None:
    print("$", " ".join(argv), flush=True)
    subprocess.run([sys.executable, *argv], check=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--parts", nargs="+", choices=list(PARTS), default=list(PARTS))
    parser.add_argument("--logdir", default="runs/hierarchy")
    parser.add_argument("--skip-runs", action="store_true", help="copy and analyse finished runs")
    parser.add_argument("--tasks", nargs="+", choices=sorted({*Q1_TASKS, *Q3_TASKS}),
                        help="q1's, f's, q2mg's, q3's and fq2's tasks (default: each part's all)")  # fmt: skip
    parser.add_argument("--sweeps", nargs="+", help="only these of the parts' sweeps")
    parser.add_argument(
        "--cells",
        nargs="+",
        help="only these cells of q1, f, q2mg, q3, fq2, q3disc and the box's parts",
    )
    args = parser.parse_args()
    global ONLY_CELLS
    ONLY_CELLS = None if args.cells is None else set(args.cells)
    logdir = Path(args.logdir)
    RESULTS.mkdir(parents=True, exist_ok=True)
    timing_path = RESULTS / "timing.json"
    for part in args.parts:
        started = time.perf_counter()
        if part == "puzzlebox" and not args.skip_runs:
            run(str(HERE / "puzzle_box_h2.py"), "--logdir", str(logdir))
        if part == "q4" and not args.skip_runs:
            run(str(HERE / "q4_fifth_skewer.py"))  # (its records go straight to the results)
        if part in BOX_PARTS and not args.skip_runs:
            cells = ["--cells", *args.cells] if args.cells else []
            run(str(HERE / "puzzle_box_round.py"), "--parts", part, "--logdir", str(logdir),
                *cells)  # fmt: skip
        if part == "q1":
            run_q1(logdir, args.skip_runs, args.tasks or Q1_TASKS)
        if part == "f":
            run_f(logdir, args.skip_runs, args.tasks or Q1_TASKS)
        if part == "q2mg":
            run_q2_minigrid(logdir, args.skip_runs, args.tasks or MINIGRID)
        if part == "q3":
            run_q3(logdir, args.skip_runs, args.tasks or tuple(Q3_TASKS))
        if part == "fq2":
            run_f_q2(logdir, args.skip_runs, args.tasks or MINIGRID)
        if part == "fq2s":
            run_f_q2(logdir, args.skip_runs, args.tasks or MINIGRID, ("stride10", "stride20"))
        if part == "q3disc":
            run_q3_discovered(logdir, args.skip_runs)
        if part == "preset":
            run_preset(logdir, args.skip_runs)
        if part == "subgoal-mentor":
            gym_cell("subgoal_mentor_taxi", "taxi", ("imitation",), "subgoal-mentor", [], None,
                     logdir, args.skip_runs)  # fmt: skip
        for name in [n for n in PARTS[part] if args.sweeps is None or n in args.sweeps]:
            if not args.skip_runs:
                run("-m", "himit_torch.cli", "sweep", str(HERE / f"{name}.toml"),
                    "--out", str(logdir / name), "--no-ray")  # fmt: skip
            target = RESULTS / name
            target.mkdir(parents=True, exist_ok=True)
            for record in RECORDS:
                shutil.copy(logdir / name / record, target / record)
        if not args.skip_runs:
            some = part in ("q1", "f", "q2mg", "q3", "fq2", "fq2s") and args.tasks is not None
            key = f"{part} ({' '.join(args.tasks)})" if some else part
            if args.sweeps:
                key = f"{part} ({' '.join(n for n in PARTS[part] if n in args.sweeps)})"
            if args.cells and part in (
                "q1",
                "f",
                "q2mg",
                "q3",
                "fq2",
                "q3disc",
                "fq2s",
                *BOX_PARTS,
            ):
                key = f"{part} ({' '.join(args.cells)})"
            # read again just before writing: another part may have run beside this one
            timing = json.loads(timing_path.read_text()) if timing_path.exists() else {}
            timing[key] = round((time.perf_counter() - started) / 60, 1)
            timing_path.write_text(json.dumps(timing, indent=2) + "\n")
    run(str(HERE / "analyse.py"))
    run(str(HERE / "where_pays.py"))
    if "preset" in args.parts:
        run(str(HERE / "choose_preset.py"))


if __name__ == "__main__":
    main()
