"""The learner's settings (:class:`LearnerConfig`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import torch

from himit_torch.validation import as_choice, as_float, as_int

if TYPE_CHECKING:
    pass

__all__ = ["EPS_SCHEDULES", "LearnerConfig"]

#: ``LearnerConfig.eps_schedule`` values, in the order of their code in the compiled engine.
EPS_SCHEDULES = ("decision", "step", "goals", "paper")


@dataclass
class LearnerConfig:
    """Settings of the learner. Defaults follow the paper where it speaks (ε, γ from the world) and
    ``docs/reproduction-notes.md`` (what an earlier straightforward implementation showed) where
    it is silent."""

    backups: int = 10
    """Prioritized-sweeping backups per decision (the paper: about the number of options needed to
    reach the goal). The option's start state is always backed up first, within this budget."""
    sweep_rounds: int = 2
    """The backups of one planning step run in this many rounds; the states of one round (the
    highest priorities) are backed up together, and their changes propagate before the next
    round. ``sweep_rounds = backups`` is classic one-at-a-time sweeping (slowest)."""
    plan_every: int = 1
    """Sweep every this many ticks, for all runs that decided since the last sweep, with
    ``backups`` per decision they made, in ``sweep_rounds`` rounds of up to
    ``plan_every · backups / sweep_rounds`` states. 1 = plan at every decision (the paper's loop).
    Larger values trade a few ticks of planning delay for speed (fewer, larger tensor ops): a
    sweep after a decision at ``s`` updates ``s`` and the states *behind* it, not the state the
    next choice is made in. Models are still updated at every decision."""
    rng_chunk: int = 256
    """Per-run uniforms are drawn for this many ticks at once (speed only; results identical)."""
    priority_threshold: float = 1e-6
    """A state enters the sweeping queue only with a priority ``|ΔQ|`` above this."""
    initial_value: float = -1.0
    """Initial ``V`` of every non-terminal state, and the value of the prior's unseen outcome.
    −1 = step reward / (1 − γ), the value of never reaching the goal in the paper's worlds: a
    neutral start. 0 is optimistic there at most states (true values are negative
    except near the goal, up to the goal reward +1), which turns ε-greedy into systematic
    exploration."""
    untried_value: float | None = None
    """Value of an option never tried in a state: ``None`` leaves it out of the max (and out of
    greedy choice unless nothing was tried there); a number counts it with that ``Q`` (0 =
    the optimistic "Q = 0 for untried options" of a straightforward implementation)."""
    concentration: float = 0.0
    """Dirichlet prior mass of the option model on the unseen-successor outcome (0 = the
    maximum-likelihood model)."""
    mentor_concentration: float = 0.0
    """Same for the mentor model (only in states where the mentor was seen: the prior never
    creates a mentor term elsewhere)."""
    confidence_z: float = 1.0
    """Width of Price & Boutilier's confidence test, used by the ``…_confident`` agents: the
    mentor term at ``s`` counts only where its lower bound (mean − z·sd, from the Dirichlet
    variances) beats the upper bound (mean + z·sd) of every own option."""
    mentor_override_after: int | None = None
    """Ignore the mentor term at ``s`` once the run has executed its own options there this many
    times (own experience overrides the mentor); ``None`` = never."""
    mentor_fade: float | None = None
    """Shrink the mentor term towards the run's own estimate as its own experience grows (issue
    11, item 4): where some own option was tried at ``s``, eq. 2's mentor term ``m`` is replaced
    by ``(k·m + n·own) / (k + n)`` with ``k = mentor_fade``, ``n`` the own options executed from
    ``s`` and ``own`` the best own ``Q`` there — the mentor's evidence counts as ``k`` own
    executions, so the mentor's value leads early and the run's own value decides in the limit
    (no lasting upward bias). Where nothing own was tried, ``m`` is used as it is. ``None`` = no
    fading (the paper's eq. 2)."""
    eps_start: float = 0.75
    """ε until the run's first goal."""
    eps_decay: float = 0.999
    """After the first goal, ε is multiplied by this at every decision…"""
    eps_min: float = 0.01
    """…down to this floor."""
    eps_schedule: str = "decision"
    """When ε changes (every schedule starts at ``eps_start`` and never goes below ``eps_min``):

    * ``"decision"`` (default): ×``eps_decay`` at every decision (option choice) once the run has
      found the goal — the rule of the earlier implementation, not a statement of the paper.
    * ``"step"``: ×``eps_decay`` at every primitive step once the run has found the goal (the
      step of the first goal included).
    * ``"goals"``: ``eps_start`` until the run has reached ``eps_goals`` goals, then ``eps_min``
      at once (explore fully until the goal is known well, then exploit).
    * ``"paper"``: a literal reading of the paper (Sec. III: "ε begins at 0.75 and starts to
      decay to a minimum of 0.01 after the agent first finds the goal"). The paper names the start,
      the trigger (the first goal) and the floor, but neither the rate nor the unit of the decay;
      the one event its sentence names is finding the goal, so here ε is ×``eps_decay`` at every
      goal reached (episode end), the first included. With the default 0.999 ε stays near its
      start for thousands of goals: the rate is this reading's free parameter."""
    eps_goals: int = 10
    """Goals after which the ``"goals"`` schedule drops ε to ``eps_min`` (other schedules ignore
    it)."""
    option_models: str = "learned"
    """Where each run's option model comes from: ``"learned"`` (counts of its own executions, the
    paper) or ``"exact"``: before the first step every ``(s, o)`` row the run may use is preloaded
    with the exact model (:func:`~himit_torch.exact.option_models.option_models` and
    :func:`~himit_torch.exact.option_models.option_durations` of the world and options) as
    ``exact_model_count`` pseudo-executions in exact proportions — count ``N``, summed reward
    ``N·r(s,o)``, per successor ``N·Pr(s'|s,o)`` and ``N·P^o[s,s']`` — so every posterior mean
    is the exact model and the run's own executions move it by at most ``1/N``. Values are not
    solved: ``V`` starts at ``initial_value`` and the states whose backup would change their
    value are queued with that change as priority, so planning still runs on the usual budget.
    Preloaded rows count as tried (they are usable at once); ``state_tries`` stays 0, so
    ``mentor_override_after`` counts only own executions. The world's ``max_option_steps`` cut is
    not modelled. Needs a world with a true model (``transition_model`` or ``dynamics_table``)."""
    exact_model_count: float = 1e6
    """Pseudo-executions per row of the ``"exact"`` option models."""
    mentor_choice: str = "greedy"
    """How a run picks its own option (greedy choices only) in a state where the mentor term wins
    eq. 2. ``"greedy"``: the best own option by its ``Q`` — values that the mentor term has already
    raised downstream. ``"match"`` (Price & Boutilier's rule, for options): the own options whose
    first action's learned one-step model best reproduces the mentor's observed move,
    ``Σ_s' p̂(s'|s, π_o(s)) p_m(s'|s)``, best ``Q`` among those; greedy where no tried action
    matches."""
    tie_break: str = "random"
    """Greedy ties (|ΔQ| ≤ 1e-12): ``"random"`` among the best, or ``"first"`` (lowest option)."""
    window: int = 5000
    """Steps per window of the ``goals_in_window`` metric."""
    max_option_steps: int = 100_000
    """An option still running after this many primitive steps is stopped (and learned from as
    if it had terminated there), so an option that never terminates cannot freeze its run."""
    resample_every: int = 0
    """When the ``…_psrl`` agents (posterior sampling, :mod:`himit_torch.learner.posterior_sampling`) draw
    a fresh model from their posteriors: 0 = at each episode start (after each goal; PSRL's
    "one sample per episode"), ``N ≥ 1`` = every ``N`` decisions (own options executed) instead.
    A run also draws when it is created and when it is given demonstrations. Between draws a row
    with a new outcome keeps a sample of its updated posterior (a coupling that moves it only by
    the new outcome's share). Other agents ignore it."""
    reward_bound_check: str = "error"
    """What to do when a mentor-reward module's declared ``upper_bound`` exceeds the learner's
    real best reward per step (the guarantee of eq. 2 needs ``R_m`` not to overestimate it):
    ``"error"`` (ValueError), ``"warn"`` (a warning) or ``"off"``. Values above a module's own
    declared bound are always an error."""

    #: Field kinds for the input rules of :mod:`himit_torch.validation` (whole numbers are never
    #: truncated, bools and strings never taken for numbers, every number finite).
    _INTS = (
        "backups",
        "sweep_rounds",
        "plan_every",
        "rng_chunk",
        "window",
        "max_option_steps",
        "resample_every",
    )
    _FLOATS = (
        "priority_threshold",
        "initial_value",
        "concentration",
        "mentor_concentration",
        "confidence_z",
        "eps_start",
        "eps_decay",
        "eps_min",
    )
    _CHOICES = {
        "mentor_choice": ("greedy", "match"),
        "tie_break": ("random", "first"),
        "reward_bound_check": ("error", "warn", "off"),
    }

    def __post_init__(self):
        for name in self._INTS:
            setattr(self, name, as_int(f"LearnerConfig.{name}", getattr(self, name)))
        for name in self._FLOATS:
            setattr(self, name, as_float(f"LearnerConfig.{name}", getattr(self, name)))
        if self.untried_value is not None:
            self.untried_value = as_float("LearnerConfig.untried_value", self.untried_value)
        if self.mentor_override_after is not None:
            self.mentor_override_after = as_int(
                "LearnerConfig.mentor_override_after", self.mentor_override_after, minimum=0
            )
        for name, choices in self._CHOICES.items():
            as_choice(f"LearnerConfig.{name}", getattr(self, name), choices)

        def bad(name, why):
            raise ValueError(f"LearnerConfig.{name}={getattr(self, name)!r}: {why}")

        if self.backups < 1:
            bad("backups", "needs at least 1 backup per decision")
        if not 1 <= self.sweep_rounds <= self.backups:
            bad("sweep_rounds", f"must lie in 1…backups ({self.backups})")
        for name in ("concentration", "mentor_concentration", "priority_threshold"):
            if not getattr(self, name) >= 0:
                bad(name, "must be ≥ 0")
        for name in ("eps_start", "eps_min", "eps_decay"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                bad(name, "must lie in [0, 1]")
        if self.eps_min > self.eps_start:
            bad("eps_min", f"must not exceed eps_start={self.eps_start}")
        if not self.confidence_z >= 0:
            bad("confidence_z", "must be ≥ 0")
        if self.eps_schedule not in EPS_SCHEDULES:
            bad("eps_schedule", f"use one of {list(EPS_SCHEDULES)}")
        if self.eps_goals < 1:
            bad("eps_goals", "must be ≥ 1 goal")
        if self.mentor_fade is not None and not self.mentor_fade > 0:
            bad("mentor_fade", "must be > 0 (the mentor's weight in own executions) or None")
        if self.option_models not in ("learned", "exact"):
            bad("option_models", "use 'learned' or 'exact'")
        if not self.exact_model_count > 0:
            bad("exact_model_count", "must be > 0 pseudo-executions")
        if self.mentor_choice not in ("greedy", "match"):
            bad("mentor_choice", "use 'greedy' or 'match'")
        if self.tie_break not in ("random", "first"):
            bad("tie_break", "use 'random' or 'first'")
        if self.window < 1:
            bad("window", "must be ≥ 1 step")
        if self.plan_every < 1:
            bad("plan_every", "must be ≥ 1 tick")
        if self.reward_bound_check not in ("error", "warn", "off"):
            bad("reward_bound_check", "use 'error', 'warn' or 'off'")
        if self.rng_chunk < 1:
            bad("rng_chunk", "must be ≥ 1 tick")
        if self.max_option_steps < 1:
            bad("max_option_steps", "must be ≥ 1 step")
        if self.resample_every < 0:
            bad("resample_every", "must be ≥ 0 (0 = at each episode start, N = every N decisions)")
        if not torch.isfinite(torch.tensor(float(self.initial_value))):
            bad("initial_value", "must be finite")
