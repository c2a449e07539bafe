"""The recommended preset's search, scored by the criterion PROTOCOL.md declared before the runs.

Reads the six sweeps of the search (``runs.csv`` and ``results.csv`` of each) and writes
``search.md`` beside this file: every candidate on each world, and the choice.

    python experiments/presets/analyse_search.py [--sweeps runs/presets] [--out experiments/presets/search.md]
"""

import argparse
import csv
import statistics
from collections import defaultdict
from pathlib import Path

from scipy import stats

#: (sweep prefix, cell, agent) → candidate id (PROTOCOL.md's table).
CANDIDATES = {
    ("baselines", "baseline", "imitation"): "plain",
    ("search", "baseline", "imitation"): "fade20",
    ("search", "mentor_fade=5.0", "imitation"): "fade5",
    ("search", "mentor_fade=50.0", "imitation"): "fade50",
    ("search", "eps_decay=0.9999", "imitation"): "fade20_eps",
    ("search", "mentor_choice=match", "imitation"): "fade20_match",
    ("search", "agents=imitation_confident", "imitation_confident"): "fade20_confident",
    ("override", "mentor_override_after=5", "imitation"): "override5",
    ("override", "mentor_override_after=20", "imitation"): "override20",
    ("baselines", "baseline", "options"): "options (non-imitator)",
    ("baselines", "baseline", "primitives"): "primitives (non-imitator)",
}
WORLDS = ("exp1", "exp2")
EARLY_STEPS = 50_000


def t_interval(values: list[float]) -> tuple[float, float, float]:
    """Mean and its 95 % Student-t interval."""
    mean = statistics.fmean(values)
    low, high = stats.t.interval(0.95, len(values) - 1, loc=mean, scale=stats.sem(values))
    return mean, low, high


def read(sweeps: Path) -> dict:
    """candidate → world → seed → measures."""
    out: dict = defaultdict(lambda: defaultdict(dict))
    for world in WORLDS:
        for prefix in ("baselines", "search", "override"):
            folder = sweeps / f"{prefix}_{world}"
            early: dict = defaultdict(int)
            with open(folder / "results.csv") as f:
                for row in csv.DictReader(f):
                    if int(row["step"]) <= EARLY_STEPS:
                        early[row["cell"], row["agent"], row["seed"]] += int(row["goals_in_window"])
            with open(folder / "runs.csv") as f:
                for row in csv.DictReader(f):
                    key = (prefix, row["cell"], row["agent"])
                    if key not in CANDIDATES:
                        continue
                    out[CANDIDATES[key]][world][int(row["seed"])] = {
                        "greedy_pct_mentor": float(row["greedy_percent_of_mentor"]),
                        "late_goals": int(row["late_goals"]),
                        "first_goal_step": int(row["first_goal_step"]),
                        "early_goals": early[row["cell"], row["agent"], row["seed"]],
                    }
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sweeps", default="runs/presets")
    parser.add_argument("--out", default=str(Path(__file__).with_name("search.md")))
    args = parser.parse_args()
    data = read(Path(args.sweeps))

    rows, scores = [], {}
    for name, worlds in data.items():
        cells = []
        for world in WORLDS:
            runs = worlds[world]
            greedy = t_interval([r["greedy_pct_mentor"] for r in runs.values()])
            late = t_interval([r["late_goals"] for r in runs.values()])
            early = statistics.fmean(r["early_goals"] for r in runs.values())
            found = [r["first_goal_step"] for r in runs.values() if r["first_goal_step"] >= 0]
            failed = len(runs) - len(found)
            first = statistics.median(found) if found else float("nan")
            cells.append(
                f"{greedy[0]:.1f} [{greedy[1]:.1f}, {greedy[2]:.1f}] | {late[0]:.0f} "
                f"[{late[1]:.0f}, {late[2]:.0f}] | {early:.0f} | {first:.0f}"
                + (f" ({failed} never)" if failed else "")
            )
            scores.setdefault(name, []).append((greedy[0], early))
        rows.append((name, cells))
    imitators = {n: s for n, s in scores.items() if "non-imitator" not in n}
    primary = {n: min(g for g, _ in s) for n, s in imitators.items()}
    best = max(primary.values())
    close = [n for n in imitators if primary[n] >= best - 1.0]
    chosen = max(close, key=lambda n: sum(e for _, e in imitators[n]))

    lines = [
        "# The recommended preset's search: every candidate, scored as PROTOCOL.md declared",
        "",
        "Held-out seeds 1000–1009 (10 runs per cell), random ties, the experiments' default "
        "budgets (exp1: 80×80 with corner options, 300k steps; exp2: 40×40, 200k). Made by "
        "`experiments/presets/*.toml` (`himit sweep`) and this page by "
        "`python experiments/presets/analyse_search.py`.",
        "",
        "Per world: **greedy** — the frozen greedy policy at the end, its goals per window as a % "
        "of the mentor's own rate, exact (mean over the 10 seeds [95 % Student-t interval of the "
        "mean]); **late** — goals in the last 50k steps (mean [95 % t-interval]); **early** — "
        "goals in the first 50k steps (mean); **first goal** — median steps to the first goal "
        "over the runs that found it.",
        "",
        "| candidate | exp1 greedy | exp1 late | exp1 early | exp1 first goal | exp2 greedy | "
        "exp2 late | exp2 early | exp2 first goal | criterion: min greedy |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    order = sorted(rows, key=lambda r: -primary.get(r[0], -1e9))
    for name, cells in order:
        crit = f"{primary[name]:.1f}" if name in primary else "–"
        lines.append(f"| {name} | {' | '.join(cells)} | {crit} |")
    lines += [
        "",
        f"**Chosen: `{chosen}`.** Best on the primary criterion: {best:.1f} % "
        f"(the smaller of its two worlds' mean greedy % of the mentor's rate); within 1 point of "
        f"it: {', '.join(sorted(close))}; of those, the most goals in the first 50k steps, "
        "summed over the two worlds.",
    ]
    Path(args.out).write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
