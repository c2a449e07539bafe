"""The paper's experiments (Section III) as configurations and one batched runner.

One :class:`ExperimentConfig` per experiment holds the paper's settings, field by field; it is
saved as JSON in the run directory and can be loaded back (``himit run --config``). All agents
and seeds of one world run in one :class:`~himit_torch.Learner` batch (:func:`run_world`, in named
steps: the mentor and its demonstrations, the learner, the greedy tracker, checkpoints and logger,
the run, the result). The experiments are a study (:class:`ExperimentStudy`, run by
:func:`~himit_torch.runs.study.run_study`); :func:`run_experiments` shares several experiments'
worlds out over one pool with the same pieces. A run directory holds::

    config.json                 the configuration
    curves.csv                  per window: world, agent, seed, step, goals, ε, episodes, …
    tb/<world>__<agent>__seed<k>/   TensorBoard event files (scalars, images, hparams)
    checkpoints/world<N>.pt     the whole learner state every ``checkpoint_every`` steps (format:
    checkpoints/world<N>.prev.pt  ``himit_torch.runs.checkpoints``), and the generation before it
    worlds/world<N>.json        what happened in one world (written when it is finished)
    figures/*.png               the paper's Figs. 2–5, ours
    results.md                  our numbers beside the paper's
"""

from __future__ import annotations

import json
import os
import sys
from collections.abc import Callable, Iterator, Sequence
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path
from typing import Any, ClassVar

import torch

from himit_torch.exact.greedy_evaluation import (
    PolicyEvaluation,
    PolicyEvaluator,
    evaluate_option_choice,
)
from himit_torch.exact.optimum import primitive_optimum
from himit_torch.learner.agents import AGENTS
from himit_torch.learner.config import LearnerConfig
from himit_torch.learner.learner import Learner
from himit_torch.learner.presets import agent_settings_text
from himit_torch.mentor.demonstrations import Demonstrations
from himit_torch.mentor.observation import (
    CoarseDemonstrations,
    observe_at_option_ends,
    observe_every,
)
from himit_torch.mentor.policy import (
    exact_mentor_transitions,
    mentor_policy,
    record_demonstrations,
    run_mentor,
)
from himit_torch.mentor.reward import mentor_reward_module
from himit_torch.options.builders import learner_options, mentor_options
from himit_torch.options.bundle import Options
from himit_torch.runs.checkpoints import BatchShape
from himit_torch.runs.config import EXPERIMENTS, ExperimentConfig, load_config
from himit_torch.runs.greedy import CURVE_COLUMNS, GreedyReference, GreedyTracker
from himit_torch.runs.mentoring import mentor_detour_of, recorded_mentor_episodes
from himit_torch.runs.pool import run_pool, workers_for
from himit_torch.runs.runner import (
    Checkpoints,
    Maps,
    WindowHook,
    batch_runs,
    check_run_dir,
    merge_csv,
    run_names,
    run_windows,
    source_commit,
    watch_demonstrations,
    write_atomically,
)
from himit_torch.runs.study import (
    Field,
    InfoTopic,
    RunFlags,
    StudyEntry,
    check_resumed_config,
    optimum_lines,
    option_kinds_text,
    prepare_run_dir,
    read_record,
    read_table,
    run_study,
    series_of,
    write_rows,
)
from himit_torch.validation import refuse_unknown_fields
from himit_torch.viz.tensorboard import TensorBoardLogger
from himit_torch.worlds.multirooms import MultiRooms

__all__ = [
    "ExperimentStudy",
    "run_experiment",
    "run_experiments",
    "run_world",
    "read_world_result",
    "check_curves",
    "WorldResult",
    "rewrite_report",
    "run_command",
    "optimal_reference",
    "PAPER",
]

#: What the paper reports (Section III, Figs. 3–5).
PAPER: dict[str, dict[str, Any]] = {
    "exp1": {
        "experiment": 1,
        "world": (80, 10),
        "slip": 0.1,
        "optimal_goals_per_5000": 26.3,
        "optimal_steps": 190,
    },
    "exp2": {
        "experiment": 2,
        "world": (40, 10),
        "slip": 0.1,
        "optimal_goals_per_5000": 53.2,
        "optimal_steps": 94,
        "non_imitator_failures": "4 of 5 runs never found the goal",
    },
    "exp3": {
        "claim": "the benefit of imitation grows with the world's size (64 → 120); numbers "
        "only as a bar chart"
    },
}


