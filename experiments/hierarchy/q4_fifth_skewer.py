"""Q4 of PROTOCOL.md (amendment "Q4, the fifth skewer"): options discovered from the mentor's
4-skewer episodes, expressed relative to the skewer they act on (``skewer_routine_options``),
carried to the 5-skewer box; eq. 2 with them and with the given options, each beside its
no-mentor control, per schedule.

    python experiments/hierarchy/q4_fifth_skewer.py [--schedules paper explore-goals]
        [--cells relative_eq2 relative_options given_eq2 given_options] [--seeds 20]
        [--first-seed 0] [--steps 300000]

Each cell's record is ``experiments/results/hierarchy/q4_<schedule>_<cell>.json`` (per run: its
seed, the organisation its seed's mentor showed, the routines its options were built from, the
first opening, openings, openings per window, the greedy policy's exact value and gap, and its
greedy plan read without slips); the timing of each cell is in its record. ``where_pays.py``
reads them (its Q4 section, ``fifth_skewer.py``). The study's settings otherwise
(``himit run puzzlebox``'s experiment (c): ``PuzzleBoxConfig``'s defaults).
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import asdict, replace
from pathlib import Path

from himit_torch.exact.greedy_evaluation import PolicyEvaluator
from himit_torch.learner.learner import Learner
from himit_torch.learner.presets import apply_preset
from himit_torch.mentor.puzzle_box import map_demonstrations
from himit_torch.options.builders import primitive_options
from himit_torch.options.bundle import Options
from himit_torch.options.skewer_routines import discover_skewer_routines, skewer_routine_options
from himit_torch.runs.puzzle_box import (
    PreparedBox,
    PuzzleBoxConfig,
    greedy_plan,
    greedy_values,
    watched_episodes,
    watched_organisation,
)
from himit_torch.runs.runner import run_windows, source_commit, watch_demonstrations
from himit_torch.worlds.puzzle_box import PuzzleBox

HERE = Path(__file__).resolve().parent
RESULTS = HERE.parent / "results" / "hierarchy"
#: The cells, in the order they run: name → (agent, options: "relative" or "given").
CELLS = {
    "relative_eq2": ("imitation", "relative"),
    "relative_options": ("options", "relative"),
    "given_eq2": ("imitation", "given"),
    "given_options": ("options", "given"),
}
SCHEDULES = ("paper", "explore-goals")
#: The state mapping of the mentor's 4-skewer episodes into the 5-skewer box (footnote 2).
MAPPING = "any"


def relative_options(box: PuzzleBox, routines) -> Options:
    """The learner's options with routines: the box's primitives (the given learner's, the pinch
    grip included), then each routine on every skewer."""
    return Options.concat([primitive_options(box), skewer_routine_options(box, routines)])


def run_setting(seeds: int = 20, first_seed: int = 0, steps: int = 300_000):
    """What every cell shares: the study's configuration with these seeds and steps, the
    5-skewer box prepared with the given options, each seed's mentor episodes on the 4-skewer
    box mapped into it, and each seed's routines discovered from them."""
    config = PuzzleBoxConfig(seeds=seeds, first_seed=first_seed, transfer_steps=steps)
    small = PuzzleBox(config.skewers, slip=config.slip, pinch_slip=config.pinch_slip)
    demos = watched_episodes(config, small)
    routines = {s: discover_skewer_routines(small, d) for s, d in demos.items()}
    big = PreparedBox.build(config.transfer_skewers, config.slip, config.pinch_slip)
    mapped = {s: map_demonstrations(d, small, big.world, MAPPING) for s, d in demos.items()}
    return config, big, mapped, routines


def run_cell(config: PuzzleBoxConfig, big: PreparedBox, mapped: dict, routines: dict,
             schedule: str, cell: str) -> dict:  # fmt: skip
    """One cell's runs: its seeds in batches of equal options (a run does not depend on its
    batch), each for ``config.transfer_steps`` steps; per run its record."""
    agent, kind = CELLS[cell]
    learner_config = replace(apply_preset(config.learner, schedule), mentor_trial=True)
    seeds = config.seed_list
    groups: dict[tuple, list[int]] = {}
    for s in seeds:
        key = tuple((r.start, r.end) for r in routines[s]) if kind == "relative" else ()
        groups.setdefault(key, []).append(s)
    records: dict[int, dict] = {}
    started = time.perf_counter()
    for group in groups.values():
        if kind == "relative":
            options = relative_options(big.world, routines[group[0]])
            evaluator = PolicyEvaluator(big.world, options, window=1)
        else:
            options, evaluator = big.options, big.evaluator
        learner = Learner(big.world, options, [agent] * len(group), group,
                          config=learner_config, engine=config.engine)  # fmt: skip
        if agent == "imitation":
            watch_demonstrations(learner, {s: mapped[s] for s in group})
        run_windows(learner, config.transfer_steps)
        greedy = learner.views.greedy_options()
        values = greedy_values(evaluator, learner)
        windows = [[int(w[b]) for w in learner.metrics.goals_in_window] for b in range(len(group))]
        for b, s in enumerate(group):
            plan = greedy_plan(big.world, options, greedy[b], focus=config.skewers)
            del plan["states"]
            records[s] = {
                "seed": s,
                "watched": watched_organisation(s, config.first_seed),
                "routines": [[r.start, r.end, r.segments] for r in routines[s]],
                "options": len(options),
                "first_opening": int(learner.views.first_goal_step[b]),
                "openings": int(learner.views.goals[b]),
                "window_openings": windows[b],
                "greedy_value": values[b],
                "value_gap": big.value_star - values[b],
                **plan,
            }
    return {
        "cell": cell,
        "schedule": schedule,
        "agent": agent,
        "options": kind,
        "mapping": MAPPING,
        "steps": config.transfer_steps,
        "window": learner_config.window,
        "skewers": config.transfer_skewers,
        "mentor_skewers": config.skewers,
        "value_star": big.value_star,
        "learner": asdict(learner_config),
        "commit": source_commit(),
        "wall_seconds": round(time.perf_counter() - started, 1),
        "runs": [records[s] for s in seeds],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--schedules", nargs="+", choices=SCHEDULES, default=list(SCHEDULES))
    parser.add_argument("--cells", nargs="+", choices=list(CELLS), default=list(CELLS))
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--steps", type=int, default=PuzzleBoxConfig.transfer_steps)
    parser.add_argument("--out", default=str(RESULTS), help="where the records go")
    args = parser.parse_args()
    config, big, mapped, routines = run_setting(args.seeds, args.first_seed, args.steps)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for schedule in args.schedules:
        for cell in args.cells:
            record = run_cell(config, big, mapped, routines, schedule, cell)
            path = out / f"q4_{schedule}_{cell}.json"
            path.write_text(json.dumps(record, indent=1) + "\n")
            print(f"{path.name}: {record['wall_seconds']} s", flush=True)


if __name__ == "__main__":
    main()
