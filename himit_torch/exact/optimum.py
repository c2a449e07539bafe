"""The optimum a world's runs are measured against, computed once: the optimal policy over
primitive actions (exact option models → SMDP value iteration), its expected steps from start to
goal and its exact evaluation over windows (:func:`primitive_optimum`); and the same for any
option set (:func:`option_optimum`, e.g. the learner's, for ``himit info``)."""

from __future__ import annotations

from dataclasses import dataclass

from himit_torch.exact.greedy_evaluation import (
    OptionPolicy,
    PolicyEvaluation,
    PolicyEvaluator,
    optimal_policy_evaluation,
)
from himit_torch.exact.option_models import OptionModels, option_models_and_durations
from himit_torch.exact.planning import PlanResult, expected_steps, smdp_value_iteration
from himit_torch.options.builders import primitive_options
from himit_torch.options.bundle import Options

__all__ = ["PrimitiveOptimum", "primitive_optimum", "option_optimum"]


@dataclass(frozen=True)
class PrimitiveOptimum:
    """The optimal policy over primitive actions of a world, exact (true model)."""

    models: tuple[OptionModels, OptionModels]
    """The primitive options' exact ``(discounted, durations)`` models."""
    plan: PlanResult
    """SMDP value iteration on them (tolerance 1e-10; ties to the lowest action)."""
    steps_to_goal: float
    """Expected primitive steps from the start state to a terminal state (slips included)."""
    evaluation: PolicyEvaluation
    """The optimal policy's exact evaluation over windows of ``window`` steps (one run): its
    goal rate, and ``value_start``, the exact value of the policy value iteration found (so an
    optimal greedy policy's value gap is 0 to round-off)."""

    start_state: int
    """The world's start state."""

    @property
    def value_start(self) -> float:
        """``V*(start)`` as value iteration reports it."""
        return float(self.plan.values[self.start_state])


def primitive_optimum(world, window: int) -> PrimitiveOptimum:
    """:class:`PrimitiveOptimum` of ``world`` (any world :func:`~himit_torch.primitive_options`
    accepts), its policy evaluated over windows of ``window`` steps: the models once, for the
    steps, ``V*`` and the evaluation."""
    models = option_models_and_durations(world, primitive_options(world))
    plan = smdp_value_iteration(models[0])
    steps = expected_steps(models[1], plan.policy, world.start_state, world.terminal_mask)
    evaluation = optimal_policy_evaluation(world, window, models=models, plan=plan)
    return PrimitiveOptimum(models, plan, float(steps), evaluation, int(world.start_state))


def option_optimum(world, options: Options, window: int) -> PolicyEvaluation:
    """The exact evaluation (one run, goal rate and steps per episode; ``value_start`` left
    NaN) of the optimal policy over ``options``, over windows of ``window`` steps."""
    models = option_models_and_durations(world, options)
    policy = smdp_value_iteration(models[0]).policy
    evaluator = PolicyEvaluator(world, options, window, models=models)
    return evaluator.evaluate(OptionPolicy.deterministic(policy), values=False)
