"""``himit run puzzlebox``: Whiten et al.'s (2006) three findings, run on the model.

The box (:class:`~himit_torch.PuzzleBox`), the learner's skills and the mentor's
(:mod:`himit_torch.options.puzzle_box`), and mentors of either organisation with the state
mapping of footnote 2 (:mod:`himit_torch.mentor.puzzle_box`). Three experiments, each a set of
learner batches of ``seeds`` runs (one batch per condition, every seed watching its own mentor
episodes):

(a) **Speed** (``skewers``-skewer box, ``steps`` steps): ``imitation`` (options + the mentor term
    of eq. 2) against ``options`` (the same options, no mentor) and ``primitives``. Endpoints,
    declared here before any run: the step of the first opening; openings per window (the last
    window's); the exact value ``V^π(start)`` of the run's greedy option policy on the true model
    (every ``eval_every`` steps and at the end; :func:`greedy_values`).

(b) **Copying the organisation** (the same runs): seed ``s`` watches a skewer-by-skewer mentor
    when ``s − first_seed`` is even, a step-by-step one when it is odd. Endpoints: the share of
    imitators whose greedy policy, read without slips (:func:`greedy_plan`), follows the
    organisation it watched, against the share of non-imitators (``options`` runs, which watched
    nothing) that follow the organisation its seed's imitator watched; the share of steps the
    greedy policy does with the mentor's grip (pinch), and the share of runs whose whole
    low-level sequence is the mentor's.

(c) **A new element** (``transfer_skewers``-skewer box, ``transfer_steps`` steps): the mentor's
    episodes come from the ``skewers``-skewer box (the same episodes as in (a)), mapped into the
    larger box (:func:`~himit_torch.mentor.puzzle_box.map_demonstrations`): ``plain`` (the extra
    skewers stay in) and ``any`` (the mentor's box seen in any ``skewers`` of the learner's
    skewers, the others at any level), against ``options`` without demonstrations. Endpoints:
    the first opening; the share of imitators whose greedy policy follows the watched
    organisation over *all* skewers, the new ones included (assimilation); openings per window.

A run directory holds ``config.json``, ``curves.csv`` (per batch, run and window: openings, ε,
greedy value where evaluated), ``batches/<batch>.json`` (per run: first opening, the greedy
plan, its organisation), ``checkpoints/``, ``tb/`` (TensorBoard), ``figures/`` and
``results.md`` (:mod:`himit_torch.runs.puzzle_box_report`).
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterator
from dataclasses import asdict, dataclass, field, replace
from functools import cached_property
from pathlib import Path
from typing import Any, ClassVar

import torch

from himit_torch.exact.greedy_evaluation import PolicyEvaluator, evaluate_option_choice
from himit_torch.exact.optimum import PrimitiveOptimum, primitive_optimum
from himit_torch.exact.option_models import option_durations
from himit_torch.exact.planning import expected_steps, optimal_baseline
from himit_torch.learner.config import LearnerConfig
from himit_torch.learner.learner import Learner
from himit_torch.mentor.demonstrations import Demonstrations
from himit_torch.mentor.policy import record_demonstrations
from himit_torch.mentor.puzzle_box import map_demonstrations, organisation_mentor
from himit_torch.options.bundle import Options
from himit_torch.options.puzzle_box import intended_rollout, puzzle_box_options
from himit_torch.runs.checkpoints import BatchShape
from himit_torch.runs.runner import (
    Checkpoints,
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
    RunConfig,
    StudyEntry,
    option_kinds_text,
    read_record,
    read_table,
    run_each,
    run_study,
    series_of,
    write_rows,
)
from himit_torch.validation import check_memory, parse_document, read_text, setting
from himit_torch.viz.tensorboard import TensorBoardLogger
from himit_torch.worlds.puzzle_box import (
    ORGANISATIONS,
    PuzzleBox,
    organisation_of,
    organisation_scores,
    puzzle_box_size,
)

__all__ = [
    "PuzzleBoxConfig",
    "SPEED_CONDITIONS",
    "TRANSFER_CONDITIONS",
    "watched_organisation",
    "watched_episodes",
    "greedy_values",
    "greedy_plan",
    "run_puzzle_box",
    "PuzzleBoxStudy",
    "PreparedBox",
    "run_box_batch",
    "puzzle_box_run_command",
    "recorded_run_command",
    "VARIANTS",
]

#: Experiment (a)/(b): condition → learner agent (``himit_torch.AGENTS``).
SPEED_CONDITIONS = {"imitation": "imitation", "options": "options", "primitives": "primitives"}
#: Experiment (c): condition → agent; ``plain`` and ``any`` are the state mappings.
TRANSFER_CONDITIONS = {"options": "options", "plain": "imitation", "any": "imitation"}
#: Variants of experiment (b) (:attr:`PuzzleBoxConfig.variants`).
VARIANTS = ("harder_pinch", "no_pinch")


def _default_learner() -> LearnerConfig:
    """The paper experiments' learner settings (plan every 4 ticks, one round)."""
    return LearnerConfig(plan_every=4, sweep_rounds=1, window=5000)


