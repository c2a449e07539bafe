"""Every run's frozen greedy policy, evaluated exactly while a batch learns.

A :class:`GreedyTracker`, a window hook of :func:`~himit_torch.runs.runner.run_windows`, freezes
each run's greedy policy every ``every`` steps and at the run's end
(:meth:`learner.views.greedy_policy <himit_torch.LearnerViews.greedy_policy>`: ε = 0 over its own
options, ties as configured) and evaluates it on the world's true model
(:class:`~himit_torch.exact.greedy_evaluation.PolicyEvaluator`: goals per window, the share of
start states from which it is sure to reach the goal, and at the end ``V^π(start)``), as a
percentage of the optimum's and of the mentor's own goal rate (both evaluated the same way).
The evaluations go to TensorBoard (``eval/…``), to ``curves.csv`` (:data:`CURVE_COLUMNS`, empty
between evaluations), to the run's summary, and into checkpoints, so a resumed run reports what
an uninterrupted one does.

States where a run has tried none of its options follow the ``"uniform"`` rule (as the learner
acts: any option available there; :data:`~himit_torch.exact.greedy_evaluation.UNTRIED_RULES`).
The final policy is also evaluated under ``"stuck"`` (such states never left:
:attr:`GreedyTracker.stuck`), so a summary can say how much of its goal rate rests on chance
moves where the run knows nothing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import torch

from himit_torch.exact.greedy_evaluation import PolicyEvaluation, PolicyEvaluator
from himit_torch.learner.learner import Learner
from himit_torch.state_checks import DamagedState, in_range, section, tensor_of
from himit_torch.viz.tensorboard import TensorBoardLogger

__all__ = ["GreedyTracker", "GreedyReference", "CURVE_COLUMNS"]

#: The columns a tracker adds to ``curves.csv`` (empty where the window had no evaluation).
CURVE_COLUMNS = (
    "greedy_goals_per_window",
    "greedy_pct_optimal",
    "greedy_pct_mentor",
    "greedy_reach_share",
)

#: Round-off an exact evaluation's solve may leave beyond a range's bounds.
_ROUND_OFF = 1e-6
_LARGEST = float(torch.finfo(torch.float64).max)
#: Each field's ``(low, high, meaning)`` in a checkpoint (``goals_per_window``'s ``high`` is per
#: step of the window: at most one goal a step); ``value_start`` may also be NaN (not solved).
_RANGES = {
    "value_start": (-_LARGEST, _LARGEST, "a finite value, or NaN where it was not solved"),
    "goal_probability": (-_ROUND_OFF, 1 + _ROUND_OFF, "a probability"),
    "steps_per_episode": (0.0, math.inf, "expected steps ≥ 0, inf where an episode may not end"),
    "goals_per_window": (-_ROUND_OFF, 1 + _ROUND_OFF, "goals per window, at most one a step"),
    "reach_share": (-_ROUND_OFF, 1 + _ROUND_OFF, "a share of the start states"),
}
_FIELDS = tuple(_RANGES)  # a checkpoint's fields


@dataclass(frozen=True)
class GreedyReference:
    """The goal rates a greedy policy is compared with: the optimum's (exact planning over
    primitive actions) and the mentor's own (its policy over its own options), per window."""

    optimal: PolicyEvaluation
    mentor: PolicyEvaluation

    @property
    def optimal_goals_per_window(self) -> float:
        return float(self.optimal.goals_per_window[0])

    @property
    def mentor_goals_per_window(self) -> float:
        return float(self.mentor.goals_per_window[0])


