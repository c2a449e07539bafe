"""``himit run discovery``: learners with options discovered from the mentor's states
(:mod:`himit_torch.options.discovery`) against primitives only and the hand-built doorway options, on
experiment 1's and experiment 2's worlds.

Per world and seed (each seed records its own mentor episodes, as in the other experiments):

* ``primitives``, ``imitation_primitives`` — primitive options only, without / with the mentor
  term (one batch, all seeds). Their counts after ``warmup`` steps are where the discovered
  options come from: the learner's *own* learned one-step model.
* ``doorway_options``, ``doorway_imitation`` — primitives + the hand-built doorway options
  (``doorway_options(world, "direct")``, built from the true layout), without / with the mentor
  term.
* ``discovered_options``, ``discovered_imitation`` — the first ``warmup`` steps are those of
  ``primitives`` / ``imitation_primitives`` (the same runs); then the subgoals found in the
  seed's demonstrations and options to them built from that run's one-step counts, and *the same
  run* goes on with primitives + those options (``options`` / ``imitation`` variant:
  :func:`~himit_torch.learner.option_refresh.with_options` carries its models, values, counters, ε and
  random stream). Every ``refresh_every`` steps after that the options are built again from the
  run's latest one-step counts and swapped in the same way (options that came out unchanged keep
  their models; changed ones start empty). The subgoals are not searched again: they come from
  the demonstrations, which do not change.

The mentor demonstrates the learner's task, or (``mentor_goal = "top-right"``) its walk to
another goal, as in the experiments (:func:`~himit_torch.runs.mentoring.recorded_mentor_episodes`):
then the subgoals come from those demonstrations, and the learner is still rewarded at its own
goal. The learners' settings are ``learner`` (by default the paper's experiments'), under
``preset`` where one is named.

Goals are counted over the whole run; at its end each run's frozen greedy policy is evaluated
exactly (over its own options at that time; as % of the optimum's goal rate, as the experiments'
summaries). Results: ``config.json``, ``curves.csv``, ``runs.csv`` (per run: first goal, total
goals, the greedy policy's % of the optimum, discovered options), ``subgoals.csv``
(per seed: the subgoals found, precision/recall against the world's doorways, time),
``demonstrations_needed.csv`` (precision/recall against the number of mentor episodes),
``results.md`` and ``figures/``.
"""

from __future__ import annotations

import csv
import functools
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, ClassVar, NamedTuple

import numpy as np

from himit_torch.exact.greedy_evaluation import PolicyEvaluator
from himit_torch.exact.optimum import primitive_optimum
from himit_torch.learner.config import LearnerConfig
from himit_torch.learner.learner import Learner
from himit_torch.learner.option_refresh import with_options
from himit_torch.mentor.demonstrations import Demonstrations
from himit_torch.mentor.policy import mentor_policy
from himit_torch.options.builders import doorway_options, mentor_options, primitive_options
from himit_torch.options.bundle import Options
from himit_torch.options.discovery import (
    discover_subgoals,
    learned_subgoal_options,
    one_step_counts,
)
from himit_torch.runs.config import EXPERIMENTS
from himit_torch.runs.mentoring import recorded_mentor_episodes
from himit_torch.runs.runner import run_windows, source_commit, watch_demonstrations
from himit_torch.runs.study import RunConfig, StudyEntry, run_each, run_study, write_rows
from himit_torch.statistics import paired_comparison, t_interval
from himit_torch.validation import setting
from himit_torch.viz.results_page import provenance_line, write_results_page

__all__ = [
    "DiscoveryConfig",
    "DiscoveryStudy",
    "DiscoveryResults",
    "DISCOVERY_AGENTS",
    "run_discovery",
    "discovery_run_command",
]

#: The compared learners, in the order of the tables.
DISCOVERY_AGENTS = (
    "primitives",
    "imitation_primitives",
    "doorway_options",
    "doorway_imitation",
    "discovered_options",
    "discovered_imitation",
)


