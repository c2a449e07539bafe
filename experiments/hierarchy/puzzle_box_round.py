"""Where hierarchy pays, on the puzzle box (PROTOCOL.md, amendment "Q1 and Q3 on the puzzle
box"): the study's batches (``himit run puzzlebox``'s :func:`~himit_torch.runs.puzzle_box.run_box_batch`),
one per learner, on its boxes, mentors and budgets, under the round's settings.

    python experiments/hierarchy/puzzle_box_round.py [--parts q1box fbox q3box]
        [--logdir runs/hierarchy] [--cells NAME ...]

- ``q1box``: the 4-skewer box of the study's first finding, 100k steps; the four learners
  (:data:`AGENTS`: eq. 2, options only, eq. 1, primitives only), trial on, per schedule
  (``q1_puzzlebox4_<schedule>``);
- ``fbox``: eq. 2 with trial and ``mentor_feasibility`` N = 1, 3 on the same box
  (``f_puzzlebox4_<schedule>_n<N>``);
- ``q3box``: the 5-skewer box of the study's third finding, 300k steps, the mentor's 4-skewer
  episodes mapped in by the ``plain`` mapping; the four learners per initial value and schedule
  (``q3_puzzlebox5_iv<value>_<schedule>``).

Each cell's records (``config.json``, ``commit.txt``: the code's commit; per learner ``batches/<agent>.json``, the runs' first
openings, openings and final greedy values, and ``batches/<agent>.csv``, openings per window)
are copied into ``experiments/results/hierarchy/<cell>/``; ``where_pays.py`` reads them.
"""

from __future__ import annotations

import argparse
import shutil
from dataclasses import replace
from pathlib import Path

from himit_torch.mentor.puzzle_box import map_demonstrations
from himit_torch.runs.puzzle_box import (
    PreparedBox,
    PuzzleBoxConfig,
    run_box_batch,
    watched_episodes,
)
from himit_torch.runs.runner import source_commit

HERE = Path(__file__).resolve().parent
RESULTS = HERE.parent / "results" / "hierarchy"
#: The four learners of every cell (``himit_torch.AGENTS``): eq. 2, its no-mentor control, eq. 1
#: (the mentor term over the learner's primitives), its no-mentor control.
AGENTS = ("imitation", "options", "imitation_primitives", "primitives")
IMITATORS = ("imitation", "imitation_primitives")
SCHEDULES = ("paper", "explore-goals")
#: Q3's initial values (−1: the box's learner's default, the neutral value of −0.01 a step at
#: γ = 0.99; 0 for all four learners).
Q3_INITIAL_VALUES = (-1.0, 0.0)
F_TRIES = (1, 3)
#: The mapping of the mentor's 4-skewer episodes into the 5-skewer box (the study's ``plain``:
#: the fifth skewer stays in, so no mapped episode opens the learner's box).
MAPPING = "plain"


def cell_config(schedule: str, **learner) -> PuzzleBoxConfig:
    """The study's settings (seeds 0–19, its boxes, budgets and mentor episodes) under the
    schedule's preset, with trial and any other ``learner`` settings; the greedy policies
    evaluated and checkpoints saved only at the end (the endpoints are the end's; an evaluation
    draws no random numbers, so it does not change a run)."""
    base = PuzzleBoxConfig(seeds=20, variants=()).with_preset(schedule)
    return replace(
        base,
        eval_every=base.transfer_steps,
        checkpoint_every=base.transfer_steps,
        learner=replace(base.learner, mentor_trial=True, **learner),
    )


def run_cell(name: str, config: PuzzleBoxConfig, box: PreparedBox, agents, demos: dict,
             steps: int, logdir: Path, focus: int | None = None) -> None:  # fmt: skip
    """One cell: a batch of 20 seeds per agent (the imitators watching ``demos``), its records
    copied into the results."""
    run_dir = logdir / name
    target = RESULTS / name / "batches"
    target.mkdir(parents=True, exist_ok=True)
    (RESULTS / name / "config.json").write_text(config.to_json() + "\n")
    (RESULTS / name / "commit.txt").write_text(source_commit() + "\n")
    for agent in agents:
        watched = demos if agent in IMITATORS else None
        run_box_batch(config, box, agent, agent, agent, watched, steps, steps, run_dir,
                      False, False, {}, focus)  # fmt: skip
        for suffix in (".json", ".csv"):
            shutil.copy(run_dir / "batches" / f"{agent}{suffix}", target)
        print(f"{name}: {agent}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--parts", nargs="+", choices=("q1box", "fbox", "q3box"),
                        default=["q1box", "fbox", "q3box"])  # fmt: skip
    parser.add_argument("--logdir", default="runs/hierarchy")
    parser.add_argument("--cells", nargs="+", help="only these cells (by name)")
    args = parser.parse_args()
    logdir = Path(args.logdir)

    def wanted(name: str) -> bool:
        return args.cells is None or name in args.cells

    base = cell_config("paper")
    small = PreparedBox.build(base.skewers, base.slip, base.pinch_slip)
    demos = watched_episodes(base, small.world)
    if "q1box" in args.parts or "fbox" in args.parts:
        for schedule in SCHEDULES:
            config = cell_config(schedule)
            name = f"q1_puzzlebox{config.skewers}_{schedule}"
            if "q1box" in args.parts and wanted(name):
                run_cell(name, config, small, AGENTS, demos, config.steps, logdir)
            for tries in F_TRIES if "fbox" in args.parts else ():
                name = f"f_puzzlebox{config.skewers}_{schedule}_n{tries}"
                if wanted(name):
                    run_cell(name, cell_config(schedule, mentor_feasibility=tries), small,
                             ("imitation",), demos, config.steps, logdir)  # fmt: skip
    if "q3box" in args.parts:
        big = PreparedBox.build(base.transfer_skewers, base.slip, base.pinch_slip)
        mapped = {
            s: map_demonstrations(d, small.world, big.world, MAPPING) for s, d in demos.items()
        }
        for schedule in SCHEDULES:
            for value in Q3_INITIAL_VALUES:
                config = cell_config(schedule, initial_value=value)
                name = f"q3_puzzlebox{config.transfer_skewers}_iv{value:g}_{schedule}"
                if wanted(name):
                    run_cell(name, config, big, AGENTS, mapped, config.transfer_steps, logdir,
                             focus=config.skewers)  # fmt: skip


if __name__ == "__main__":
    main()