@dataclass
class PuzzleBoxConfig(RunConfig):
    """Settings of ``himit run puzzlebox`` (module docstring); the cross-field
    rules follow the declared ones."""

    name: str = RunConfig.shared("name", "puzzlebox")
    skewers: int = setting(
        4,
        ge=2,
        le=5,
        doc="Skewers of the box of (a) and (b), and of the mentor's box in (c) (the study: 4).",
    )
    transfer_skewers: int = setting(
        5,
        ge=2,
        le=5,
        hint="6 skewers: 357,000 states",
        doc="Skewers of the learner's box in (c) (the study's test box: 5).",
    )
    seeds: int = RunConfig.shared(
        "seeds", 20, doc="Runs per condition (half watch each organisation)."
    )
    first_seed: int = RunConfig.shared("first_seed", 0)
    steps: int = RunConfig.shared("steps", 100_000, doc="Primitive steps per run in (a) and (b).")
    transfer_steps: int = setting(300_000, ge=1, doc="Primitive steps per run in (c).")
    mentor_episodes: int = RunConfig.shared(
        "mentor_episodes", 20, doc="Mentor episodes (states only) per seed."
    )
    slip: float = setting(
        0.1, ge=0.0, lt=1.0, doc="Probability that a movement fails, with either grip."
    )
    pinch_slip: float | None = setting(
        None,
        ge=0.0,
        lt=1.0,
        doc="""
        Failure probability of the mentor's grip, the pinch (None: ``slip``, both grips equally
        good: the main design).""",
    )
    harder_pinch: float = setting(
        0.2,
        ge=0.0,
        lt=1.0,
        doc="Failure probability of the pinch in (b)'s ``harder_pinch`` variant.",
    )
    variants: tuple[str, ...] = setting(
        ("harder_pinch", "no_pinch"),
        choices=VARIANTS,
        empty=True,
        doc="""
        (b) again, imitation and options on the ``skewers``-skewer box, with :data:`VARIANTS`:
        ``harder_pinch`` — the mentor's pinch fails ``harder_pinch`` of the time (its movements
        a little worse than the learner's own); ``no_pinch`` — the learner has no pinch grip (it
        cannot pass through the mentor's states between subgoals: only its subgoals can be
        copied). Empty: (b) on the main design only.""",
    )
    window: int = RunConfig.shared(
        "window", 5000, doc="Openings are counted per window of this many steps."
    )
    eval_every: int = setting(
        10_000,
        ge=1,
        doc="""
        The greedy policies' exact values are computed every this many steps (a multiple of the
        window) and at the end, in (a)/(b); in (c) every ``3 · eval_every`` (a 5-skewer box has
        50,000 states).""",
    )
    checkpoint_every: int = setting(
        50_000, ge=1, doc="Save the whole state every this many steps (a multiple of the window)."
    )
    engine: str = RunConfig.shared("engine", "auto")
    learner: LearnerConfig = RunConfig.shared("learner", default_factory=_default_learner)
    preset: str | None = RunConfig.shared("preset", None)

    def __post_init__(self):
        self.check_run_settings()
        if not self.skewers <= self.transfer_skewers:
            raise ValueError(
                f"PuzzleBoxConfig.skewers={self.skewers!r}: must be ≥ 2 and ≤ transfer_skewers "
                f"({self.transfer_skewers})"
            )
        for name in ("eval_every", "checkpoint_every"):
            if getattr(self, name) % self.window:
                raise ValueError(
                    f"PuzzleBoxConfig.{name}={getattr(self, name)!r}: must be a positive "
                    f"multiple of the window ({self.window})"
                )

    def check_size(self) -> None:
        """Refuse, before anything runs, a configuration whose batches
        would not fit in memory (each box's batch counted at its least, one row per state;
        :func:`himit_torch.validation.check_memory`)."""
        for skewers in (self.skewers, self.transfer_skewers):
            states = puzzle_box_size(skewers)
            check_memory(
                f"PuzzleBoxConfig: a batch of {self.seeds:,} runs on the {skewers}-skewer box "
                f"({states:,} states)",
                self.seeds * states * (Learner.BYTES_PER_RUN_STATE + Learner.BYTES_PER_RUN_ROW),
                "use fewer seeds",
            )

    def quick(self) -> PuzzleBoxConfig:
        """A tiny budget on small boxes (2 and 3 skewers; smoke tests, ``--quick``)."""
        return replace(
            self,
            skewers=2,
            transfer_skewers=3,
            seeds=min(self.seeds, 2),
            steps=2 * self.window,
            transfer_steps=2 * self.window,
            mentor_episodes=min(self.mentor_episodes, 3),
            eval_every=self.window,
            checkpoint_every=self.window,
        )


