"""The preset's choice (PROTOCOL.md, amendment "the preset"): eq. 2 with the segment term and
trial under each candidate's base preset, on held-out seeds 5000–5019 at the five conditions
where the setting won; the presets' rule picks one.

    python experiments/hierarchy/choose_preset.py [--results experiments/results/hierarchy]

Reads the sweeps ``preset_ends_exp2``, ``preset_stride_exp2``, ``preset_ends_exp1`` and the Taxi
cells ``preset_taxi_<base>`` (``run_hierarchy.py --parts preset``); writes
``preset_choice.json`` and ``preset_choice.md`` beside them. The rule: per candidate and
condition the mean over seeds of endpoint 1 (the greedy policy's exact % of the optimum); the
highest minimum over the conditions wins; a candidate within ``TOLERANCE`` points of the best
minimum is preferred if its endpoint 3 (goals in the first quarter of the budget, the windows
that end within it; per-condition means summed over the conditions) is higher.
"""

from __future__ import annotations

import argparse
import csv
import json
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from common import HERE
from where_pays import EQ2, load_gymnasium_cell

#: The candidates: id → the base preset the sweeps and Taxi cells name them by.
CANDIDATES = {
    "segments-trial-paper": "paper",
    "segments-trial-explore-goals": "explore-goals",
    "segments-trial-mentor-fade": "mentor-fade",
    "segments-trial-recommended": "recommended",
}
#: The conditions: label → (the sweep, its stride or None, its budget), Taxi's read apart.
SWEEP_CONDITIONS = {
    "exp2, option ends": ("preset_ends_exp2", None, 200_000),
    "exp2, stride 10": ("preset_stride_exp2", "10", 200_000),
    "exp2, stride 20": ("preset_stride_exp2", "20", 200_000),
    "exp1, option ends": ("preset_ends_exp1", None, 300_000),
}
TAXI = "Taxi, every state"
#: Points of endpoint 1 within which two minima tie (the presets' rule's tolerance).
TOLERANCE = 1.0
#: The preset the winner is registered as.
PRESET_NAME = "subgoal-mentor"

#: Per candidate, per condition: (mean of endpoint 1, mean of endpoint 3, seeds).
Table = Mapping[str, Mapping[str, tuple[float, float, int]]]


def choose(table: Table, tolerance: float = TOLERANCE) -> tuple[str, dict[str, dict]]:
    """The rule applied to ``table``: the winner, and per candidate its minimum of endpoint 1
    over the conditions (and the condition that gives it), its endpoint-3 sum, and whether it is
    within ``tolerance`` of the best minimum (the candidates the tie-break decides among).

    Raises:
        ValueError: the candidates were not all measured at the same conditions."""
    conditions = {frozenset(by) for by in table.values()}
    if len(conditions) != 1:
        raise ValueError("choose: the candidates' conditions differ; each needs every condition")
    scores: dict[str, dict] = {}
    for candidate, by in table.items():
        worst = min(by, key=lambda c: by[c][0])
        scores[candidate] = {
            "minimum": by[worst][0],
            "at": worst,
            "early_goals": sum(v[1] for v in by.values()),
        }
    best = max(s["minimum"] for s in scores.values())
    for s in scores.values():
        s["tied_with_best"] = s["minimum"] >= best - tolerance
    winner = max(
        (c for c, s in scores.items() if s["tied_with_best"]),
        key=lambda c: (scores[c]["early_goals"], scores[c]["minimum"]),
    )
    return winner, scores


def sweep_means(directory: Path, stride: str | None, budget: int) -> dict[str, tuple]:
    """Per base preset, eq. 2's (mean endpoint 1, mean endpoint 3, seeds) in one sweep's
    records (at ``stride`` where the sweep has several)."""
    with (directory / "runs.csv").open() as f:
        runs = [r for r in csv.DictReader(f) if r["agent"] == EQ2]
    with (directory / "results.csv").open() as f:
        windows = [r for r in csv.DictReader(f) if r["agent"] == EQ2]

    def keep(row: dict, preset: str) -> bool:
        return row["preset"] == preset and (stride is None or row["observation_stride"] == stride)

    out = {}
    for preset in CANDIDATES.values():
        greedy = {int(r["seed"]): float(r["greedy_percent_of_optimal"]) for r in runs
                  if keep(r, preset)}  # fmt: skip
        early = dict.fromkeys(greedy, 0.0)
        for row in windows:
            if keep(row, preset) and int(row["step"]) <= budget // 4:
                early[int(row["seed"])] += float(row["goals_in_window"])
        out[preset] = (float(np.mean(list(greedy.values()))),
                       float(np.mean(list(early.values()))), len(greedy))  # fmt: skip
    return out


