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
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path

import numpy as np
import torch

from himit_torch.runs.checkpoints import BatchShape, CheckpointGenerations, NoGoodCheckpoint
from himit_torch.exact.option_models import option_durations, option_models
from himit_torch.exact.planning import expected_steps, smdp_value_iteration
from himit_torch.learner.agents import AGENTS
from himit_torch.learner.learner import Learner
from himit_torch.learner.config import LearnerConfig
from himit_torch.mentor.policy import exact_mentor_transitions, mentor_policy, record_demonstrations
from himit_torch.options.builders import learner_options, mentor_options, primitive_options
from himit_torch.mentor.reward import MENTOR_REWARDS, mentor_reward_module
from himit_torch.viz.tensorboard import TensorBoardLogger
from himit_torch.validation import as_choice, as_float, as_int, as_tuple, check_memory
from himit_torch.worlds.multirooms import MultiRooms

__all__ = [
    "ExperimentConfig",
    "EXPERIMENTS",
    "run_experiment",
    "run_experiments",
    "load_config",
    "WorldResult",
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


@dataclass
class ExperimentConfig:
    """One experiment: which worlds, agents, seeds, budget and learner settings."""

    name: str = "exp2"
    """Experiment id (``exp1``, ``exp2``, ``exp3`` or your own)."""
    sizes: tuple[int, ...] = (40,)
    """World sizes N (N×N cells); each is one batch."""
    room_size: int = 4
    """Cells per room side, wall included: a world of size N has N / room_size rooms per side
    (the paper: 40×40 with 10×10 rooms → 4; 80×80 with 10×10 rooms → 8)."""
    corner_options: bool = False
    """Give the option agents the 8 corner options per room (experiment 1's large library)."""
    agents: tuple[str, ...] = ("imitation", "imitation_confident", "options", "primitives")
    """Agent variants, each run with every seed (see ``himit_torch.AGENTS``)."""
    seeds: int = 5
    """Runs per agent."""
    first_seed: int = 0
    """Seeds are first_seed … first_seed + seeds − 1 (a seed also picks the mentor's episodes)."""
    steps: int = 200_000
    """Primitive steps per run."""
    mentor_episodes: int = 20
    """Mentor episodes recorded (states only) before learning, per seed."""
    mentor_reward: str = "known"
    """The reward ``R_m`` the imitating runs give the mentor's transitions (eq. 2): ``known``
    (the world's own reward, the paper's), ``salience`` (``SalienceReward`` with its defaults,
    fitted on each seed's own demonstrations: intrinsic, no knowledge of the world's reward) or
    ``none`` (``ZeroReward``: r_m = 0). See ``himit_torch.mentor.reward``."""
    mentor_preference: float | None = None
    """The mentor takes an extended option within this of the best value (None: one step's cost)."""
    mentor_model: str = "learned"
    """Where the imitators' mentor model ``p_m(s'|s)`` comes from: ``"learned"`` — counts of the
    ``mentor_episodes`` recorded demonstrations (the paper); ``"exact"`` — the mentor's exact
    transition model (:func:`~himit_torch.mentor.policy.exact_mentor_transitions`: expected counts of
    ``mentor_episodes`` episodes, so the same total mass, at every state the mentor reaches with
    positive probability). Demonstrations are still recorded for the figures."""
    slip: float = 0.1
    """Probability that an action fails (the paper: 10 %)."""
    window: int = 5000
    """Goals are counted per window of this many steps (the paper's 5000)."""
    checkpoint_every: int = 25_000
    """Save the whole state every this many steps (a multiple of ``window``)."""
    device: str = "cpu"
    """Where the batch runs (``cpu`` or ``cuda``)."""
    engine: str = "auto"
    """Which engine carries out the ticks: ``auto`` (the compiled ``numba`` loop on a CPU, the
    ``torch`` engine on a GPU), ``numba`` or ``torch``. Both give the same curves."""
    learner: LearnerConfig = field(default_factory=LearnerConfig)
    """Learner settings (see ``LearnerConfig``)."""

    def __post_init__(self):
        # Input rules of himit_torch.validation: lists become tuples, whole numbers are never
        # truncated, bools and strings are not numbers, every number is finite.
        if isinstance(self.learner, dict):
            _refuse_unknown_fields(self.learner, LearnerConfig, "ExperimentConfig.learner")
            self.learner = LearnerConfig(**self.learner)
        if not isinstance(self.learner, LearnerConfig):
            raise ValueError(
                f"ExperimentConfig.learner must be a LearnerConfig or a dict, got "
                f"{type(self.learner).__name__}"
            )
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"ExperimentConfig.name must be a non-empty string, got {self.name!r}")
        self.sizes = tuple(
            as_int(f"ExperimentConfig.sizes[{i}]", v, minimum=1)
            for i, v in enumerate(as_tuple("ExperimentConfig.sizes", self.sizes))
        )
        self.agents = as_tuple("ExperimentConfig.agents", self.agents)
        if not all(isinstance(a, str) for a in self.agents):
            raise ValueError(f"ExperimentConfig.agents must be names, got {list(self.agents)}")
        self.room_size = as_int("ExperimentConfig.room_size", self.room_size, minimum=2)
        for name, minimum in (
            ("seeds", 1),
            ("first_seed", 0),
            ("steps", 1),
            ("mentor_episodes", 1),
            ("window", 1),
            ("checkpoint_every", 1),
        ):
            setattr(self, name, as_int(f"ExperimentConfig.{name}", getattr(self, name), minimum))
        if not isinstance(self.corner_options, (bool, np.bool_)):
            raise ValueError(
                f"ExperimentConfig.corner_options must be true or false, got "
                f"{self.corner_options!r}"
            )
        self.corner_options = bool(self.corner_options)
        self.slip = as_float("ExperimentConfig.slip", self.slip, 0.0, 1.0, high_open=True)
        if self.mentor_preference is not None:
            self.mentor_preference = as_float(
                "ExperimentConfig.mentor_preference", self.mentor_preference, low=0.0
            )
        as_choice("ExperimentConfig.engine", self.engine, ("auto", "numba", "torch"))
        if not isinstance(self.device, str):
            raise ValueError(
                f"ExperimentConfig.device must be a string such as 'cpu' or 'cuda', "
                f"got {self.device!r}"
            )
        try:
            torch.device(self.device)
        except RuntimeError as err:
            raise ValueError(
                f"ExperimentConfig.device={self.device!r} is not a torch device "
                f"({err}); use e.g. 'cpu' or 'cuda'"
            ) from None

        def bad(name, why):
            raise ValueError(f"ExperimentConfig.{name}={getattr(self, name)!r}: {why}")

        if not self.sizes:
            bad("sizes", "needs at least one world size")
        for s in self.sizes:
            if s <= 0 or s % self.room_size:
                bad(
                    "sizes", f"every size must be a positive multiple of room_size={self.room_size}"
                )
        unknown = sorted(set(self.agents) - set(AGENTS))
        if unknown or not self.agents:
            bad("agents", f"unknown or empty; use some of {sorted(AGENTS)}")
        if self.seeds < 1:
            bad("seeds", "needs at least one seed")
        if self.steps < 1:
            bad("steps", "must be ≥ 1")
        if self.mentor_episodes < 1:
            bad("mentor_episodes", "must be ≥ 1")
        if self.mentor_model not in ("learned", "exact"):
            bad("mentor_model", "use 'learned' or 'exact'")
        if self.mentor_reward not in MENTOR_REWARDS:
            bad("mentor_reward", f"use one of {list(MENTOR_REWARDS)}")
        if self.window < 1 or self.checkpoint_every < 1 or self.checkpoint_every % self.window:
            bad("checkpoint_every", f"must be a positive multiple of window={self.window}")
        if self.learner.window != self.window:
            self.learner = replace(self.learner, window=self.window)

    def check_size(self) -> None:
        """Refuse, before anything runs, a world of this experiment whose world, option tables
        and batch would not fit in memory (:func:`himit_torch.validation.check_memory`): not
        hours later when that world's turn comes. Called by :func:`run_experiment` (not on
        construction, so that defining an experiment never depends on the memory free now)."""
        for size in self.sizes:
            check_memory(
                f"ExperimentConfig: world {size}×{size} with its options and a batch of "
                f"{len(self.agents) * self.seeds} runs",
                self.estimate_bytes(size),
                "use smaller sizes, fewer agents or seeds",
            )

    def estimate_bytes(self, size: int) -> int:
        """Rough bytes one world of this experiment needs: the world, the learner's and the
        mentor's dense option tables and the batch's per-run tables (the constants of
        ``MultiRooms``, ``options`` and ``Learner``)."""
        from himit_torch.options.builders import BYTES_PER_OPTION_STATE

        S, R = size * size, size // self.room_size
        options = 4 + 4 * R * (R - 1) + (8 * R * R if self.corner_options else 0)
        rows = 4 * S + (options - 4) * (self.room_size - 1) ** 2
        batch = len(self.agents) * self.seeds
        return (
            S * MultiRooms.BYTES_PER_STATE
            + 2 * options * S * BYTES_PER_OPTION_STATE
            + batch * (S * Learner.BYTES_PER_RUN_STATE + rows * Learner.BYTES_PER_RUN_ROW)
        )

    def to_json(self) -> str:
        return json.dumps(asdict(self), indent=2)

    def world(self, size: int) -> MultiRooms:
        return MultiRooms(size=size, rooms=size // self.room_size, slip=self.slip)

    def quick(self) -> ExperimentConfig:
        """A tiny budget of the same experiment, for smoke tests and ``--quick``."""
        return replace(
            self,
            seeds=min(self.seeds, 2),
            steps=min(self.steps, 4 * self.window),
            sizes=self.sizes[:2],
            checkpoint_every=self.window,
            mentor_episodes=min(self.mentor_episodes, 5),
        )


def _paper_learner() -> LearnerConfig:
    """The experiments' learner: the library defaults, planning every 4 ticks in one round
    (``plan_every=4, sweep_rounds=1``). On experiment 2, against planning at every decision in
    two rounds, it gave the same totals at 200k steps (imitation 1903 vs 1898, options-only
    identical failures) but a slower start (goals by 75k steps: imitation 615 vs 646); see
    experiments/results/results.md."""
    return LearnerConfig(plan_every=4, sweep_rounds=1)


#: The paper's three experiments with our defaults (see ``experiments/results/results.md``).
EXPERIMENTS: dict[str, ExperimentConfig] = {
    "exp1": ExperimentConfig(
        name="exp1",
        sizes=(80,),
        room_size=8,
        corner_options=True,
        steps=300_000,
        learner=_paper_learner(),
    ),
    "exp2": ExperimentConfig(
        name="exp2",
        sizes=(40,),
        room_size=4,
        corner_options=False,
        steps=200_000,
        learner=_paper_learner(),
    ),
    "exp3": ExperimentConfig(
        name="exp3",
        sizes=(64, 80, 96, 120),
        room_size=8,
        corner_options=True,
        steps=130_000,
        agents=("imitation", "options", "primitives"),
        learner=_paper_learner(),
    ),
}


def _refuse_unknown_fields(data: dict, cls, where: str) -> None:
    known = {f.name for f in fields(cls)}
    unknown = sorted(set(data) - known)
    if unknown:
        raise ValueError(f"{where}: unknown fields {unknown}; known: {sorted(known)}")


def load_config(path: str | os.PathLike) -> ExperimentConfig:
    """An :class:`ExperimentConfig` from a JSON file (as saved in a run directory)."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        raise ValueError(f"config file {path} does not exist") from None
    except json.JSONDecodeError as err:
        raise ValueError(f"config file {path} is not valid JSON: {err}") from None
    except UnicodeDecodeError as err:  # e.g. a binary file (a pickle) in its place
        raise ValueError(f"config file {path} is not valid JSON: not UTF-8 text ({err})") from None
    if not isinstance(data, dict):
        raise ValueError(f"config file {path} must hold a JSON object")
    _refuse_unknown_fields(data, ExperimentConfig, f"config file {path}")
    learner = data.get("learner", {})
    if not isinstance(learner, dict):
        raise ValueError(f"config file {path}: 'learner' must be an object")
    _refuse_unknown_fields(learner, LearnerConfig, f"config file {path}: learner")
    try:
        data["learner"] = LearnerConfig(**learner)
        return ExperimentConfig(**data)
    except ValueError as err:
        raise ValueError(f"config file {path}: {err}") from None
    except TypeError as err:
        raise ValueError(f"config file {path}: {err}") from None


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

    def percent_of_optimal(self) -> list[float]:
        """Total goals as a percentage of what the optimal policy reaches in the same steps."""
        best = self.steps / self.optimal_steps
        return [100.0 * g / best for g in self.goals]


def _optimum(world: MultiRooms) -> tuple[float, float]:
    """Expected steps of the optimal (primitive) policy from start to goal, and V*(start)."""
    prims = primitive_options(world)
    plan = smdp_value_iteration(option_models(world, prims))
    steps = expected_steps(
        option_durations(world, prims), plan.policy, world.start_state, world.terminal_mask
    )
    return steps, float(plan.values[world.start_state])


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


def _atomic_write(path: Path, text: str) -> None:
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def _state_layout_version() -> int:
    """The learner's state layout version (1 for learners from before it was declared): stored in
    every checkpoint so that a checkpoint of another layout is refused by name."""
    return int(getattr(Learner, "STATE_LAYOUT_VERSION", 1))


def _resume(
    generations: CheckpointGenerations,
    learner: Learner,
    batch: BatchShape,
    layout: int,
    config: ExperimentConfig,
) -> float:
    """Restore ``learner`` from the newest good checkpoint generation; returns the wall seconds
    the run had used. Nothing saved yet: the learner is left as it is (a run killed before its
    first checkpoint starts over). A damaged newest file: one line on stderr, then the previous
    generation — the learner then redoes the lost interval exactly as it first ran it.

    Raises:
        ValueError: no generation is good, or the checkpoint is for another state layout or
            batch, or it does not fit this learner; the message names the file.
    """
    try:
        resumed = generations.load(
            map_location=config.device, expect_batch=batch, expect_layout=layout
        )
    except NoGoodCheckpoint as err:
        raise ValueError(f"--resume: {err}; start over with --force") from None
    if resumed is None:
        return 0.0
    found = resumed.checkpoint
    for skipped in resumed.skipped:
        if skipped.step is not None and skipped.step > found.header.step:
            redo = f"{skipped.step - found.header.step} steps will be redone"
        else:
            redo = (
                f"the steps after it (up to checkpoint_every={config.checkpoint_every}) will "
                "be redone"
            )
        print(
            f"himit: warning: {skipped.path}: {skipped.reason}; resuming from "
            f"{(found.path or generations.newest).name} at step {found.header.step}: {redo}",
            file=sys.stderr,
        )
    payload = found.payload
    if not isinstance(payload, dict) or not isinstance(payload.get("learner"), dict):
        raise ValueError(f"{found.path} holds no learner state; start over with --force")
    try:
        learner.load_state_dict(payload["learner"])
    except ValueError as err:
        raise ValueError(f"{found.path}: {err}; start over with --force") from None
    except (KeyError, TypeError, IndexError, AttributeError, RuntimeError) as err:
        raise ValueError(
            f"{found.path} (step {found.header.step}) could not be restored into this learner "
            f"({type(err).__name__}: {err}) although its state layout version {layout} is this "
            "himit_torch's: please report it; start over with --force"
        ) from None
    elapsed = payload.get("elapsed", 0.0)
    return float(elapsed) if isinstance(elapsed, (int, float)) else 0.0


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
    seeds = list(range(config.first_seed, config.first_seed + config.seeds))
    agents = [a for a in config.agents for _ in seeds]
    run_seeds = [s for _ in config.agents for s in seeds]
    # The mentor (its own [O, S] option tables: 0.23 GB on 120×120 with corners) records every
    # seed's episodes and is gone before the learner's tables are built, so the two never share
    # the process's peak memory. Each seed's episodes come from its own generator: the order
    # changes nothing.
    mentor = mentor_policy(
        world, mentor_options(world, corners=config.corner_options), config.mentor_preference
    )
    demos = {s: record_demonstrations(world, mentor, config.mentor_episodes, seed=s) for s in seeds}
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
    for s in seeds:  # each seed watches its own mentor episodes
        learner.add_demonstrations(
            demos[s] if exact is None else exact,
            runs=[b for b, rs in enumerate(run_seeds) if rs == s],
        )
    generations = CheckpointGenerations(run_dir / "checkpoints" / f"world{size}.pt")
    batch = BatchShape(tuple(agents), tuple(run_seeds), world.num_states)
    layout = _state_layout_version()
    if resume:
        elapsed = _resume(generations, learner, batch, layout, config)
    else:
        generations.clear()  # a fresh run: stale files must never become its "previous" one
        elapsed = 0.0
    names = [f"world{size}__{a}__seed{s}" for a, s in zip(agents, run_seeds)]
    optimal_steps, true_v = _optimum(world)
    # A resumed run purges what it logged after its last checkpoint (windows up to t were logged
    # before the checkpoint); a fresh one refuses folders that hold another run's events.
    logger = TensorBoardLogger(
        run_dir / "tb",
        names,
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
    logged = len(learner.metrics.steps)
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(
            total=config.steps,
            initial=learner.t,
            unit="step",
            mininterval=1.0,
            desc=f"{config.name} {size}×{size} B={learner.batch}",
        )
    start = time.perf_counter()
    while learner.t < config.steps:
        chunk = min(config.window - learner.t % config.window, config.steps - learner.t)
        learner.run(chunk)
        if bar is not None:
            bar.update(chunk)
        while logged < len(learner.metrics.steps):
            logger.window(learner, logged)
            logged += 1
            if on_window is not None:
                on_window(learner)
        if learner.t % maps_every == 0 or learner.t == config.steps:
            logger.maps(learner, map_runs, learner.t, mentor_visits)
        if learner.t % config.checkpoint_every == 0 or learner.t == config.steps:
            logger.flush()  # everything logged so far is on disk before the checkpoint says so
            generations.save(
                {"learner": learner.state_dict(), "elapsed": elapsed + time.perf_counter() - start},
                step=learner.t,
                batch=batch,
                state_layout_version=layout,
            )
    if bar is not None:
        bar.close()
    wall = elapsed + time.perf_counter() - start
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
            }
            for b in range(learner.batch)
        ],
        learner.t,
    )
    logger.close()
    _write_curves(run_dir / "worlds" / f"curves{size}.csv", learner, size)
    _atomic_write(run_dir / "worlds" / f"world{size}.json", json.dumps(asdict(result), indent=1))
    _world_figure(
        run_dir, config, world, demos[seeds[0]], learner, agents, run_seeds, seeds[0], size
    )
    return result


def mentor_rewards(config: ExperimentConfig, world, agents, run_seeds, demos) -> list | None:
    """The reward modules of a batch for ``config.mentor_reward``: ``None`` for ``known`` (the
    learner's default, :class:`~himit_torch.KnownReward`), else one module per run — fitted on
    that run's seed's demonstrations for ``salience`` — and ``None`` for runs that do not imitate."""
    if config.mentor_reward == "known":
        return None
    modules: list = []
    fitted: dict = {}
    for agent, seed in zip(agents, run_seeds):
        if not AGENTS[agent][1]:  # the variant has no mentor term
            modules.append(None)
            continue
        if seed not in fitted:
            fitted[seed] = mentor_reward_module(config.mentor_reward, world, demos[seed])
        modules.append(fitted[seed])
    return modules


def _write_curves(path: Path, learner: Learner, size: int) -> None:
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
                    ]
                )
    os.replace(tmp, path)


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
def source_commit() -> str:
    """The git commit of the code that runs (``+dirty`` if it has uncommitted changes), or
    ``"unknown"`` outside a git checkout: recorded with every result."""
    import subprocess

    root = Path(__file__).resolve().parent.parent
    try:
        commit = subprocess.run(
            ["git", "rev-parse", "--short=12", "HEAD"],
            cwd=root,
            text=True,
            capture_output=True,
            timeout=10,
            check=True,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no", "--", "himit_torch"],
            cwd=root,
            text=True,
            capture_output=True,
            timeout=10,
            check=True,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return commit + ("+dirty" if dirty else "")


def _check_run_dir(run_dir: Path, resume: bool, force: bool) -> None:
    finished = (run_dir / "results.md").exists()
    started = (run_dir / "config.json").exists()
    if force:
        return
    if finished and not resume:
        raise ValueError(
            f"{run_dir} already holds a finished run; choose another --logdir or pass "
            "--force to overwrite it"
        )
    if started and not finished and not resume:
        raise ValueError(
            f"{run_dir} holds an unfinished run; pass --resume to continue it or "
            "--force to start over"
        )


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
        _check_run_dir(run_dir, resume, force)
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
            initializer=_share_cores,
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
    if force and run_dir.exists():
        import shutil

        for sub in ("checkpoints", "tb", "worlds", "figures"):
            shutil.rmtree(run_dir / sub, ignore_errors=True)
        for f in ("results.md", "curves.csv", "config.json"):
            (run_dir / f).unlink(missing_ok=True)
    run_dir.mkdir(parents=True, exist_ok=True)
    cfg_path = run_dir / "config.json"
    if resume and cfg_path.exists():
        saved = load_config(cfg_path)
        if asdict(saved) != asdict(config):
            raise ValueError(
                f"--resume: {cfg_path} holds a different configuration than the one "
                "given; resume with the saved one (--config "
                f"{cfg_path}) or start over with --force"
            )
    _atomic_write(cfg_path, config.to_json())
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
    results = [finished[size] for size in config.sizes]
    _merge_curves(run_dir, config)
    from himit_torch.viz.report import write_figures, write_results

    write_figures(run_dir, config, results)
    write_results(run_dir, config, results)
    return results


def _share_cores(threads: int) -> None:
    """A world's process: one torch thread, ``threads`` for the compiled engine."""
    torch.set_num_threads(1)
    try:
        import numba
    except ImportError:
        return
    numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))  # type: ignore[attr-defined]


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
