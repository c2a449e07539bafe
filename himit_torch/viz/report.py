"""Figures like the paper's Figs. 3–5 and ``results.md`` from a finished run directory."""

from __future__ import annotations

import csv
import math
import shlex
import statistics
from collections import defaultdict
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from himit_torch.viz.plotting import (
    CURVE_COLORS,
    plot_first_goals,
    plot_goal_curves,
    save_figure,
)
from himit_torch.viz.results_page import learner_settings_line
from himit_torch.viz.tensorboard import tensorboard_command

__all__ = [
    "read_curves",
    "write_figures",
    "write_world_figures",
    "write_results",
    "provenance_line",
    "plot_curves",
    "plot_scaling",
    "plot_first_goal_steps",
    "PAPER_OPTIMAL_GOALS",
]

#: One distinct colour per agent, the same in every figure.
AGENT_COLORS = {
    "imitation": CURVE_COLORS[1],
    "imitation_confident": CURVE_COLORS[3],
    "options": CURVE_COLORS[0],
    "primitives": CURVE_COLORS[2],
    "imitation_primitives": CURVE_COLORS[4],
    "imitation_primitives_confident": CURVE_COLORS[6],
    "imitation_psrl": CURVE_COLORS[5],
    "options_psrl": CURVE_COLORS[7],
    # (beyond the palette's eight: Tol's wine and teal, apart from every colour above)
    "pbrs": "#882255",
    "pbrs_primitives": "#44AA99",
    # (Tol's indigo: apart from the wine and teal above and the palette's eight)
    "bco": "#332288",
}

#: The paper's optimal goals per 5000 steps, by world size (both worlds have 10×10 rooms).
PAPER_OPTIMAL_GOALS = {40: 53.2, 80: 26.3}


def read_curves(run_dir: str | Path, name: str = "curves.csv") -> dict:
    """``{world: {agent: {seed: (steps [W], goals [W])}}}`` from ``run_dir/name``: the run's
    ``curves.csv``, or one world's own (``name="worlds/curves<N>.csv"``)."""
    out: dict = defaultdict(lambda: defaultdict(dict))
    with (Path(run_dir) / name).open() as f:
        rows = list(csv.DictReader(f))
    acc: dict = defaultdict(lambda: ([], []))
    for r in rows:
        key = (int(r["world"]), r["agent"], int(r["seed"]))
        acc[key][0].append(int(r["step"]))
        acc[key][1].append(int(r["goals_in_window"]))
    for (world, agent, seed), (steps, goals) in acc.items():
        out[world][agent][seed] = (np.array(steps), np.array(goals))
    return out


def plot_curves(
    curves_of_world: dict,
    optimal: float | None,
    title: str,
    paper_optimal: float | None = None,
    window: int | None = None,
) -> Figure:
    """Goals in the last window against steps (the paper's Figs. 3 and 4): per agent the mean
    over seeds, the seeds' range as a band and, where the seeds split, the median; ``n`` and
    how many runs found the goal in the legend. The exact optimum is drawn and labelled, the
    paper's (``paper_optimal``) too if given."""
    fig = Figure(figsize=(9.5, 4.4), layout="constrained")
    ax = fig.add_subplot()
    agents = list(curves_of_world)
    steps = next(iter(curves_of_world[agents[0]].values()))[0]
    goals = {a: np.stack([g for _, g in curves_of_world[a].values()]) for a in agents}
    plot_goal_curves(
        ax,
        steps,
        goals,
        colors=AGENT_COLORS,
        optimum=optimal,
        paper_optimum=paper_optimal,
        window=window,
    )
    ax.set_title(title, fontsize="medium")
    return fig


def plot_first_goal_steps(result, title: str) -> Figure:
    """Each run's first-goal step per agent (a dot per seed, median bar), from a
    :class:`~himit_torch.runs.experiment.WorldResult`."""
    firsts = {
        a: [f for f, b in zip(result.first_goal_step, result.agents) if b == a]
        for a in dict.fromkeys(result.agents)
    }
    fig = Figure(figsize=(9.5, 0.7 + 0.55 * len(firsts) + 0.9), layout="constrained")
    ax = fig.add_subplot()
    plot_first_goals(ax, firsts, result.steps, colors=AGENT_COLORS, title=title)
    return fig