#: The columns of ``runs.csv``, one row per run: its first goal (−1: never), goals over the run,
#: its greedy policy's % of the optimum at the end, and the options discovered for it at the
#: warm-up (empty for a run that has none built).
RUN_COLUMNS = (
    "world",
    "agent",
    "seed",
    "first_goal_step",
    "total_goals",
    "greedy_percent_of_optimal",
    "discovered_options",
)


@dataclass
class DiscoveryConfig(RunConfig):
    """Settings of the discovery experiment; its mentor, mentor episodes and window are each
    world's experiment's (:data:`~himit_torch.runs.config.EXPERIMENTS`), its learner settings
    ``learner`` (by default theirs)."""

    name: str = RunConfig.shared("name", "discovery")
    worlds: tuple[str, ...] = setting(
        ("exp2", "exp1"),
        choices=("exp1", "exp2"),
        doc="Whose worlds (and steps, mentor episodes, mentor) to use: ``exp1``, ``exp2``.",
    )
    seeds: int = RunConfig.shared("seeds", 10, doc="Runs per agent and world.")
    first_seed: int = RunConfig.shared("first_seed", 0)
    steps: int | None = RunConfig.shared(
        "steps", None, doc="Steps per run (None: each experiment's own)."
    )
    warmup: int = setting(
        20_000,
        ge=1,
        doc="""
        Steps of the primitives-only phase whose one-step model the options are built from (a
        multiple of the window).""",
    )
    refresh_every: int | None = setting(
        None,
        ge=1,
        doc="""
        Steps between rebuilds of a discovered run's options from its latest one-step counts
        after the warm-up (a multiple of the window); ``None``: built once, at the warm-up.""",
    )
    max_steps_factor: float = setting(
        2.0,
        gt=0.0,
        doc="""
        An option's initiation set: where its subgoal lies within ``max_steps_factor ×
        separation`` expected steps in the learned model.""",
    )
    demonstrations_needed: tuple[int, ...] = setting(
        (1, 2, 5, 10, 20),
        ge=1,
        doc="Mentor episode counts at which subgoal precision/recall is measured.",
    )
    engine: str = RunConfig.shared("engine", "auto")
    mentor_goal: str = RunConfig.shared("mentor_goal")
    preset: str | None = RunConfig.shared("preset", None)
    learner: LearnerConfig = RunConfig.shared(
        "learner",
        default_factory=lambda: EXPERIMENTS["exp1"].learner,
        doc="Learner settings (``LearnerConfig``; default: the paper's experiments' own, which "
        "exp1 and exp2 share).",
    )

    def __post_init__(self):
        self.check_run_settings()
        for w in self.worlds:
            window = EXPERIMENTS[w].window
            steps = self.steps_of(w)
            if self.warmup < window or self.warmup % window or self.warmup >= steps:
                raise ValueError(
                    f"DiscoveryConfig.warmup={self.warmup}: must be a positive multiple "
                    f"of the window ({window}) below the steps ({steps})"
                )
            if steps % window:
                raise ValueError(
                    f"DiscoveryConfig.steps={steps}: must be a multiple of the window ({window})"
                )
        if self.refresh_every is not None:
            window = min(EXPERIMENTS[w].window for w in self.worlds)
            if any(self.refresh_every % EXPERIMENTS[w].window for w in self.worlds):
                raise ValueError(
                    f"DiscoveryConfig.refresh_every={self.refresh_every}: must be a positive "
                    f"multiple of the window ({window}), or None (options built once)"
                )

    def steps_of(self, world: str) -> int:
        return int(self.steps or EXPERIMENTS[world].steps)

    def separation(self, world: str) -> int:
        """Subgoal separation for ``world``: its room spacing − 1 (the one scale discovery is
        told)."""
        return EXPERIMENTS[world].room_size - 1

    def quick(self) -> DiscoveryConfig:
        return replace(
            self,
            seeds=min(self.seeds, 2),
            steps=4 * EXPERIMENTS["exp2"].window,
            warmup=EXPERIMENTS["exp2"].window,
            worlds=self.worlds[:1],
            demonstrations_needed=(2, 5),
        )