def read_table(results: Path) -> Table:
    """The candidates' per-condition means from the committed records."""
    table: dict[str, dict[str, tuple]] = {c: {} for c in CANDIDATES}
    for condition, (sweep, stride, budget) in SWEEP_CONDITIONS.items():
        means = sweep_means(results / sweep, stride, budget)
        for candidate, preset in CANDIDATES.items():
            table[candidate][condition] = means[preset]
    for candidate, preset in CANDIDATES.items():
        cell = load_gymnasium_cell(results / f"preset_taxi_{preset}", "taxi", preset)
        table[candidate][TAXI] = (float(cell.greedy[EQ2].mean()),
                                  float(cell.goals_q1[EQ2].mean()), len(cell.seeds))  # fmt: skip
    return table


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--results", default=str(HERE.parent / "results" / "hierarchy"))
    args = parser.parse_args()
    results = Path(args.results)
    table = read_table(results)
    winner, scores = choose(table)
    conditions = list(next(iter(table.values())))
    record = {
        "rule": "highest minimum over the conditions of the mean greedy % of the optimum; within "
        f"{TOLERANCE} point of the best minimum, the most goals in the first quarter of the "
        "budget (per-condition means, summed)",
        "seeds": "5000-5019",
        "conditions": conditions,
        "candidates": {
            c: {
                "base_preset": CANDIDATES[c],
                "by_condition": {k: list(v) for k, v in by.items()},
                **scores[c],
            }  # fmt: skip
            for c, by in table.items()
        },
        "winner": winner,
        "registered_as": PRESET_NAME,
    }
    (results / "preset_choice.json").write_text(json.dumps(record, indent=2) + "\n")
    lines = [
        "# The preset's choice: eq. 2 with the segment term and trial, on held-out seeds",
        "",
        "*Written by `python experiments/hierarchy/choose_preset.py` from the committed records "
        'of `run_hierarchy.py --parts preset`, as the protocol\'s amendment "the preset" '
        "declared it before the runs. Eq. 2 alone, seeds 5000–5019 (20 per cell), "
        "`mentor_segments` and `mentor_trial` on, each candidate's base preset otherwise.*",
        "",
        "Mean over the seeds of the greedy policy's exact % of the optimum (endpoint 1), and in "
        "brackets of the goals in the first quarter of the budget (endpoint 3):",
        "",
        "| candidate | " + " | ".join(conditions) + " | minimum | endpoint 3, summed |",
        "|---|" + "---|" * (len(conditions) + 2),
    ]
    for candidate, by in table.items():
        s = scores[candidate]
        cells = " | ".join(f"{by[c][0]:.1f} ({by[c][1]:.0f})" for c in conditions)
        mark = "**" if candidate == winner else ""
        lines.append(f"| {mark}{candidate}{mark} | {cells} | {s['minimum']:.1f} ({s['at']}) | "
                     f"{s['early_goals']:.0f} |")  # fmt: skip
    tied = [c for c, s in scores.items() if s["tied_with_best"]]
    lines += [
        "",
        f"**Chosen: `{winner}`** (base preset `{CANDIDATES[winner]}`): the highest minimum "
        + (
            "alone."
            if len(tied) == 1
            else f"within {TOLERANCE:g} point of the best ({', '.join(tied)}), and of those the "
            "most early goals."
        )
        + f" Registered as the learner preset `{PRESET_NAME}` only if the round's tally still "
        "holds (the protocol's condition; `where_pays.md`).",
        "",
    ]
    (results / "preset_choice.md").write_text("\n".join(lines))
    print(f"wrote {results / 'preset_choice.md'}: {winner}")


if __name__ == "__main__":
    main()