def plot_scaling(results, agents) -> Figure:
    """Total goals as a percentage of the optimal policy's, per world size (the paper's Fig. 5)."""
    fig = Figure(figsize=(7, 4.2), layout="constrained")
    ax = fig.add_subplot()
    sizes = [r.size for r in results]
    width = 0.8 / len(agents)
    for i, agent in enumerate(agents):
        means, lows, highs = [], [], []
        for r in results:
            pct = [p for p, a in zip(r.percent_of_optimal(), r.agents) if a == agent]
            means.append(np.mean(pct))
            lows.append(np.mean(pct) - min(pct))
            highs.append(max(pct) - np.mean(pct))
        x = np.arange(len(sizes)) + (i - (len(agents) - 1) / 2) * width
        ax.bar(
            x,
            means,
            width,
            yerr=[lows, highs],
            capsize=3,
            label=agent,
            color=AGENT_COLORS.get(agent),
        )
    ax.set_xticks(np.arange(len(sizes)), [f"{s}×{s}" for s in sizes])
    ax.set_ylabel("total goals, % of optimal")
    n = len(results[0].agents) // len(agents)
    ax.set_title(
        f"goals in {results[0].steps:,} steps as % of the optimal policy's (bars: mean "
        f"of n={n} seeds, whiskers: their range)",
        fontsize="medium",
    )
    ax.legend(fontsize="small")
    ax.grid(axis="y", alpha=0.3)
    return fig


def _save(fig: Figure, path: Path) -> None:
    save_figure(fig, path, dpi=110, fit=True)


def _world_figure_paths(run_dir: Path, config, size: int) -> tuple[Path, Path]:
    """Where :func:`write_world_figures` puts world ``size``'s curves and first goals."""
    number = {"exp1": 3, "exp2": 4}.get(config.name, "")
    return (
        run_dir / "figures" / f"fig{number}_curves_world{size}.png",
        run_dir / "figures" / f"first_goal_world{size}.png",
    )


def write_world_figures(run_dir: Path, config, result, curves_of_world: dict) -> None:
    """One finished world's figures in ``run_dir/figures``: its goal curves (the paper's Figs. 3
    and 4, from ``curves_of_world``: one world's entry of :func:`read_curves`) and each run's
    first goal (from ``result``, its :class:`~himit_torch.runs.experiment.WorldResult`)."""
    size = result.size
    paper = PAPER_OPTIMAL_GOALS.get(size) if result.rooms == 10 and config.window == 5000 else None
    where = (
        f"{config.name}: {size}×{size}, a {result.rooms}×{result.rooms} grid of rooms of "
        f"{config.room_size}×{config.room_size} cells"
        f"{', corner options' if config.corner_options else ''}"
    )
    curves_path, first_goal_path = _world_figure_paths(run_dir, config, size)
    _save(
        plot_curves(
            curves_of_world,
            result.optimal_goals_per_window,
            where,
            paper_optimal=paper,
            window=config.window,
        ),
        curves_path,
    )
    _save(plot_first_goal_steps(result, f"{where}: first goal of each run"), first_goal_path)


def write_figures(run_dir: Path, config, results, worlds: bool = True) -> None:
    """The run's figures in ``run_dir/figures``: each world's (:func:`write_world_figures`) and,
    for several worlds, the goals as a share of the optimum's per world size (Fig. 5).

    ``worlds=False``: only the world figures not drawn yet. A run's world processes draw
    their own as each world ends (off the report's critical path); a run resumed from an
    older version may lack some."""
    curves = read_curves(run_dir)
    for r in results:
        if not curves.get(r.size):
            continue  # fewer steps than one window: no curve to draw
        drawn = all(p.exists() for p in _world_figure_paths(run_dir, config, r.size))
        if worlds or not drawn:
            write_world_figures(run_dir, config, r, curves[r.size])
    if len(results) > 1:
        _save(plot_scaling(results, list(config.agents)), run_dir / "figures" / "fig5_scaling.png")