def _per_agent() -> dict:
    return {a: {} for a in DISCOVERY_AGENTS}


@dataclass
class _World:
    """One world's setting for :func:`_run_world`: the experiment's world, its mentor and each
    seed's episodes, the subgoals found in them, and the results gathered so far."""

    exp: str
    base: Any
    world: Any
    mentor: Any
    seeds: list[int]
    demos: dict[int, Demonstrations]
    separation: int
    log: Callable[..., None]
    prims: Options
    found: dict[int, Any] = field(default_factory=dict)
    goals: dict[str, dict[int, np.ndarray]] = field(default_factory=_per_agent)
    first_goal: dict[str, dict[int, int]] = field(default_factory=_per_agent)
    greedy: dict[str, dict[int, float]] = field(default_factory=_per_agent)
    build_seconds: list[float] = field(default_factory=list)
    option_counts: dict[tuple[str, int], int] = field(default_factory=dict)
    refreshes: list[int] = field(default_factory=list)
    wall: dict[str, float] = field(default_factory=dict)

    def batch(self, lcfg: LearnerConfig, engine: str, options: Options, agents, run_seeds):
        """A learner batch on the world, every seed watching its own episodes."""
        learner = Learner(self.world, options, agents, run_seeds, config=lcfg, engine=engine)
        watch_demonstrations(learner, self.demos)
        return learner

    def record(self, learner: Learner, names: list[str], run_seeds: list[int]) -> None:
        """Each run's goals per window, first goal and greedy policy's % of the optimum, under
        its name: its frozen greedy policy now (over the learner's options, untried states
        uniform), evaluated exactly."""
        goals = np.asarray([[int(g) for g in row] for row in learner.metrics.goals_in_window]).T
        evaluation = PolicyEvaluator(self.world, learner.options, self.base.window).evaluate(
            learner.views.greedy_policy(), values=False
        )
        greedy = evaluation.percent_of(self.optimal_goals_per_window).tolist()
        for b, (a, s) in enumerate(zip(names, run_seeds)):
            self.goals[a][s] = goals[b]
            self.first_goal[a][s] = int(learner.views.first_goal_step[b])
            self.greedy[a][s] = greedy[b]

    @functools.cached_property
    def optimal_goals_per_window(self) -> float:
        """The optimum's goals per window (the reference of the greedy policies' %)."""
        return float(primitive_optimum(self.world, self.base.window).evaluation.goals_per_window[0])


def _find_subgoals(config: DiscoveryConfig, w: _World) -> tuple[list[dict], list[dict]]:
    """The subgoals found in each seed's episodes (kept in ``w.found``), and their precision
    and recall against the number of demonstrations."""
    subgoal_rows = []
    for s in w.seeds:
        t0 = time.perf_counter()
        sg = discover_subgoals(w.demos[s], separation=w.separation)
        seconds = time.perf_counter() - t0
        w.found[s] = sg
        pr = sg.precision_recall(w.world.doorways)
        pr_all = sg.precision_recall(w.world.doorways, visited_only=False)
        subgoal_rows.append(
            {
                "world": w.exp,
                "seed": s,
                "episodes": w.base.mentor_episodes,
                "found": pr["found"],
                "doorways_visited": pr["true"],
                "hits": pr["hits"],
                "precision": pr["precision"],
                "recall_visited": pr["recall"],
                "recall_all": pr_all["recall"],
                "seconds": seconds,
                "subgoals": " ".join(map(str, sg.states)),
            }
        )
    needed_rows = []
    for n in config.demonstrations_needed:
        recorded = recorded_mentor_episodes(
            replace(w.base, mentor_episodes=n), w.world, w.mentor, w.seeds
        )
        for s in w.seeds:
            d = recorded[s]
            t0 = time.perf_counter()
            pr = discover_subgoals(d, separation=w.separation).precision_recall(w.world.doorways)
            needed_rows.append(
                {
                    "world": w.exp,
                    "episodes": n,
                    "seed": s,
                    **pr,
                    "seconds": time.perf_counter() - t0,
                }
            )
    return subgoal_rows, needed_rows


