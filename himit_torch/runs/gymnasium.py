"""Hierarchical imitation on Gymnasium's tabular environments: Taxi, CliffWalking, FrozenLake 8×8.

For each task: the world through :func:`~himit_torch.from_gymnasium`; the learner's options
(primitives plus navigation options, :data:`TASKS`); a mentor that is *optimal* — value
iteration on the true model, primitive actions — and is watched through its states only; then
one :class:`~himit_torch.Learner` batch of every agent × seed. A run directory holds::

    config.json               the configuration
    curves.csv                per window: task, agent, seed, step, goals, episodes, ε,
                              greedy value gap, mentor term wins
    tasks/<task>.json         per-run summaries and the task's optimum
    tb/<task>__<agent>__seed<k>/   TensorBoard event files (scalars, hparams)
    figures/*.png             learning curves (mean and 95 % CI over seeds), final-window bars;
                              MiniGrid's tasks: paths_<task>.png, the first seed's paths
                              (the record's ``paths``) over MiniGrid's drawing
    results.md                the table: mean ± 95 % CI (Student t over seeds), n per cell

Metrics (per window of ``window`` steps):

* ``goals`` — arrivals at the task's *goal* states (:attr:`TableWorld.goal_mask`: Taxi's
  deliveries, CliffWalking's goal, FrozenLake's goal — not its holes), counted from the
  learner's visit counts; the paper's "goals in the last window".
* ``episodes`` — episodes ended (any terminal state: FrozenLake's holes too).
* ``value_gap`` — ``V*(μ) − V^π(μ)``: how far the run's current greedy option policy is from
  the optimum, both evaluated *exactly* on the true model from the start distribution ``μ``
  (:meth:`PolicyEvaluation.value_gap <himit_torch.PolicyEvaluation.value_gap>`). 0 = optimal.
  ``π`` is the same frozen greedy policy as the columns below (ties as configured; a state where
  the run has tried nothing: uniformly any of its options there, the ``"uniform"`` rule of
  :mod:`himit_torch.exact.greedy_evaluation`).
* ``greedy_goals_per_window``, ``greedy_pct_optimal``, ``greedy_pct_mentor``,
  ``greedy_reach_share`` — the run's greedy policy frozen as it acts (ε = 0, ties as configured,
  untried states: any enabled option), evaluated exactly (:mod:`himit_torch.runs.greedy`): its
  long-run goals per window, as a % of the optimal policy's and of the mentor's (here the
  mentor *is* an optimal policy, so the two differ only where the optimal values tie). The task
  record also holds the final policy's two percentages under the ``"stuck"`` rule (a state the
  run has tried nothing at is never left): ``greedy_percent_of_optimal_stuck``,
  ``greedy_percent_of_mentor_stuck``.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass, replace
from functools import partial
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import torch

from himit_torch.exact.greedy_evaluation import (
    PolicyEvaluator,
    evaluate_option_choice,
    optimal_policy_evaluation,
)
from himit_torch.learner.agents import AGENTS
from himit_torch.learner.config import LearnerConfig
from himit_torch.learner.learner import Learner
from himit_torch.learner.presets import agent_settings_text
from himit_torch.mentor.minigrid import demonstrations_in, minigrid_mentor
from himit_torch.mentor.observation import observe_at_option_ends, observe_every
from himit_torch.mentor.policy import mentor_policy, record_demonstrations, run_mentor
from himit_torch.mentor.reward import KnownReward
from himit_torch.options.builders import primitive_options
from himit_torch.options.bundle import Options
from himit_torch.options.minigrid import minigrid_options
from himit_torch.options.taxi import taxi_navigation_options
from himit_torch.options.toy_text import cliff_options, frozen_lake_options
from himit_torch.runs import minigrid
from himit_torch.runs.config import OBSERVATIONS
from himit_torch.runs.greedy import CURVE_COLUMNS, GreedyReference, GreedyTracker
from himit_torch.runs.runner import (
    batch_runs,
    merge_csv,
    run_names,
    run_windows,
    source_commit,
    watch_demonstrations,
)
from himit_torch.runs.study import (
    INFO_WINDOW,
    Field,
    InfoTopic,
    RunConfig,
    StudyEntry,
    check_record,
    option_kinds_text,
    read_config_file,
    read_table,
    run_each,
    run_study,
    series_of,
    write_rows,
)
from himit_torch.statistics import bca_interval
from himit_torch.validation import parse_document, read_text, setting
from himit_torch.viz.results_page import (
    learner_settings_line,
    plot_command,
    provenance_line,
    write_results_page,
)
from himit_torch.viz.tensorboard import TensorBoardLogger, tensorboard_command
from himit_torch.worlds.gymnasium import from_gymnasium
from himit_torch.worlds.minigrid import MiniGridWorld, from_minigrid
from himit_torch.worlds.table_world import TableWorld

__all__ = [
    "GymTask",
    "TASKS",
    "GymExperimentConfig",
    "GymnasiumStudy",
    "run_gym_experiment",
    "gym_run_command",
    "run_task",
    "neutral_value",
]


@dataclass(frozen=True)
class GymTask:
    """One Gymnasium task: the environment, its kwargs and the learner's extended options."""

    env_id: str
    kwargs: dict
    extended_options: Callable[[TableWorld], Options]
    about: str
    steps: int
    """Primitive steps per run unless the configuration sets ``steps``."""
    make_world: Callable[[float], TableWorld] | None = None
    """The world at a discount (``None``: :func:`~himit_torch.from_gymnasium` of the id)."""
    make_mentor: Callable[[TableWorld], Any] | None = None
    """The mentor (``None``: the optimal policy over primitives)."""
    mentor_world: Callable[[float], TableWorld] | None = None
    """Transfer: the world whose task the mentor demonstrates, of the learner's layout; its
    demonstrations are watched as the learner's states
    (:func:`~himit_torch.mentor.minigrid.demonstrations_in`). ``None``: the learner's world."""

    def world(self, gamma: float) -> TableWorld:
        if self.make_world is not None:
            return self.make_world(gamma)
        return from_gymnasium(self.env_id, gamma=gamma, **self.kwargs)

    def options(self, world: TableWorld) -> Options:
        """Primitives first, then the extended options."""
        return Options.concat([primitive_options(world), self.extended_options(world)])