def puzzle_box_run_command(
    config: PuzzleBoxConfig, run_dir: str | os.PathLike | None = None
) -> str | None:
    """The ``himit run puzzlebox`` command that rebuilds ``config`` exactly, or None where none
    can (its other settings are the scripts')."""
    return ENTRY.run_command(config, run_dir)


def recorded_run_command(run_dir: str | os.PathLike) -> str | None:
    """:func:`puzzle_box_run_command` of the configuration a finished run directory's
    ``summary.json`` records (None where it no longer builds one: an older record)."""
    from himit_torch.runs.puzzle_box_report import read_summary

    recorded = {k: v for k, v in read_summary(Path(run_dir))["config"].items() if k != "box_steps"}
    try:
        config = PuzzleBoxConfig(**recorded)
    except (TypeError, ValueError):
        return None
    return puzzle_box_run_command(config, run_dir)


def watched_organisation(seed: int, first_seed: int = 0) -> str:
    """The organisation seed ``seed``'s mentor shows: skewer by skewer for even ``seed −
    first_seed``, step by step for odd."""
    return ORGANISATIONS[(int(seed) - int(first_seed)) % 2]


# ================================================================================ evaluation
def greedy_values(evaluator: PolicyEvaluator, learner: Learner) -> list[float]:
    """``V^π(start)`` of every run's frozen greedy policy
    (:meth:`learner.views.greedy_policy <himit_torch.LearnerViews.greedy_policy>`), exact on the
    true model: the same frozen policy as every study's greedy endpoint (ties as ``tie_break``
    says; an untried state: any of its options, uniformly). Runs before this definition are not
    comparable."""
    return evaluator.evaluate(learner.views.greedy_policy(), values=True).value_start.tolist()


def greedy_plan(
    box: PuzzleBox, options: Options, policy: torch.Tensor, focus: int | None = None
) -> dict[str, Any]:
    """What a greedy option policy ``policy [S]`` does from the start when nothing
    slips (:func:`~himit_torch.options.puzzle_box.intended_rollout`): whether it opens the box, its
    steps in order (``"i.j"``: skewer ``i``, step ``j``), their organisation and scores (with
    ``focus``, also for that skewer alone), its grips, where it gets stuck, and its states."""
    states, opened = intended_rollout(box, options, policy)
    advances = box.subgoals(states)
    grips = box.grasps_used(states)
    stuck = None
    if not opened:
        last = int(states[-1])
        option = int(policy[last])
        progress, at, grasp = box.decode(last)
        hand = "home" if at is None else f"at skewer {at + 1}, {grasp}"
        stuck = f"{list(progress)}, hand {hand}: " + (
            options.names[option] if option >= 0 else "nothing tried"
        )
    return {
        "opens": opened,
        "steps_taken": int(states.numel() - 1),
        "subgoals": [f"{i + 1}.{j}" for i, j in advances],
        "organisation": organisation_of(advances, box.skewers, box.steps)
        if opened
        else "incomplete",
        "scores": _scores(organisation_scores(advances, box.skewers, box.steps)),
        "focus_scores": None
        if focus is None
        else _scores(organisation_scores(advances, box.skewers, box.steps, focus)),
        "pinch_steps": grips.count("pinch"),
        "power_steps": grips.count("power"),
        "stuck_at": stuck,
        "states": states.tolist(),
    }


# ================================================================================ one batch
@dataclass
class PreparedBox:
    """A box and what every batch on it shares: its learner options and, computed when first
    asked for and then kept, its exact references (the evaluator, ``V*(start)``, the optimal
    steps to open it; the exact models of the 5-skewer box take ≈ 15 s, which a batch with
    options of its own never needs); :func:`run_box_batch` runs a condition's batch on it."""

    world: PuzzleBox
    options: Options

    @classmethod
    def build(
        cls, skewers: int, slip: float, pinch_slip: float | None, pinch: bool = True
    ) -> PreparedBox:
        """The box of ``skewers`` skewers with these slips and its learner options
        (``pinch=False``: without the pinch grip)."""
        world = PuzzleBox(skewers, slip=slip, pinch_slip=pinch_slip)
        return cls(world, puzzle_box_options(world, "learner", pinch=pinch))

    @cached_property
    def evaluator(self) -> PolicyEvaluator:
        """The exact evaluator of policies over the learner options (the box's values only:
        its window, for goal rates, is unused)."""
        return PolicyEvaluator(self.world, self.options, window=1)

    @cached_property
    def optimum(self) -> PrimitiveOptimum:
        """The optimum over primitives: its expected steps to open the box, and its policy's
        exact value (:attr:`value_star`)."""
        return primitive_optimum(self.world, window=1)

    @property
    def value_star(self) -> float:
        """``V*(start)``: the exact value of the optimal policy, so that an optimal greedy
        policy's gap is 0 to round-off."""
        return float(self.optimum.evaluation.value_start[0])