@dataclass
class GreedyTracker:
    """Exact evaluations of a batch's greedy policies at the ends of the windows
    that reach ``every, 2·every, …`` and at ``steps`` (``every = 0``: at the end only);
    ``V^π(start)`` at the end only unless ``values`` (it doubles the cost).

    Args:
        evaluator: over the learner's options, in its world, with the window of its curves.
        reference: the optimum's and the mentor's rates.
        logger: where the ``eval/…`` scalars go (``None``: nowhere).

    ``evaluations``: step → evaluation under the ``"uniform"`` rule (checkpointed); ``stuck``: the
    final policy under the ``"stuck"`` rule, set by :meth:`finish`."""

    evaluator: PolicyEvaluator
    reference: GreedyReference
    every: int
    steps: int
    logger: TensorBoardLogger | None = None
    values: bool = False
    evaluations: dict[int, PolicyEvaluation] = field(default_factory=dict)
    stuck: PolicyEvaluation | None = None

    def __call__(self, learner: Learner, index: int) -> None:
        """The window hook: evaluate if window ``index`` ends now on the schedule."""
        step = int(learner.metrics.steps[index])
        if step == learner.views.t and self.due(step, learner.config.window):
            self.evaluate(learner)

    def due(self, step: int, window: int) -> bool:
        """Whether the schedule evaluates at ``step``, the end of a window of
        ``window`` steps (the window that reaches a multiple of ``every``, and the run's end)."""
        return (self.every > 0 and step // self.every > (step - window) // self.every) or (
            step == self.steps
        )

    def finish(self, learner: Learner) -> PolicyEvaluation:
        """The evaluation at the run's end (done now unless a window hook already did); also
        the final policy's under the ``"stuck"`` rule, into :attr:`stuck`."""
        if learner.views.t not in self.evaluations:
            self.evaluate(learner)
        # Computed from the learner's final state and not checkpointed: a resumed run ends in the
        # same state as an uninterrupted one, so it gets the same answer. Its goal rates are what
        # the summaries report (its values are not solved: V = 0 where a run is stuck).
        self.stuck = self.evaluator.evaluate(
            learner.views.greedy_policy(untried="stuck"), values=False
        )
        return self.evaluations[learner.views.t]

    def evaluate(self, learner: Learner) -> PolicyEvaluation:
        """Evaluate every run's greedy policy now (``"uniform"`` rule), record and log it."""
        step = learner.views.t
        result = self.evaluator.evaluate(
            learner.views.greedy_policy(), values=self.values or step >= self.steps
        )
        self.evaluations[step] = result
        if self.logger is not None:
            tags = {
                "eval/greedy_goals_per_window": result.goals_per_window,
                "eval/greedy_percent_of_optimal": self.percent_of_optimal(result),
                "eval/greedy_percent_of_mentor": self.percent_of_mentor(result),
                "eval/greedy_reach_share": result.reach_share,
                "eval/greedy_value_start": result.value_start,
            }
            lists = {tag: values.tolist() for tag, values in tags.items()}
            for b in range(len(result)):
                finite = {tag: v[b] for tag, v in lists.items() if math.isfinite(v[b])}
                self.logger.scalars(b, finite, step)
        return result

    def percent_of_optimal(self, result: PolicyEvaluation) -> torch.Tensor:
        return result.percent_of(self.reference.optimal_goals_per_window)

    def percent_of_mentor(self, result: PolicyEvaluation) -> torch.Tensor:
        return result.percent_of(self.reference.mentor_goals_per_window)

    def curve_cells(self, step: int, run: int) -> list[str]:
        """The :data:`CURVE_COLUMNS` cells of ``run`` at the window ending at ``step``."""
        result = self.evaluations.get(int(step))
        if result is None:
            return [""] * len(CURVE_COLUMNS)
        return [
            f"{float(result.goals_per_window[run]):.3f}",
            f"{float(self.percent_of_optimal(result)[run]):.2f}",
            f"{float(self.percent_of_mentor(result)[run]):.2f}",
            f"{float(result.reach_share[run]):.3f}",
        ]

    # ---------------------------------------------------------------------------- checkpoints
    def state_dict(self) -> dict:
        steps = sorted(self.evaluations)
        return {
            "steps": steps,
            **{f: [getattr(self.evaluations[s], f).clone() for s in steps] for f in _FIELDS},
        }

    def load_state_dict(self, state: dict, learner: Learner | None = None) -> None:
        """Restore the evaluations of a checkpoint (one from before
        trackers existed holds none). Everything is checked before anything is kept
        (:class:`~himit_torch.state_checks.DamagedState` naming the field): distinct increasing steps
        on the schedule (:meth:`due`), none past ``steps`` or the restored ``learner``'s step; per
        field one float64 ``[B]`` tensor per step (``B`` the learner's batch); each value in its range
        (``_RANGES``; never a NaN rate)."""
        state = section(state, "greedy", ("steps", *_FIELDS))
        steps = state["steps"]
        last = self.steps if learner is None else min(self.steps, int(learner.views.t))
        if (
            type(steps) is not list
            or any(type(s) is not int or not 1 <= s <= last for s in steps)
            or any(a >= b for a, b in zip(steps, steps[1:]))
        ):
            reached = "" if learner is None else f", the step this checkpoint reached, {last}"
            raise DamagedState(
                "greedy.steps",
                f"is not a list of distinct step numbers in increasing order, each in 1…{last} "
                f"(the run's length{reached})",
            )
        window = int(self.evaluator.window)
        off = [s for s in steps if s != self.steps and (s % window or not self.due(s, window))]
        if off:
            raise DamagedState(
                "greedy.steps",
                f"holds {off[:5]}, off this tracker's schedule (every={self.every} in windows of "
                f"{window} steps, and the end, {self.steps})",
            )
        batch = None if learner is None else int(learner.batch)
        for f, (low, high, meaning) in _RANGES.items():
            values = state[f]
            if type(values) is not list or len(values) != len(steps):
                raise DamagedState(f"greedy.{f}", f"is not a list of {len(steps)} tensors")
            high = high * window if f == "goals_per_window" else high
            for i, value in enumerate(values):
                where = f"greedy.{f}[{i}]"
                tensor_of(value, where, torch.float64, (batch,))
                batch = value.shape[0]
                solved = ~value.isnan() if f == "value_start" else None
                in_range(value, where, low, high, meaning, solved)
        self.evaluations = {
            s: PolicyEvaluation(
                **{f: state[f][i].clone() for f in _FIELDS}, window=self.evaluator.window
            )
            for i, s in enumerate(steps)
        }