#: The tasks, by name.
TASKS: dict[str, GymTask] = {
    "taxi": GymTask(
        "Taxi-v4",
        {},
        taxi_navigation_options,
        "Taxi-v4: 500 states, 300 start states, 6 actions; options: drive to R, G, "
        "Y, B (Dietterich's navigation subtasks)",
        steps=60_000,
    ),
    "cliffwalking": GymTask(
        "CliffWalking-v1",
        {},
        cliff_options,
        "CliffWalking-v1: 4×12, −1 a step, −100 and back to the start at the "
        "cliff; options: to the two top corners",
        steps=30_000,
    ),
    "frozenlake8x8": GymTask(
        "FrozenLake-v1",
        {"map_name": "8x8", "is_slippery": True},
        frozen_lake_options,
        "FrozenLake-v1 8×8, slippery: +1 at the goal, holes end the episode; "
        "options: to the corners (0,7) and (7,0)",
        steps=100_000,
    ),
}


def _minigrid_skills(world: TableWorld) -> Options:
    """The learner's "go to and face X" skills of a MiniGrid world, without its primitives."""
    options = minigrid_options(world)  # type: ignore[arg-type]
    return options.select([i for i, k in enumerate(options.kinds) if k != "primitive"])


def _minigrid_task(
    env_id: str, about: str, steps: int = 100_000, mentor_goal: tuple[int, int] | None = None
) -> GymTask:
    """A MiniGrid task (reset seed 0, no slip): the learner's skills beside the primitives, and
    the MiniGrid mentor with its own right-handed skills (:func:`~himit_torch.minigrid_mentor`);
    with ``mentor_goal``, the mentor demonstrates the same layout with its goal moved to that
    cell (transfer)."""
    name = env_id if mentor_goal is None else f"{env_id}, transfer"
    return GymTask(
        env_id,
        {},
        _minigrid_skills,
        f"{name}: {about}",
        steps,
        make_world=lambda gamma: from_minigrid(env_id, gamma=gamma),
        make_mentor=minigrid_mentor,  # type: ignore[arg-type]
        mentor_world=(
            None
            if mentor_goal is None
            else lambda gamma: from_minigrid(env_id, gamma=gamma, goal=mentor_goal)
        ),
    )


def _transfer_task(
    env_id: str, steps: int, mentor_goal: tuple[int, int], goal: tuple[int, int]
) -> GymTask:
    """A DoorKey task whose mentor shows the layout with its goal moved to ``mentor_goal``; the
    learner is rewarded at MiniGrid's own goal, which ``goal`` names for the task's description
    only (it is not checked against the layout)."""
    return _minigrid_task(
        env_id,
        f"the mentor demonstrates the layout with its goal moved to {mentor_goal}, the learner "
        f"is rewarded at MiniGrid's goal {goal}",
        steps,
        mentor_goal,
    )


_DOORKEY = (
    "get the key, open the door, reach the goal; options: go to and face the key, the door, the "
    "goal"
)

#: MiniGrid's key-and-door tasks (``himit run minigrid``), each with ``himit run minigrid``'s
#: default budget; the benchmark fixed its own for seven of them on held-out seeds
#: (``experiments/benchmark/minigrid_benchmark.py``'s ``MINIGRID_BUDGETS``).
MINIGRID_TASKS: dict[str, GymTask] = {
    "doorkey5x5": _minigrid_task("MiniGrid-DoorKey-5x5-v0", _DOORKEY, 50_000),
    "doorkey6x6": _minigrid_task("MiniGrid-DoorKey-6x6-v0", _DOORKEY),
    "unlock": _minigrid_task(
        "MiniGrid-Unlock-v0",
        "get the key and open the door; options: go to and face the key, the door",
    ),
    "doorkey8x8": _minigrid_task("MiniGrid-DoorKey-8x8-v0", _DOORKEY),
    "unlockpickup": _minigrid_task(
        "MiniGrid-UnlockPickup-v0",
        "get the key, open the door, pick up the box behind it; options: go to and face the box, "
        "the key, the door",
    ),
    "keycorridors3r1": _minigrid_task(
        "MiniGrid-KeyCorridorS3R1-v0",
        "get the key, open the locked door, pick up the ball; options: go to and face the key, "
        "the ball, either door",
    ),
    "multiroomn2s4": _minigrid_task(
        "MiniGrid-MultiRoom-N2-S4-v0",
        "open the door to the next room, reach the goal; options: go to and face the door, the "
        "goal",
    ),
    "multiroomn4s5": _minigrid_task(
        "MiniGrid-MultiRoom-N4-S5-v1",
        "open three doors in turn, reach the goal; options: go to and face each door, the goal",
    ),
    "fourrooms": _minigrid_task(
        "MiniGrid-FourRooms-v0",
        "reach the goal through the gaps between four rooms; options: go to and face the goal",
    ),
    # transfer: the mentor shows the layout with its goal moved (5×5, 6×6: one cell past the
    # door, on the learner's way; 8×8: one cell past the door the other way, off it), the
    # learner is rewarded at MiniGrid's goal
    "doorkey5x5_transfer": _transfer_task("MiniGrid-DoorKey-5x5-v0", 50_000, (3, 2), (3, 3)),
    "doorkey6x6_transfer": _transfer_task("MiniGrid-DoorKey-6x6-v0", 100_000, (4, 2), (4, 4)),
    "doorkey8x8_transfer": _transfer_task("MiniGrid-DoorKey-8x8-v0", 100_000, (6, 1), (6, 6)),
}
TASKS.update(MINIGRID_TASKS)