def run_box_batch(
    config: PuzzleBoxConfig,
    box: PreparedBox,
    tag: str,
    condition: str,
    agent: str,
    demos: dict[int, Demonstrations] | None,
    steps: int,
    eval_every: int,
    run_dir: Path,
    resume: bool,
    progress: bool,
    mentor_plans: dict[str, list[int]],
    focus: int | None = None,
) -> dict[str, Any]:
    """One condition's runs on one box: ``agent`` on ``config``'s seeds for
    ``steps`` steps, every seed watching its own ``demos`` (``None``: none), its greedy policies
    evaluated exactly every ``eval_every`` steps. Returns the batch's summary, also in
    ``run_dir/batches/<tag>.json`` (rows: ``<tag>.csv``).

    Args:
        tag: the batch's name (its files, checkpoint and TensorBoard runs).
        condition: the condition's label in the records.
        resume: continue from the batch's checkpoint and evaluations in ``run_dir``.
        mentor_plans: organisation → the mentor's states when nothing slips; ``{}``: not
            compared.
        focus: also score the organisation for skewer ``focus`` alone (:func:`greedy_plan`)."""
    seeds = config.seed_list
    learner, checkpoints, elapsed = _batch_learner(config, box, agent, demos, run_dir, tag, resume)
    evals_path = run_dir / "batches" / f"{tag}.evals.json"
    evals = _saved_evaluations(evals_path, len(seeds), learner.views.t) if resume else {}
    paired = [watched_organisation(s, config.first_seed) for s in seeds]
    names = run_names(tag, [condition] * len(seeds), seeds)
    resume_step = learner.views.t if resume else None
    logger = TensorBoardLogger(
        run_dir / "tb", names, true_value_start=box.value_star, resume_step=resume_step
    )
    evaluate = _Evaluations(box, evals, evals_path, paired, logger, eval_every, steps, focus)
    evals_path.parent.mkdir(parents=True, exist_ok=True)
    wall = run_windows(
        learner,
        steps,
        on_window=[logger.window, evaluate],
        logger=logger,
        checkpoints=checkpoints,
        progress=f"{tag} B={learner.batch}" if progress else None,
        elapsed=elapsed,
    )
    runs = _final_runs(config, box, learner, evals, demos, mentor_plans, focus)
    summary = _batch_summary(box, tag, condition, agent, learner, wall, runs)
    _close_logger(logger, condition, box.world.skewers, runs, learner.views.t)
    rows = _window_rows(config, tag, condition, learner, evals, demos is not None)
    write_rows(run_dir / "batches" / f"{tag}.csv", _COLUMNS, rows)
    write_atomically(run_dir / "batches" / f"{tag}.json", json.dumps(summary, indent=1))
    return summary


def _batch_learner(
    config: PuzzleBoxConfig,
    box: PreparedBox,
    agent: str,
    demos: dict[int, Demonstrations] | None,
    run_dir: Path,
    tag: str,
    resume: bool,
) -> tuple[Learner, Checkpoints, float]:
    """A batch's learner (``agent`` on every seed, each watching its ``demos``), its
    checkpoints, and the wall time its runs already took (resumed: from the checkpoint)."""
    seeds = config.seed_list
    learner = Learner(
        box.world,
        box.options,
        [agent] * len(seeds),
        seeds,
        config=config.learner,
        engine=config.engine,
    )
    if demos is not None:
        watch_demonstrations(learner, demos)
    checkpoints = Checkpoints(
        run_dir / "checkpoints" / f"{tag}.pt",
        BatchShape((agent,) * len(seeds), tuple(seeds), box.world.num_states),
        config.checkpoint_every,
    )
    return learner, checkpoints, checkpoints.start(learner, resume)


def _close_logger(logger: TensorBoardLogger, condition, skewers, runs, t: int) -> None:
    """Each run's hyperparameters and final metrics, then close the batch's logger."""
    logger.hparams(
        [{"condition": condition, "skewers": skewers} for _ in runs],
        [
            {
                "hparam/total_goals": float(r["openings"]),
                "hparam/first_goal_step": float(
                    r["first_opening"] if r["first_opening"] >= 0 else t + 1
                ),
            }
            for r in runs
        ],
        t,
    )
    logger.close()