# =========================================================================== one world's batch
@dataclass
class WorldResult:
    """What happened in one world: per-run summaries and the optimal baseline."""

    size: int
    rooms: int
    agents: list[str]
    seeds: list[int]
    optimal_steps: float
    optimal_goals_per_window: float
    goals: list[int]
    first_goal_step: list[int]
    final_window_goals: list[int]
    value_start: list[float]
    true_value_start: float
    mentor_term_wins: list[float]
    wall_seconds: float
    steps: int
    engine: str = "unknown"
    commit: str = "unknown"
    # The frozen greedy policies at the end, exact (runs.greedy); empty for runs written before
    # they existed or with greedy_every = None.
    greedy_goals_per_window: list[float] = field(default_factory=list)
    greedy_percent_of_optimal: list[float] = field(default_factory=list)
    greedy_percent_of_mentor: list[float] = field(default_factory=list)
    greedy_value_start: list[float] = field(default_factory=list)
    greedy_reach_share: list[float] = field(default_factory=list)
    # The same final policies with the "stuck" rule (a state the run has tried nothing at is
    # never left; exact.greedy_evaluation): how much of the rate rests on untried states.
    greedy_percent_of_optimal_stuck: list[float] = field(default_factory=list)
    greedy_percent_of_mentor_stuck: list[float] = field(default_factory=list)
    mentor_goals_per_window: float = float("nan")
    mentor_value_start: float = float("nan")

    def percent_of_optimal(self) -> list[float]:
        """Total goals as a percentage of what the optimal policy reaches in the same steps."""
        best = self.steps / self.optimal_steps
        return [100.0 * g / best for g in self.goals]


def optimal_reference(world: MultiRooms, window: int) -> tuple[float, float, PolicyEvaluation]:
    """The optimum a world's runs are measured against
    (:func:`~himit_torch.exact.optimum.primitive_optimum`): steps start → goal, ``V*(start)`` and
    its exact evaluation over windows of ``window`` steps."""
    best = primitive_optimum(world, window)
    return best.steps_to_goal, best.value_start, best.evaluation


def _hparams(config: ExperimentConfig, size: int, agent: str) -> dict:
    """A run group's settings for TensorBoard's HParams dashboard: agent, experiment,
    world and every setting off the library's defaults (never the seed, which it aggregates)."""
    hp = {"agent": agent, "experiment": config.name, "world": f"{size}×{size}"}
    for settings, default, left_out in (
        (config, ExperimentConfig(), _NOT_HPARAMS),
        (config.learner, LearnerConfig(window=config.window), frozenset()),
    ):
        hp.update(
            {
                f.name: getattr(settings, f.name)
                for f in fields(settings)
                if f.name not in left_out and getattr(settings, f.name) != getattr(default, f.name)
            }
        )
    return hp


#: The experiment's settings left out of its hparams: the seeds TensorBoard aggregates, the
#: learner's settings (listed one by one beside them), and what does not change a run's course.
_NOT_HPARAMS = frozenset(
    "name sizes agents seeds first_seed device checkpoint_every greedy_every learner".split()
)


@dataclass
class _WorldBatch:
    """One world's batch as :func:`run_world` sets it up: the experiment, the world and its
    runs (every agent × seed, agent-major), and where its records go."""

    config: ExperimentConfig
    size: int
    run_dir: Path
    world: MultiRooms
    seeds: list[int]
    agents: list[str]
    run_seeds: list[int]


@dataclass
class _Mentoring:
    """What the mentor leaves a batch (the exact parts ``None`` where not asked for)."""

    recorded: dict
    demos: dict
    second: dict
    mentor_eval: PolicyEvaluation | None
    exact: object | None


def run_world(
    config: ExperimentConfig,
    size: int,
    run_dir: Path,
    resume: bool,
    progress: bool = True,
    on_window: Callable | None = None,
) -> WorldResult:
    """Run every agent × seed of one world in one batch (resuming from its checkpoint), and
    write its curves, figures and record (``worlds/world<size>.json``, last)."""
    seeds, agents, run_seeds = batch_runs(config.agents, config.first_seed, config.seeds)
    batch = _WorldBatch(config, size, run_dir, config.world(size), seeds, agents, run_seeds)
    mentoring = _mentoring(batch)
    learner, options = _learner(batch, mentoring)
    optimal_steps, true_v, optimal_eval = optimal_reference(batch.world, config.window)
    greedy = _greedy_tracker(batch, options, mentoring.mentor_eval, optimal_eval)
    checkpoints = Checkpoints(
        run_dir / "checkpoints" / f"world{size}.pt",
        BatchShape(tuple(agents), tuple(run_seeds), batch.world.num_states),
        config.checkpoint_every,
        config.device,
        companions={} if greedy is None else {"greedy": greedy},
    )
    elapsed = checkpoints.start(learner, resume)
    logger = _logger(batch, learner, options, true_v, resume)
    wall = _run_batch(
        batch, learner, logger, greedy, checkpoints, mentoring.demos, progress, on_window, elapsed
    )
    result = _world_result(batch, learner, optimal_steps, true_v, wall)
    if greedy is not None:
        _add_greedy_results(result, greedy, greedy.finish(learner))
    _log_hparams(batch, logger, learner, result)
    logger.close()
    _write_curves(run_dir / "worlds" / f"curves{size}.csv", learner, size, greedy)
    # The world's figures are drawn as it ends, not with the report; the record comes last, so
    # a world with a record has its figures.
    _world_figure(batch, mentoring.recorded[seeds[0]], learner)
    _world_curve_figures(run_dir, config, result)
    write_atomically(run_dir / "worlds" / f"world{size}.json", json.dumps(asdict(result), indent=1))
    return result