@dataclass
class GymExperimentConfig(RunConfig):
    """The Gymnasium comparison: tasks, agents, seeds, budget and learner
    settings, each declared with :func:`~himit_torch.validation.setting`."""

    name: str = RunConfig.shared("name", "gymnasium")
    tasks: tuple[str, ...] = setting(
        ("taxi", "cliffwalking", "frozenlake8x8"),
        choices=tuple(TASKS),
        doc="Which of :data:`TASKS`; each is one learner batch.",
    )
    agents: tuple[str, ...] = setting(
        ("imitation", "options", "primitives"),
        choices=tuple(AGENTS),
        doc="Agent variants (``himit_torch.AGENTS``), each run with every seed.",
    )
    seeds: int = RunConfig.shared("seeds", 10, doc="Runs per agent and task.")
    first_seed: int = RunConfig.shared("first_seed", 0)
    steps: int | None = RunConfig.shared(
        "steps",
        None,
        doc="""
        Primitive steps per run; ``None``: each task's own budget (:data:`TASKS`: Taxi 60k,
        CliffWalking 30k, FrozenLake 100k).""",
    )
    mentor_episodes: int = RunConfig.shared("mentor_episodes", 20)
    gamma: float = setting(
        0.99,
        gt=0.0,
        lt=1.0,
        doc="Discount of every task (Gymnasium's envs carry none; exact value iteration needs "
        "γ < 1).",
    )
    window: int = RunConfig.shared(
        "window",
        2000,
        doc="Goals are counted, and the greedy policy evaluated, every this many steps.",
    )
    neutral_initial_value: bool = setting(
        True,
        doc="""
        Set each task's ``learner.initial_value`` to its step reward / (1 − γ), the value of
        never reaching the goal — the neutral start that −1 is in the paper's worlds
        (:func:`neutral_value`): −100 in Taxi and CliffWalking, 0 in FrozenLake (where −1 would
        make holes, worth 0, the best place to go). ``False`` keeps ``learner.initial_value``
        for every task.""",
    )
    observation: str = setting(
        "stride",
        choices=OBSERVATIONS,
        doc="""
        What the learner sees of the mentor (as ``ExperimentConfig.observation``; default
        ``stride``: every ``observation_stride``-th state). ``option-ends``: only where the
        mentor's options end (in MiniGrid its skills and its ``pickup`` / ``toggle`` /
        ``forward`` steps: the key faced, picked up, the door opened), with each episode's
        first and last state.""",
    )
    observation_stride: int = setting(
        1,
        ge=1,
        doc="""
        Coarse observation (default 1: every state): the learner sees states 0, k, 2k, … and
        the last of each mentor episode (``himit_torch.mentor.observation``).""",
    )
    device: str = RunConfig.shared("device", "cpu")
    learner: LearnerConfig = RunConfig.shared(  # the paper experiments' learner
        "learner", default_factory=partial(LearnerConfig, plan_every=4, sweep_rounds=1, window=2000)
    )
    preset: str | None = RunConfig.shared("preset", None)

    def __post_init__(self):
        self.check_run_settings()
        if self.observation == "option-ends" and self.observation_stride != 1:
            raise ValueError(
                f"{type(self).__name__}.observation='option-ends' watches the mentor's option "
                f"ends; it cannot be combined with observation_stride={self.observation_stride}: "
                "leave the stride at 1"
            )

    def quick(self) -> GymExperimentConfig:
        """A tiny budget (smoke tests, ``--quick``)."""
        return replace(
            self,
            seeds=min(self.seeds, 2),
            steps=2 * self.window,
            mentor_episodes=min(self.mentor_episodes, 5),
        )

    def steps_of(self, task: str) -> int:
        """Primitive steps per run in ``task``."""
        return TASKS[task].steps if self.steps is None else self.steps


@dataclass
class MiniGridExperimentConfig(GymExperimentConfig):
    """The same comparison on MiniGrid's key-and-door tasks (``himit run minigrid``): the
    learner's "go to and face X" skills beside the primitives, the MiniGrid mentor with its own
    right-handed skills (:data:`MINIGRID_TASKS`)."""

    name: str = RunConfig.shared("name", "minigrid")
    tasks: tuple[str, ...] = setting(
        ("doorkey6x6",),
        choices=tuple(TASKS),
        doc="Which of :data:`TASKS`; each is one learner batch (MiniGrid's: "
        + ", ".join(MINIGRID_TASKS)
        + ").",
    )


def gym_run_command(
    config: GymExperimentConfig, run_dir: str | os.PathLike | None = None
) -> str | None:
    """The ``himit run gymnasium`` (or, for MiniGrid's tasks, ``himit run minigrid``) command
    that rebuilds ``config`` exactly, or None where none can (its other settings are the
    script's, ``experiments/gymnasium_worlds.py``)."""
    return _entry_of(config).run_command(config, run_dir)


def _entry_of(config: GymExperimentConfig) -> StudyEntry:
    """``minigrid``'s entry where ``config``'s tasks are MiniGrid's, else ``gymnasium``'s."""
    return MINIGRID_ENTRY if any(task in MINIGRID_TASKS for task in config.tasks) else ENTRY


# ================================================================================ evaluation
def episode_statistics(world: TableWorld, policy: torch.Tensor) -> tuple[float, float]:
    """``(P(goal), E[steps])`` of an episode from the start distribution under the primitive
    ``policy [S]`` (exact: :func:`~himit_torch.exact.greedy_evaluation.evaluate_option_choice`
    over the primitive options; ``(0, inf)`` where some episode may never end)."""
    evaluation = evaluate_option_choice(world, primitive_options(world), policy, 1)
    length = float(evaluation.steps_per_episode[0])
    p_goal = float(evaluation.goal_probability[0])
    return (p_goal, length) if math.isfinite(length) and length > 0 else (0.0, float("inf"))


def optimal_goals_per_window(world: TableWorld, policy: torch.Tensor, window: int) -> float:
    """Goals per ``window`` steps of the primitive ``policy [S]`` run as a continuing stream of
    episodes from the start distribution (renewal: window · P(goal) / E[steps])."""
    p_goal, length = episode_statistics(world, policy)
    return window * p_goal / length


def neutral_value(world: TableWorld) -> float:
    """The value of never reaching a terminal state: the most common reward of the transitions
    out of non-terminal states (the step reward), divided by ``1 − γ``."""
    table = world.dynamics_table()
    prob = torch.diff(table.cdf, dim=-1, prepend=torch.zeros_like(table.cdf[..., :1]))
    live = (prob > 0) & ~world.terminal_mask[:, None, None]
    values, counts = torch.unique(table.rewards[live], return_counts=True)
    return float(values[counts.argmax()]) / (1.0 - world.gamma)


# ================================================================================ the runner
@dataclass
class _TaskBatch:
    """One task's batch as :func:`run_task` builds it: the world, the learner's options, the
    mentor, the learner (every agent × seed, demonstrations watched) and its references."""

    name: str
    task: GymTask
    world: TableWorld
    options: Options
    mentor: Any
    known: KnownReward
    learner: Learner
    agents: list[str]
    run_seeds: list[int]
    optimal_value: float
    greedy: GreedyTracker
    shown: TableWorld
    """The world whose task the mentor shows (transfer; else ``world``)."""


