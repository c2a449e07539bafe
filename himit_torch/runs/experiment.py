"""The paper's experiments (Section III) as configurations and one batched runner.

One :class:`ExperimentConfig` per experiment holds the paper's settings, field by field; it is
saved as JSON in the run directory and can be loaded back (``himit run --config``). All agents
and seeds of one world run in one :class:`~himit_torch.Learner` batch. A run directory holds::

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

import csv
import json
import os
import sys
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path

import torch

from himit_torch.exact.greedy_evaluation import (
    PolicyEvaluation,
    PolicyEvaluator,
    evaluate_option_choice,
    optimal_policy_evaluation,
)
from himit_torch.exact.option_models import option_models_and_durations
from himit_torch.exact.planning import expected_steps, smdp_value_iteration
from himit_torch.learner.agents import AGENTS
from himit_torch.learner.config import LearnerConfig
from himit_torch.learner.learner import Learner
from himit_torch.learner.presets import agent_settings_text
from himit_torch.mentor.demonstrations import Demonstrations
from himit_torch.mentor.observation import first_part, observe_every
from himit_torch.mentor.policy import (
    exact_mentor_transitions,
    mentor_detour,
    mentor_policy,
    record_demonstrations,
)
from himit_torch.mentor.reward import mentor_reward_module
from himit_torch.options.builders import learner_options, mentor_options, primitive_options
from himit_torch.runs.checkpoints import BatchShape
from himit_torch.runs.config import ExperimentConfig, load_config, run_command
from himit_torch.runs.greedy import CURVE_COLUMNS, GreedyReference, GreedyTracker
from himit_torch.runs.runner import (
    Checkpoints,
    Maps,
    WindowHook,
    batch_runs,
    check_run_dir,
    run_names,
    run_windows,
    share_cores,
    source_commit,
    watch_demonstrations,
    write_atomically,
)
from himit_torch.runs.study import prepare_run_dir
from himit_torch.viz.tensorboard import TensorBoardLogger
from himit_torch.worlds.multirooms import MultiRooms

__all__ = [
    "run_experiment",
    "run_experiments",
    "run_world",
    "WorldResult",
    "rewrite_report",
    "optimal_reference",
    "PAPER",
]

#: What the paper reports (Section III, Figs. 3–5).
PAPER = {
    "exp1": {"optimal_goals_per_5000": 26.3, "optimal_steps": 190},
    "exp2": {
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
    """The optimum a world's runs are measured against: the expected steps of the optimal
    (primitive) policy from start to goal, ``V*(start)``, and that policy's exact evaluation
    over windows of ``window`` steps (the reference of the greedy policies' "% of optimum", and
    the ``optimal_*`` numbers of :class:`WorldResult`)."""
    prims = primitive_options(world)
    models = option_models_and_durations(world, prims)
    plan = smdp_value_iteration(models[0])
    steps = expected_steps(models[1], plan.policy, world.start_state, world.terminal_mask)
    evaluation = optimal_policy_evaluation(world, window, models=models, plan=plan)
    return steps, float(plan.values[world.start_state]), evaluation


def _hparams(config: ExperimentConfig, size: int, agent: str) -> dict:
    """The settings that tell a run's group apart in TensorBoard's HParams dashboard: its agent,
    experiment and world, and every setting that differs from the library's defaults (the seed
    never: the seeds of one group are what the dashboard aggregates)."""
    hp = {"agent": agent, "experiment": config.name, "world": f"{size}×{size}"}
    skip = {
        "name",
        "sizes",
        "agents",
        "seeds",
        "first_seed",
        "device",
        "checkpoint_every",
        "greedy_every",
        "learner",
    }
    default = ExperimentConfig()
    hp.update(
        {
            f.name: getattr(config, f.name)
            for f in fields(config)
            if f.name not in skip and getattr(config, f.name) != getattr(default, f.name)
        }
    )
    default_learner = LearnerConfig(window=config.window)
    hp.update(
        {
            f.name: getattr(config.learner, f.name)
            for f in fields(config.learner)
            if getattr(config.learner, f.name) != getattr(default_learner, f.name)
        }
    )
    return hp


def run_world(
    config: ExperimentConfig,
    size: int,
    run_dir: Path,
    resume: bool,
    progress: bool = True,
    on_window: Callable | None = None,
) -> WorldResult:
    """Run every agent × seed of one world in one batch (resuming from its checkpoint)."""
    world = config.world(size)
    seeds, agents, run_seeds = batch_runs(config.agents, config.first_seed, config.seeds)
    # The mentor (its own [O, S] option tables: 0.23 GB on 120×120 with corners) records every
    # seed's episodes and is gone before the learner's tables are built, so the two never share
    # the process's peak memory. Each seed's episodes come from its own generator: the order
    # changes nothing.
    mentor = mentor_policy(
        world,
        mentor_options(world, corners=config.corner_options),
        config.mentor_preference,
        # the paper's worlds keep their mentor; a maze or a moved goal may trap it in a cycle
        break_cycles=config.layout != "open" or config.goal_needs_primitives,
    )
    # The stresses on the mentor (config.mentor_noise, .mentor_detour) change what it shows, not
    # its policy: the "% of mentor" reference below stays the undisturbed one.
    detour = (
        mentor_detour(
            world,
            corners=config.corner_options,
            prefer_extended_within=config.mentor_preference,
        )
        if config.mentor_detour
        else None
    )
    recorded = {
        s: record_demonstrations(
            world,
            mentor,
            config.mentor_episodes,
            seed=s,
            noise=config.mentor_noise,
            detour=detour,
        )
        for s in seeds
    } if config.mentor_goal == "same" else _other_goal(config, world, seeds)  # fmt: skip
    del detour
    if config.mentor_coverage < 1:  # only the first part of each route (mentor_coverage)
        recorded = {s: first_part(d, config.mentor_coverage) for s, d in recorded.items()}
    # what the learner observes of them (config.observation_stride; stride 1: the same objects)
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
    del mentor
    options = learner_options(world, corners=config.corner_options)
    learner = Learner(
        world,
        options,
        agents,
        run_seeds,
        config=config.learner,
        reward=mentor_rewards(config, world, agents, run_seeds, demos),
        device=config.device,
        engine=config.engine,
    )
    watch_demonstrations(learner, demos if exact is None else dict.fromkeys(seeds, exact))
    if second:
        watch_demonstrations(learner, second, mentor=1)
    optimal_steps, true_v, optimal_eval = optimal_reference(world, config.window)
    greedy = None
    if mentor_eval is not None:
        greedy = GreedyTracker(
            PolicyEvaluator(world, options, config.window),
            GreedyReference(optimal_eval, mentor_eval),
            config.greedy_every or 0,
            config.steps,
        )
    checkpoints = Checkpoints(
        run_dir / "checkpoints" / f"world{size}.pt",
        BatchShape(tuple(agents), tuple(run_seeds), world.num_states),
        config.checkpoint_every,
        config.device,
        companions={} if greedy is None else {"greedy": greedy},
    )
    elapsed = checkpoints.start(learner, resume)
    # A resumed run purges what it logged after its last checkpoint (windows up to t were logged
    # before the checkpoint); a fresh one refuses folders that hold another run's events.
    logger = TensorBoardLogger(
        run_dir / "tb",
        run_names(f"world{size}", agents, run_seeds),
        world=world,
        options=options,
        true_value_start=true_v,
        initial_value=config.learner.initial_value,
        resume_step=learner.t if resume else None,
    )
    if not resume or learner.t == 0:
        for b in range(learner.batch):
            logger.text(b, "settings", f"seed {run_seeds[b]}\n\n```\n{config.to_json()}\n```")
    # Maps during training for the first two seeds of every agent: more than one seed, at a cost
    # (≈ 0.2 s a run and checkpoint) that stays small beside the run.
    map_runs = [b for b, s in enumerate(run_seeds) if s in seeds[:2]]
    # ... half-way and at the end (drawing them costs ≈ 0.2 s a run: at every checkpoint they
    # took longer than the learning itself)
    maps_every = config.checkpoint_every * max(1, round(config.steps / 2 / config.checkpoint_every))
    mentor_visits = {
        b: torch.bincount(
            torch.cat([torch.as_tensor(e) for e in demos[run_seeds[b]].episodes]),
            minlength=world.num_states,
        )
        for b in map_runs
    }
    hooks: list[WindowHook] = [logger.window]
    if greedy is not None:
        greedy.logger = logger
        hooks.append(greedy)
    if on_window is not None:
        hooks.append(lambda learner, _: on_window(learner))
    wall = run_windows(
        learner,
        config.steps,
        on_window=hooks,
        logger=logger,
        maps=Maps(map_runs, maps_every, mentor_visits),
        checkpoints=checkpoints,
        progress=f"{config.name} {size}×{size} B={learner.batch}" if progress else None,
        elapsed=elapsed,
    )
    final = None if greedy is None else greedy.finish(learner)
    m = learner.metrics
    result = WorldResult(
        size=size,
        rooms=world.rooms,
        agents=agents,
        seeds=run_seeds,
        optimal_steps=optimal_steps,
        optimal_goals_per_window=config.window / optimal_steps,
        goals=learner.goals.tolist(),
        first_goal_step=learner.first_goal_step.tolist(),
        final_window_goals=(
            m.goals_in_window[-1].tolist() if m.goals_in_window else [0] * len(agents)
        ),
        value_start=learner.state_values()[:, world.start_state].tolist(),
        true_value_start=true_v,
        mentor_term_wins=learner.mentor_win_share().tolist(),
        wall_seconds=wall,
        steps=learner.t,
        engine=learner.engine.name,
        commit=source_commit(),
    )
    if greedy is not None and final is not None:
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
    # A run that never found the goal counts as finding it just after its end.
    firsts = [f if f >= 0 else learner.t + 1 for f in result.first_goal_step]
    logger.hparams(
        [_hparams(config, size, a) for a in agents],
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
        learner.t,
    )
    logger.close()
    _write_curves(run_dir / "worlds" / f"curves{size}.csv", learner, size, greedy)
    write_atomically(run_dir / "worlds" / f"world{size}.json", json.dumps(asdict(result), indent=1))
    _world_figure(
        run_dir, config, world, recorded[seeds[0]], learner, agents, run_seeds, seeds[0], size
    )
    return result


def mentor_rewards(config: ExperimentConfig, world, agents, run_seeds, demos) -> list | None:
    """The reward modules of a batch for ``config.mentor_reward``: ``None`` for ``known`` (the
    learner's default, :class:`~himit_torch.KnownReward`), else one module per run — fitted on
    that run's seed's demonstrations for ``salience`` — and ``None`` for runs that read no
    demonstrations (neither a mentor term nor a shaping potential)."""
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


def _write_curves(
    path: Path, learner: Learner, size: int, greedy: GreedyTracker | None = None
) -> None:
    """The world's ``curves.csv`` rows, one per run and window; with ``greedy``, its
    :data:`~himit_torch.runs.greedy.CURVE_COLUMNS` after the others."""
    path.parent.mkdir(parents=True, exist_ok=True)
    m = learner.metrics
    tmp = path.with_suffix(".tmp")
    with tmp.open("w", newline="") as f:
        out = csv.writer(f)
        out.writerow(
            [
                "world",
                "agent",
                "seed",
                "step",
                "goals_in_window",
                "epsilon",
                "episodes",
                "mean_episode_steps",
                "backups",
                "decisions",
                "mentor_term_wins",
                *(CURVE_COLUMNS if greedy is not None else ()),
            ]
        )
        for i, step in enumerate(m.steps):
            for b in range(learner.batch):
                out.writerow(
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
                    ]
                )
    os.replace(tmp, path)


#: Added to a seed to make the generator of its second mentor's episodes
#: (``ExperimentConfig.second_mentor``): the first mentor's episodes stay those of a run without.
SECOND_MENTOR_STREAM = 1 << 40


def _second_mentor(config, world, mentor, seeds) -> dict:
    """Each seed's episodes of the second mentor (``ExperimentConfig.second_mentor``; none:
    an empty dict): the same mentor erring with ``second_mentor_noise``, or taking the
    detour of ``mentor_detour``, from its own generator."""
    if config.second_mentor == "none":
        return {}
    detour = (
        mentor_detour(
            world, corners=config.corner_options, prefer_extended_within=config.mentor_preference
        )
        if config.second_mentor == "detour"
        else None
    )
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


def _other_goal(config, world, seeds) -> dict:
    """Each seed's episodes of a mentor demonstrating another goal (``ExperimentConfig.
    mentor_goal``): its walk to the top-right corner cell, in a copy of the world with that
    goal, shown to the learner in its own world (where the corner is no goal)."""
    leg = mentor_detour(
        world, corners=config.corner_options, prefer_extended_within=config.mentor_preference
    )
    return {
        s: Demonstrations(
            record_demonstrations(
                leg.first_leg,
                leg.to_waypoint,
                config.mentor_episodes,
                seed=s,
                noise=config.mentor_noise,
            ).episodes,
            world,
        )
        for s in seeds
    }


def _world_figure(run_dir, config, world, demos, learner, agents, run_seeds, seed, size):
    from himit_torch.viz.plotting import save_world_figure

    fig_dir = run_dir / "figures"
    fig_dir.mkdir(parents=True, exist_ok=True)
    imitator = next(
        (b for b, a in enumerate(agents) if run_seeds[b] == seed and a.startswith("imitation")),
        None,
    )
    learned = None
    if imitator is not None:
        learned = learner.greedy_trajectory(
            imitator, max_steps=20 * size * size // config.room_size, seed=seed
        )
    save_world_figure(
        fig_dir / f"fig2_world{size}.png",
        world,
        demonstrations=demos,
        learner_states=learned,
        title=f"{size}×{size}, {world.rooms}×{world.rooms} rooms: mentor (states only) "
        f"and the imitator's greedy path",
    )


# ================================================================================ the runner
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
    the saved one) and ends with exactly the curves an uninterrupted run gives. A directory with a
    finished run is not overwritten unless ``force``.

    Worlds run in parallel, one process each, ``workers`` at a time (default: as many as there
    are cores, at most one per world); the cores are shared out between them, so each world's
    compiled engine gets ``cores // workers`` threads. Each world is independent of the others,
    so the results are the same for any ``workers``. ``workers=1`` runs them in this process.
    """
    return run_experiments([(config, run_dir)], resume, force, progress, workers)[0]