def _fmt(values, digits=1) -> str:
    values = [v for v in values if v is not None and math.isfinite(v)]
    if not values:
        return "–"
    if len(values) == 1:
        return f"{values[0]:.{digits}f}"
    return f"{statistics.mean(values):.{digits}f} ± {statistics.stdev(values):.{digits}f}"


def _reach_step(steps, goals, level) -> int | None:
    """First step at whose window the goals reached ``level``."""
    hits = np.flatnonzero(goals >= level)
    return int(steps[hits[0]]) if hits.size else None


def _stress_lines(config) -> list[str]:
    """The run's stress settings that differ from their defaults (``config.stresses()``;
    ``mentor_episodes`` is in the line above), as a paragraph; none for a run without."""
    stresses: dict[str, object] = getattr(config, "stresses", dict)()
    stresses.pop("mentor_episodes", None)
    if not stresses:
        return []
    return [
        "Stresses (docs/stresses.md): "
        + ", ".join(f"`{k}={v}`" for k, v in stresses.items())
        + ".",
        "",
    ]


def provenance_line(run_dir: Path, results, run_command: str | None) -> str:
    """The page's provenance: the commit(s) its runs recorded (each world's record), the
    command that redraws the page from its records, and the one that reruns the runs
    (``run_command``, from :func:`himit_torch.runs.experiment.run_command`; None: no ``himit run``
    command writes these settings into this directory — a sweep's trial, the demo)."""
    commits = list(dict.fromkeys(r.commit for r in results))
    runs = (
        f"`{run_command}`"
        if run_command
        else "`run_experiment` of the settings in `config.json` (no `himit run` command writes "
        "them here)"
    )
    return (
        f"Runs recorded at commit{'s' if len(commits) > 1 else ''} "
        + ", ".join(f"`{c}`" for c in commits)
        + f" (from `worlds/*.json`); this page: `himit plot {shlex.quote(str(run_dir))}`; "
        f"the runs: {runs}."
    )


