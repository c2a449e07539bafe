"""The benchmark on MiniGrid's key-and-door tasks (PROTOCOL.md, amendment of 2026-11-29): the
fair factorial's 18 cells per task — every method under both exploration schedules, eq. 2 and
eq. 1 also with mentor fading — seeds 0–19, random ties, each task at its budget
(``MINIGRID_BUDGETS``, fixed by the amendment's rule on held-out seeds).

    python experiments/benchmark/minigrid_benchmark.py [--tasks T …] [--logdir runs/benchmark/minigrid]
    python experiments/benchmark/minigrid_benchmark.py --calibrate   # the budgets' held-out look

A cell is one batch of ``himit run minigrid``'s runner (:func:`~himit_torch.runs.gymnasium.run_task`)
per task and preset: every agent of the preset but BCO together, BCO alone (the slowest method,
run after the other cells of the five tasks the amendment commits to, then the two others'
cells, BCO's last). A finished cell (its ``tasks/<task>.json``) is kept, so an
interrupted run resumes where it stopped. The records are copied into
``experiments/results/benchmark/minigrid/<preset>/<task>.json`` (and ``.csv``: per window;
BCO's ``<task>.bco.json``), which ``analyse.py`` reads. ``--calibrate`` runs options only on
seeds 4000–4002 for 200k steps under both schedules into ``minigrid/calibration/`` and prints
the budgets the amendment's rule gives.
"""

from __future__ import annotations

import argparse
import csv
import math
import shutil
import time
from collections import defaultdict
from dataclasses import replace
from pathlib import Path

HERE = Path(__file__).resolve().parent
OUT = HERE.parent / "results" / "benchmark" / "minigrid"
#: The tasks in the order they run (by their number of states), each with its step budget: the
#: amendment's rule applied to the calibration records (``--calibrate``).
MINIGRID_BUDGETS = {
    "multiroomn2s4": 100_000,
    "keycorridors3r1": 100_000,
    "doorkey5x5": 100_000,
    "unlock": 150_000,
    "fourrooms": 100_000,
    "multiroomn4s5": 100_000,
    "doorkey6x6": 100_000,
}
#: The tasks the amendment commits to: the first five (the two others run if time allows).
COMMITTED = 5
#: The factorial's cells (run_benchmark.py's CELLS): preset → its agents.
CELLS = {
    "paper": ("imitation", "imitation_primitives", "pbrs", "pbrs_primitives", "bco", "options",
              "primitives"),
    "mentor-fade": ("imitation", "imitation_primitives"),
    "explore-goals": ("imitation", "imitation_primitives", "pbrs", "pbrs_primitives", "bco",
                      "options", "primitives"),
    "recommended": ("imitation", "imitation_primitives"),
}  # fmt: skip
#: The calibration: options only on held-out seeds, both schedules, 200k steps.
CALIBRATION_SEEDS, CALIBRATION_STEPS = (4000, 3), 200_000
CALIBRATION_PRESETS = ("paper", "explore-goals")


def config_of(task: str, preset: str, agents, seeds: int, first_seed: int, steps: int):
    """``himit run minigrid``'s configuration of one cell (random ties)."""
    from himit_torch.runs.gymnasium import MiniGridExperimentConfig

    config = MiniGridExperimentConfig(
        tasks=(task,), agents=tuple(agents), seeds=seeds, first_seed=first_seed, steps=steps
    ).with_preset(preset)
    return replace(config, learner=replace(config.learner, tie_break="random"))


def run_cell(config, task: str, cell_dir: Path) -> None:
    """One batch, unless its record is there (a finished cell is kept)."""
    from himit_torch.runs.gymnasium import run_task

    if (cell_dir / "tasks" / f"{task}.json").exists():
        return
    started = time.perf_counter()
    run_task(config, task, cell_dir, progress=False)
    (cell_dir / "config.json").write_text(config.to_json() + "\n")
    print(f"{cell_dir}: {time.perf_counter() - started:.0f} s", flush=True)


def cells(tasks):
    """(task, preset, agents, tag) in running order: the five tasks the amendment commits to,
    then the two others; within each group every task's cells without BCO, then BCO's."""
    committed = list(MINIGRID_BUDGETS)[:COMMITTED]
    for group in ([t for t in tasks if t in committed], [t for t in tasks if t not in committed]):
        for task in group:
            for preset, agents in CELLS.items():
                yield task, preset, tuple(a for a in agents if a != "bco"), ""
        for task in group:
            for preset, agents in CELLS.items():
                if "bco" in agents:
                    yield task, preset, ("bco",), ".bco"