def _observed(config: GymExperimentConfig, world: TableWorld, mentor, seed: int):
    """What a run of ``seed`` sees of its mentor's recorded episodes (``config.observation``):
    every ``observation_stride``-th state (1: the demonstrations themselves), or the states
    where the mentor's options end, from the same episodes' rollout; recorded in the world
    whose task the mentor shows (``GymTask.mentor_world``)."""
    if config.observation == "option-ends":
        rollout = run_mentor(world, mentor, config.mentor_episodes, seed=seed)
        return observe_at_option_ends(rollout, world)
    recorded = record_demonstrations(world, mentor, config.mentor_episodes, seed=seed)
    return observe_every(recorded, config.observation_stride)


def _build_task_batch(config: GymExperimentConfig, task_name: str) -> _TaskBatch:
    """The task's world, options and optimal mentor; one learner batch of every agent × seed
    watching its seed's mentor episodes; the exact optimum and the greedy tracker."""
    task = TASKS[task_name]
    world = task.world(config.gamma)
    options = task.options(world)
    shown = world if task.mentor_world is None else task.mentor_world(config.gamma)
    mentor = (
        task.make_mentor(shown)
        if task.make_mentor is not None
        else mentor_policy(shown, primitive_options(shown), prefer_extended_within=0.0)
    )
    seeds, agents, run_seeds = batch_runs(config.agents, config.first_seed, config.seeds)
    known = KnownReward(world)
    learner_config = config.learner
    if config.neutral_initial_value:
        learner_config = replace(learner_config, initial_value=neutral_value(world))
    learner = Learner(
        world,
        options,
        agents,
        run_seeds,
        config=learner_config,
        reward=[known if AGENTS[a].uses_demonstrations else None for a in agents],
        device=config.device,
    )
    observed = {s: _observed(config, shown, mentor, s) for s in seeds}
    if shown is not world:
        observed = {s: demonstrations_in(world, d, shown) for s, d in observed.items()}  # type: ignore[arg-type]
    watch_demonstrations(learner, observed)
    # The optimum over primitives, exact: its goal rate, and V*(μ) for the value gap.
    optimal = optimal_policy_evaluation(world, config.window)
    # Every window: the greedy policies' goal rates and values (the value gap), one evaluation.
    greedy = GreedyTracker(
        PolicyEvaluator(world, options, config.window),
        GreedyReference(
            # (the mentor's rate on the task it shows)
            optimal,
            evaluate_option_choice(shown, mentor.options, mentor.option, config.window),
        ),
        config.window,
        config.steps_of(task_name),
        values=True,
    )
    return _TaskBatch(
        task_name, task, world, options, mentor, known, learner, agents, run_seeds,
        float(optimal.value_start[0]), greedy, shown,
    )  # fmt: skip


class _WindowLog:
    """The ``on_window`` callback of a task's batch: each window's rows of ``curves.csv``
    (``rows``) and its scalars: goals (arrivals at the goal states, from the visit counts),
    episodes, ε, the greedy policy's exact value gap. ``reached``: each run's goals so far (at
    the last window's end)."""

    def __init__(self, run: _TaskBatch, logger: TensorBoardLogger):
        self.run, self.logger = run, logger
        self.goal = run.world.goal_mask.to(run.learner.device)
        self.rows: list[dict[str, Any]] = []
        self.reached = torch.zeros(run.learner.batch, dtype=torch.int64)

    def __call__(self, learner: Learner, index: int) -> None:
        run, greedy = self.run, self.run.greedy
        reached = learner.views.visit_counts()[:, self.goal].sum(1).cpu()
        goals, self.reached = reached - self.reached, reached
        m, t = learner.metrics, learner.views.t
        evaluation = greedy.evaluations[t] if t in greedy.evaluations else greedy.evaluate(learner)
        gap = evaluation.value_gap(run.optimal_value).tolist()
        coverage = learner.views.model_coverage().cpu()
        for b in range(learner.batch):
            row: dict[str, Any] = {
                "task": run.name,
                "agent": run.agents[b],
                "seed": run.run_seeds[b],
                "step": t,
                "goals": int(goals[b]),
                "episodes": int(m.goals_in_window[index][b]),
                "epsilon": float(m.epsilon[index][b]),
                "value_gap": gap[b],
                "mentor_term_wins": float(m.mentor_term_wins[index][b]),
                **dict(zip(CURVE_COLUMNS, greedy.curve_cells(t, b))),
            }
            self.rows.append(row)
            scalars = {
                "charts/goals_in_window": row["goals"],
                "charts/episodes_in_window": row["episodes"],
                "charts/epsilon": row["epsilon"],
                "eval/greedy_value_gap": gap[b],
                "planner/backups": float(m.backups[index][b]),
                "model/coverage": float(coverage[b]),
            }
            if math.isfinite(row["mentor_term_wins"]):
                scalars["mentor/term_wins"] = row["mentor_term_wins"]
            self.logger.scalars(b, scalars, t)