def write_results(
    run_dir: Path, config, results, agent_settings: str = "", run_command: str | None = None
) -> None:
    """``results.md``: per world and agent, our numbers beside the paper's."""
    # agent_settings: what each agent ran with (learner.presets.agent_settings_text), and
    # run_command: the himit run command of config (runs.experiment.run_command), given by the
    # caller: viz does not import the learner or the runs (the layers of pyproject.toml)
    curves = read_curves(run_dir)
    lines = [
        f"# {config.name}: results",
        "",
        provenance_line(run_dir, results, run_command),
        "",
        f"Worlds {', '.join(f'{s}×{s}' for s in config.sizes)} (rooms of {config.room_size} "
        f"cells), corner options: {config.corner_options}, {config.seeds} seeds, "
        f"{config.steps:,} steps per run, {config.mentor_episodes} mentor episodes, "
        f"window {config.window}"
        + (
            f", mentor reward `{config.mentor_reward}`"
            if getattr(config, "mentor_reward", "known") != "known"
            else ""
        )
        + ".",
        "",
        *_stress_lines(config),
        learner_settings_line(config),
        "",
        *([agent_settings, ""] if agent_settings else []),
    ]
    lines += [
        f"Every **±** below is mean ± standard deviation over the {config.seeds} seeds (the "
        "seeds' spread, not a confidence interval); the paired tests and intervals of the "
        "claims are in `experiments/results/claims/claims.md`.",
        "",
    ]
    for r in results:
        lines += [
            f"## {r.size}×{r.size}, {r.rooms}×{r.rooms} rooms",
            "",
            f"Optimal policy (exact, primitives): {r.optimal_steps:.1f} steps a trip, "
            f"{r.optimal_goals_per_window:.1f} goals per {config.window} steps, "
            f"V*(start) = {r.true_value_start:.3f}.",
        ]
        paper = PAPER_OPTIMAL_GOALS.get(r.size)
        if paper and r.rooms == 10:
            lines.append(f"Paper: ≈ {paper} goals per 5000 steps.")
        greedy = bool(getattr(r, "greedy_goals_per_window", None))
        if greedy:
            mentor = r.mentor_goals_per_window
            lines.append(
                f"The mentor's own policy (exact): {mentor:.1f} goals per {config.window} steps "
                f"({100 * mentor / r.optimal_goals_per_window:.1f} % of optimal), V(start) = "
                f"{r.mentor_value_start:.3f}."
            )
        greedy_head = (
            " greedy policy at the end: goals per window | % of optimal | % of mentor | "
            "V^π(start) | sure to reach the goal |"
            if greedy
            else ""
        )
        lines += [
            "",
            "| agent | runs that found the goal | first goal (step, per seed) | goals in "
            "last window | total goals | % of optimal | V(start) (truth "
            f"{r.true_value_start:.3f}) | steps to half the optimal rate | mentor term wins |"
            + greedy_head,
            "|---|---|---|---|---|---|---|---|---|" + ("---|" * 5 if greedy else ""),
        ]
        half = r.optimal_goals_per_window / 2
        for agent in dict.fromkeys(r.agents):
            idx = [b for b, a in enumerate(r.agents) if a == agent]
            firsts = [r.first_goal_step[b] for b in idx]
            found = sum(f >= 0 for f in firsts)
            seeds_curves = curves.get(r.size, {}).get(agent, {})
            reach = [
                _reach_step(seeds_curves[r.seeds[b]][0], seeds_curves[r.seeds[b]][1], half)
                if r.seeds[b] in seeds_curves
                else None
                for b in idx
            ]
            reach_txt = ", ".join("never" if x is None else f"{x // 1000}k" for x in reach)
            lines.append(
                f"| {agent} | {found}/{len(idx)} | "
                f"{', '.join('never' if f < 0 else f'{f:,}' for f in firsts)} | "
                f"{_fmt([r.final_window_goals[b] for b in idx])} | "
                f"{_fmt([r.goals[b] for b in idx], 0)} | "
                f"{_fmt([r.percent_of_optimal()[b] for b in idx])} | "
                f"{_fmt([r.value_start[b] for b in idx], 3)} | {reach_txt} | "
                f"{_fmt([r.mentor_term_wins[b] for b in idx], 2)} |"
                + (
                    f" {_fmt([r.greedy_goals_per_window[b] for b in idx])} | "
                    f"{_fmt([r.greedy_percent_of_optimal[b] for b in idx])} | "
                    f"{_fmt([r.greedy_percent_of_mentor[b] for b in idx])} | "
                    f"{_fmt([r.greedy_value_start[b] for b in idx], 3)} | "
                    f"{sum(r.greedy_reach_share[b] >= 1.0 for b in idx)}/{len(idx)} |"
                    if greedy
                    else ""
                )
            )
        if greedy:
            lines += [
                "",
                "The greedy policy: each run's policy at the end frozen (ε = 0 over its own "
                "options, ties as configured: random ties → uniform over the tied options), "
                "evaluated exactly on the true model (`himit_torch.exact.greedy_evaluation`): "
                f"long-run goals per {config.window} steps of episode after episode, as a % of the "
                "optimal policy's and of the mentor's own; V^π(start); *sure to reach the goal*: "
                "runs whose policy reaches it from the start with probability 1.",
            ]
        lines += [
            "",
            f"Wall time for this world's batch of {len(r.agents)} runs: "
            f"{r.wall_seconds:.0f} s (engine `{r.engine}`, code at "
            f"commit `{r.commit}`).",
            "",
        ]
    if len(results) > 1:
        lines += [
            "## Scaling (the paper's Fig. 5)",
            "",
            "| world | " + " | ".join(dict.fromkeys(results[0].agents)) + " |",
            "|---|" + "---|" * len(dict.fromkeys(results[0].agents)),
        ]
        for r in results:
            cells = []
            for agent in dict.fromkeys(r.agents):
                cells.append(
                    _fmt([p for p, a in zip(r.percent_of_optimal(), r.agents) if a == agent])
                )
            lines.append(f"| {r.size}×{r.size} | " + " | ".join(cells) + " |")
        lines.append("")
    lines += [
        "Figures: `figures/`. Curves: `curves.csv`. TensorBoard: "
        f"`{tensorboard_command(Path(run_dir) / 'tb')}`.",
        "",
    ]
    (run_dir / "results.md").write_text("\n".join(lines))
