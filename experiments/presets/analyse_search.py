"""The recommended preset's search, scored by the criteria PROTOCOL.md declared before the runs.

Reads the sweeps of every round (``runs.csv`` and ``results.csv`` of each, committed under
``experiments/results/presets/records/``) and writes ``experiments/results/presets/search.md``:
every candidate on each world, and each round's choice. Round 3 is the fair factorial's pick of
the recommended imitator (``../benchmark/PROTOCOL.md``, amendment of 2026-11-26).

    python experiments/presets/analyse_search.py [--sweeps experiments/results/presets/records] [--out experiments/results/presets/search.md]

The records are made by ``himit sweep experiments/presets/<name>.toml --out
runs/presets/<name>`` for each spec beside this file (rounds 1 and 2), and by
``experiments/benchmark/run_benchmark.py --parts pick`` (round 3), then copied into
``records/`` (``runs.csv``, ``results.csv``, ``sweep.json`` of each sweep).
"""

import argparse
import csv
import statistics
from collections import defaultdict
from pathlib import Path

from himit_torch.statistics import t_interval

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
#: Round 2 (fresh seeds 2000–2009).
ROUND2 = {
    ("round2", "baseline", "imitation"): "fade20_eps9998",
    ("round2", "eps_decay=0.9995", "imitation"): "fade20_eps9995",
    ("round2", "eps_decay=0.9999", "imitation"): "fade20_eps9999",
    ("round2", "mentor_fade=5.0", "imitation"): "fade5_eps9998",
    ("round2", "mentor_fade=50.0", "imitation"): "fade50_eps9998",
    ("round2", "eps_schedule=goals", "imitation"): "fade20_goals",
}
#: Round 3, the fair factorial's pick (fresh seeds 3000–3009): every imitator cell.
ROUND3 = {
    (prefix, f"eps_schedule={schedule}", agent): f"{label}, {preset}"
    for agent, label in (
        ("imitation", "eq. 2"),
        ("imitation_primitives", "eq. 1"),
        ("pbrs", "PBRS"),
        ("pbrs_primitives", "PBRS, primitives"),
        ("bco", "BCO"),
    )
    for prefix, schedule, preset in (
        ("fair_plain", "decision", "paper"),
        ("fair_plain", "goals", "explore-goals"),
        ("fair_fade", "decision", "mentor-fade"),
        ("fair_fade", "goals", "recommended"),
    )
    if prefix == "fair_plain" or agent in ("imitation", "imitation_primitives")
}
#: Round 2's floor on the smaller of the two worlds' mean greedy % of the mentor's rate.
ROUND2_FLOOR = 97.0
WORLDS = ("exp1", "exp2")
EARLY_STEPS = 50_000


def read(sweeps: Path, candidates: dict) -> dict:
    """candidate → world → seed → measures."""
    out: dict = defaultdict(lambda: defaultdict(dict))
    for world in WORLDS:
        for prefix in sorted({prefix for prefix, _, _ in candidates}):
            folder = sweeps / f"{prefix}_{world}"
            early: dict = defaultdict(int)
            with open(folder / "results.csv") as f:
                for row in csv.DictReader(f):
                    if int(row["step"]) <= EARLY_STEPS:
                        early[row["cell"], row["agent"], row["seed"]] += int(row["goals_in_window"])
            with open(folder / "runs.csv") as f:
                for row in csv.DictReader(f):
                    key = (prefix, row["cell"], row["agent"])
                    if key not in candidates:
                        continue
                    out[candidates[key]][world][int(row["seed"])] = {
                        "greedy_pct_mentor": float(row["greedy_percent_of_mentor"]),
                        "late_goals": int(row["late_goals"]),
                        "first_goal_step": int(row["first_goal_step"]),
                        "early_goals": early[row["cell"], row["agent"], row["seed"]],
                    }
    return out