def _task_summary(
    config: GymExperimentConfig, run: _TaskBatch, log: _WindowLog, wall: float
) -> dict:
    """The task's record (``tasks/<task>.json``) from its finished batch and window rows."""
    learner, world, greedy, rows = run.learner, run.world, run.greedy, log.rows
    last = [r for r in rows if r["step"] == learner.views.t]
    final = greedy.finish(learner)
    stuck = greedy.stuck
    assert stuck is not None  # finish evaluated it
    first_goal_windows = [
        min(
            (r["step"] for r in rows if r["goals"] > 0 and r["agent"] == a and r["seed"] == sd),
            default=-1,
        )
        for a, sd in zip(run.agents, run.run_seeds)
    ]
    every_end_a_goal = bool(torch.equal(world.terminal_mask.cpu(), world.goal_mask.cpu()))
    return {
        "task": run.name,
        "env_id": run.task.env_id,
        "kwargs": run.task.kwargs,
        "about": run.task.about,
        "engine": learner.engine.name,
        "commit": source_commit(),
        "num_states": world.num_states,
        "num_actions": world.num_actions,
        "options": list(run.options.names),
        "agents": run.agents,
        "seeds": run.run_seeds,
        "optimal_value": run.optimal_value,
        "optimal_goals_per_window": greedy.reference.optimal_goals_per_window,
        "total_goals": [int(x) for x in log.reached.tolist()],
        "first_goal_window": first_goal_windows,
        # Each run's first goal (−1: never). Exact where every terminal state is a goal (the
        # learner's first episode end is then its first goal: Taxi, CliffWalking); where some
        # are not (FrozenLake's holes), the end of the first window with a goal — an upper
        # bound, to the window ("first_goal_resolution" says which).
        "first_goal_step": (
            learner.views.first_goal_step.tolist() if every_end_a_goal else first_goal_windows
        ),
        "first_goal_resolution": 1 if every_end_a_goal else config.window,
        "final_goals": [r["goals"] for r in last],
        "final_value_gap": [r["value_gap"] for r in last],
        "mentor_term_wins": [r["mentor_term_wins"] for r in last],
        "mentor_goals_per_window": greedy.reference.mentor_goals_per_window,
        "greedy_goals_per_window": final.goals_per_window.tolist(),
        "greedy_percent_of_optimal": greedy.percent_of_optimal(final).tolist(),
        "greedy_percent_of_mentor": greedy.percent_of_mentor(final).tolist(),
        "greedy_percent_of_optimal_stuck": greedy.percent_of_optimal(stuck).tolist(),
        "greedy_percent_of_mentor_stuck": greedy.percent_of_mentor(stuck).tolist(),
        "greedy_value_start": final.value_start.tolist(),
        "greedy_goal_probability": final.goal_probability.tolist(),
        "wall_seconds": wall,
        "steps": learner.views.t,
        "initial_value": learner.config.initial_value,
        "ambiguous_reward_pairs": run.known.ambiguous_pairs,
        "known_reward": run.known.note,
    }


def run_task(
    config: GymExperimentConfig, task_name: str, run_dir: Path, progress: bool = True
) -> dict:
    """One task: every agent × seed in one batch; returns the task's summary (also written)."""
    run = _build_task_batch(config, task_name)
    # A task has no resume: a rerun starts its runs' TensorBoard folders over.
    logger = TensorBoardLogger(
        run_dir / "tb", run_names(task_name, run.agents, run.run_seeds), overwrite=True
    )
    run.greedy.logger = logger
    log = _WindowLog(run, logger)
    wall = run_windows(
        run.learner,
        config.steps_of(task_name),
        on_window=[log],
        progress=f"{task_name} B={run.learner.batch}" if progress else None,
    )
    summary = _task_summary(config, run, log, wall)
    if isinstance(run.world, MiniGridWorld):
        summary["paths"] = _minigrid_paths(run)
    # Settings without the seed, so that a task's seeds of one agent form one HParams group; the
    # metrics at step 0, where SummaryWriter.add_hparams put them.
    hp = {k: v for k, v in asdict(run.learner.config).items() if v is not None}
    gaps = summary["final_value_gap"] or [math.nan] * run.learner.batch
    logger.hparams(
        [dict(hp, task=task_name, agent=a) for a in run.agents],
        [
            {"hparam/total_goals": float(total), "hparam/final_value_gap": float(gap)}
            for total, gap in zip(summary["total_goals"], gaps)
        ],
        0,
    )
    logger.close()
    (run_dir / "tasks").mkdir(parents=True, exist_ok=True)
    (run_dir / "tasks" / f"{task_name}.json").write_text(json.dumps(summary, indent=1))
    write_rows(run_dir / "tasks" / f"{task_name}.csv", _COLUMNS, log.rows)
    return summary


def _minigrid_paths(run: _TaskBatch) -> dict[str, list[int]]:
    """A MiniGrid task's paths for ``figures/paths_<task>.png`` (kept in its
    record for ``himit plot``): the first seed's first mentor episode and, per agent, that seed's
    greedy trajectory (at most five times the mentor's steps)."""
    seed = run.run_seeds[0]
    seen = record_demonstrations(run.shown, run.mentor, 1, seed=seed)
    if run.shown is not run.world:
        seen = demonstrations_in(run.world, seen, run.shown)  # type: ignore[arg-type, assignment]
    mentor = seen.episodes[0]
    max_steps = 5 * max(len(mentor) - 1, 1)
    paths = {"mentor": [int(s) for s in mentor]}
    for b, (agent, run_seed) in enumerate(zip(run.agents, run.run_seeds)):
        if run_seed == seed and agent not in paths:
            trajectory = run.learner.views.greedy_trajectory(b, max_steps, seed=seed)
            paths[agent] = [int(s) for s in trajectory]
    return paths


_COLUMNS = (
    "task",
    "agent",
    "seed",
    "step",
    "goals",
    "episodes",
    "epsilon",
    "value_gap",
    "mentor_term_wins",
    *CURVE_COLUMNS,
)


class GymnasiumStudy:
    """The Gymnasium comparison as a :class:`~himit_torch.runs.study.Study`: one
    batch per task (:func:`run_task`), then ``curves.csv``; its report the figures and
    ``results.md``. It does not resume."""

    config_class: ClassVar[type] = GymExperimentConfig
    folders: ClassVar[tuple[str, ...]] = ("tb", "tasks", "figures")
    #: ``--force`` clears the folders only (the files are written again).
    files: ClassVar[tuple[str, ...]] = ()

    def run(
        self, config: GymExperimentConfig, run_dir: Path, resume: bool, progress: bool
    ) -> list[dict]:
        """Every task's batch, then ``curves.csv``; the tasks' summaries."""
        summaries = [run_task(config, t, run_dir, progress) for t in config.tasks]
        parts = [run_dir / "tasks" / f"{t}.csv" for t in config.tasks]
        merge_csv(parts, run_dir / "curves.csv", newline="\n")
        return summaries

    def report(self, config: GymExperimentConfig, run_dir: Path, summaries: list[dict]) -> None:
        """The figures and ``results.md``."""
        write_gym_figures(run_dir, config, summaries)
        write_gym_results(run_dir, config, summaries)


def run_gym_experiment(
    config: GymExperimentConfig,
    run_dir: str | os.PathLike,
    force: bool = False,
    progress: bool = True,
) -> list[dict]:
    """Run every task of ``config`` into ``run_dir``, then figures and
    ``results.md`` (a finished run is overwritten only with ``force``)."""
    return run_study(GymnasiumStudy(), config, run_dir, resume=None, force=force, progress=progress)