def _batch_summary(box, tag, condition, agent, learner, wall, runs) -> dict[str, Any]:
    """A finished batch's record (``batches/<tag>.json``)."""
    return {
        "batch": tag,
        "skewers": box.world.skewers,
        "num_states": box.world.num_states,
        "condition": condition,
        "agent": agent,
        "steps": learner.views.t,
        "value_star": box.value_star,
        "optimal_steps": box.optimum.steps_to_goal,
        "engine": learner.engine.name,
        "wall_seconds": wall,
        "runs": runs,
    }


def _saved_evaluations(path: Path, runs: int, t: int) -> dict[int, dict[str, list]]:
    """A resumed batch's saved evaluations up to its checkpoint's step ``t`` (none saved: ``{}``)."""
    if not path.exists():
        return {}
    return {k: v for k, v in read_evaluations(path, runs).items() if k <= t}


class _Evaluations:
    """The ``on_window`` hook of a batch: every ``eval_every`` steps and at the
    end, each run's greedy policy evaluated and its plan read (saved to ``evals_path``)."""

    def __init__(self, box, evals, evals_path, paired, logger, eval_every, steps, focus):
        self.box, self.evals, self.evals_path, self.paired = box, evals, evals_path, paired
        self.logger, self.eval_every, self.steps, self.focus = logger, eval_every, steps, focus

    def __call__(self, learner: Learner, index: int) -> None:
        box, paired = self.box, self.paired
        step = learner.metrics.steps[index]
        if step != learner.views.t or (step % self.eval_every and step != self.steps):
            return
        greedy = learner.views.greedy_options()  # the plans: ties to the lowest option
        values = greedy_values(box.evaluator, learner)
        plans = [
            greedy_plan(box.world, box.options, greedy[b], self.focus) for b in range(learner.batch)
        ]
        self.evals[step] = {
            "value": values,
            "organisation": [p["organisation"] for p in plans],
            "watched_score": [p["scores"][o] for p, o in zip(plans, paired)],
            "pinch_steps": [p["pinch_steps"] for p in plans],
        }
        for b, v in enumerate(values):
            self.logger.scalars(
                b,
                {
                    "eval/greedy_value_gap": box.value_star - v,
                    "eval/follows_watched": float(plans[b]["organisation"] == paired[b]),
                    "eval/pinch_steps": float(plans[b]["pinch_steps"]),
                },
                step,
            )
        write_atomically(self.evals_path, json.dumps(self.evals))


def _final_runs(config, box, learner, evals, demos, mentor_plans, focus) -> list[dict]:
    """Each run's record at the end: its first opening, openings, final greedy value and plan."""
    greedy = learner.views.greedy_options()
    runs = []
    for b, seed in enumerate(config.seed_list):
        plan = greedy_plan(box.world, box.options, greedy[b], focus)
        states = plan.pop("states")  # for the comparison: the subgoals say what a reader needs
        watched = watched_organisation(seed, config.first_seed)
        reference = mentor_plans.get(watched)
        runs.append(
            {
                "seed": seed,
                "watched": watched if demos is not None else None,
                "paired_organisation": watched,
                "first_opening": int(learner.views.first_goal_step[b]),
                "openings": int(learner.views.goals[b]),
                "final_window_openings": int(learner.metrics.goals_in_window[-1][b]),
                "greedy_value": evals[max(evals)]["value"][b] if evals else None,
                "mentor_term_wins": _finite(float(learner.views.mentor_win_share()[b])),
                "same_low_level_as_mentor": reference is not None and states == reference,
                **plan,
            }
        )
    return runs


def _window_rows(config, tag, condition, learner, evals, watching: bool) -> list[dict]:
    """The batch's rows of ``curves.csv``: per window and run."""
    m = learner.metrics
    return [
        {
            "batch": tag,
            "skewers": learner.world.skewers,
            "condition": condition,
            "seed": seed,
            "watched": watched_organisation(seed, config.first_seed) if watching else "",
            "step": step,
            "openings": int(m.goals_in_window[i][b]),
            "epsilon": float(m.epsilon[i][b]),
            "greedy_value": evals[step]["value"][b] if step in evals else "",
            "organisation": evals[step]["organisation"][b] if step in evals else "",
        }
        for i, step in enumerate(m.steps)
        for b, seed in enumerate(config.seed_list)
    ]


_COLUMNS = (
    "batch",
    "skewers",
    "condition",
    "seed",
    "watched",
    "step",
    "openings",
    "epsilon",
    "greedy_value",
    "organisation",
)