def run_experiments(
    plans: Sequence[tuple[ExperimentConfig, str | os.PathLike]],
    resume: bool = False,
    force: bool = False,
    progress: bool = True,
    workers: int | None = None,
) -> list[list[WorldResult]]:
    """Run several experiments, each into its own run directory, as one pool of worlds.

    The worlds of all ``plans`` (``(config, run_dir)`` pairs) are shared out over ``workers``
    processes together, the most expensive first (steps × runs × world side), so one
    experiment's small world fills the time another's large world leaves free; each experiment
    gets its figures and ``results.md`` as soon as its last world is done. Every world is
    independent, so each run directory ends exactly as :func:`run_experiment` alone leaves it
    (``himit run paper``: the paper's three experiments in one command). ``resume``, ``force``
    and ``workers`` mean what they mean for :func:`run_experiment`; every run directory is
    checked before any world starts.

    Returns:
        Per plan, its worlds' results in the order of its ``config.sizes``.
    """
    dirs = [Path(run_dir) for _, run_dir in plans]
    if len(set(map(os.path.abspath, dirs))) != len(dirs):
        raise ValueError(f"run_experiments: two plans share a run directory ({dirs})")
    for (config, _), run_dir in zip(plans, dirs, strict=True):
        config.check_size()
        check_run_dir(run_dir, force=force, resume=bool(resume))
    finished: list[dict[int, WorldResult]] = [
        _prepare_run_dir(config, run_dir, resume, force)
        for (config, _), run_dir in zip(plans, dirs, strict=True)
    ]
    todo = [
        (i, size)
        for i, (config, _) in enumerate(plans)
        for size in config.sizes
        if size not in finished[i]
    ]
    # the most expensive worlds first (a longest-first schedule); stable, so one experiment's
    # worlds of equal cost keep the order of its sizes, largest first as before
    todo.sort(key=lambda job: _world_cost(plans[job[0]][0], job[1]), reverse=True)
    results: list[list[WorldResult] | None] = [None] * len(plans)
    cores = os.cpu_count() or 1
    workers_used = min(len(todo), cores) if workers is None else min(int(workers), len(todo))

    def world_done(i: int, size: int, result: WorldResult) -> None:
        finished[i][size] = result
        config = plans[i][0]
        if progress and workers_used > 1:
            print(f"{config.name}: world {size}×{size} done", file=sys.stderr, flush=True)
        if all(s in finished[i] for s in config.sizes):
            results[i] = _finish_run_dir(config, dirs[i], finished[i])

    for i, (config, _) in enumerate(plans):  # nothing left to run (a resumed, finished run)
        if all(s in finished[i] for s in config.sizes):
            results[i] = _finish_run_dir(config, dirs[i], finished[i])
    if workers_used > 1:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor, as_completed

        # "spawn": a forked child of a process whose OpenMP threads already ran can hang.
        pool = ProcessPoolExecutor(
            workers_used,
            mp_context=multiprocessing.get_context("spawn"),
            initializer=share_cores,
            initargs=(max(1, cores // workers_used),),
        )
        try:
            # A cold Numba cache is compiled once, here, while the workers set up their worlds;
            # they wait for it at their first tick instead of each compiling it too.
            with _kernels_prepared_here([plans[i][0] for i, _ in todo]):
                futures = {
                    pool.submit(run_world, plans[i][0], size, dirs[i], resume, False): (i, size)
                    for i, size in todo
                }
            for future in as_completed(futures):
                world_done(*futures[future], future.result())
        finally:  # a failed world stops the rest instead of letting them run to the end
            pool.shutdown(wait=True, cancel_futures=True)
    else:
        for i, size in todo:
            world_done(i, size, run_world(plans[i][0], size, dirs[i], resume, progress))
    assert all(r is not None for r in results)  # every world of every plan ran or was resumed
    return [r for r in results if r is not None]


def _kernels_prepared_here(configs: Sequence[ExperimentConfig]):
    """:func:`~himit_torch.runs.kernels.kernels_prepared_here` when some world will run
    on the compiled engine, else nothing."""
    from contextlib import nullcontext

    from himit_torch.learner.engines import numba_available

    compiled = any(c.engine != "torch" and c.device == "cpu" for c in configs)
    if not (compiled and numba_available()):
        return nullcontext()
    from himit_torch.runs.kernels import kernels_prepared_here

    return kernels_prepared_here()


def _world_cost(config: ExperimentConfig, size: int) -> int:
    """A world's relative cost for scheduling: primitive steps of all its runs × its side (a
    sweep's work grows with the states the options reach)."""
    return config.steps * config.seeds * len(config.agents) * size


def _prepare_run_dir(
    config: ExperimentConfig, run_dir: Path, resume: bool, force: bool
) -> dict[int, WorldResult]:
    """Clear (``force``) or check (``resume``) ``run_dir``, save the configuration, and return
    the worlds a resumed run already finished."""
    cfg_path = run_dir / "config.json"
    prepare_run_dir(
        run_dir,
        config,
        resume,
        force,
        ("checkpoints", "tb", "worlds", "figures"),
        ("results.md", "curves.csv", "config.json"),
        resume_hint=f"resume with the saved one (--config {cfg_path})",
        load=load_config,
    )
    finished = {}
    for size in config.sizes:
        done = run_dir / "worlds" / f"world{size}.json"
        if resume and done.exists():
            finished[size] = WorldResult(**json.loads(done.read_text()))
    return finished


def _finish_run_dir(
    config: ExperimentConfig, run_dir: Path, finished: dict[int, WorldResult]
) -> list[WorldResult]:
    """The finished experiment's ``curves.csv``, figures and ``results.md``."""
    _merge_curves(run_dir, config)
    return _write_report(run_dir, config, finished)


def _write_report(run_dir: Path, config: ExperimentConfig, finished: dict) -> list[WorldResult]:
    """The figures and ``results.md`` of finished worlds (``size → WorldResult``), in the
    order of ``config.sizes``: what a run writes at its end and ``himit plot`` redraws."""
    from himit_torch.viz.report import write_figures, write_results

    results = [finished[size] for size in config.sizes]
    write_figures(run_dir, config, results)
    write_results(
        run_dir,
        config,
        results,
        agent_settings_text(config.agents, config.learner),
        run_command(config, run_dir),
    )
    return results


def rewrite_report(run_dir: str | os.PathLike) -> None:
    """Redraw the figures and ``results.md`` of a finished run directory from its
    ``config.json``, ``curves.csv`` and ``worlds/world<N>.json`` (``himit plot``): the page
    :func:`run_experiment` wrote, from the records alone.

    Raises:
        ValueError: ``config.json`` is missing or invalid, or a world has not finished.
    """
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
        finished[size] = WorldResult(**json.loads(path.read_text()))
    _write_report(run_dir, config, finished)


def _merge_curves(run_dir: Path, config: ExperimentConfig) -> None:
    rows: list[list[str]] = []
    header: list[str] = []
    for size in config.sizes:
        with (run_dir / "worlds" / f"curves{size}.csv").open() as f:
            reader = csv.reader(f)
            header = next(reader)
            rows.extend(reader)
    tmp = run_dir / "curves.csv.tmp"
    with tmp.open("w", newline="") as f:
        out = csv.writer(f)
        out.writerow(header)
        out.writerows(rows)
    os.replace(tmp, run_dir / "curves.csv")