# ================================================================================ reporting
def rewrite_gym_report(run_dir: str | os.PathLike) -> None:
    """Redraw the figures and ``results.md`` of a finished ``himit run gymnasium`` directory
    from its ``config.json``, ``curves.csv`` and ``tasks/*.json`` (``himit plot``)."""
    run_dir = Path(run_dir)
    config = read_config_file(GymExperimentConfig, run_dir / "config.json")
    summaries = [
        read_task_record(run_dir / "tasks" / f"{task}.json", task) for task in config.tasks
    ]
    read_gym_curves(run_dir)  # (checked before anything is drawn)
    GymnasiumStudy().report(config, run_dir, summaries)


#: What a task record (``tasks/<task>.json``) must hold for its page; every other list in it
#: holds one number (or null) per run too.
_TASK_RECORD = {
    "task": Field("text"),
    "about": Field("text"),
    "agents": Field("list"),
    "options": Field("list"),
    "steps": Field("whole"),
    "optimal_value": Field("number"),
    "optimal_goals_per_window": Field("number", above=0),
    "initial_value": Field("number"),
    "known_reward": Field("text"),
    "wall_seconds": Field("number"),
    **{
        key: Field("list", per_run="number?")
        for key in (
            "first_goal_window",
            "total_goals",
            "final_goals",
            "final_value_gap",
            "mentor_term_wins",
            "greedy_percent_of_mentor",
            "greedy_goal_probability",
        )
    },
    "paths": Field("object", optional=True),
}


def read_task_record(path: Path, task: str | None = None) -> dict:
    """A task record, refused where its page could not read it
    (:func:`~himit_torch.runs.study.check_record`; ``task``: or where it is another task's)."""
    where = f"task record {path}"
    fix = "; the record is damaged (run the task again, or restore the file)"
    data = parse_document(where, read_text(where, path), "json")
    lists = [k for k, v in data.items() if isinstance(v, list)] if isinstance(data, dict) else []
    schema = {**dict.fromkeys(lists, Field("list", per_run="number?")), **_TASK_RECORD}
    check_record(data, schema, where, fix, runs="agents")
    paths = data.get("paths", {})
    if not all(
        isinstance(v, list)
        and v
        and all(isinstance(x, int) and not isinstance(x, bool) and x >= 0 for x in v)
        for v in paths.values()
    ):
        raise ValueError(
            f"{where}: field 'paths' must map each path's name to its states (whole numbers "
            f"≥ 0), got {paths!r:.60}{fix}"
        )
    if task is not None and data["task"] != task:
        raise ValueError(f"{where}: field 'task' is {data['task']!r:.60}, not {task!r}{fix}")
    return data


def read_gym_curves(run_dir: str | os.PathLike) -> dict:
    """``{task: {agent: (steps [W], goals [n, W], gaps [n, W])}}`` from ``curves.csv``.

    Raises:
        ValueError: the file is missing or damaged (:func:`~himit_torch.runs.study.read_table`,
            :func:`~himit_torch.runs.study.series_of`); the message names the file."""
    path = Path(run_dir) / "curves.csv"
    where = f"curves file {path}"
    fix = "; the record is damaged (run the study again, or restore the file)"
    rows = read_table(path, where, ("seed", "step"), ("goals", "value_gap"), ("task", "agent"), fix)
    curves: dict = {}
    for r in rows:
        curves.setdefault(r["task"], {}).setdefault(r["agent"], []).append(r)
    for task, agents in curves.items():
        for agent, agent_rows in agents.items():
            at = f"{where} ({task}, {agent})"
            steps, goals = series_of(agent_rows, "goals", at, fix)
            _, gaps = series_of(agent_rows, "value_gap", at, fix)
            agents[agent] = (np.array(steps), np.array(goals), np.array(gaps))
    return curves


def write_gym_figures(run_dir: Path, config: GymExperimentConfig, summaries: list[dict]) -> None:
    """Per task: goals per window and the greedy value gap against steps (mean, 95 % CI band)."""
    from matplotlib.figure import Figure

    from himit_torch.viz.plotting import plot_mean_band, save_figure
    from himit_torch.viz.report import AGENT_COLORS

    curves = read_gym_curves(run_dir)
    fig_dir = run_dir / "figures"
    for summary in summaries:
        task = summary["task"]
        if task not in curves:
            continue
        fig = Figure(figsize=(11, 4), layout="constrained")
        ax_goals, ax_gap = fig.subplots(1, 2)
        for agent, (steps, goals, gaps) in curves[task].items():
            color = AGENT_COLORS.get(agent)
            for ax, data in ((ax_goals, goals), (ax_gap, gaps)):
                label = f"{agent} (n={data.shape[0]})"
                plot_mean_band(ax, steps, data, color=color, label=label)
        optimal = summary["optimal_goals_per_window"]
        ax_goals.axhline(optimal, color="0.3", ls="--", lw=1, label=f"optimal ≈ {optimal:.1f}")
        ax_goals.set_ylabel(f"goals per {config.window} steps")
        ax_gap.set_ylabel("V*(μ) − V^greedy(μ)  (exact; 0 = optimal)")
        ax_gap.set_yscale("symlog", linthresh=0.1)
        for ax in (ax_goals, ax_gap):
            ax.set_xlabel("total primitive steps")
            ax.grid(alpha=0.3)
            ax.legend(fontsize="small")
        fig.suptitle(f"{summary['about']} — mean and 95 % CI over seeds", fontsize="medium")
        save_figure(fig, fig_dir / f"curves_{task}.png", dpi=100, fit=True)
        if "paths" in summary:
            _write_paths_figure(fig_dir / f"paths_{task}.png", config, summary)


def _write_paths_figure(path: Path, config: GymExperimentConfig, summary: dict) -> None:
    """A MiniGrid task's ``figures/paths_<task>.png``: the task's recorded paths (the mentor's
    first episode, each agent's greedy trajectory for the first seed) over MiniGrid's drawing of
    the start (:func:`~himit_torch.viz.minigrid.plot_minigrid_paths`)."""
    from himit_torch.viz.minigrid import plot_minigrid_paths
    from himit_torch.viz.plotting import save_figure
    from himit_torch.viz.report import AGENT_COLORS

    world = TASKS[summary["task"]].world(config.gamma)
    if not isinstance(world, MiniGridWorld):
        raise ValueError(
            f"task record tasks/{summary['task']}.json holds 'paths', which only MiniGrid's "
            "tasks draw; the record is damaged (run the task again, or restore the file)"
        )
    terminal = world.terminal_mask.tolist()
    paths, colors = [], []
    for name, states in summary["paths"].items():
        if max(states) >= world.num_states:
            raise ValueError(
                f"task record tasks/{summary['task']}.json: path {name!r} holds state "
                f"{max(states)}, outside the task's {world.num_states} states; the record is "
                "damaged (run the task again, or restore the file)"
            )
        steps = f"{len(states) - 1} steps" + (", the goal" if terminal[states[-1]] else ", no goal")
        label = "mentor, first episode" if name == "mentor" else f"{name}, greedy"
        paths.append((f"{label} ({steps})", states))
        # The mentor magenta: no agent's colour, and it shows on MiniGrid's black floor and on
        # the legend's white.
        colors.append("magenta" if name == "mentor" else AGENT_COLORS.get(name, "0.6"))
    fig = plot_minigrid_paths(
        world,
        paths,
        colors=colors,
        title=f"{summary.get('env_id', summary['task'])}: seed {config.first_seed}'s paths",
    )
    save_figure(fig, path, dpi=100)