def _mentoring(batch: _WorldBatch) -> _Mentoring:
    """The mentor's part of a batch. The mentor's own option tables are gone when this
    returns, so they never share the peak memory with the learner's."""
    config, world, seeds = batch.config, batch.world, batch.seeds
    mentor = mentor_policy(
        world,
        mentor_options(world, corners=config.corner_options),
        config.mentor_preference,
        # the paper's worlds keep their mentor; a maze or a moved goal may trap it in a cycle
        break_cycles=config.layout != "open" or config.goal_needs_primitives,
    )
    recorded = recorded_mentor_episodes(config, world, mentor, seeds)
    # what the learner observes of them (config.observation_stride; stride 1: the same objects;
    # or where the mentor's options end: its episodes again, the same as recorded, from the
    # rollout that says where each option began)
    demos: dict[int, Demonstrations | CoarseDemonstrations]
    if config.observation == "option-ends":
        demos = {
            s: observe_at_option_ends(
                run_mentor(world, mentor, config.mentor_episodes, seed=s), world
            )
            for s in seeds
        }
    else:
        demos = {s: observe_every(d, config.observation_stride) for s, d in recorded.items()}
    second = {
        s: observe_every(d, config.observation_stride)
        for s, d in _second_mentor(config, world, mentor, seeds).items()
    }
    # the mentor's own goal rate, exactly, while its options exist
    mentor_eval = (
        None
        if config.greedy_every is None
        else evaluate_option_choice(world, mentor.options, mentor.option, config.window)
    )
    exact = (
        exact_mentor_transitions(world, mentor, float(config.mentor_episodes))
        if config.mentor_model == "exact"
        else None
    )
    return _Mentoring(recorded, demos, second, mentor_eval, exact)


def _learner(batch: _WorldBatch, mentoring: _Mentoring) -> tuple[Learner, Options]:
    """The batch's learner on the learner's options, every run watching its seed's mentor
    (the exact mentor model instead, with ``mentor_model="exact"``) and its second mentor."""
    config, world = batch.config, batch.world
    options = learner_options(world, corners=config.corner_options)
    learner = Learner(
        world,
        options,
        batch.agents,
        batch.run_seeds,
        config=config.learner,
        reward=mentor_rewards(config, world, batch.agents, batch.run_seeds, mentoring.demos),
        device=config.device,
        engine=config.engine,
    )
    exact = mentoring.exact
    watch_demonstrations(
        learner, mentoring.demos if exact is None else dict.fromkeys(batch.seeds, exact)
    )
    if mentoring.second:
        watch_demonstrations(learner, mentoring.second, mentor=1)
    return learner, options


def _greedy_tracker(
    batch: _WorldBatch,
    options: Options,
    mentor_eval: PolicyEvaluation | None,
    optimal_eval: PolicyEvaluation,
) -> GreedyTracker | None:
    """The tracker of the runs' frozen greedy policies (``None`` with ``greedy_every=None``)."""
    if mentor_eval is None:
        return None
    return GreedyTracker(
        PolicyEvaluator(batch.world, options, batch.config.window),
        GreedyReference(optimal_eval, mentor_eval),
        batch.config.greedy_every or 0,
        batch.config.steps,
    )


def _logger(
    batch: _WorldBatch, learner: Learner, options: Options, true_v: float, resume: bool
) -> TensorBoardLogger:
    """The batch's TensorBoard logger (a resumed run purges what it logged after its last
    checkpoint; a fresh one logs each run's settings)."""
    config = batch.config
    logger = TensorBoardLogger(
        batch.run_dir / "tb",
        run_names(f"world{batch.size}", batch.agents, batch.run_seeds),
        world=batch.world,
        options=options,
        true_value_start=true_v,
        initial_value=config.learner.initial_value,
        resume_step=learner.views.t if resume else None,
    )
    if not resume or learner.views.t == 0:
        for b in range(learner.batch):
            logger.text(b, "settings", f"seed {batch.run_seeds[b]}\n\n```\n{config.to_json()}\n```")
    return logger


