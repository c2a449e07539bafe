"""An experiment's configuration (:class:`ExperimentConfig`), the paper's three
(:data:`EXPERIMENTS`), and loading one from a ``config.json`` (:func:`load_config`).

Every field is declared once with :func:`~himit_torch.validation.setting` (type, range or
choices, doc), as :class:`~himit_torch.learner.config.LearnerConfig`'s are: validation and the
``himit run`` flags come from that declaration, and only the cross-field rules are written out.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, fields, replace
from typing import Any, ClassVar

from himit_torch.learner.agents import AGENTS
from himit_torch.learner.config import LearnerConfig
from himit_torch.learner.learner import Learner
from himit_torch.mentor.reward import MENTOR_REWARDS
from himit_torch.runs.study import RunConfig, read_config_file
from himit_torch.validation import check_memory, setting
from himit_torch.worlds.multirooms import MultiRooms, maze_doorways, primitives_only_goal

__all__ = [
    "ExperimentConfig",
    "EXPERIMENTS",
    "MENTOR_MODELS",
    "LAYOUTS",
    "STRESS_SETTINGS",
    "load_config",
]

#: ``ExperimentConfig.mentor_model``: counts of the demonstrations, or the mentor's exact model.
MENTOR_MODELS = ("learned", "exact")

#: ``ExperimentConfig.layout``: every doorway open (the paper's), or a maze of rooms.
LAYOUTS = ("open", "maze")

#: ``ExperimentConfig.second_mentor``: none, or a second demonstration set watched alongside the
#: first by a mentor that errs (``noisy``) or takes a needless detour (``detour``).
SECOND_MENTORS = ("none", "noisy", "detour")

#: ``ExperimentConfig.observation``: every ``observation_stride``-th mentor state, or only the
#: states where the mentor's options end.
OBSERVATIONS = ("stride", "option-ends")

#: The settings that stress the learner (docs/stresses.md), each with its neutral default.
STRESS_SETTINGS = (
    "mentor_episodes",
    "slip",
    "mentor_noise",
    "mentor_detour",
    "observation_stride",
    "layout",
    "goal_needs_primitives",
)


#: The settings that change what the mentor shows when off their defaults (in the order the
#: cross-field errors name them): an exact mentor model, or one watched at its option ends, shows
#: none of them.
_DEMONSTRATION_STRESSES = (
    "mentor_noise mentor_detour observation_stride second_mentor mentor_coverage mentor_goal "
    "observation"
).split()


@dataclass
class ExperimentConfig(RunConfig):
    """One experiment: which worlds, agents, seeds, budget and learner settings (the shared
    settings are :class:`~himit_torch.runs.study.RunConfig`'s)."""

    name: str = RunConfig.shared(
        "name",
        "exp2",
        doc="Experiment id (``exp1``, ``exp2``, ``exp3`` or your own; the run directory's name).",
    )
    sizes: tuple[int, ...] = setting(
        (40,), ge=1, doc="World sizes N (N×N cells); each is one batch."
    )
    room_size: int = setting(
        4,
        ge=2,
        doc="""
        Cells per room side, wall included: a world of size N has N / room_size rooms per side
        (the paper: 40×40 with 10×10 rooms → 4; 80×80 with 10×10 rooms → 8).""",
    )
    corner_options: bool = setting(
        False,
        doc="Give the option agents the 8 corner options per room (experiment 1's large library).",
    )
    agents: tuple[str, ...] = setting(
        ("imitation", "imitation_confident", "options", "primitives"),
        choices=tuple(AGENTS),
        doc="Agent variants, each run with every seed (see ``himit_torch.AGENTS``).",
    )
    seeds: int = RunConfig.shared("seeds", 5, doc="Runs per agent.")
    first_seed: int = RunConfig.shared("first_seed", 0)
    steps: int = RunConfig.shared("steps", 200_000)
    mentor_episodes: int = RunConfig.shared(
        "mentor_episodes",
        20,
        doc="""
        Mentor episodes recorded (states only) before learning, per seed (default 20). A stress
        axis: how many demonstrations (the benchmark's 1 … 100).""",
    )
    mentor_reward: str = setting(
        "known",
        choices=MENTOR_REWARDS,
        doc="""
        The reward ``R_m`` the imitating runs give the mentor's transitions (eq. 2): ``known``
        (the world's own reward, the paper's), ``salience`` (``SalienceReward`` with its defaults,
        fitted on each seed's own demonstrations: intrinsic, no knowledge of the world's reward) or
        ``none`` (``ZeroReward``: r_m = 0). See ``himit_torch.mentor.reward``.""",
    )
    mentor_preference: float | None = setting(
        None,
        ge=0.0,
        doc="""
        The mentor takes an extended option within this of the best value (None: one step's
        cost).""",
    )
    mentor_model: str = setting(
        "learned",
        choices=MENTOR_MODELS,
        doc="""
        Where the imitators' mentor model ``p_m(s'|s)`` comes from: ``"learned"`` — counts of the
        ``mentor_episodes`` recorded demonstrations (the paper); ``"exact"`` — the mentor's exact
        transition model (:func:`~himit_torch.mentor.policy.exact_mentor_transitions`: expected
        counts of ``mentor_episodes`` episodes, so the same total mass, at every state the mentor
        reaches with positive probability). Demonstrations are still recorded for the figures.""",
    )
    slip: float = setting(
        0.1,
        ge=0.0,
        lt=1.0,
        doc="""
        Probability that an action fails, moving to one of the other three directions (default
        and the paper: 0.1). A stress axis: it acts on the mentor, the learner and the exact
        evaluations alike.""",
    )
    # The stresses (docs/stresses.md): each default leaves the paper's setting unchanged.
    mentor_noise: float = setting(
        0.0,
        ge=0.0,
        lt=1.0,
        doc="""
        A mentor that errs (default 0: never). At each of the demonstrating mentor's decisions,
        with this probability, it takes a primitive action drawn uniformly from the four (a
        primitive option: one step) instead of its own option, then decides again; drawn from
        each seed's own generator (``run_mentor(noise=…)``). Only the recorded demonstrations
        change: the "% of mentor" reference stays the undisturbed mentor's policy.""",
    )
    mentor_detour: bool = setting(
        False,
        doc="""
        A mentor taking a needless detour (default false): every demonstration first walks to
        the top-right corner cell ``(0, N − 1)`` — on no shortest path of the open layout —
        then to the goal (``mentor_detour``, ``detour_waypoint``). Only the recorded
        demonstrations change, as for ``mentor_noise``.""",
    )
    mentor_coverage: float = setting(
        1.0,
        gt=0.0,
        le=1.0,
        doc="""
        Demonstrations that cover only part of the way (default 1: all of it). Each recorded
        episode keeps its first ``⌈coverage · T⌉`` states (at least two): 0.5 shows the first
        half of each route, and nothing of the rest.""",
    )
    mentor_goal: str = RunConfig.shared("mentor_goal")
    second_mentor: str = setting(
        "none",
        choices=SECOND_MENTORS,
        doc="""
        Several mentors (``LearnerConfig.mentors``, default ``none``: one mentor). ``noisy``: the
        learner also watches a second mentor, the same one erring with probability
        ``second_mentor_noise`` (as ``mentor_noise`` does); ``detour``: a second mentor taking
        the needless detour of ``mentor_detour``. The second mentor's ``mentor_episodes``
        episodes come from a generator of its own, and go to the learner's second mentor model
        (``learner.mentors`` is derived from it: 2 with a second mentor, else 1). The first mentor is the one ``mentor_noise`` and
        ``mentor_detour`` describe; the "% of mentor" reference stays the undisturbed mentor's
        policy.""",
    )
    second_mentor_noise: float = setting(
        0.5,
        ge=0.0,
        lt=1.0,
        doc="""
        How often the ``noisy`` second mentor errs (default 0.5; read only with
        ``second_mentor = "noisy"``).""",
    )
    observation_stride: int = setting(
        1,
        ge=1,
        doc="""
        Coarse observation (default 1: every state). The learner sees only states 0, k, 2k, …
        and the last of each mentor episode, so its mentor model's transitions join states up
        to k primitive steps apart; eq. 2 is left as it is and its mentor term treats a k-step
        move as one step (``himit_torch.mentor.observation`` says what that costs).""",
    )
    observation: str = setting(
        "stride",
        choices=OBSERVATIONS,
        doc="""
        What the learner sees of the mentor (default ``stride``: every ``observation_stride``-th
        state). ``option-ends``: only the states where the mentor's options end — a doorway,
        the goal — with each episode's first and last
        (:func:`~himit_torch.mentor.observation.observe_at_option_ends`): the subgoals, not the
        movements. Each observed move is one of the mentor's options; with
        ``learner.mentor_segments`` it is scored with its duration.""",
    )
    layout: str = setting(
        "open",
        choices=LAYOUTS,
        doc="""
        The rooms' doorways (default ``open``: all open, the paper's). ``maze``: doorways closed
        so that the open ones join the rooms in a spanning tree (``maze_doorways``, from the
        fixed seed ``MAZE_SEED``: every run and seed shares the one maze of each size).""",
    )
    goal_needs_primitives: bool = setting(
        False,
        doc="""
        Move the goal to the middle of the bottom row of the bottom-right room
        (``primitives_only_goal``), a cell no doorway or corner option is aimed at, so only
        primitives reach it on purpose (default false: the bottom-right corner, which the
        corner options reach). Needs rooms of ≥ 4 cells per side.""",
    )
    window: int = RunConfig.shared("window", 5000)
    checkpoint_every: int = setting(
        100_000,
        ge=1,
        doc="""
        Save the whole state every this many steps (a multiple of ``window``), and at the
        end. A save of exp1's state (20 runs on 80×80) takes ≈ 0.25 s, and 100,000 steps of
        its runs take ≈ 1.5 s to learn on two cores: a kill loses at most that much.""",
    )
    greedy_every: int | None = setting(
        0,
        ge=0,
        hint="steps; 0: at the end only; none: never",
        doc="""
        Evaluate every run's frozen greedy policy (ε = 0, ties as configured) exactly on the true
        model every this many steps and at the end: goals per window, % of the optimum's and of
        the mentor's own rate (``curves.csv``, TensorBoard ``eval/…``), and ``V^π(start)`` at the
        end (``results.md``). ``0`` (the default): at the end only; ``None``: never (no option
        models are built). Evaluated at the end of each window that reaches a multiple of it.
        Cost (``himit_torch.runs.greedy``): the options' exact models once per world (≈ 0.6 s on
        80×80 with corner options, 1.5 s on 120×120), then ≈ 5 ms a run per evaluation on 40×40,
        ≈ 40 ms on 80×80 and ≈ 50–100 ms on 120×120 (more at the end, with ``V^π``): at the end
        only, the paper's reproduction takes ≈ 9 % longer; ``25000`` (every checkpoint) ≈ 30 %.""",
    )
    device: str = RunConfig.shared("device", "cpu")
    engine: str = RunConfig.shared("engine", "auto")
    learner: LearnerConfig = RunConfig.shared("learner", default_factory=LearnerConfig)
    preset: str | None = RunConfig.shared("preset", None)

    #: The learner settings derived from the experiment's own: its window, and its mentors
    #: (2 with a ``second_mentor``, else 1).
    derived_learner: ClassVar[tuple[str, ...]] = ("window", "mentors")

    def derived_learner_settings(self) -> dict[str, Any]:
        """:meth:`RunConfig.derived_learner_settings`, and ``mentors`` (above)."""
        derived = super().derived_learner_settings()
        return {**derived, "mentors": 1 + (self.second_mentor != "none")}

    def __post_init__(self):
        self.check_run_settings()
        # Cross-field rules (each field on its own is checked above).
        if any(s % self.room_size for s in self.sizes):
            raise ValueError(
                f"ExperimentConfig.sizes={self.sizes!r}: every size must be a positive multiple "
                f"of room_size={self.room_size}"
            )
        if self.checkpoint_every % self.window:
            raise ValueError(
                f"ExperimentConfig.checkpoint_every={self.checkpoint_every!r}: must be a positive "
                f"multiple of window={self.window}"
            )
        defaults = {f.name: f.default for f in fields(self)}
        stressed = [
            f"{name}={getattr(self, name)!r}"
            for name in _DEMONSTRATION_STRESSES
            if getattr(self, name) != defaults[name]
        ]
        if self.observation == "option-ends":
            mixed = [s for s in stressed if not s.startswith("observation=")]
            if mixed:
                raise ValueError(
                    f"ExperimentConfig.observation='option-ends' watches the undisturbed mentor's "
                    f"option ends; it cannot be combined with {', '.join(mixed)}: leave those at "
                    "their defaults"
                )
        if self.mentor_goal != "same" and self.mentor_detour:
            raise ValueError(
                f"ExperimentConfig.mentor_goal={self.mentor_goal!r}: a mentor demonstrating "
                "another goal takes no detour to the learner's; set mentor_detour=False"
            )
        if self.mentor_model == "exact" and stressed:
            raise ValueError(
                f"ExperimentConfig.mentor_model='exact' is the undisturbed mentor's exact model; "
                f"it cannot show {', '.join(stressed)}: use mentor_model='learned' (the "
                "demonstrations' counts)"
            )
        if self.goal_needs_primitives:
            for size in self.sizes:
                try:
                    primitives_only_goal(size, size // self.room_size)
                except ValueError as err:
                    raise ValueError(f"ExperimentConfig.goal_needs_primitives: {err}") from None

    def check_size(self) -> None:
        """Refuse, before anything runs, a world of this experiment that would not fit in memory
        (:func:`himit_torch.validation.check_memory`), not hours later when its turn comes."""
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
        # a detour's first leg has its own
        mentors = 2 if self.mentor_detour or self.second_mentor == "detour" else 1
        return (
            S * MultiRooms.BYTES_PER_STATE
            + (1 + mentors) * options * S * BYTES_PER_OPTION_STATE
            + batch * (S * Learner.BYTES_PER_RUN_STATE + rows * Learner.BYTES_PER_RUN_ROW)
        )

    def world(self, size: int) -> MultiRooms:
        rooms = size // self.room_size
        return MultiRooms(
            size=size,
            rooms=rooms,
            slip=self.slip,
            goal=primitives_only_goal(size, rooms) if self.goal_needs_primitives else None,
            closed_doorways=maze_doorways(size, rooms) if self.layout == "maze" else (),
        )

    def stresses(self) -> dict[str, object]:
        """The stress settings (:data:`STRESS_SETTINGS`) that differ from their defaults."""
        default = ExperimentConfig()
        return {
            name: getattr(self, name)
            for name in STRESS_SETTINGS
            if getattr(self, name) != getattr(default, name)
        }

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


def load_config(path: str | os.PathLike) -> ExperimentConfig:
    """An :class:`ExperimentConfig` from a JSON file (as saved in a run directory;
    :func:`~himit_torch.runs.study.read_config_file`).

    Raises:
        ValueError: the file is missing or not a valid configuration; the message names it."""
    return read_config_file(ExperimentConfig, path)
