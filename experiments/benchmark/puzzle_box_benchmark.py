"""The benchmark's tenth world: every cell of the fair factorial on the puzzle box (Whiten et
al.'s 4-skewer keyway-fruit box, the speed condition of ``himit run puzzlebox``), seeds 0–19,
100k steps: every method under both exploration schedules, the methods with a mentor term with
and without fading (PROTOCOL.md, amendment of 2026-11-26).

Endpoints as PROTOCOL.md's, with one change the box imposes: its exact evaluator gives the value
``V^π(start)`` of the frozen greedy policy, not a goal rate, so the greedy endpoint is the value
gap ``V*(start) − V^π(start)`` (0 = optimal). Each seed watches the mentor of the organisation
``himit run puzzlebox`` gives it (skewer by skewer for even seeds, step by step for odd ones).
The greedy policy is the one every world uses
(``learner.views.greedy_policy``: ties random, untried states uniform over the available options).
The paired tests are made by ``analyse.py`` with the other worlds; this script runs the cells
and writes a descriptive table.

    python experiments/benchmark/puzzle_box_benchmark.py [--logdir runs/benchmark/puzzlebox]

Writes ``experiments/results/benchmark/puzzlebox.md`` and copies each batch's record
(``batches/<agent>_<preset>.json``, ``.csv``) into ``puzzlebox/`` beside it.
"""

from __future__ import annotations

import argparse
import csv
import json
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np

from himit_torch.learner.agents import AGENTS
from himit_torch.learner.presets import apply_preset
from himit_torch.mentor.policy import record_demonstrations
from himit_torch.mentor.puzzle_box import organisation_mentor
from himit_torch.options.puzzle_box import intended_rollout
from himit_torch.runs.puzzle_box import (
    PreparedBox,
    PuzzleBoxConfig,
    run_box_batch,
    watched_organisation,
)
from himit_torch.runs.runner import source_commit
from himit_torch.statistics import (
    bca_interval,
    first_goal_survival,
)
from himit_torch.worlds.puzzle_box import ORGANISATIONS

HERE = Path(__file__).resolve().parent
OUT = HERE.parent / "results" / "benchmark"
#: The factorial's cells on the box: (agent, preset), as run_benchmark.py's CELLS.
ALL_AGENTS = ("imitation", "imitation_primitives", "pbrs", "pbrs_primitives", "bco", "options",
              "primitives")  # fmt: skip
MENTOR_AGENTS = ("imitation", "imitation_primitives")
CELLS = [
    (agent, preset)
    for preset, agents in (
        ("paper", ALL_AGENTS),
        ("mentor-fade", MENTOR_AGENTS),
        ("explore-goals", ALL_AGENTS),
        ("recommended", MENTOR_AGENTS),
    )
    for agent in agents
]
EARLY_STEPS = 50_000


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--logdir", default="runs/benchmark/puzzlebox")
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--steps", type=int, default=PuzzleBoxConfig.steps)
    parser.add_argument("--skip-runs", action="store_true", help="tabulate finished batches")
    parser.add_argument(
        "--print-only", action="store_true", help="print the table; copy nothing into the results"
    )
    args = parser.parse_args()
    run_dir = Path(args.logdir)
    base = replace(PuzzleBoxConfig(), seeds=args.seeds, steps=args.steps)
    if not args.skip_runs:
        box = PreparedBox.build(base.skewers, base.slip, base.pinch_slip)
        mentors = {org: organisation_mentor(box.world, org) for org in ORGANISATIONS}
        demos = {
            s: record_demonstrations(
                box.world,
                mentors[watched_organisation(s, base.first_seed)],
                base.mentor_episodes,
                seed=s,
            )
            for s in base.seed_list
        }
        plans = {
            org: intended_rollout(box.world, mentors[org].options, mentors[org].option)[0].tolist()
            for org in ORGANISATIONS
        }
        for agent, preset in CELLS:
            config = replace(base, learner=apply_preset(base.learner, preset))
            variant = AGENTS[agent]
            watched = demos if (variant.mentor or variant.shaping or variant.cloning) else None
            tag = f"{agent}_{preset}"
            print(tag, flush=True)
            run_box_batch(config, box, tag, tag, agent, watched, base.steps, base.steps,
                          run_dir, False, False, plans)  # fmt: skip
        (run_dir / "commit.txt").write_text(source_commit() + "\n")
    write(run_dir, base, OUT if args.seeds >= 20 and not args.print_only else None)