def _run_batch(
    batch: _WorldBatch,
    learner: Learner,
    logger: TensorBoardLogger,
    greedy: GreedyTracker | None,
    checkpoints: Checkpoints,
    demos: dict,
    progress: bool,
    on_window: Callable | None,
    elapsed: float,
) -> float:
    """Run the batch to its last step (:func:`~himit_torch.runs.runner.run_windows`);
    returns the run's wall seconds."""
    config, run_seeds = batch.config, batch.run_seeds
    # Maps for the first seed of every agent, half-way (the first window end from there) and
    # at the end: drawn as arrays, a few ms a map (viz.plotting.MapRenderer).
    map_runs = [b for b, s in enumerate(run_seeds) if s == batch.seeds[0]]
    maps_every = -(-config.steps // (2 * config.window)) * config.window
    mentor_visits = {
        b: torch.bincount(
            torch.cat([torch.as_tensor(e) for e in demos[run_seeds[b]].episodes]),
            minlength=batch.world.num_states,
        )
        for b in map_runs
    }
    hooks: list[WindowHook] = [logger.window]
    if greedy is not None:
        greedy.logger = logger
        hooks.append(greedy)
    if on_window is not None:
        hooks.append(lambda learner, _: on_window(learner))
    return run_windows(
        learner,
        config.steps,
        on_window=hooks,
        logger=logger,
        maps=Maps(map_runs, maps_every, mentor_visits),
        checkpoints=checkpoints,
        progress=f"{config.name} {batch.size}×{batch.size} B={learner.batch}" if progress else None,
        elapsed=elapsed,
    )


def _world_result(
    batch: _WorldBatch, learner: Learner, optimal_steps: float, true_v: float, wall: float
) -> WorldResult:
    """The finished batch's :class:`WorldResult` (the greedy policies' part apart)."""
    world, m = batch.world, learner.metrics
    return WorldResult(
        size=batch.size,
        rooms=world.rooms,
        agents=batch.agents,
        seeds=batch.run_seeds,
        optimal_steps=optimal_steps,
        optimal_goals_per_window=batch.config.window / optimal_steps,
        goals=learner.views.goals.tolist(),
        first_goal_step=learner.views.first_goal_step.tolist(),
        final_window_goals=(
            m.goals_in_window[-1].tolist() if m.goals_in_window else [0] * len(batch.agents)
        ),
        value_start=learner.views.state_values()[:, world.start_state].tolist(),
        true_value_start=true_v,
        mentor_term_wins=learner.views.mentor_win_share().tolist(),
        wall_seconds=wall,
        steps=learner.views.t,
        engine=learner.engine.name,
        commit=source_commit(),
    )


def _add_greedy_results(
    result: WorldResult, greedy: GreedyTracker, final: PolicyEvaluation
) -> None:
    """``result`` with the frozen greedy policies at the end (``final``), against the optimum
    and the mentor, and with the "stuck" rule where the tracker evaluated it."""
    result.greedy_goals_per_window = final.goals_per_window.tolist()
    result.greedy_percent_of_optimal = greedy.percent_of_optimal(final).tolist()
    result.greedy_percent_of_mentor = greedy.percent_of_mentor(final).tolist()
    result.greedy_value_start = final.value_start.tolist()
    result.greedy_reach_share = final.reach_share.tolist()
    stuck = greedy.stuck
    if stuck is not None:
        result.greedy_percent_of_optimal_stuck = greedy.percent_of_optimal(stuck).tolist()
        result.greedy_percent_of_mentor_stuck = greedy.percent_of_mentor(stuck).tolist()
    result.mentor_goals_per_window = greedy.reference.mentor_goals_per_window
    result.mentor_value_start = float(greedy.reference.mentor.value_start[0])


def _log_hparams(
    batch: _WorldBatch, logger: TensorBoardLogger, learner: Learner, result: WorldResult
) -> None:
    """Each run's settings and final measures in TensorBoard's HParams dashboard."""
    # A run that never found the goal counts as finding it just after its end.
    firsts = [f if f >= 0 else learner.views.t + 1 for f in result.first_goal_step]
    logger.hparams(
        [_hparams(batch.config, batch.size, a) for a in batch.agents],
        [
            {
                "hparam/total_goals": result.goals[b],
                "hparam/final_window_goals": result.final_window_goals[b],
                "hparam/first_goal_step": firsts[b],
                "hparam/value_start": result.value_start[b],
                **(
                    {"hparam/greedy_percent_of_mentor": result.greedy_percent_of_mentor[b]}
                    if result.greedy_percent_of_mentor
                    else {}
                ),
            }
            for b in range(learner.batch)
        ],
        learner.views.t,
    )


def mentor_rewards(config: ExperimentConfig, world, agents, run_seeds, demos) -> list | None:
    """The reward modules of a batch for ``config.mentor_reward``: ``None`` for
    ``known``, else one per run (fitted on its seed's demonstrations; ``None`` for a run that reads
    none)."""
    if config.mentor_reward == "known":
        return None
    modules: list = []
    fitted: dict = {}
    for agent, seed in zip(agents, run_seeds):
        if not AGENTS[agent].uses_demonstrations:  # no mentor term, no shaping potential
            modules.append(None)
            continue
        if seed not in fitted:
            fitted[seed] = mentor_reward_module(config.mentor_reward, world, demos[seed])
        modules.append(fitted[seed])
    return modules


#: The columns of a world's ``curves.csv`` (then the greedy tracker's, where it has one).
_CURVES = (
    "world", "agent", "seed", "step", "goals_in_window", "epsilon", "episodes",
    "mean_episode_steps", "backups", "decisions", "mentor_term_wins",
)  # fmt: skip


def _write_curves(path: Path, learner: Learner, size: int, greedy: GreedyTracker | None) -> None:
    """The world's ``curves.csv`` rows, one per run and window; with ``greedy``, its
    :data:`~himit_torch.runs.greedy.CURVE_COLUMNS` after the others."""
    m = learner.metrics
    columns = (*_CURVES, *(CURVE_COLUMNS if greedy is not None else ()))
    rows = [
        dict(
            zip(
                columns,
                [
                    size,
                    learner.agents[b],
                    learner.seeds[b],
                    step,
                    int(m.goals_in_window[i][b]),
                    f"{float(m.epsilon[i][b]):.5f}",
                    int(m.episodes[i][b]),
                    f"{float(m.mean_episode_steps[i][b]):.2f}",
                    int(m.backups[i][b]),
                    int(m.decisions[i][b]),
                    f"{float(m.mentor_term_wins[i][b]):.4f}",
                    *(greedy.curve_cells(step, b) if greedy is not None else ()),
                ],
            )
        )
        for i, step in enumerate(m.steps)
        for b in range(learner.batch)
    ]
    write_rows(path, columns, rows)


#: Added to a seed to make the generator of its second mentor's episodes
#: (``ExperimentConfig.second_mentor``): the first mentor's episodes stay those of a run without.
SECOND_MENTOR_STREAM = 1 << 40


def _second_mentor(config, world, mentor, seeds) -> dict:
    """Each seed's episodes of the second mentor (``second_mentor``; none: ``{}``),
    from its own generator."""
    if config.second_mentor == "none":
        return {}
    detour = mentor_detour_of(config, world) if config.second_mentor == "detour" else None
    noise = config.second_mentor_noise if config.second_mentor == "noisy" else 0.0
    return {
        s: record_demonstrations(
            world,
            mentor,
            config.mentor_episodes,
            seed=s + SECOND_MENTOR_STREAM,
            noise=noise,
            detour=detour,
        )
        for s in seeds
    }


def _world_curve_figures(run_dir: Path, config: ExperimentConfig, result: WorldResult) -> None:
    """The world's curves and first goals (:func:`~himit_torch.viz.report.write_world_figures`),
    from the curves it has just written."""
    from himit_torch.viz.report import read_curves, write_world_figures

    curves = read_curves(run_dir, f"worlds/curves{result.size}.csv").get(result.size)
    if curves:  # (none: fewer steps than one window)
        write_world_figures(run_dir, config, result, curves)


def _world_figure(batch: _WorldBatch, demos: Demonstrations, learner: Learner) -> None:
    """Fig. 2: the first seed's demonstrations (``demos``) and its imitator's greedy path."""
    from himit_torch.viz.plotting import save_world_figure

    seed, size, world = batch.seeds[0], batch.size, batch.world
    fig_dir = batch.run_dir / "figures"
    fig_dir.mkdir(parents=True, exist_ok=True)
    runs = enumerate(zip(batch.agents, batch.run_seeds))
    imitator = next((b for b, (a, s) in runs if s == seed and a.startswith("imitation")), None)
    learned = None
    if imitator is not None:
        learned = learner.views.greedy_trajectory(
            imitator, max_steps=20 * size * size // batch.config.room_size, seed=seed
        )
    save_world_figure(
        fig_dir / f"fig2_world{size}.png",
        world,
        demonstrations=demos,
        learner_states=learned,
        title=f"{size}×{size}, {world.rooms}×{world.rooms} rooms: mentor (states only) "
        f"and the imitator's greedy path",
    )


# ================================================================================ the study
class ExperimentStudy:
    """The paper's experiments as a :class:`~himit_torch.runs.study.Study`: one run
    directory per experiment, one learner batch per world (:func:`run_world`), ``workers`` processes
    (:func:`run_experiment`); its pieces also serve :func:`run_experiments`."""

    config_class: ClassVar[type] = ExperimentConfig
    folders: ClassVar[tuple[str, ...]] = ("checkpoints", "tb", "worlds", "figures")
    files: ClassVar[tuple[str, ...]] = ("results.md", "curves.csv", "config.json")

    def __init__(self, workers: int | None = None):
        self.workers = workers

    @staticmethod
    def resume_hint(run_dir: str | os.PathLike) -> str:
        """What a refused ``--resume`` with another configuration suggests."""
        return f"resume with the saved one (--config {Path(run_dir) / 'config.json'})"

    def prepare(self, config: ExperimentConfig, run_dir: Path, resume: bool, force: bool) -> None:
        """Clear (``force``) or check (``resume``) ``run_dir`` and save the
        configuration (:func:`~himit_torch.runs.study.prepare_run_dir`)."""
        prepare_run_dir(
            run_dir,
            config,
            resume,
            force,
            self.folders,
            self.files,
            resume_hint=self.resume_hint(run_dir),
            load=load_config,
        )

    @staticmethod
    def finished(config: ExperimentConfig, run_dir: Path, resume: bool) -> dict[int, WorldResult]:
        """The worlds a resumed run already finished (``size → WorldResult``; none unless
        ``resume``)."""
        records = {size: run_dir / "worlds" / f"world{size}.json" for size in config.sizes}
        return {s: read_world_result(p, s) for s, p in records.items() if resume and p.exists()}

    def run(
        self, config: ExperimentConfig, run_dir: Path, resume: bool, progress: bool
    ) -> list[WorldResult]:
        """Run the worlds ``run_dir`` has not finished (``workers`` at a time); returns every
        world's result in the order of ``config.sizes``."""
        run_dir = Path(run_dir)
        [results] = _run_worlds(
            self, [(config, run_dir)], [self.finished(config, run_dir, resume)], resume, progress
        )
        return results

    def report(
        self, config: ExperimentConfig, run_dir: Path, results: Sequence[WorldResult]
    ) -> None:
        """The finished experiment's ``curves.csv`` (its worlds' merged), figures (those across
        worlds; a world's own only where its process did not draw them) and ``results.md``."""
        merge_csv(
            [run_dir / "worlds" / f"curves{size}.csv" for size in config.sizes],
            run_dir / "curves.csv",
        )
        _write_report(run_dir, config, {r.size: r for r in results}, redraw_worlds=False)


def run_experiment(
    config: ExperimentConfig,
    run_dir: str | os.PathLike,
    resume: bool = False,
    force: bool = False,
    progress: bool = True,
    workers: int | None = None,
) -> list[WorldResult]:
    """Run an experiment into ``run_dir``: every world, then figures and ``results.md``.

    ``resume=True`` continues an interrupted run from its checkpoints (the configuration must be
    the saved one) with exactly the curves of an uninterrupted run; a finished run is overwritten
    only with ``force``. Worlds run ``workers`` at a time (default: one per core, at most one per
    world), the cores shared out between them; the results are the same for any ``workers``."""
    study = ExperimentStudy(workers)
    return run_study(
        study,
        config,
        run_dir,
        resume=bool(resume),
        force=force,
        progress=progress,
        check=lambda: config.check_size(),  # (after run_study has checked config's type)
        resume_hint=study.resume_hint(run_dir) if isinstance(run_dir, (str, os.PathLike)) else "",
        load=load_config,
    )


def run_experiments(
    plans: Sequence[tuple[ExperimentConfig, str | os.PathLike]],
    resume: bool = False,
    force: bool = False,
    progress: bool = True,
    workers: int | None = None,
) -> list[list[WorldResult]]:
    """Run several experiments (``(config, run_dir)`` plans) as one pool of
    worlds, the most expensive first; each gets its report as soon as its last world is done and
    ends exactly as :func:`run_experiment` alone leaves it (``himit run paper``). Every run
    directory is checked before any world starts.

    Returns:
        Per plan, its worlds' results in the order of its ``config.sizes``."""
    planned = [(config, Path(run_dir)) for config, run_dir in plans]
    dirs = [run_dir for _, run_dir in planned]
    if len(set(map(os.path.abspath, dirs))) != len(dirs):
        raise ValueError(f"run_experiments: two plans share a run directory ({dirs})")
    study = ExperimentStudy(workers)
    for config, run_dir in planned:  # all checked before any changes
        config.check_size()
        check_run_dir(run_dir, force=force, resume=bool(resume))
        if resume and not force:
            check_resumed_config(run_dir, config, study.resume_hint(run_dir), load_config)
    finished = []
    for config, run_dir in planned:
        study.prepare(config, run_dir, resume, force)
        finished.append(study.finished(config, run_dir, resume))
    return _run_worlds(study, planned, finished, resume, progress, report=True)


def _run_worlds(
    study: ExperimentStudy,
    plans: Sequence[tuple[ExperimentConfig, Path]],
    finished: list[dict[int, WorldResult]],
    resume: bool,
    progress: bool,
    report: bool = False,
) -> list[list[WorldResult]]:
    """Run the worlds of ``plans`` not ``finished`` yet (``study.workers`` at a
    time, the most expensive first; with ``report``, each plan's report when its last world is
    done); per plan, its worlds' results in the order of its sizes."""
    todo = [
        (i, size)
        for i, (config, _) in enumerate(plans)
        for size in config.sizes
        if size not in finished[i]
    ]
    # the most expensive worlds first (a longest-first schedule); stable, so one experiment's
    # worlds of equal cost keep the order of its sizes
    todo.sort(key=lambda job: _world_cost(plans[job[0]][0], job[1]), reverse=True)
    results: list[list[WorldResult] | None] = [None] * len(plans)
    workers_used = workers_for(len(todo), study.workers)

    def report_if_done(i: int) -> None:
        config, run_dir = plans[i]
        if all(size in finished[i] for size in config.sizes):
            results[i] = done = [finished[i][size] for size in config.sizes]
            if report:
                study.report(config, run_dir, done)

    def announce(job: Any) -> None:
        if progress:
            name = plans[job[0]][0].name
            print(f"{name}: world {job[1]}×{job[1]} done", file=sys.stderr, flush=True)

    def world_done(job: Any, result: WorldResult) -> None:
        i, size = job
        finished[i][size] = result
        report_if_done(i)

    for i in range(len(plans)):  # nothing left to run (a resumed, finished run)
        report_if_done(i)
    if workers_used > 1:
        jobs = [((i, size), (plans[i][0], size, plans[i][1], resume, False)) for i, size in todo]
        prepared = _kernels_prepared_here([plans[i][0] for i, _ in todo])
        run_pool(run_world, jobs, workers_used, world_done, announce, prepared)
    else:
        for i, size in todo:
            config, run_dir = plans[i]
            world_done((i, size), run_world(config, size, run_dir, resume, progress))
    assert all(r is not None for r in results)  # every world of every plan ran or was resumed
    return [r for r in results if r is not None]


def _kernels_prepared_here(configs: Sequence[ExperimentConfig]):
    """:func:`~himit_torch.runs.kernels.kernels_prepared_here` when some world will run
    on the compiled engine, else ``None`` (:func:`~himit_torch.runs.pool.run_pool`: nothing)."""
    from himit_torch.learner.engines import numba_available

    compiled = any(c.engine != "torch" and c.device == "cpu" for c in configs)
    if not (compiled and numba_available()):
        return None
    from himit_torch.runs.kernels import kernels_prepared_here  # (imports Numba)

    return kernels_prepared_here()


def _world_cost(config: ExperimentConfig, size: int) -> int:
    """A world's relative cost for scheduling: primitive steps of all its runs × its side (a
    sweep's work grows with the states the options reach)."""
    return config.steps * config.seeds * len(config.agents) * size


def _write_report(
    run_dir: Path, config: ExperimentConfig, finished: dict, redraw_worlds: bool = True
) -> None:
    """The figures and ``results.md`` of finished worlds (``size → WorldResult``);
    ``redraw_worlds=False``: a world's own figures only where its process did not draw them."""
    from himit_torch.viz.report import write_figures, write_results

    results = [finished[size] for size in config.sizes]
    write_figures(run_dir, config, results, worlds=redraw_worlds)
    write_results(
        run_dir,
        config,
        results,
        agent_settings_text(config.agents, config.learner),
        run_command(config, run_dir),
    )


def rewrite_report(run_dir: str | os.PathLike) -> None:
    """Redraw the figures and ``results.md`` of a finished run directory from its
    records (``himit plot``).

    Raises:
        ValueError: ``config.json`` is missing or invalid, a world has not finished, or a record
            is damaged; the message names the file."""
    run_dir = Path(run_dir)
    config = load_config(run_dir / "config.json")
    finished = {}
    for size in config.sizes:
        path = run_dir / "worlds" / f"world{size}.json"
        if not path.exists():
            raise ValueError(
                f"{run_dir}: world {size} has not finished ({path} is missing); "
                "finish it with himit run … --resume"
            )
        finished[size] = read_world_result(path, size)
    check_curves(run_dir / "curves.csv")
    _write_report(run_dir, config, finished)


#: What a world's record (``worlds/world<size>.json``, a :class:`WorldResult`) must hold for
#: its page: the per-run lists one entry per run (the greedy ones may be empty: runs without
#: greedy evaluations, or written before they existed); the optimum what percentages divide by.
_WORLD_RECORD = {
    "size": Field("whole"),
    "rooms": Field("whole", above=0),
    "seeds": Field("list", per_run="whole"),
    "optimal_steps": Field("number", above=0),
    "optimal_goals_per_window": Field("number", above=0),
    **{
        n: Field("list", per_run="whole")
        for n in ("goals", "first_goal_step", "final_window_goals")
    },
    **{n: Field("list", per_run="number") for n in ("value_start", "mentor_term_wins")},
    "true_value_start": Field("number"),
    "wall_seconds": Field("number"),
    "steps": Field("whole", above=0),
    "engine": Field("text", optional=True),
    "commit": Field("text", optional=True),
    **{
        f.name: Field("list", per_run="number", or_empty=True, optional=True)
        for f in fields(WorldResult)
        if f.name.startswith("greedy_")
    },
    "mentor_goals_per_window": Field("number", optional=True),
    "mentor_value_start": Field("number", optional=True),
}


def read_world_result(path: Path, size: int) -> WorldResult:
    """The :class:`WorldResult` a finished world left in ``path`` (``worlds/world<size>.json``).

    Raises:
        ValueError: the file is not a valid record of world ``size``; the message names the file
            and the field."""
    where = f"world record {path}"
    fix = "; delete it and rerun the world (himit run … --resume)"
    data = read_record(path, where, _WORLD_RECORD, fix, runs="agents")
    refuse_unknown_fields(data, WorldResult, where)
    if data["size"] != size:
        raise ValueError(
            f"{where}: field 'size' is {data['size']}, not this file's world ({size}){fix}"
        )
    return WorldResult(**data)


def check_curves(path: Path) -> None:
    """Refuse a ``curves.csv`` the report could not read
    (:func:`~himit_torch.runs.study.read_table`, :func:`~himit_torch.runs.study.series_of`).

    Raises:
        ValueError: naming the file, and the line and column where one is at fault."""
    where = f"curves file {path}"
    fix = "; rerun the experiment (himit run … --force) to write it again"
    rows = read_table(
        path, where, whole=("world", "seed", "step", "goals_in_window"), text=("agent",), fix=fix
    )
    curves: dict[tuple[str, str], list[dict[str, str]]] = {}
    for row in rows:
        curves.setdefault((row["world"], row["agent"]), []).append(row)
    for (world, agent), rows_of in curves.items():  # each a rectangle: seeds × the same steps
        series_of(rows_of, "goals_in_window", f"{where} (world {world}, {agent})", fix)


# ================================================================ the command line's entries
#: ``himit run paper``: the paper's three experiments, their worlds in one pool.
PAPER_EXPERIMENTS = ("exp1", "exp2", "exp3")


def run_command(config: ExperimentConfig, run_dir: str | os.PathLike | None = None) -> str | None:
    """The ``himit run`` command that rebuilds ``config`` exactly (its experiment's flags, else
    ``--config <run_dir>/config.json``: :meth:`~himit_torch.runs.study.StudyEntry.run_command`),
    or None where ``config.name`` is no experiment of
    :data:`~himit_torch.runs.config.EXPERIMENTS` or ``run_dir`` is not named ``config.name``."""
    entry = next((e for e in ENTRIES if e.name == config.name and e.name in EXPERIMENTS), None)
    return None if entry is None else entry.run_command(config, run_dir)


def _moved_checkpoints(config: ExperimentConfig, given: frozenset[str]) -> ExperimentConfig:
    """A shorter ``--steps`` still saves at least once before its end (at a window boundary),
    unless ``--checkpoint-every`` is given too."""
    if "steps" not in given or "checkpoint_every" in given:
        return config
    window = config.window
    every = max(window, min(config.checkpoint_every, config.steps // window * window))
    return replace(config, checkpoint_every=every)


def _describe(config: ExperimentConfig, run_dir: Path) -> str:
    return (
        f"{config.name}: worlds {list(config.sizes)}, agents {list(config.agents)}, "
        f"{config.seeds} seeds, {config.steps:,} steps → {run_dir}"
    )


def _run_plans(plans: Sequence[tuple[ExperimentConfig, Path]], flags: RunFlags) -> None:
    run_experiments(plans, **asdict(flags))


def _info_flags(parser) -> None:
    parser.add_argument("--size", type=int, default=40, help="cells per side, N (default 40)")
    parser.add_argument("--rooms", type=int, default=10, help="rooms per side, R (default 10)")
    parser.add_argument(
        "--corner-options",
        action="store_true",
        help="give the learner (and the mentor) 8 corner options per room (experiment 1)",
    )
    parser.add_argument(
        "--no-doorway-options",
        action="store_true",
        help="the learner gets primitives only (plus corners if asked)",
    )


def _info(args) -> Iterator[str]:
    """``himit info``: a MultiRooms world, its options and optimal trips, beside the paper's
    numbers where it is one of its worlds."""
    world = MultiRooms(size=args.size, rooms=args.rooms, slip=args.slip)
    learner = learner_options(
        world, doorways=not args.no_doorway_options, corners=args.corner_options
    )
    mentor_opts = mentor_options(world, corners=args.corner_options)
    yield (
        f"world      {world.size}×{world.size} cells, {world.rooms}×{world.rooms} rooms "
        f"{world.room_size} cells apart (one-cell walls between), slip {world.slip}, gamma "
        f"{world.gamma}, reward {world.step_reward} a step and {world.goal_reward} at the goal"
    )
    yield (
        f"states     {world.num_states} (free cells {int(world.free_mask.sum())}, doorways "
        f"{len(world.doorway_rooms)}, rooms {world.num_rooms})"
    )
    yield f"start/goal {world.coords(world.start_state)} → {world.coords(world.goal_state)}"
    yield (
        f"learner    {learner.num_options} options ({option_kinds_text(learner)}; "
        "doorway/corner options head directly to their target)"
    )
    yield (
        f"mentor     {mentor_opts.num_options} options ({option_kinds_text(mentor_opts)}; "
        "doorway/corner options travel along the room's walls)"
    )
    lines, width = optimum_lines(world, learner, mentor_policy(world, mentor_opts))
    yield from lines
    for paper in PAPER.values():
        if (paper.get("world"), paper.get("slip")) == ((world.size, world.rooms), world.slip):
            label = f"paper, experiment {paper['experiment']}"
            approx = "≈" + format(paper["optimal_steps"], ".0f")
            yield f"{label:<{width}}{approx:>18}{paper['optimal_goals_per_5000']:>22.1f}"


_INFO = InfoTopic(None, _info_flags, _info)


def _entry(name: str) -> StudyEntry:
    return StudyEntry(
        name,
        f"the paper's experiment {name[-1]} (himit_torch.runs.experiment)",
        ExperimentConfig,
        configs=lambda: (EXPERIMENTS[name],),
        run=_run_plans,
        describe=_describe,
        redraw=rewrite_report,
        adjust=_moved_checkpoints,
        run_flags=("config", "resume", "workers"),
        info=_INFO if name == "exp1" else None,
        rerun_config_file=True,
    )


#: The registry entries of ``himit run exp1``, ``exp2``, ``exp3`` and ``paper``.
ENTRIES = (
    *(_entry(name) for name in PAPER_EXPERIMENTS),
    StudyEntry(
        "paper",
        "the paper's experiments 1, 2 and 3, their worlds shared out over the cores together "
        "(each keeps its own name and configuration)",
        ExperimentConfig,
        configs=lambda: tuple(EXPERIMENTS[name] for name in PAPER_EXPERIMENTS),
        run=_run_plans,
        describe=_describe,
        redraw=rewrite_report,
        flag_defaults=ExperimentConfig,
        adjust=_moved_checkpoints,
        run_flags=("resume", "workers"),
        skip=("name",),
    ),
)
