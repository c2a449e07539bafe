"""The hierarchy study's runs in one command (PROTOCOL.md): each part's sweeps, their records
copied into ``experiments/results/hierarchy/``, then ``analyse.py``.

    python experiments/hierarchy/run_hierarchy.py
        [--parts segments trial puzzlebox mentors largest carryover q1]
        [--logdir runs/hierarchy] [--skip-runs]

Each part's wall time is written to ``experiments/results/hierarchy/timing.json``. The part
``q1`` (the amendment of 2026-11-29: Q1 on Gymnasium's Taxi) runs ``himit run gymnasium`` per
schedule instead of a sweep, and ``where_pays.py`` writes its page.
"""

import argparse
import json
import shutil
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
RESULTS = HERE.parent / "results" / "hierarchy"
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
}
#: What a sweep's record keeps in the repository: per-run summaries, per-window goals, its spec.
RECORDS = ("runs.csv", "results.csv", "sweep.json")
#: Q1's Gymnasium runs (PROTOCOL.md, amendment of 2026-11-29): per task and schedule one
#: ``himit run gymnasium`` of the four learners, trial on for the imitators, seeds 0–19.
Q1_TASKS = ("taxi",)
Q1_SCHEDULES = ("paper", "explore-goals")
Q1_AGENTS = ("imitation", "imitation_primitives", "options", "primitives")


def run_q1(logdir: Path, skip_runs: bool) -> None:
    """Q1's Gymnasium cells: run each (unless ``skip_runs``), then copy its records (the
    config, the task's summary and per-window curves) into the results."""
    for task in Q1_TASKS:
        for schedule in Q1_SCHEDULES:
            name = f"q1_{task}_{schedule}"
            if not skip_runs:
                run("-m", "himit_torch.cli", "run", "gymnasium", "--tasks", task,
                    "--agents", *Q1_AGENTS, "--seeds", "20", "--preset", schedule,
                    "--mentor-trial", "--name", name, "--logdir", str(logdir), "--quiet",
                    "--force")  # fmt: skip
            target = RESULTS / name / "tasks"
            target.mkdir(parents=True, exist_ok=True)
            shutil.copy(logdir / name / "config.json", RESULTS / name / "config.json")
            for suffix in (".json", ".csv"):
                shutil.copy(logdir / name / "tasks" / f"{task}{suffix}", target)


def run(*argv: str) -> None:
    print("$", " ".join(argv), flush=True)
    subprocess.run([sys.executable, *argv], check=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--parts", nargs="+", choices=list(PARTS), default=list(PARTS))
    parser.add_argument("--logdir", default="runs/hierarchy")
    parser.add_argument("--skip-runs", action="store_true", help="copy and analyse finished runs")
    args = parser.parse_args()
    logdir = Path(args.logdir)
    RESULTS.mkdir(parents=True, exist_ok=True)
    timing_path = RESULTS / "timing.json"
    timing = json.loads(timing_path.read_text()) if timing_path.exists() else {}
    for part in args.parts:
        started = time.perf_counter()
        if part == "puzzlebox" and not args.skip_runs:
            run(str(HERE / "puzzle_box_h2.py"), "--logdir", str(logdir))
        if part == "q1":
            run_q1(logdir, args.skip_runs)
        for name in PARTS[part]:
            if not args.skip_runs:
                run("-m", "himit_torch.cli", "sweep", str(HERE / f"{name}.toml"),
                    "--out", str(logdir / name))  # fmt: skip
            target = RESULTS / name
            target.mkdir(parents=True, exist_ok=True)
            for record in RECORDS:
                shutil.copy(logdir / name / record, target / record)
        if not args.skip_runs:
            timing[part] = round((time.perf_counter() - started) / 60, 1)
            timing_path.write_text(json.dumps(timing, indent=2) + "\n")
    run(str(HERE / "analyse.py"))
    run(str(HERE / "where_pays.py"))


if __name__ == "__main__":
    main()
