"""The benchmark's tables and figures, as PROTOCOL.md declared: the leaderboard (methods × worlds
on the claims' endpoints, every method against eq. 2 paired by seed, Holm over the table) and
one figure per stress axis.

    python experiments/benchmark/analyse.py [--results experiments/results]

Reads the claims' runs (``<results>/paper-random``, ``recommended-random``), the benchmark's own
(``<results>/benchmark/worlds``) and the stress sweep (``<results>/benchmark/stress_exp2``);
writes ``<results>/benchmark/leaderboard.md``, ``leaderboard.csv`` and ``stress_<axis>.png``.
"""

from __future__ import annotations

import argparse
import csv
import importlib.util
import json
import math
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

from himit_torch.statistics import bca_interval, first_goal_survival

# The claims' loader and tests, one place (loaded by path: both scripts are called analyse.py).
_spec = importlib.util.spec_from_file_location(
    "claims_analyse", Path(__file__).resolve().parents[1] / "claims" / "analyse.py"
)
claims = importlib.util.module_from_spec(_spec)  # type: ignore[arg-type]
sys.modules["claims_analyse"] = claims  # (its dataclasses look their module up)
_spec.loader.exec_module(claims)  # type: ignore[union-attr]
WORLDS, Test, World = claims.WORLDS, claims.Test, claims.World
_km_text, adjust, compare, load_dir = (
    claims._km_text,
    claims.adjust,
    claims.compare,
    claims.load_dir,
)


#: Method → (folder of its runs, agent name there).
METHODS = {
    "eq. 2 (paper)": ("paper-random", "imitation"),
    "eq. 2, recommended": ("recommended-random", "imitation"),
    "implicit imitation (eq. 1)": ("benchmark", "imitation_primitives"),
    "PBRS": ("benchmark", "pbrs"),
    "PBRS, primitives": ("benchmark", "pbrs_primitives"),
    "BCO": ("benchmark", "bco"),
    "options only": ("paper-random", "options"),
    "primitives only": ("paper-random", "primitives"),
}
REFERENCE = "eq. 2 (paper)"
ENDPOINTS = ("first_goal", "early", "greedy_optimal")
#: The stress axes of stress_exp2.toml: setting → (label, its default).
AXES = {
    "mentor_episodes": ("demonstrations per seed", 20),
    "mentor_noise": ("mentor noise (probability of a random primitive)", 0.0),
    "mentor_detour": ("the mentor's detour", False),
    "observation_stride": ("observation stride (every k-th mentor state)", 1),
    "slip": ("slip", 0.1),
    "layout": ("layout", "open"),
}
STRESS_AGENTS = ("imitation", "imitation_primitives", "pbrs", "bco", "options")


def method_world(data: dict, method: str, world: str) -> World:
    """The runs of ``method`` on ``world``, as a World holding only that method (as agent
    ``method``)."""
    folder, agent = METHODS[method]
    source = data[folder][world]
    out = World(world, source.budget)
    for (a, seed), run in source.runs.items():
        if a == agent:
            out.runs[method, seed] = run
    return out


