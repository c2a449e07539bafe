"""The learner's settings (:class:`LearnerConfig`), each declared once.

Every field is declared with :func:`~himit_torch.validation.setting`: its type is the annotation,
and the ``Setting`` in the field's metadata holds its range or choices, its doc, and whether and
how the compiled engine reads it. Everything else is generated from that declaration:

* **validation** — :func:`~himit_torch.validation.check_settings` in ``__post_init__`` (whole
  numbers never truncated, bools and strings never numbers, floats finite, ranges, choices,
  ``None`` where the type allows it); only the cross-field rules are written out here;
* **the kernel's settings** — :func:`kernel_fields` (and :data:`KERNEL_FIELDS`): every field
  declared ``kernel=True``, encoded as a number;
* **a CLI flag per field** — ``himit run --mentor-fade 20`` (:mod:`himit_torch.cli`), its help
  the field's doc.

Why metadata rather than the docstring under each field: the doc, the range and the kernel's
encoding sit in one object that validation, the CLI and the kernel read at run time, without
parsing the source (attribute docstrings exist only in the source text). Field names, order,
defaults and types are those of the plain dataclass, so ``asdict`` (in checkpoints and
``config.json``) is unchanged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from himit_torch.mentor.cloning import INVERSE_MODELS
from himit_torch.validation import check_settings, setting, settings_of

__all__ = [
    "EPS_SCHEDULES",
    "OPTION_MODELS",
    "MENTOR_CHOICES",
    "TIE_BREAKS",
    "REWARD_BOUND_CHECKS",
    "LearnerConfig",
    "KERNEL_FIELDS",
    "kernel_fields",
    "kernel_field_types",
]

#: ``LearnerConfig.eps_schedule`` values, in the order of their code in the compiled engine.
EPS_SCHEDULES = ("decision", "step", "goals", "paper")
#: ``LearnerConfig.option_models``: counts of the run's own executions, or the exact model.
OPTION_MODELS = ("learned", "exact")
#: ``LearnerConfig.mentor_choice`` (the kernel reads the index: 1 = match).
MENTOR_CHOICES = ("greedy", "match")
#: ``LearnerConfig.tie_break`` (the kernel reads the index: 1 = first).
TIE_BREAKS = ("random", "first")
#: ``LearnerConfig.reward_bound_check``.
REWARD_BOUND_CHECKS = ("error", "warn", "off")


@dataclass
class LearnerConfig:
    """Settings of the learner. Defaults follow the paper where it speaks (ε, γ from the world) and
    ``docs/reproduction-notes.md`` (what an earlier straightforward implementation showed) where
    it is silent."""

    backups: int = setting(
        10,
        ge=1,
        hint="backups per decision",
        kernel=True,
        doc="""
        Prioritized-sweeping backups per decision (the paper: about the number of options needed to
        reach the goal). The option's start state is always backed up first, within this budget.""",
    )
    sweep_rounds: int = setting(
        2,
        ge=1,
        doc="""
        The backups of one planning step run in this many rounds; the states of one round (the
        highest priorities) are backed up together, and their changes propagate before the next
        round. ``sweep_rounds = backups`` is classic one-at-a-time sweeping (slowest).""",
    )
    plan_every: int = setting(
        1,
        ge=1,
        kernel=True,
        doc="""
        Sweep every this many ticks, for all runs that decided since the last sweep, with
        ``backups`` per decision they made, in ``sweep_rounds`` rounds of up to
        ``plan_every · backups / sweep_rounds`` states. 1 = plan at every decision (the paper's loop).
        Larger values trade a few ticks of planning delay for speed (fewer, larger tensor ops): a
        sweep after a decision at ``s`` updates ``s`` and the states *behind* it, not the state the
        next choice is made in. Models are still updated at every decision.""",
    )
    rng_chunk: int = setting(
        256,
        ge=1,
        doc="""
        Per-run uniforms are drawn for this many ticks at once (speed only; results identical).""",
    )
    priority_threshold: float = setting(
        1e-6,
        ge=0.0,
        kernel=True,
        doc="""
        A state enters the sweeping queue only with a priority ``|ΔQ|`` above this.""",
    )
    initial_value: float = setting(
        -1.0,
        kernel=True,
        doc="""
        Initial ``V`` of every non-terminal state, and the value of the prior's unseen outcome.
        −1 = step reward / (1 − γ), the value of never reaching the goal in the paper's worlds: a
        neutral start. 0 is optimistic there at most states (true values are negative
        except near the goal, up to the goal reward +1), which turns ε-greedy into systematic
        exploration.""",
    )
    untried_value: float | None = setting(
        None,
        kernel_none=math.nan,
        kernel=True,
        doc="""
        Value of an option never tried in a state: ``None`` leaves it out of the max (and out of
        greedy choice unless nothing was tried there); a number counts it with that ``Q`` (0 =
        the optimistic "Q = 0 for untried options" of a straightforward implementation).""",
    )
    concentration: float = setting(
        0.0,
        ge=0.0,
        kernel=True,
        doc="""
        Dirichlet prior mass of the option model on the unseen-successor outcome (0 = the
        maximum-likelihood model).""",
    )
    mentor_concentration: float = setting(
        0.0,
        ge=0.0,
        kernel=True,
        doc="""
        Same for the mentor model (only in states where the mentor was seen: the prior never
        creates a mentor term elsewhere).""",
    )
    confidence_z: float = setting(
        1.0,
        mentor_term=True,
        ge=0.0,
        kernel=True,
        doc="""
        Width of Price & Boutilier's confidence test, used by the ``…_confident`` agents: the
        mentor term at ``s`` counts only where its lower bound (mean − z·sd, from the Dirichlet
        variances) beats the upper bound (mean + z·sd) of every own option.""",
    )
    mentor_override_after: int | None = setting(
        None,
        mentor_term=True,
        ge=0,
        kernel_none=-1,
        kernel=True,
        doc="""
        Ignore the mentor term at ``s`` once the run has executed its own options there this many
        times (own experience overrides the mentor); ``None`` = never.""",
    )
    mentor_fade: float | None = setting(
        None,
        mentor_term=True,
        gt=0.0,
        kernel_none=0.0,
        hint="the mentor's weight in own executions; None: no fading",
        kernel=True,
        doc="""
        Shrink the mentor term towards the run's own estimate as its own experience grows: where
        some own option was tried at ``s``, eq. 2's mentor term ``m`` is replaced
        by ``(k·m + n·own) / (k + n)`` with ``k = mentor_fade``, ``n`` the own options executed from
        ``s`` and ``own`` the best own ``Q`` there — the mentor's evidence counts as ``k`` own
        executions, so the mentor's value leads early and the run's own value decides in the limit
        (no lasting upward bias). Where nothing own was tried, ``m`` is used as it is. ``None`` = no
        fading (the paper's eq. 2).""",
    )
    mentor_segments: bool = setting(
        False,
        mentor_term=True,
        doc="""
        Score each observed mentor move as the segment it is (SMDP form, as an own option is
        scored): a move of ``k`` primitive steps gets the discount ``γ^k`` and the discounted
        reward of its steps, the unseen ones at the least reward the run's reward module gives
        any observed move (:func:`~himit_torch.learner.backups.segment_reward`). The move's
        length is what the demonstrations say (``CoarseDemonstrations.durations``: the learner
        knows when it saw each state); full demonstrations have only one-step moves, where this
        is the paper's term exactly. ``False`` = every observed move scored as one step (the
        paper's eq. 1 and 2), optimistic under coarse observation.""",
    )
    mentor_feasibility: int | None = setting(
        None,
        mentor_term=True,
        ge=1,
        kernel_none=0,
        kernel=True,
        hint="tries of every own option at a state; None: never tested",
        doc="""
        Feasibility testing over options (Price & Boutilier's action feasibility testing, with
        option termination models in place of action models): drop the mentor term at ``s``
        once every enabled own option has been tried there at least this many times and none of
        those tries ended in a state the mentor was seen moving to from ``s``
        (:func:`~himit_torch.learner.backups.feasible_mentor`) — the learner cannot reproduce
        the mentor's move there, so its value is not the learner's. Zero successes in ``n``
        tries bound an option's chance of reaching them below ``1 − 0.05^(1/n)`` at 95 %.
        ``None`` = never tested (the paper's eq. 2).""",
    )
    mentors: int = setting(
        1,
        ge=1,
        le=64,
        hint="how many demonstration sets the run watches, each with its own mentor model",
        doc="""
        Several mentors: the number of mentor models, one per demonstration set
        (``Learner.add_demonstrations(…, mentor=k)``; they may differ in skill, skill level or
        organisation). Each mentor's moves go to its own Dirichlet model, and eq. 2 takes the
        largest of the mentor terms seen at ``s``
        (:func:`~himit_torch.learner.backups.best_mentor`): each mentor's move is one more
        thing the learner could do there, so a poor mentor's term counts only where it is the
        best on offer. The chosen term meets the own options as one mentor's would (its
        confidence test, override, fading and feasibility). Shaping and cloning pool the
        mentors' moves. ``1`` = the paper's single mentor.""",
    )
    eps_start: float = setting(
        0.75,
        ge=0.0,
        le=1.0,
        doc="""
        ε until the run's first goal.""",
    )
    eps_decay: float = setting(
        0.999,
        ge=0.0,
        le=1.0,
        kernel=True,
        doc="""
        After the first goal, ε is multiplied by this at every decision…""",
    )
    eps_min: float = setting(
        0.01,
        ge=0.0,
        le=1.0,
        kernel=True,
        doc="""
        …down to this floor.""",
    )
    eps_schedule: str = setting(
        "decision",
        choices=EPS_SCHEDULES,
        kernel=True,
        doc="""
        When ε changes (every schedule starts at ``eps_start`` and never goes below ``eps_min``):

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
          start for thousands of goals: the rate is this reading's free parameter.""",
    )
    eps_goals: int = setting(
        10,
        ge=1,
        hint="goals before ε drops to eps_min",
        kernel=True,
        doc="""
        Goals after which the ``"goals"`` schedule drops ε to ``eps_min`` (other schedules ignore
        it).""",
    )
    option_models: str = setting(
        "learned",
        choices=OPTION_MODELS,
        doc="""
        Where each run's option model comes from: ``"learned"`` (counts of its own executions, the
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
        not modelled. Needs a world with a true model (``transition_model`` or ``dynamics_table``).""",
    )
    exact_model_count: float = setting(
        1e6,
        gt=0.0,
        hint="pseudo-executions per row",
        doc="""
        Pseudo-executions per row of the ``"exact"`` option models.""",
    )
    mentor_choice: str = setting(
        "greedy",
        mentor_term=True,
        choices=MENTOR_CHOICES,
        kernel=True,
        doc="""
        How a run picks its own option (greedy choices only) in a state where the mentor term wins
        eq. 2. ``"greedy"``: the best own option by its ``Q`` — values that the mentor term has already
        raised downstream. ``"match"`` (Price & Boutilier's rule, for options): the own options whose
        first action's learned one-step model best reproduces the mentor's observed move,
        ``Σ_s' p̂(s'|s, π_o(s)) p_m(s'|s)``, best ``Q`` among those; greedy where no tried action
        matches.""",
    )
    mentor_trial: bool = setting(
        False,
        mentor_term=True,
        kernel=True,
        doc="""
        Trial of untried own options where the mentor leads (the option-level analogue of Price
        & Boutilier's k-step repair): in a state where the mentor term wins eq. 2 and some enabled
        own option was never tried there, the greedy choice tries one — of the untried options,
        those whose first action's learned one-step model best reproduces the mentor's observed
        move, any untried one where none does (:func:`~himit_torch.learner.choice.trial_candidates`).
        ε-exploration is unchanged: with probability ε the run picks any enabled option, as
        always; the trial replaces only the greedy choice, so it ends at each state once every
        option there has been tried. Applies to eq. 1 (untried primitives) and eq. 2 alike.
        ``False`` = the paper's greedy choice.""",
    )
    tie_break: str = setting(
        "random",
        choices=TIE_BREAKS,
        kernel=True,
        doc="""
        Greedy ties (``|ΔQ| ≤ 1e-12``): ``"random"`` among the best, or ``"first"`` (lowest option).""",
    )
    window: int = setting(
        5000,
        ge=1,
        kernel=True,
        doc="""
        Steps per window of the ``goals_in_window`` metric.""",
    )
    max_option_steps: int = setting(
        100_000,
        ge=1,
        kernel=True,
        doc="""
        An option still running after this many primitive steps is stopped (and learned from as
        if it had terminated there), so an option that never terminates cannot freeze its run.""",
    )
    resample_every: int = setting(
        0,
        ge=0,
        hint="0 = at each episode start, N = every N decisions",
        kernel=True,
        doc="""
        When the ``…_psrl`` agents (posterior sampling, :mod:`himit_torch.learner.posterior_sampling`) draw
        a fresh model from their posteriors: 0 = at each episode start (after each goal; PSRL's
        "one sample per episode"), ``N ≥ 1`` = every ``N`` decisions (own options executed) instead.
        A run also draws when it is created and when it is given demonstrations. Between draws a row
        with a new outcome keeps a sample of its updated posterior (a coupling that moves it only by
        the new outcome's share). Other agents ignore it.""",
    )
    reward_bound_check: str = setting(
        "error",
        choices=REWARD_BOUND_CHECKS,
        doc="""
        What to do when a mentor-reward module's declared ``upper_bound`` exceeds the learner's
        real best reward per step (the guarantee of eq. 2 needs ``R_m`` not to overestimate it):
        ``"error"`` (ValueError), ``"warn"`` (a warning) or ``"off"``. Values above a module's own
        declared bound are always an error.""",
    )
    bco_every: int = setting(
        1000,
        ge=1,
        hint="ticks between relabelling and re-cloning",
        doc="""
        The ``bco`` agent (behavioural cloning from observation, Torabi, Warnell & Stone 2018;
        :mod:`himit_torch.mentor.cloning`) relabels the demonstrations with its inverse model of
        its own transitions and re-clones its policy every this many ticks (and when it is given
        demonstrations). Torabi et al.'s BCO(α) re-clones after every α·(pre-demonstration
        phase) steps: small values are BCO(α) with a small α; a value beyond the run's length
        is BCO(0) with no cloned policy at all, and one of half its length BCO(0) after a
        first phase of that many steps. Other agents ignore it.""",
    )
    bco_inverse_model: str = setting(
        "likelihood",
        choices=INVERSE_MODELS,
        doc="""
        The ``bco`` agent's inverse model ``p(a | s, s')`` from its own counts ``n(s, a, s')``:
        ``"likelihood"`` — ``∝ n(s, a, s') / n(s, a)``, a uniform prior over actions, as BCO(0)'s
        random pre-demonstration phase gives; ``"counts"`` — ``∝ n(s, a, s')``, what a model
        trained on the run's own transitions estimates, its own action frequencies the prior over
        actions. Under slip, ``"counts"`` confirms its own wrong labels: a run that takes its
        (wrongly) cloned action far more often than the right one explains the mentor's move by
        the slips of the wrong one (``docs/bco.md``). Other agents ignore it.""",
    )

    def __post_init__(self):
        check_settings(self)
        # Cross-field rules (each field on its own is checked above).
        if self.sweep_rounds > self.backups:
            raise ValueError(
                f"LearnerConfig.sweep_rounds={self.sweep_rounds}: must lie in 1…backups "
                f"({self.backups})"
            )
        if self.eps_min > self.eps_start:
            raise ValueError(
                f"LearnerConfig.eps_min={self.eps_min}: must not exceed eps_start={self.eps_start}"
            )