def _finite(x: float) -> float | None:
    return x if math.isfinite(x) else None


def _scores(scores: dict[str, float]) -> dict[str, float | None]:
    return {k: _finite(v) for k, v in scores.items()}


#: What each evaluation of a batch's ``*.evals.json`` holds: one value per run.
_EVALUATION = {
    "value": Field("list", per_run="number?"),
    "organisation": Field("list", per_run="text"),
    "watched_score": Field("list", per_run="number?"),
    "pinch_steps": Field("list", per_run="number?"),
}

#: What a finished batch's ``batches/<tag>.json`` holds for ``--resume``.
_BATCH_RECORD = {
    "batch": Field("text"),
    "skewers": Field("whole"),
    "condition": Field("text"),
    "agent": Field("text"),
    "steps": Field("whole"),
    "runs": Field("list", items={}),  # (one object per run)
}


def read_evaluations(
    path: Path, runs: int, command: str = "--resume"
) -> dict[int, dict[str, list]]:
    """A batch's saved greedy evaluations (``batches/<tag>.evals.json``), read
    for ``command`` (``--resume``; ``himit plot`` also wants one); a damaged file is a
    ``ValueError`` naming it."""
    where = f"{command}: {path}"
    data = parse_document(where, read_text(where, path), "json")
    if not isinstance(data, dict) or (command != "--resume" and not data):
        raise ValueError(f"{command}: {path} holds a {type(data).__name__}, not evaluations")
    out: dict[int, dict[str, list]] = {}
    for key, entry in data.items():
        if not (isinstance(key, str) and key.isdigit() and len(key) <= 12):
            raise ValueError(f"{command}: {path}: {key!r} is not a step; delete the file")
        if not isinstance(entry, dict) or any(
            f.fault(entry.get(k), runs) for k, f in _EVALUATION.items()
        ):
            raise ValueError(
                f"{where}: step {key} does not hold {', '.join(_EVALUATION)} "
                f"for each of the batch's {runs} runs; delete the file (the batch resumes "
                "without its earlier evaluations) or start over with --force"
            )
        out[int(key)] = entry
    return out


def read_batch(path: Path, tag: str) -> dict[str, Any]:
    """A finished batch's record (``batches/<tag>.json``), read for ``--resume``; a damaged
    file is a ``ValueError`` naming it (delete it and the batch runs again)."""
    where = f"--resume: {path}"
    fix = "; delete it to run the batch again, or start over with --force"
    data = read_record(path, where, _BATCH_RECORD, fix)
    if data["batch"] != tag:
        raise ValueError(f"{where} is batch {data['batch']!r:.60}, not {tag!r}{fix}")
    return data


# ================================================================================ the runner
@dataclass
class _Batches:
    """Runs the batches of one run directory in order (a finished one, on ``resume``, is read
    back instead) and keeps their summaries."""

    config: PuzzleBoxConfig
    run_dir: Path
    resume: bool
    progress: bool
    done: list[dict[str, Any]] = field(default_factory=list)

    def __call__(
        self, box: PreparedBox, tag, condition, agent, watched, steps, eval_every, plans, focus=None
    ) -> None:
        done = self.run_dir / "batches" / f"{tag}.json"
        if self.resume and done.exists():
            self.done.append(read_batch(done, tag))
            return
        self.done.append(
            run_box_batch(
                self.config, box, tag, condition, agent, watched, steps, eval_every,
                self.run_dir, self.resume, self.progress, plans, focus,
            )
        )  # fmt: skip


def watched_episodes(config: PuzzleBoxConfig, box: PuzzleBox, mentors: dict | None = None) -> dict:
    """Each seed's mentor episodes on ``box`` (``{seed: Demonstrations}``), from the mentor of
    the organisation it watches (:func:`watched_organisation`): ``mentors`` by organisation, or
    :func:`~himit_torch.mentor.puzzle_box.organisation_mentor`'s on ``box`` where None."""
    if mentors is None:
        mentors = {org: organisation_mentor(box, org) for org in ORGANISATIONS}
    return {
        s: record_demonstrations(
            box, mentors[watched_organisation(s, config.first_seed)], config.mentor_episodes, seed=s
        )
        for s in config.seed_list
    }


def _run_variants(config: PuzzleBoxConfig, batch: _Batches, demos: dict, plans: dict) -> None:
    """(b) again on each of :attr:`PuzzleBoxConfig.variants`' boxes, imitation and options."""
    for variant in config.variants:
        if variant == "harder_pinch":
            # the same mentors on a box where their pinch fails more often: their episodes again
            box = PreparedBox.build(config.skewers, config.slip, config.harder_pinch)
            demos_v = watched_episodes(config, box.world)
        else:  # the same box and episodes, a learner without the pinch
            box = PreparedBox.build(config.skewers, config.slip, config.pinch_slip, pinch=False)
            demos_v = demos
        for condition in ("imitation", "options"):
            watched = demos_v if condition == "imitation" else None
            batch(box, f"{variant}_{condition}", condition, condition, watched, config.steps,
                  config.eval_every, plans)  # fmt: skip


