"""The benchmark's tenth world: every method on the puzzle box (Whiten et al.'s 4-skewer
keyway-fruit box, the speed condition of ``himit run puzzlebox``), seeds 0–19, 100k steps.

Endpoints as PROTOCOL.md's, with one change the box imposes: its exact evaluator gives the value
``V^π(start)`` of the frozen greedy policy, not a goal rate, so the greedy endpoint is the value
gap ``V*(start) − V^π(start)`` (0 = optimal). Each seed watches the mentor of the organisation
``himit run puzzlebox`` gives it (skewer by skewer for even seeds, step by step for odd ones).
Every method against eq. 2 paired by seed; Holm over this table.

    python experiments/benchmark/puzzle_box_benchmark.py [--logdir runs/benchmark/puzzlebox]

Writes ``experiments/results/benchmark/puzzlebox.md`` and copies each batch's record
(``batches/*.json``, ``*.csv``) beside it. ≈ 3–5 min on a 2-core CPU.
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
    PuzzleBoxConfig,
    _Box,
    _run_batch,
    watched_organisation,
)
from himit_torch.statistics import (
    bca_interval,
    first_goal_sign_test,
    first_goal_survival,
    holm,
    paired_comparison,
)
from himit_torch.worlds.puzzle_box import ORGANISATIONS

HERE = Path(__file__).resolve().parent
OUT = HERE.parent / "results" / "benchmark"
#: Method → (agent, preset): the leaderboard's methods.
METHODS = {
    "eq. 2 (paper)": ("imitation", "paper"),
    "eq. 2, recommended": ("imitation", "recommended"),
    "implicit imitation (eq. 1)": ("imitation_primitives", "paper"),
    "PBRS": ("pbrs", "paper"),
    "PBRS, primitives": ("pbrs_primitives", "paper"),
    "BCO": ("bco", "paper"),
    "options only": ("options", "paper"),
    "primitives only": ("primitives", "paper"),
}
REFERENCE = "eq. 2 (paper)"
EARLY_STEPS = 50_000


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--logdir", default="runs/benchmark/puzzlebox")
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--steps", type=int, default=PuzzleBoxConfig.steps)
    parser.add_argument("--skip-runs", action="store_true", help="tabulate finished batches")
    args = parser.parse_args()
    run_dir = Path(args.logdir)
    base = replace(PuzzleBoxConfig(), seeds=args.seeds, steps=args.steps)
    if not args.skip_runs:
        box = _Box.build(base.skewers, base.slip, base.pinch_slip)
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
        for method, (agent, preset) in METHODS.items():
            config = replace(base, learner=apply_preset(base.learner, preset))
            variant = AGENTS[agent]
            watched = demos if (variant.mentor or variant.shaping or variant.cloning) else None
            tag = f"{agent}_{preset}"
            print(f"{method}: {tag}", flush=True)
            _run_batch(config, box, tag, tag, agent, watched, base.steps, base.steps,
                       run_dir, False, False, plans)  # fmt: skip
    write(run_dir, base, OUT if args.seeds >= 20 else None)


def write(run_dir: Path, base: PuzzleBoxConfig, out: Path | None) -> None:
    """The table, into ``out`` with the batches' records beside it (``None``: printed only)."""
    records, early = {}, {}
    for method, (agent, preset) in METHODS.items():
        tag = f"{agent}_{preset}"
        records[method] = json.loads((run_dir / "batches" / f"{tag}.json").read_text())
        totals: dict[int, int] = {}
        with open(run_dir / "batches" / f"{tag}.csv") as f:
            for row in csv.DictReader(f):
                if int(row["step"]) <= EARLY_STEPS:
                    totals[int(row["seed"])] = totals.get(int(row["seed"]), 0) + int(
                        row["openings"]
                    )
        early[method] = [totals[s] for s in base.seed_list]
    star = records[REFERENCE]["value_star"]

    def runs(method: str, key: str) -> list:
        by_seed = {r["seed"]: r for r in records[method]["runs"]}
        return [by_seed[s][key] for s in base.seed_list]

    def gap(method: str) -> list[float]:
        return [star - v for v in runs(method, "greedy_value")]

    tests = {}
    for method in METHODS:
        if method == REFERENCE:
            continue
        tests[method, "first"] = first_goal_sign_test(
            runs(method, "first_opening"), runs(REFERENCE, "first_opening")
        )
        tests[method, "early"] = paired_comparison(early[method], early[REFERENCE])
        # a smaller gap is better: compare the negated gaps, so that > 0 is better
        tests[method, "gap"] = paired_comparison(
            [-g for g in gap(method)], [-g for g in gap(REFERENCE)]
        )
    keys = list(tests)
    adjusted = holm([p for k in keys for p in (tests[k].t_p, tests[k].sign_p)])
    p_holm = {k: (adjusted[2 * i], adjusted[2 * i + 1]) for i, k in enumerate(keys)}

    def mark(method: str, endpoint: str) -> str:
        if method == REFERENCE:
            return ""
        p = min(x for x in p_holm[method, endpoint] if x == x)
        if p >= 0.05:
            return ""
        t = tests[method, endpoint]
        better = t.wins > t.losses if endpoint == "first" else t.difference.estimate > 0
        return " ▲" if better else " ▼"

    steps = records[REFERENCE]["steps"]
    lines = [
        "# The puzzle box in the benchmark (generated by "
        "`experiments/benchmark/puzzle_box_benchmark.py`)",
        "",
        f"The 4-skewer box ({records[REFERENCE]['num_states']} states), {steps:,} steps per run, "
        f"seeds 0–{base.seed_list[-1]} (each watching the mentor of the organisation `himit run "
        "puzzlebox` gives it), random ties, every method at its documented settings. Endpoints "
        "of `PROTOCOL.md` but the greedy one: the box's exact evaluator gives the value of the "
        "frozen greedy policy, so the table gives its **value gap** V*(start) − V^π(start) "
        f"(V* = {star:.3f}; 0 = optimal; mean [95 % BCa]). **▲ / ▼**: better / worse than eq. 2 "
        "(paper preset), paired by seed, Holm-adjusted p < 0.05 over this table (t-test or sign "
        "test).",
        "",
        "| method | first opening (KM median [95 %]) | never | openings in the first 50k "
        "steps | greedy value gap at the end |",
        "|---|---|---|---|---|",
    ]
    for method in METHODS:
        s = first_goal_survival(runs(method, "first_opening"), steps)
        km = s.median

        def k(x: float) -> str:
            return "never" if not np.isfinite(x) else f"{x / 1000:.1f}k"

        lines.append(
            f"| {method} | {k(km.estimate)} [{k(km.low)}, {k(km.high)}]{mark(method, 'first')} | "
            f"{s.never}/{s.runs} | {np.mean(early[method]):.0f}{mark(method, 'early')} | "
            f"{bca_interval(gap(method)).format(3)}{mark(method, 'gap')} |"
        )
    walls = ", ".join(f"{records[m]['wall_seconds']:.0f}" for m in METHODS)
    lines += [
        "",
        f"Engine `{records[REFERENCE]['engine']}`; wall time per batch of {len(base.seed_list)} "
        f"runs, in the table's order: {walls} s.",
        "",
    ]
    if out is None:
        print("\n".join(lines))
        return
    out.mkdir(parents=True, exist_ok=True)
    (out / "puzzlebox.md").write_text("\n".join(lines))
    target = out / "puzzlebox"
    target.mkdir(exist_ok=True)
    for agent, preset in METHODS.values():
        for ext in ("json", "csv"):
            name = f"{agent}_{preset}.{ext}"
            shutil.copy(run_dir / "batches" / name, target / name)
    print("\n".join(lines))


if __name__ == "__main__":
    main()