def collect(logdir: Path, tasks, report: bool = True) -> None:
    """Copy every finished cell's record into ``OUT`` (``<preset>/<task>[.bco].{json,csv}``);
    ``report``: name the cells not run yet."""
    for task, preset, _, tag in cells(tasks):
        source = logdir / preset / f"{task}{tag}" / "tasks"
        if not (source / f"{task}.json").exists():
            if report:
                print(f"not run yet: {preset} {task}{tag}")
            continue
        (OUT / preset).mkdir(parents=True, exist_ok=True)
        for ext in ("json", "csv"):
            shutil.copy(source / f"{task}.{ext}", OUT / preset / f"{task}{tag}.{ext}")


def plateau_step(path: Path, tail: int = 50_000, share: float = 0.9) -> int:
    """The first window end at which the goals per window (mean over the seeds) reach ``share``
    of their mean over the last ``tail`` steps (the amendment's *T*)."""
    goals: dict = defaultdict(list)
    with path.open() as f:
        for row in csv.DictReader(f):
            goals[int(row["step"])].append(float(row["goals"]))
    steps = sorted(goals)
    mean = [sum(goals[s]) / len(goals[s]) for s in steps]
    last = [m for s, m in zip(steps, mean) if s > steps[-1] - tail]
    level = share * sum(last) / len(last)
    return next(s for s, m in zip(steps, mean) if m >= level)


def budget_rule(t: int) -> int:
    """5·T rounded up to a multiple of 50k, at least 100k, at most 200k."""
    return min(200_000, max(100_000, math.ceil(5 * t / 50_000) * 50_000))


def calibrate(logdir: Path, tasks) -> dict[str, int]:
    """Options only on the held-out seeds; the budgets of the amendment's rule."""
    first, n = CALIBRATION_SEEDS
    for preset in CALIBRATION_PRESETS:
        for task in tasks:
            config = config_of(task, preset, ("options",), n, first, CALIBRATION_STEPS)
            run_cell(config, task, logdir / "calibration" / preset / task)
            target = OUT / "calibration" / preset
            target.mkdir(parents=True, exist_ok=True)
            for ext in ("json", "csv"):
                source = logdir / "calibration" / preset / task / "tasks" / f"{task}.{ext}"
                shutil.copy(source, target / f"{task}.{ext}")
    return budgets(tasks)


def budgets(tasks, root: Path = OUT / "calibration") -> dict[str, int]:
    """Each task's budget from the committed calibration records."""
    return {
        task: budget_rule(max(plateau_step(root / p / f"{task}.csv") for p in CALIBRATION_PRESETS))
        for task in tasks
    }


def main() -> None:
    import torch

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--tasks", nargs="+", choices=list(MINIGRID_BUDGETS),
                        default=list(MINIGRID_BUDGETS))  # fmt: skip
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--logdir", default="runs/benchmark/minigrid")
    parser.add_argument("--no-bco", action="store_true", help="every cell but BCO's")
    parser.add_argument("--calibrate", action="store_true", help="the budgets' held-out look")
    parser.add_argument("--skip-runs", action="store_true", help="copy finished cells only")
    parser.add_argument("--no-collect", action="store_true", help="run the cells; copy nothing")
    args = parser.parse_args()
    torch.set_num_threads(1)  # tiny tensors: one thread per process is fastest
    logdir = Path(args.logdir)
    if args.calibrate:
        for task, budget in calibrate(logdir, args.tasks).items():
            print(f"{task}: {budget:,} steps")
        return
    if not args.skip_runs:
        for task, preset, agents, tag in cells(args.tasks):
            if tag and args.no_bco:
                continue
            config = config_of(task, preset, agents, args.seeds, 0, MINIGRID_BUDGETS[task])
            run_cell(config, task, logdir / preset / f"{task}{tag}")
            if not args.no_collect:  # after each cell: a partial run is usable
                collect(logdir, args.tasks, report=False)
    if not args.no_collect:
        collect(logdir, args.tasks)


if __name__ == "__main__":
    main()