def _cell(values, digits: int = 1) -> str:
    """Mean [95 % BCa bootstrap interval] over the seeds (a t-interval can leave the possible
    range on skewed counts near zero)."""
    v = [x for x in values if x is not None and math.isfinite(x)]
    if not v:
        return "–"
    if len(v) == 1:
        return f"{v[0]:.{digits}f} (n=1)"
    return bca_interval(v).format(digits)


def write_gym_results(run_dir: Path, config: GymExperimentConfig, summaries: list[dict]) -> None:
    """``results.md``: per task and agent, mean [95 % BCa interval] over seeds
    (:func:`~himit_torch.viz.results_page.write_results_page`: the provenance, then this
    study's sections)."""
    write_results_page(
        run_dir,
        f"{config.name}: hierarchical imitation on Gymnasium's tabular environments",
        [_provenance(run_dir, config, summaries)],
        [
            _settings_section(config),
            *(_task_section(config, s) for s in summaries),
            [
                f"Curves: `curves.csv`. TensorBoard: `{tensorboard_command(Path(run_dir) / 'tb')}`.",
                "",
            ],
        ],
    )


def _provenance(run_dir: Path, config: GymExperimentConfig, summaries: list[dict]) -> str:
    """Which commits and engines ran the tasks, how the page is redrawn and the runs rerun."""
    commits = list(dict.fromkeys(s.get("commit", "unknown") for s in summaries))
    command = gym_run_command(config, run_dir)
    engines = ", ".join(sorted({f"`{s.get('engine', 'unknown')}`" for s in summaries}))
    study = _entry_of(config).name
    # (the Gymnasium comparison's committed runs came from the script, with settings no flag has)
    script = " (the same as `python experiments/gymnasium_worlds.py`)" * (study == "gymnasium")
    fallback = (
        "those of `python experiments/gymnasium_worlds.py`, not all of them flags of "
        "`himit run gymnasium`"
        if study == "gymnasium"
        else "not all of them flags of `himit run minigrid`"
    )
    return provenance_line(
        commits,
        f" (from `tasks/*.json`), engine {engines}",
        plot_command(run_dir),
        (f"`{command}`" if command else f"the settings in `config.json` ({fallback})")
        + f". Produced by `himit run {study}`{script}; settings: "
        "`himit_torch/runs/gymnasium.py`.",
    )


def _settings_section(config: GymExperimentConfig) -> list[str]:
    """The budgets, the learner's and agents' settings, and what the columns mean."""
    return [
        f"{config.seeds} seeds per agent and task, "
        + ", ".join(f"{t} {config.steps_of(t):,}" for t in config.tasks)
        + " steps per run, "
        f"{config.mentor_episodes} mentor episodes (states only) per seed, γ = {config.gamma}, "
        f"window {config.window}. Cells: mean [95 % BCa bootstrap interval of the mean] over "
        "seeds (n = seeds; 9999 resamples). "
        + (
            "The mentor is optimal for its own options (MiniGrid's tasks: right-handed skills, "
            "so it may be slower than the optimum over primitives, and a greedy policy may "
            "exceed 100 % of its rate)"
            if any(TASKS[name].make_mentor is not None for name in config.tasks)
            else "The mentor is optimal (value iteration on the true model, primitive actions)"
        )
        + "; the imitator's mentor reward is `KnownReward` (the least "
        "reward of the actions consistent with each observed move).",
        "",
        learner_settings_line(config),
        "",
        agent_settings_text(config.agents, config.learner),
        "",
        "Columns: *goals, last window* — arrivals at the goal states in the last "
        f"{config.window} steps (optimal: the optimal policy's renewal rate); *total goals* — "
        "over the whole run; *value gap* — V*(μ) − V^π(μ) of the run's final greedy policy "
        "(the one of *greedy*, below), both exact on the true model from the start "
        "distribution (0 = optimal); "
        "*first goal* — end of the first window with a goal (runs that never reached one are "
        "left out, and counted in *found*); *greedy* — the run's greedy policy at the end frozen "
        "as it acts (ε = 0, ties as configured, a state it has tried nothing at: uniformly any "
        "of its options there) and evaluated exactly: its long-run goals per "
        "window as a % of the mentor's own (the mentor is optimal), and the probability that an "
        "episode from μ ends at a goal.",
        "",
    ]