def leaderboard(data: dict) -> tuple[list[str], list[Test]]:
    tests = []
    for world in WORLDS:
        merged = World(world, data["paper-random"][world].budget)
        for m in METHODS:
            merged.runs.update(method_world(data, m, world).runs)
        for m in METHODS:
            if m == REFERENCE:
                continue
            for e in ENDPOINTS:
                tests.append(
                    Test(
                        "benchmark",
                        "",
                        world,
                        f"{m} − {REFERENCE}",
                        e,
                        "random",
                        compare(merged, m, REFERENCE, e),
                    )
                )
    adjust(tests)
    by = {(t.world, t.comparison, t.endpoint): t for t in tests}

    def cell(world: str, m: str, endpoint: str) -> str:
        w = method_world(data, m, world)
        if endpoint == "first_goal":
            s = first_goal_survival(w.values(m, "first_goal"), w.budget)
            text = _km_text(s.median).split(" [")[0]
        else:
            digits = 1 if endpoint == "greedy_optimal" else 0
            text = f"{np.mean(w.values(m, endpoint)):.{digits}f}"
        if m != REFERENCE:
            t = by[world, f"{m} − {REFERENCE}", endpoint]
            p = min(x for x in t.p_holm.values() if not math.isnan(x))
            if p < 0.05:
                if endpoint == "first_goal":
                    better = t.result.wins > t.result.losses
                else:
                    better = t.result.difference.estimate > 0
                text += " ▲" if better else " ▼"
        return text

    lines = []
    titles = {
        "greedy_optimal": "The greedy policy at the end, % of optimal (mean of 20 seeds)",
        "first_goal": "Steps to the first goal (Kaplan–Meier median; 'never': the curve does "
        "not fall to ½)",
        "early": "Goals in the first 50k steps (mean of 20 seeds)",
    }
    for endpoint in ("greedy_optimal", "first_goal", "early"):
        lines += [
            f"## {titles[endpoint]}",
            "",
            "| method | " + " | ".join(WORLDS) + " | mean rank |",
            "|---|" + "---|" * (len(WORLDS) + 1),
        ]
        ranks: dict = defaultdict(list)
        for world in WORLDS:
            score = {}
            for m in METHODS:
                w = method_world(data, m, world)
                if endpoint == "first_goal":
                    s = first_goal_survival(w.values(m, "first_goal"), w.budget)
                    score[m] = -s.median.estimate
                else:
                    score[m] = float(np.mean(w.values(m, endpoint)))
            order = sorted(METHODS, key=lambda m: -score[m])
            for rank, m in enumerate(order, 1):
                ranks[m].append(rank)
        for m in METHODS:
            cells = [cell(world, m, endpoint) for world in WORLDS]
            lines.append(f"| {m} | " + " | ".join(cells) + f" | {np.mean(ranks[m]):.1f} |")
        lines.append("")
    return lines, tests


def batch_check(data: dict) -> str:
    """Whether options-only of the benchmark's batch equals the claims' runs, run by run."""
    same, total = 0, 0
    for world in WORLDS:
        ours = data["benchmark"][world]
        theirs = data["paper-random"][world]
        for (agent, seed), run in ours.runs.items():
            if agent == "options":
                total += 1
                same += run == theirs.runs["options", seed]
    return (
        f"Options-only, run again in the benchmark's batches beside the new agents, equals the "
        f"claims' runs in {same} of {total} runs (every endpoint, every world)."
    )


def stress_figures(results: Path, out: Path) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sweep = results / "benchmark" / "stress_exp2"
    rows = list(csv.DictReader((sweep / "runs.csv").open()))
    steps = json.loads((sweep / "sweep.json").read_text())["cells"][0]["config"]["steps"]

    def level_of(row: dict, axis: str):
        cell = row["cell"]
        for other in AXES:
            if cell.startswith(f"{other}="):
                return cell.split("=", 1)[1] if other == axis else None
        return str(AXES[axis][1])  # the baseline cell: every axis at its default

    for axis, (label, default) in AXES.items():
        levels: dict = defaultdict(lambda: defaultdict(list))
        for r in rows:
            level = level_of(r, axis)
            if level is not None:
                levels[level][r["agent"]].append(r)

        order = sorted(levels, key=lambda level, d=str(default): _level_key(level, d))
        fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4))
        for agent in STRESS_AGENTS:
            g, f = [], []
            for level in order:
                rs = levels[level][agent]
                g.append(bca_interval([float(r["greedy_percent_of_optimal"]) for r in rs]))
                f.append(first_goal_survival([int(r["first_goal_step"]) for r in rs], steps).median)
            x = np.arange(len(order))
            ax1.errorbar(
                x,
                [i.estimate for i in g],
                yerr=[[i.estimate - i.low for i in g], [i.high - i.estimate for i in g]],
                marker="o",
                capsize=3,
                label=agent,
            )
            fin = [min(i.estimate, steps) / 1000 for i in f]
            lo = [min(i.low, steps) / 1000 for i in f]
            hi = [min(i.high, steps) / 1000 for i in f]
            ax2.errorbar(
                x,
                fin,
                yerr=[np.subtract(fin, lo), np.subtract(hi, fin)],
                marker="o",
                capsize=3,
                label=agent,
            )
        for ax in (ax1, ax2):
            ax.set_xticks(np.arange(len(order)), order)
            ax.set_xlabel(label)
        ax1.set_ylabel("greedy policy at the end, % of optimal\n(mean, 95 % BCa)")
        ax2.set_ylabel("first goal, thousands of steps\n(KM median, 95 % interval; top: never)")
        ax1.legend(fontsize=8)
        fig.suptitle(f"Experiment 2 (40×40), 20 seeds per point: {label}")
        fig.tight_layout()
        fig.savefig(out / f"stress_{axis}.png", dpi=90)
        plt.close(fig)
    return _stress_table(rows, steps)