def _discovered(config: DiscoveryConfig, w: _World, learner: Learner, run: int, seed: int):
    """Primitives + options to ``seed``'s subgoals from the latest one-step counts of run
    ``run`` of ``learner``."""
    tb = time.perf_counter()
    built = learned_subgoal_options(
        one_step_counts(learner, run),
        w.world.num_actions,
        w.found[seed],
        terminal=w.world.terminal_mask,
        max_steps=config.max_steps_factor * w.separation,
        gamma=w.world.gamma,
        usable=w.world.free_mask & ~w.world.terminal_mask,
    )
    w.build_seconds.append(time.perf_counter() - tb)
    return w.prims if built is None else Options.concat(w.prims, built)


def _run_discovered(config: DiscoveryConfig, w: _World, phase1: Learner, out: Path) -> None:
    """The discovered-options runs: each primitives run of ``phase1`` goes on with the options
    built from its own counts, rebuilt as it learns (every ``refresh_every`` steps)."""
    steps, n_prims = config.steps_of(w.exp), phase1.options.num_options
    for variant, source, agent in (
        ("discovered_options", "primitives", "options"),
        ("discovered_imitation", "imitation_primitives", "imitation"),
    ):
        for i, s in enumerate(w.seeds):
            run = (0 if source == "primitives" else len(w.seeds)) + i
            opts = _discovered(config, w, phase1, run, s)
            n_ext = opts.num_options - n_prims
            w.option_counts[(variant, s)] = n_ext
            if s == w.seeds[0] and n_ext:
                _subgoal_figure(
                    out / "figures" / f"options_{variant}_{w.exp}.png",
                    w.world,
                    w.found[s],
                    w.demos[s],
                    opts.select(list(range(n_prims, opts.num_options))),
                    f"{w.exp}'s world, seed {s}: subgoals and options built\nfrom "
                    f"{source}'s model after {config.warmup:,} steps",
                )
            learner = with_options(phase1, opts, runs=[run], agents=[agent])
            n_swaps = 0
            while learner.views.t < steps:
                # to the end, or to the next rebuild where there are rebuilds
                run_windows(learner, min(steps, learner.views.t + (config.refresh_every or steps)))
                if learner.views.t < steps:
                    learner = with_options(learner, _discovered(config, w, learner, 0, s))
                    n_swaps += 1
            w.refreshes.append(n_swaps)
            w.record(learner, [variant], [s])