class PuzzleBoxStudy:
    """The puzzle box as a :class:`~himit_torch.runs.study.Study`: experiments
    (a)–(c), one batch per condition (finished ones read back on resume), then ``curves.csv`` and
    ``summary.json``; its report the figures and ``results.md``."""

    config_class: ClassVar[type] = PuzzleBoxConfig
    folders: ClassVar[tuple[str, ...]] = ("checkpoints", "tb", "batches", "figures")
    files: ClassVar[tuple[str, ...]] = ("results.md", "curves.csv", "config.json", "summary.json")

    def run(
        self, config: PuzzleBoxConfig, run_dir: Path, resume: bool, progress: bool
    ) -> dict[str, Any]:
        """Every batch of (a)–(c), then ``curves.csv`` and ``summary.json``; the summary."""
        small = PuzzleBox(config.skewers, slip=config.slip, pinch_slip=config.pinch_slip)
        mentors = {org: organisation_mentor(small, org) for org in ORGANISATIONS}
        demos = watched_episodes(config, small, mentors)
        batch = _Batches(config, run_dir, resume, progress)
        # each mentor's own plan (its states when nothing slips): a greedy plan through exactly
        # these states copies the mentor's movements, not only its subgoals
        plans = {
            org: intended_rollout(small, mentors[org].options, mentors[org].option)[0].tolist()
            for org in ORGANISATIONS
        }
        speed_box = PreparedBox.build(config.skewers, config.slip, config.pinch_slip)
        for condition, agent in SPEED_CONDITIONS.items():
            watched = demos if agent == "imitation" else None
            batch(speed_box, f"speed_{condition}", condition, agent, watched, config.steps,
                  config.eval_every, plans)  # fmt: skip
        del speed_box
        _run_variants(config, batch, demos, plans)
        big = PreparedBox.build(config.transfer_skewers, config.slip, config.pinch_slip)
        for condition, agent in TRANSFER_CONDITIONS.items():
            watched = (
                None
                if agent != "imitation"
                else {
                    s: map_demonstrations(d, small, big.world, condition) for s, d in demos.items()
                }
            )
            batch(big, f"transfer_{condition}", condition, agent, watched, config.transfer_steps,
                  3 * config.eval_every, {}, focus=config.skewers)  # fmt: skip
        parts = [run_dir / "batches" / f"{b['batch']}.csv" for b in batch.done]
        merge_csv(parts, run_dir / "curves.csv", newline="\n")
        summary = {
            "config": {**asdict(config), "box_steps": small.steps},
            "commit": source_commit(),
            "mentor_plans": {org: mentors_subgoals(small, plans[org]) for org in ORGANISATIONS},
            "batches": batch.done,
        }
        write_atomically(run_dir / "summary.json", json.dumps(summary, indent=1))
        return summary

    def report(self, config: PuzzleBoxConfig, run_dir: Path, summary: dict[str, Any]) -> None:
        """The figures and ``results.md``."""
        from himit_torch.runs.puzzle_box_report import (
            write_puzzle_box_figures,
            write_puzzle_box_results,
        )

        write_puzzle_box_figures(run_dir, summary)
        write_puzzle_box_results(run_dir, summary, puzzle_box_run_command(config, run_dir))


def run_puzzle_box(
    config: PuzzleBoxConfig,
    run_dir: str | os.PathLike,
    resume: bool = False,
    force: bool = False,
    progress: bool = True,
) -> dict[str, Any]:
    """Run experiments (a)–(c) of ``config`` into ``run_dir``, then its records,
    figures and ``results.md``. ``resume`` continues an interrupted run (finished batches are not
    rerun); a finished run is overwritten only with ``force``."""
    return run_study(
        PuzzleBoxStudy(),
        config,
        run_dir,
        resume=resume,
        force=force,
        progress=progress,
        check=lambda: config.check_size(),
    )


def mentors_subgoals(box: PuzzleBox, states: list[int]) -> list[str]:
    """The ``"i.j"`` steps along a mentor's states."""
    return [f"{i + 1}.{j}" for i, j in box.subgoals(states)]