def _task_section(config: GymExperimentConfig, s: dict) -> list[str]:
    """One task's section: its options and optimum, and the table of its agents."""
    lines = [
        f"## {s['task']}",
        "",
        s["about"] + f"; {s['steps']:,} steps per run.",
        "",
        f"Options of the learner: {', '.join(s['options'])}.",
        "",
        f"Optimal: V*(μ) = {s['optimal_value']:.3f}, "
        f"{s['optimal_goals_per_window']:.1f} goals per {config.window} steps. "
        f"Learner's initial value: {s['initial_value']:g}. "
        f"KnownReward: {s['known_reward']}.",
        "",
        "| agent | n | found | goals, last window | total goals | value gap | first goal | "
        "mentor term wins | greedy, % of mentor | greedy, P(goal) |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for agent in dict.fromkeys(s["agents"]):
        idx = [b for b, a in enumerate(s["agents"]) if a == agent]
        firsts = [s["first_goal_window"][b] for b in idx]
        found = [f for f in firsts if f >= 0]
        lines.append(
            f"| {agent} | {len(idx)} | {len(found)}/{len(idx)} | "
            f"{_cell([s['final_goals'][b] for b in idx]) if s['final_goals'] else '–'} | "
            f"{_cell([s['total_goals'][b] for b in idx], 0)} | "
            f"{_cell([s['final_value_gap'][b] for b in idx], 3) if s['final_value_gap'] else '–'} | "
            f"{_cell(found, 0)} | "
            f"{_cell([s['mentor_term_wins'][b] for b in idx], 2) if s['mentor_term_wins'] else '–'} | "
            f"{_cell([s['greedy_percent_of_mentor'][b] for b in idx])} | "
            f"{_cell([s['greedy_goal_probability'][b] for b in idx], 3)} |"
        )
    return lines + [
        "",
        f"Wall time for this task's batch of {len(s['agents'])} runs: "
        f"{s['wall_seconds']:.0f} s. Figure: `figures/curves_{s['task']}.png`."
        + (
            f" Paths over MiniGrid's drawing (the mentor's first episode, each agent's greedy "
            f"trajectory, seed {config.first_seed}): `figures/paths_{s['task']}.png`."
            if "paths" in s
            else ""
        ),
        "",
    ]


# ================================================================ the command line's entry
def _info_flags(parser) -> None:
    parser.add_argument(
        "--env",
        help="a Gymnasium tabular environment instead of MultiRooms: an id "
        "(e.g. Taxi-v4, FrozenLake-v1) or a task of himit run gymnasium "
        "(taxi, cliffwalking, frozenlake8x8)",
    )
    parser.add_argument(
        "--env-kwargs",
        help='JSON keyword arguments of gymnasium.make, e.g. \'{"map_name": "8x8"}\'',
    )
    parser.add_argument(
        "--gamma", type=float, default=0.99, help="discount of a --env or --minigrid world (0.99)"
    )


def _info_world(args) -> tuple[TableWorld, Options]:
    """The world and learner options ``himit info --env`` describes."""
    try:
        kwargs = json.loads(args.env_kwargs) if args.env_kwargs else {}
    except json.JSONDecodeError as err:
        raise ValueError(f"--env-kwargs is not valid JSON: {err}") from None
    if not isinstance(kwargs, dict):
        raise ValueError('--env-kwargs must be a JSON object, e.g. \'{"map_name": "8x8"}\'')
    task = TASKS.get(args.env)
    if task is None:
        world = from_gymnasium(args.env, gamma=args.gamma, **kwargs)
        return world, primitive_options(world)
    if kwargs:
        raise ValueError(
            f"--env {args.env} is a task with its own kwargs ({task.kwargs}); give "
            f"--env {task.env_id} to choose them"
        )
    world = task.world(args.gamma)
    return world, task.options(world)


def _info(args) -> Iterator[str]:
    """``himit info --env``: a Gymnasium world through the adapter, exactly solved."""
    from himit_torch.exact.option_models import option_models
    from himit_torch.exact.planning import smdp_value_iteration, value_iteration
    from himit_torch.worlds.table_world import world_model

    world, options = _info_world(args)
    plan = value_iteration(*world_model(world), world.gamma)
    mu = world.start_distribution
    rewards = world.dynamics_table().rewards
    yield (
        f"world      {world.name} {world.describe().get('kwargs', {})} through from_gymnasium, "
        f"gamma {world.gamma}"
    )
    yield (
        f"states     {world.num_states} (start states {int((mu > 0).sum())}, terminal "
        f"{int(world.terminal_mask.sum())}, goal {int(world.goal_mask.sum())})"
    )
    yield f"actions    {world.num_actions}: {', '.join(world.action_names)}"
    yield (
        f"rewards    {float(rewards.min()):g} … {float(rewards.max()):g} per transition; "
        f"mentor reward: {KnownReward(world).note}"
    )
    extended = [n for n, k in zip(options.names, options.kinds) if k != "primitive"]
    yield (
        f"learner    {options.num_options} options ({option_kinds_text(options)}"
        + (f": {', '.join(extended)})" if extended else ")")
    )
    p_goal, length = episode_statistics(world, plan.policy)
    models = smdp_value_iteration(option_models(world, options))
    yield ""
    yield "optimal (value iteration on the true model, primitives)"
    yield f"  V*(start distribution)      {float(plan.values @ mu):.3f}"
    yield f"  with the learner's options  {float(models.values @ mu):.3f}"
    yield f"  P(goal) per episode         {p_goal:.3f}"
    yield f"  steps per episode           {length:.1f}"
    yield f"  {f'goals per {INFO_WINDOW} steps':<28}{INFO_WINDOW * p_goal / length:.1f}"


#: The settings a results page's ``himit run gymnasium`` / ``minigrid`` command may give.
_RERUN_FLAGS = ("preset", "seeds", "first_seed", "steps", "device", "tie_break")

#: The registry entry of ``himit run gymnasium`` (and ``himit info --env``).
ENTRY = StudyEntry(
    "gymnasium",
    "imitation against options and primitives on Gymnasium's Taxi, CliffWalking and "
    "FrozenLake 8×8 (himit_torch.runs.gymnasium; each task is one batch, rerun with --force)",
    GymExperimentConfig,
    configs=lambda: (GymExperimentConfig(),),
    run=run_each(run_gym_experiment),
    describe=lambda config, run_dir: (
        f"{config.name}: tasks {list(config.tasks)}, agents {list(config.agents)}, "
        f"{config.seeds} seeds → {run_dir}"
    ),
    redraw=rewrite_gym_report,
    info=InfoTopic("env", _info_flags, _info, requires=("env_kwargs",)),
    rerun_flags=_RERUN_FLAGS,
)

#: The registry entry of ``himit run minigrid`` (and ``himit info --minigrid``): the comparison
#: on MiniGrid's tasks, DoorKey-6x6 by default.
MINIGRID_ENTRY = StudyEntry(
    "minigrid",
    "imitation against options and primitives on MiniGrid's key-and-door tasks (DoorKey, "
    "Unlock, UnlockPickup, KeyCorridor, MultiRoom, FourRooms; himit_torch.runs.gymnasium; each "
    "task is one batch, rerun with --force)",
    MiniGridExperimentConfig,
    configs=lambda: (MiniGridExperimentConfig(),),
    run=run_each(run_gym_experiment),
    describe=ENTRY.describe,
    redraw=rewrite_gym_report,
    info=minigrid.INFO,
    rerun_flags=_RERUN_FLAGS,
)