def table(data: dict) -> tuple[list[str], dict]:
    """The markdown rows of every candidate, and each imitator's (greedy, early) per world."""
    rows, scores = [], {}
    for name, worlds in data.items():
        cells = []
        for world in WORLDS:
            runs = worlds[world]
            g = t_interval([r["greedy_pct_mentor"] for r in runs.values()])
            la = t_interval([r["late_goals"] for r in runs.values()])
            greedy, late = (g.estimate, g.low, g.high), (la.estimate, la.low, la.high)
            early = statistics.fmean(r["early_goals"] for r in runs.values())
            found = [r["first_goal_step"] for r in runs.values() if r["first_goal_step"] >= 0]
            failed = len(runs) - len(found)
            first = statistics.median(found) if found else float("nan")
            cells.append(
                f"{greedy[0]:.1f} [{greedy[1]:.1f}, {greedy[2]:.1f}] | {late[0]:.0f} "
                f"[{late[1]:.0f}, {late[2]:.0f}] | {early:.0f} | {first:.0f}"
                + (f" ({failed} never)" if failed else "")
            )
            if "non-imitator" not in name:
                scores.setdefault(name, []).append((greedy[0], early))
        rows.append((name, cells))
    primary = {n: min(g for g, _ in s) for n, s in scores.items()}
    header = [
        "| candidate | exp1 greedy | exp1 late | exp1 early | exp1 first goal | exp2 greedy | "
        "exp2 late | exp2 early | exp2 first goal | min greedy | early, summed |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name, cells in sorted(rows, key=lambda r: -primary.get(r[0], -1e9)):
        crit = (
            f"{primary[name]:.1f} | {sum(e for _, e in scores[name]):.0f}"
            if name in primary
            else "– | –"
        )
        header.append(f"| {name} | {' | '.join(cells)} | {crit} |")
    return header, scores


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sweeps", default="experiments/results/presets/records")
    parser.add_argument("--out", default="experiments/results/presets/search.md")
    args = parser.parse_args()

    rows1, scores1 = table(read(Path(args.sweeps), CANDIDATES))
    primary = {n: min(g for g, _ in s) for n, s in scores1.items()}
    best = max(primary.values())
    close = [n for n in scores1 if primary[n] >= best - 1.0]
    chosen1 = max(close, key=lambda n: sum(e for _, e in scores1[n]))

    rows2, scores2 = table(read(Path(args.sweeps), ROUND2))
    eligible = [n for n, s in scores2.items() if min(g for g, _ in s) >= ROUND2_FLOOR]
    chosen2 = max(eligible, key=lambda n: sum(e for _, e in scores2[n])) if eligible else None

    rows3, scores3 = table(read(Path(args.sweeps), ROUND3))
    eligible3 = [n for n, s in scores3.items() if min(g for g, _ in s) >= ROUND2_FLOOR]
    chosen3 = (
        max(eligible3, key=lambda n: sum(e for _, e in scores3[n]))
        if eligible3
        else max(scores3, key=lambda n: min(g for g, _ in scores3[n]))
    )

    lines = [
        "# The recommended preset's search: every candidate, scored as PROTOCOL.md declared",
        "",
        "Random ties, the experiments' default budgets (exp1: 80×80 with corner options, 300k "
        "steps; exp2: 40×40, 200k), 10 runs per cell. Made by `experiments/presets/*.toml` "
        "(`himit sweep`); this page by `python experiments/presets/analyse_search.py`.",
        "",
        "Per world: **greedy** — the frozen greedy policy at the end, its goals per window as a % "
        "of the mentor's own rate, exact (mean over the 10 seeds [95 % Student-t interval of the "
        "mean]); **late** — goals in the last 50k steps (mean [95 % t-interval]); **early** — "
        "goals in the first 50k steps (mean); **first goal** — median steps to the first goal "
        "over the runs that found it. **min greedy** — the smaller of the two worlds' mean "
        "greedy; **early, summed** — the two worlds' early goals added.",
        "",
        "## Round 1: held-out seeds 1000–1009",
        "",
        *rows1,
        "",
        f"**Round 1's choice: `{chosen1}`** — best on its criterion (min greedy {best:.1f} %); "
        f"within 1 point of it: {', '.join(sorted(close))}; of those, the most early goals.",
        "",
        "## Round 2: fresh held-out seeds 2000–2009",
        "",
        *rows2,
        "",
        (
            f"**Round 2's choice, the recommended preset: `{chosen2}`** — of the candidates "
            f"with min greedy ≥ {ROUND2_FLOOR:.0f} % ({', '.join(sorted(eligible))}), the most "
            "early goals."
            if chosen2
            else f"No candidate of round 2 reached min greedy ≥ {ROUND2_FLOOR:.0f} %: round "
            f"1's choice `{chosen1}` stands."
        ),
        "",
        "## Round 3, the fair factorial's pick: fresh held-out seeds 3000–3009",
        "",
        "Declared in `experiments/benchmark/PROTOCOL.md` (amendment of 2026-11-26) before its "
        "runs: every imitator under both exploration schedules, and with and without mentor "
        "fading where it has a mentor term (candidate: method, preset); round 2's rule.",
        "",
        *rows3,
        "",
        (
            f"**Round 3's choice, the recommended imitator: `{chosen3}`** — of the candidates "
            f"with min greedy ≥ {ROUND2_FLOOR:.0f} % ({', '.join(sorted(eligible3))}), the most "
            "early goals."
            if eligible3
            else f"No candidate of round 3 reached min greedy ≥ {ROUND2_FLOOR:.0f} %: the one "
            f"with the highest, `{chosen3}`."
        ),
    ]
    Path(args.out).write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