def _run_learners(config: DiscoveryConfig, w: _World, out: Path) -> str:
    """The primitives runs (whose warm-up the discovered runs continue), the discovered-options
    runs and the hand-built doorway options; returns the engine's name."""
    steps, lcfg, seeds, prims = config.steps_of(w.exp), config.learner, w.seeds, w.prims
    agents = ["primitives"] * len(seeds) + ["imitation_primitives"] * len(seeds)
    run_seeds = seeds + seeds
    t0 = time.perf_counter()
    phase1 = w.batch(lcfg, config.engine, prims, agents, run_seeds)
    run_windows(phase1, config.warmup)
    w.wall["primitives phase"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    _run_discovered(config, w, phase1, out)
    w.wall["discovered options"] = time.perf_counter() - t0
    w.log(f"discovered options done ({w.wall['discovered options']:.0f} s)")
    # ---- the primitives runs to the end
    t0 = time.perf_counter()
    run_windows(phase1, steps)
    w.wall["primitives phase"] += time.perf_counter() - t0
    w.record(phase1, agents, run_seeds)
    w.log(f"primitives done ({w.wall['primitives phase']:.0f} s)")
    # ---- hand-built doorway options
    t0 = time.perf_counter()
    hand = Options.concat(prims, doorway_options(w.world, "direct"))
    agents = ["options"] * len(seeds) + ["imitation"] * len(seeds)
    learner = w.batch(lcfg, config.engine, hand, agents, run_seeds)
    run_windows(learner, steps)
    w.wall["doorway options"] = time.perf_counter() - t0
    names = ["doorway_options" if a == "options" else "doorway_imitation" for a in agents]
    w.record(learner, names, run_seeds)
    w.log(f"doorway options done ({w.wall['doorway options']:.0f} s)")
    return learner.engine.name


def _world_setting(config: DiscoveryConfig, exp: str, progress: bool) -> _World:
    """Experiment ``exp``'s world, its mentor and each seed's recorded episodes (of the
    learner's task, or with ``config.mentor_goal`` another goal's, as the experiments record
    them)."""
    base = replace(EXPERIMENTS[exp], mentor_goal=config.mentor_goal)
    world = base.world(base.sizes[0])
    seeds = list(range(config.first_seed, config.first_seed + config.seeds))
    mentor = mentor_policy(
        world, mentor_options(world, corners=base.corner_options), base.mentor_preference
    )
    demos = recorded_mentor_episodes(base, world, mentor, seeds)
    log = (lambda *a: print(f"discovery {exp}:", *a, flush=True)) if progress else (lambda *a: None)
    return _World(
        exp, base, world, mentor, seeds, demos, config.separation(exp), log,
        primitive_options(world),
    )  # fmt: skip


def _run_world(config: DiscoveryConfig, exp: str, out: Path, progress: bool) -> dict:
    """One world: its subgoals, every learner's runs and the subgoal figure; its results."""
    w = _world_setting(config, exp, progress)
    world, seeds, demos, size, base = w.world, w.seeds, w.demos, w.base.sizes[0], w.base
    subgoal_rows, needed_rows = _find_subgoals(config, w)
    engine = _run_learners(config, w, out)
    _subgoal_figure(
        out / "figures" / f"subgoals_{exp}.png",
        world,
        w.found[seeds[0]],
        demos[seeds[0]],
        None,
        f"{exp}'s world ({size}×{size}), seed {seeds[0]}:\nsubgoals found in "
        f"{base.mentor_episodes} mentor episodes",
    )
    return {
        "world": exp,
        "size": size,
        "steps": config.steps_of(exp),
        "window": base.window,
        "goals": w.goals,
        "first_goal": w.first_goal,
        "greedy": w.greedy,
        "subgoals": subgoal_rows,
        "needed": needed_rows,
        "build_seconds": w.build_seconds,
        "refreshes": w.refreshes,
        "option_counts": w.option_counts,
        "wall": w.wall,
        "separation": w.separation,
        "seeds": seeds,
        "engine": engine,
    }


def _subgoal_figure(path: Path, world, subgoals, demos, options, title: str) -> None:
    from himit_torch.viz.plotting import plot_subgoals, save_figure

    fig = plot_subgoals(world, subgoals, demonstrations=demos, options=options, title=title)
    save_figure(fig, path, dpi=150)


def _curves_figure(path: Path, result: dict) -> None:
    from matplotlib.figure import Figure

    from himit_torch.viz.plotting import plot_goal_curves, save_figure

    window = result["window"]
    steps = np.arange(1, result["steps"] // window + 1) * window
    fig = Figure(figsize=(11, 4.5), layout="constrained")
    ax = fig.add_subplot()
    plot_goal_curves(
        ax,
        steps,
        {a: np.stack([result["goals"][a][s] for s in result["seeds"]]) for a in DISCOVERY_AGENTS},
        window=window,
    )
    ax.set_title(
        f"{result['world']}'s world ({result['size']}×{result['size']}): discovered vs "
        "hand-built options",
        fontsize="medium",
    )
    save_figure(fig, path, dpi=120)


class DiscoveryResults(NamedTuple):
    """What :meth:`DiscoveryStudy.run` returns and its report reads: each world's results (a dict
    per world) and the wall time of all of them, in seconds."""

    results: list[dict]
    total: float


class DiscoveryStudy:
    """The discovery experiment as a :class:`~himit_torch.runs.study.Study`: one
    world after another, then its CSV records; its report the curves figures and ``results.md``.
    It does not resume, and ``--force`` clears nothing (every file is written again)."""

    config_class: ClassVar[type] = DiscoveryConfig
    folders: ClassVar[tuple[str, ...]] = ()
    files: ClassVar[tuple[str, ...]] = ()

    def run(
        self, config: DiscoveryConfig, out: Path, resume: bool, progress: bool
    ) -> DiscoveryResults:
        """Every world's runs, then the CSV records."""
        t0 = time.perf_counter()
        results = [_run_world(config, w, out, progress) for w in config.worlds]
        total = time.perf_counter() - t0
        runs = [(r, a, s) for r in results for a in DISCOVERY_AGENTS for s in r["seeds"]]
        write_rows(out / "curves.csv", ("world", "agent", "seed", "step", "goals_in_window"), [
            dict(world=r["world"], agent=a, seed=s, step=(i + 1) * r["window"],
                 goals_in_window=int(g))
            for r, a, s in runs for i, g in enumerate(r["goals"][a][s])
        ])  # fmt: skip
        write_rows(out / "runs.csv", RUN_COLUMNS, [
            dict(zip(RUN_COLUMNS, (r["world"], a, s, r["first_goal"][a][s],
                                   int(r["goals"][a][s].sum()), f"{r['greedy'][a][s]:.4f}",
                                   r["option_counts"].get((a, s), ""))))
            for r, a, s in runs
        ])  # fmt: skip
        for name, key in (("subgoals.csv", "subgoals"), ("demonstrations_needed.csv", "needed")):
            rows = [row for r in results for row in r[key]]
            with (out / name).open("w", newline="") as f:
                dw = csv.DictWriter(f, fieldnames=list(rows[0]))
                dw.writeheader()
                dw.writerows(rows)
        return DiscoveryResults(results, total)

    def report(self, config: DiscoveryConfig, out: Path, finished: DiscoveryResults) -> None:
        """The curves figures and ``results.md``."""
        for r in finished.results:
            _curves_figure(out / "figures" / f"curves_{r['world']}.png", r)
        _write_results(out, config, finished.results, finished.total)


def run_discovery(
    config: DiscoveryConfig, run_dir: str | os.PathLike, force: bool = False, progress: bool = True
) -> list[dict]:
    """Run the discovery experiment into ``run_dir`` (see the module docstring;
    :class:`DiscoveryStudy` through :func:`~himit_torch.runs.study.run_study`)."""
    finished = run_study(
        DiscoveryStudy(), config, run_dir, resume=None, force=force, progress=progress
    )
    return finished.results


def discovery_run_command(
    config: DiscoveryConfig, run_dir: str | os.PathLike | None = None
) -> str | None:
    """The ``himit run discovery`` command that rebuilds ``config`` exactly, or None where none
    can (its page's command gives only ``seeds``, ``steps``, ``engine``, ``worlds``,
    ``mentor_goal``, ``preset`` and the learner's ``initial_value`` and ``mentor_trial``; not
    ``warmup``, ``refresh_every``, …)."""
    return ENTRY.run_command(config, run_dir)


def _fmt(values, digits: int = 1) -> str:
    """Mean ± 95 % t over the seeds (the mean alone for one seed); "nan ± nan" where a seed has
    no value (the precision of no subgoals found): the mean over seeds is then undefined."""
    if not np.isfinite(values).all():
        return "nan ± nan"
    return t_interval(values).plus_minus(digits)


def _write_results(out: Path, config: DiscoveryConfig, results: list[dict], total: float) -> None:
    """``results.md`` (:func:`~himit_torch.viz.results_page.write_results_page`): the
    provenance, what runs, then each world's subgoals and learning."""
    engine = ", ".join(sorted({r["engine"] for r in results}))
    command = discovery_run_command(config, out)
    provenance = [
        provenance_line(
            [source_commit()],
            " (the code that ran them; the records here hold no commit)",
            "written by the runs themselves (no command redraws it from its records)",
            f"`{command}`."
            if command
            else "the settings in `config.json` (not all of them flags of `himit run "
            "discovery`: `run_discovery` of that `DiscoveryConfig`).",
        ),
        f"Code at commit `{source_commit()}`, engine `{engine}`, {config.seeds} seeds, warm-up "
        f"{config.warmup:,} steps, initiation sets within {config.max_steps_factor:g} × "
        f"separation expected steps. Total wall time {total:.0f} s. Numbers: mean ± half-width "
        "of the 95 % confidence interval (Student's t) over seeds.",
    ]
    sections = [_what_runs(config)]
    for r in results:
        sections += [_subgoals_section(config, r), _learning_section(r)]
    write_results_page(
        out,
        "discovery: options discovered from the mentor's states",
        provenance,
        [*sections, [""]],
    )


def _what_runs(config: DiscoveryConfig) -> list[str]:
    return [
        "What runs (see `himit_torch/runs/discovery.py`): `primitives` / "
        "`imitation_primitives` — primitive options only, without / with the mentor term; "
        "`doorway_options` / `doorway_imitation` — primitives + the hand-built doorway options "
        "(shortest path, from the true layout; no corner options, also on exp1's world); "
        "`discovered_options` / `discovered_imitation` — the primitives-only run of the same "
        "seed and variant for the first `warmup` steps, then *the same run* continued "
        "(`option_refresh.with_options`: models, values, counters, ε, random stream carried) "
        "with primitives + options to the subgoals discovered in that seed's demonstrations, "
        "built from the run's own one-step counts, "
        + (
            "built once"
            if config.refresh_every is None
            else f"rebuilt from its latest counts every {config.refresh_every:,} steps "
            "(unchanged options keep their models, changed ones start empty)"
        )
        + ". Goals count over the whole run; the greedy policy is each run's at its end, "
        "evaluated exactly over its own options. Each world uses its experiment's steps, mentor "
        "and mentor episodes"
        + (
            ""
            if config.mentor_goal == "same"
            else f" (the mentor demonstrating its walk to the {config.mentor_goal} corner, not "
            "the learner's goal; the subgoals are found in those demonstrations)"
        )
        + "; each seed its own mentor episodes; the learner settings are `learner` in "
        "`config.json`.",
        "",
    ]


def _subgoals_section(config: DiscoveryConfig, r: dict) -> list[str]:
    """A world's heading and its subgoals: found, precision and recall, against the episodes."""
    sg = r["subgoals"]
    lines = [
        f"## {r['world']}'s world ({r['size']}×{r['size']}), {r['steps']:,} steps",
        "",
        "### Subgoals",
        "",
        f"Separation {r['separation']} moves; {EXPERIMENTS[r['world']].mentor_episodes} "
        "mentor episodes per seed. Recall against the doorways the mentor passed "
        "(recall_all: against all doorways of the world).",
        "",
        "| found | doorways passed | precision | recall | recall_all | time (ms) |",
        "|---|---|---|---|---|---|",
        f"| {_fmt([x['found'] for x in sg])} | {_fmt([x['doorways_visited'] for x in sg])} | "
        f"{_fmt([x['precision'] for x in sg], 2)} | "
        f"{_fmt([x['recall_visited'] for x in sg], 2)} | "
        f"{np.mean([x['recall_all'] for x in sg]):.3f} | "
        f"{1000 * np.mean([x['seconds'] for x in sg]):.1f} |",
        "",
        "Demonstrations needed (precision / recall, mean over seeds):",
        "",
        "| mentor episodes | precision | recall |",
        "|---|---|---|",
    ]
    for n in config.demonstrations_needed:
        rows = [x for x in r["needed"] if x["episodes"] == n]
        lines.append(
            f"| {n} | {_fmt([x['precision'] for x in rows], 2)} | "
            f"{_fmt([x['recall'] for x in rows], 2)} |"
        )
    n_opts = list(r["option_counts"].values())
    return lines + [
        "",
        f"Options built at the warm-up per run: {_fmt(n_opts)} (min {min(n_opts)}); "
        f"building them took {1000 * np.mean(r['build_seconds']):.0f} ms a time, "
        f"{np.mean(r['refreshes']):.0f} rebuilds a run after the warm-up.",
        "",
    ]


def _learning_section(r: dict) -> list[str]:
    """A world's learning table and the discovered imitator against the others."""
    seeds = r["seeds"]
    tot = {a: [int(r["goals"][a][s].sum()) for s in seeds] for a in DISCOVERY_AGENTS}
    last = {a: [int(r["goals"][a][s][-1]) for s in seeds] for a in DISCOVERY_AGENTS}
    reached = {a: sum(1 for s in seeds if r["first_goal"][a][s] >= 0) for a in DISCOVERY_AGENTS}
    greedy = {a: [r["greedy"][a][s] for s in seeds] for a in DISCOVERY_AGENTS}
    lines = [
        "### Learning",
        "",
        "| agent | total goals | goals in last window | runs that reached the goal | greedy "
        "policy at the end, % of optimum |",
        "|---|---|---|---|---|",
    ]
    for a in DISCOVERY_AGENTS:
        lines.append(
            f"| {a} | {_fmt(tot[a])} | {_fmt(last[a])} | {reached[a]}/{len(seeds)} | "
            f"{_fmt(greedy[a])} |"
        )
    hand, disc, prim = (
        np.mean(tot[a])
        for a in ("doorway_imitation", "discovered_imitation", "imitation_primitives")
    )
    ratio = disc / hand if hand else float("nan")
    r["ratio"] = ratio
    lines += [
        "",
        f"Discovered-options imitator / hand-built imitator (total goals): "
        f"**{100 * ratio:.0f} %** (target ≥ 80 % on exp2's world); vs primitives-only "
        f"imitation: {disc:.0f} vs {prim:.0f}",
    ]
    if len(tot["discovered_imitation"]) < 2:
        lines[-1] += " (one seed: no paired comparison)."
    else:
        # Paired over seeds: a seed's two runs share its mentor episodes and, here, its warm-up.
        c = paired_comparison(
            tot["discovered_imitation"], tot["imitation_primitives"], interval="t"
        )
        beats = c.difference.low > 0
        lines[-1] += (
            f", paired difference {c.difference.plus_minus(1, '+')} goals (paired t-test p = "
            f"{c.t_p:.3g}; {'beats it' if beats else 'does not beat it'}: the interval "
            f"{'lies above' if beats else 'does not lie above'} 0)."
        )
    return lines + [
        "",
        "Wall time: " + ", ".join(f"{k} {v:.0f} s" for k, v in r["wall"].items()),
        "",
    ]


#: The registry entry of ``himit run discovery``.
ENTRY = StudyEntry(
    "discovery",
    "options discovered from the mentor's states against hand-built doorway options "
    "(himit_torch.runs.discovery; one process on the CPU, rerun with --force)",
    DiscoveryConfig,
    configs=lambda: (DiscoveryConfig(),),
    run=run_each(run_discovery),
    describe=lambda config, run_dir: (
        f"{config.name}: worlds {list(config.worlds)}, {config.seeds} seeds → {run_dir}"
    ),
    no_redraw="its results.md and figures are written at the end of the run, and himit plot "
    "does not redraw them",
    rerun_flags=(
        *("seeds", "steps", "engine", "worlds", "mentor_goal", "preset"),
        *("initial_value", "mentor_trial"),  # (the learner's)
    ),
)