#: Version of :class:`LearnerConfig`'s schema, recorded in every checkpoint: 1 — before it was
#: recorded; 2 — ``mentor_segments``, ``mentor_trial`` and ``mentor_feasibility`` added; 3 —
#: ``mentors`` added. A checkpoint of an older schema resumes with each newer setting at its
#: declared default.
CONFIG_SCHEMA_VERSION = 3

#: The fields the compiled engine reads, in declaration order (the names of its settings tuple).
KERNEL_FIELDS: tuple[str, ...] = tuple(s.name for s in settings_of(LearnerConfig) if s.info.kernel)


def kernel_field_types() -> dict[str, type]:
    """The number type of each of :data:`KERNEL_FIELDS` as :func:`kernel_fields` encodes it:
    ``int`` for whole numbers and choices, ``float`` for real numbers."""
    return {
        s.name: int if s.kind in (int, str, bool) else float
        for s in settings_of(LearnerConfig)
        if s.info.kernel
    }


def kernel_fields(config: LearnerConfig) -> dict[str, int | float]:
    """The settings the compiled engine reads, as numbers (one per :data:`KERNEL_FIELDS`): a
    choice as its index in the field's choices, ``None`` as the field's declared
    ``kernel_none`` (``untried_value``: NaN, ``mentor_override_after``: −1,
    ``mentor_fade``: 0 — each a value the field itself never takes)."""
    out: dict[str, int | float] = {}
    for s in settings_of(LearnerConfig):
        if not s.info.kernel:
            continue
        value = getattr(config, s.name)
        if value is None:
            value = s.info.kernel_none
        elif s.info.choices:
            value = s.info.choices.index(value)
        out[s.name] = int(value) if s.kind in (int, str, bool) else float(value)
    return out