# ================================================================ the command line's entry
def redraw(run_dir: Path) -> None:
    """``himit plot``: the figures and ``results.md`` of a finished run, from its records."""
    from himit_torch.runs.puzzle_box_report import read_summary, rewrite_puzzle_box_report

    if not (run_dir / "batches").is_dir():
        raise ValueError(
            f"{run_dir} is a puzzle-box run directory without its batches/ records: its page "
            "is redrawn from them (summary.json holds only the aggregates); put the batches/ "
            "folder back, or run it again with himit run puzzlebox"
        )
    _check_batch_records(run_dir, read_summary(run_dir))
    rewrite_puzzle_box_report(run_dir, recorded_run_command(run_dir))


def _check_batch_records(run_dir: Path, summary: dict) -> None:
    """Before ``himit plot`` draws anything: each batch's curves and
    evaluations are readable, else a ``ValueError`` naming the file."""
    fix = "; the record is damaged (run the study again, or restore the file)"
    for batch in summary["batches"]:
        tag, runs = batch["batch"], len(batch["runs"])
        path = run_dir / "batches" / f"{tag}.csv"
        where = f"himit plot: {path}"
        rows = read_table(path, where, ("seed", "step"), ("openings",), fix=fix)
        _, series = series_of(rows, "openings", where, fix)
        if len(series) != runs:
            raise ValueError(f"{where} holds {len(series)} runs' curves, not {runs}{fix}")
        read_evaluations(run_dir / "batches" / f"{tag}.evals.json", runs, "himit plot")


def _info_flags(parser) -> None:
    parser.add_argument(
        "--puzzle-box",
        type=int,
        metavar="K",
        help="the puzzle box with K skewers of 4 steps (Whiten et al.'s keyway-fruit box): its "
        "size and the optimal cost of each hierarchical organisation",
    )
    parser.add_argument(
        "--pinch-slip",
        type=float,
        help="--puzzle-box: failure probability of the mentor's pinch grip (default: --slip)",
    )


def _info(args) -> Iterator[str]:
    """``himit info --puzzle-box K``: the box's size, and the optimal cost of each hierarchical
    organisation by exact planning."""
    k = args.puzzle_box
    if k < 1 or k > 5:
        raise ValueError(f"--puzzle-box {k}: give 1 … 5 skewers (6: 357,000 states)")
    box = PuzzleBox(k, slip=args.slip, pinch_slip=args.pinch_slip)
    sizes = ", ".join(f"k={j}: {puzzle_box_size(j):,}" for j in range(2, 6))
    yield (
        f"world      {box.name}, slip {box.slip} (pinch {box.pinch_slip}), gamma {box.gamma}, "
        f"reward {box.step_reward} a movement and {box.goal_reward} when the box opens"
    )
    yield f"states     {box.num_states:,} ((n+1)^k · (1+3k); {sizes})"
    yield f"actions    {box.num_actions}: {', '.join(box.action_names)}"
    best = optimal_baseline(box)
    rows = [("optimal policy (value iteration)", best.steps_to_goal, best.value_start)]
    for style, grip in (("learner", "power"), ("mentor", "pinch")):
        options = puzzle_box_options(box, style)
        if style == "learner":
            yield f"learner    {options.num_options} options ({option_kinds_text(options)})"
        durations = option_durations(box, options)
        for org in ORGANISATIONS:
            policy = organisation_mentor(box, org, options=options).option
            steps = expected_steps(durations, policy, box.start_state, box.terminal_mask)
            value = float(evaluate_option_choice(box, options, policy, 1).value_start[0])
            rows.append((f"{org:>6} by {org}, {style}'s skills ({grip})", steps, value))
    yield ""
    yield "exact planning; organisations: skewer by skewer / step by step across skewers"
    width = max(len(name) for name, _, _ in rows) + 2
    yield f"{'':<{width}}{'steps to open':>15}{'V(start)':>12}"
    for name, steps, value in rows:
        yield f"{name:<{width}}{steps:>15.3f}{value:>12.6f}"


#: The registry entry of ``himit run puzzlebox`` (and ``himit info --puzzle-box``).
ENTRY = StudyEntry(
    "puzzlebox",
    "Whiten et al.'s keyway-fruit box: speed, copying the organisation, a new skewer "
    "(himit_torch.runs.puzzle_box; its batches run one after the other)",
    PuzzleBoxConfig,
    configs=lambda: (PuzzleBoxConfig(),),
    run=run_each(run_puzzle_box, resume=True),
    describe=lambda config, run_dir: (
        f"{config.name}: {config.skewers}- and {config.transfer_skewers}-skewer boxes, "
        f"{config.seeds} seeds per condition → {run_dir}"
    ),
    redraw=redraw,
    run_flags=("resume",),
    info=InfoTopic("puzzle_box", _info_flags, _info, requires=("pinch_slip",)),
    rerun_flags=("seeds", "steps", "engine"),
)