def _level_key(level: str, default: str) -> tuple:
    """Numbers in order; words (open/maze, False/True) with the default first."""
    try:
        return (0, float(level), "")
    except ValueError:
        return (1, float(level != default), level)


def _stress_table(rows: list[dict], steps: int) -> list[str]:
    """Every stress cell: per agent the greedy % of optimal [BCa] and the KM first goal."""
    cells = list(dict.fromkeys(r["cell"] for r in rows))
    lines = [
        "| cell | " + " | ".join(STRESS_AGENTS) + " |",
        "|---|" + "---|" * len(STRESS_AGENTS),
    ]
    for cell in cells:
        out = []
        for agent in STRESS_AGENTS:
            rs = [r for r in rows if r["cell"] == cell and r["agent"] == agent]
            g = bca_interval([float(r["greedy_percent_of_optimal"]) for r in rs])
            f = first_goal_survival([int(r["first_goal_step"]) for r in rs], steps).median
            out.append(f"{g.format(1)}; {_km_text(f).split(' [')[0]}")
        lines.append(f"| {cell} | " + " | ".join(out) + " |")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--results", default="experiments/results")
    args = parser.parse_args()
    results = Path(args.results)
    out = results / "benchmark"
    data = {
        "paper-random": load_dir(results / "paper-random"),
        "recommended-random": load_dir(results / "recommended-random"),
        "benchmark": load_dir(out / "worlds"),
    }
    board, tests = leaderboard(data)
    stress = stress_figures(results, out)
    lines = [
        "# The leaderboard (generated by `experiments/benchmark/analyse.py`)",
        "",
        "Every method at its documented settings, random ties, seeds 0–19 (20 per cell), the "
        "endpoints of `experiments/benchmark/PROTOCOL.md`. **▲ / ▼**: better / worse than eq. 2 "
        "(the paper preset's `imitation`) on that endpoint, paired by seed, with Holm-adjusted "
        "p < 0.05 (the smaller of the t-test's and the sign test's; every test with its raw and "
        "adjusted p: `leaderboard.csv`). " + batch_check(data),
        "",
        *board,
        "## Stresses on experiment 2 (40×40): the greedy policy at the end, % of optimal "
        "(mean [95 % BCa]); the first goal (KM median)",
        "",
        "20 seeds per cell; one setting changed at a time from the baseline (the defaults). "
        "Figures: `stress_<setting>.png`.",
        "",
        *stress,
        "",
    ]
    (out / "leaderboard.md").write_text("\n".join(lines) + "\n")
    with open(out / "leaderboard.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(
            [
                "world",
                "comparison",
                "endpoint",
                "difference",
                "low",
                "high",
                "wins",
                "losses",
                "ties",
                "p_t",
                "p_sign",
                "p_t_holm",
                "p_sign_holm",
            ]
        )
        for t in tests:
            w.writerow([t.world, t.comparison, t.endpoint, *claims.result_cells(t)])
    print((out / "leaderboard.md").read_text())


if __name__ == "__main__":
    main()