def write(run_dir: Path, base: PuzzleBoxConfig, out: Path | None) -> None:
    """The descriptive table, into ``out`` with the batches' records beside it (``None``:
    printed only). The paired tests: ``analyse.py``."""
    records, early = {}, {}
    for agent, preset in CELLS:
        tag = f"{agent}_{preset}"
        records[tag] = json.loads((run_dir / "batches" / f"{tag}.json").read_text())
        totals: dict[int, int] = {}
        with open(run_dir / "batches" / f"{tag}.csv") as f:
            for row in csv.DictReader(f):
                if int(row["step"]) <= EARLY_STEPS:
                    totals[int(row["seed"])] = totals.get(int(row["seed"]), 0) + int(
                        row["openings"]
                    )
        early[tag] = [totals[s] for s in base.seed_list]
    first = records["imitation_paper"]
    commit_path = run_dir / "commit.txt"
    commit = commit_path.read_text().strip() if commit_path.exists() else "unknown"
    star, steps = first["value_star"], first["steps"]

    def runs(tag: str, key: str) -> list:
        by_seed = {r["seed"]: r for r in records[tag]["runs"]}
        return [by_seed[s][key] for s in base.seed_list]

    def k(x: float) -> str:
        return "never" if not np.isfinite(x) else f"{x / 1000:.1f}k"

    lines = [
        "# The puzzle box in the benchmark's factorial (generated by "
        "`experiments/benchmark/puzzle_box_benchmark.py`)",
        "",
        f"The 4-skewer box ({first['num_states']} states), {steps:,} steps per run, seeds "
        f"0–{base.seed_list[-1]} (each watching the mentor of the organisation `himit run "
        "puzzlebox` gives it), random ties, runs recorded at commit "
        f"`{commit}`. Greedy endpoint: the **value gap** "
        f"V*(start) − V^π(start) of the frozen greedy policy (V* = {star:.3f}; 0 = optimal; "
        "mean [95 % BCa]); untried states: a uniform choice among the available options. "
        "Descriptive: the paired tests, within a schedule and in 'Does the hierarchy help?', "
        "are in `leaderboard.md` and `hierarchy.md` (`analyse.py`).",
        "",
        "| agent | preset | first opening (KM median [95 %]) | never | openings in the first "
        "50k steps | greedy value gap at the end | wall time (s) |",
        "|---|---|---|---|---|---|---|",
    ]
    for agent, preset in CELLS:
        tag = f"{agent}_{preset}"
        s = first_goal_survival(runs(tag, "first_opening"), steps)
        km = s.median
        gap = [star - v for v in runs(tag, "greedy_value")]
        lines.append(
            f"| {agent} | {preset} | {k(km.estimate)} [{k(km.low)}, {k(km.high)}] | "
            f"{s.never}/{s.runs} | {np.mean(early[tag]):.0f} | {bca_interval(gap).format(3)} | "
            f"{records[tag]['wall_seconds']:.0f} |"
        )
    lines.append("")
    if out is None:
        print("\n".join(lines))
        return
    out.mkdir(parents=True, exist_ok=True)
    (out / "puzzlebox.md").write_text("\n".join(lines))
    target = out / "puzzlebox"
    if target.exists():
        shutil.rmtree(target)  # the records of the cells of this run only
    target.mkdir()
    if commit_path.exists():
        shutil.copy(commit_path, target / "commit.txt")
    for agent, preset in CELLS:
        for ext in ("json", "csv"):
            name = f"{agent}_{preset}.{ext}"
            shutil.copy(run_dir / "batches" / name, target / name)
    print("\n".join(lines))


if __name__ == "__main__":
    main()
