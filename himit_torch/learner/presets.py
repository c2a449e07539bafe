"""Named presets of the learner's settings: ``paper`` (eq. 2 as the paper states it),
``recommended`` (the settings the preset search chose for eq. 2 on held-out seeds) and its two
parts on their own, ``explore-goals`` (an exploration schedule, for every agent) and
``mentor-fade`` (a setting of the mentor term, for the agents that have one); and
``subgoal-mentor`` (eq. 2 for a mentor seen only at its subgoals or every k-th state, chosen on
held-out seeds by the hierarchy study).

A preset is a set of :class:`~himit_torch.learner.config.LearnerConfig` fields with a reason for
each value: :func:`apply_preset` sets them, :func:`preset_differences` says where a configuration
departs from one. ``ExperimentConfig.preset`` and ``GymExperimentConfig.preset`` record which
preset a run's settings came from, and refuse settings that contradict it, so a run directory's
``config.json`` never names a preset its settings do not follow. ``himit run … --preset NAME``
applies one (flags given beside it may change only fields the preset does not set).

What a preset does **not** set, and why:

* **The greedy tie rule** (``tie_break``). The paper does not say how ties are broken, and the
  answer decides its experiment 2 (``experiments/results/``): both readings are run for every
  claim. Give ``--tie-break first`` or ``random`` (the default) beside a preset.
* **World-dependent values** — ``initial_value`` (the value of never reaching the goal: −1 in the
  paper's worlds, each Gymnasium task's own), ``window``, the planning cadence (``plan_every``,
  ``sweep_rounds``: a speed setting of each experiment, validated in ``experiments/results/``).
* **Which agents run**: every agent of a run gets the preset; the non-imitators ignore its
  mentor settings, so their runs are the same under both presets (same seeds, same curves).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from types import MappingProxyType
from typing import Any

from himit_torch.learner.agents import AGENTS
from himit_torch.learner.config import LearnerConfig
from himit_torch.validation import settings_of

__all__ = [
    "Preset",
    "PRESETS",
    "agent_settings",
    "agent_settings_text",
    "apply_preset",
    "check_preset",
    "mentor_term_settings",
    "preset_differences",
]


@dataclass(frozen=True)
class Preset:
    """A named set of learner settings, each with the reason for its value."""

    name: str
    summary: str
    #: LearnerConfig field → (value, why).
    settings: Mapping[str, tuple[Any, str]]

    def changes(self) -> dict[str, Any]:
        """The fields this preset sets, and their values."""
        return {field: value for field, (value, _) in self.settings.items()}


def _preset(name: str, summary: str, **settings: tuple[Any, str]) -> Preset:
    return Preset(name, summary, MappingProxyType(settings))


#: The paper's eq. 2, every choice the paper leaves open named with the reading taken.
PAPER = _preset(
    "paper",
    "Eq. 2 as the paper states it: the mentor term enters the max of every state the mentor was "
    "seen in, with no confidence test, override or fading.",
    mentor_fade=(None, "the paper's eq. 2 has no fading: the mentor term counts fully forever"),
    mentor_override_after=(None, "the paper never lets own experience override the mentor term"),
    mentor_choice=(
        "greedy",
        "unstated: where the mentor term wins the max, the learner still acts greedily over its "
        "own options (their values already raised by the mentor term downstream); Price & "
        "Boutilier's action matching ('match') is their rule for primitives, not the paper's",
    ),
    untried_value=(
        None,
        "unstated: an option never tried has no model, so it is left out of the max (0 would be "
        "optimistic and turn ε-greedy into systematic exploration; the paper describes "
        "semi-random exploration)",
    ),
    backups=(
        10,
        "'a fixed number of backups generally equal to the number of options needed to reach "
        "the goal' (Sec. III); 19 vs 10 changes nothing detectable with 20 seeds",
    ),
    eps_start=(0.75, "stated: ε begins at 0.75"),
    eps_min=(0.01, "stated: a minimum of 0.01"),
    eps_schedule=(
        "decision",
        "stated: the decay starts after the first goal; its unit is not stated — per decision "
        "(option choice) is the reading whose rate gives usable runs (per goal, read literally, "
        "collapses every agent)",
    ),
    eps_decay=(
        0.999,
        "unstated: the rate (× 0.999 per decision, from 0.75 to the floor after ≈ 4300 decisions)",
    ),
    eps_goals=(10, "not read by the 'decision' schedule (the default, kept for completeness)"),
    option_models=("learned", "stated: the option models are learned from own executions"),
    concentration=(
        0.0,
        "unstated: the maximum-likelihood model of each tried option (no prior mass on unseen "
        "successors), the plain count model the paper describes",
    ),
    mentor_concentration=(0.0, "unstated: the same for the mentor model"),
)

#: The recommended preset's two parts, each a preset of its own (experiments/benchmark/PROTOCOL.md,
#: the fair factorial): an exploration schedule, which every agent of a run follows, and a
#: setting of the mentor term, which only the agents with a mentor term read.
_EXPLORE_GOALS = {
    "eps_schedule": (
        "goals",
        "explore at 0.75 until the goal is known well (10 goals), then act at the floor: of "
        "the candidates whose greedy policy reached ≥ 97 % of the mentor's rate on both "
        "searched worlds, the one with the most goals in the first 50k steps "
        "(experiments/results/presets/search.md, round 2). An exploration schedule: it applies "
        "to every agent of a run, imitator or not",
    ),
    "eps_goals": (10, "the goals of exploration before ε drops to its floor"),
}
_MENTOR_FADE = {
    "mentor_fade": (
        20.0,
        "the mentor's evidence counts as 20 own executions at each state, so it leads early "
        "and the run's own value decides in the limit (no lasting upward bias of the mentor "
        "term); k = 5, 20, 50 did alike on held-out seeds. A setting of the mentor term: "
        "agents without one (options, primitives, pbrs, bco) do not read it",
    ),
}

#: The paper's eq. 2 with ε held at 0.75 until the run's 10th goal (the recommended preset's
#: exploration part alone).
EXPLORE_GOALS = _preset(
    "explore-goals",
    "The paper preset with the recommended exploration schedule alone: ε held at 0.75 until the "
    "run's 10th goal, then at its floor 0.01 (eps_schedule = 'goals'). Every agent of a run "
    "follows it.",
    **{**dict(PAPER.settings), **_EXPLORE_GOALS},
)

#: The paper's eq. 2 with the mentor term fading (the recommended preset's mentor part alone).
MENTOR_FADE = _preset(
    "mentor-fade",
    "The paper preset with the recommended mentor-term setting alone: the mentor term fades "
    "into the learner's own value as its own experience grows (mentor_fade = 20). Only agents "
    "with a mentor term (imitation, imitation_primitives, …) read it.",
    **{**dict(PAPER.settings), **_MENTOR_FADE},
)

#: The settings the preset search chose for eq. 2 on held-out seeds (experiments/presets/PROTOCOL.md,
#: search.md): both parts above. Which *method* to use is the benchmark's question, answered
#: under a common schedule (experiments/results/benchmark/).
RECOMMENDED = _preset(
    "recommended",
    "Eq. 2 with the mentor term fading into the learner's own value as its own experience "
    "grows (mentor_fade = 20, the preset mentor-fade), and ε held at 0.75 until the run's 10th "
    "goal, then at its floor 0.01 (eps_schedule = 'goals', the preset explore-goals). Chosen by "
    "a rule declared before the runs, on held-out seeds 1000–1009 and 2000–2009 "
    "(experiments/results/presets/search.md; round 2's deciding rule was declared after round "
    "1's results); its results are those of seeds 0–19, which the search never saw. Its "
    "exploration part applies to every agent of a run, its mentor part only to agents with a "
    "mentor term: compare methods under one preset (experiments/results/benchmark/).",
    **{**dict(PAPER.settings), **_MENTOR_FADE, **_EXPLORE_GOALS},
)

#: The hierarchy study's preset for a mentor seen only at its subgoals or every k-th state
#: (experiments/hierarchy/PROTOCOL.md, amendment "the preset"): the mentor-fade preset with the
#: segment term and trial of untried own options.
SUBGOAL_MENTOR = _preset(
    "subgoal-mentor",
    "Eq. 2 for a mentor seen only where its options end (doorways, the goal: `observation = "
    "'option-ends'`) or every k-th state: the mentor-fade preset (the paper's ε per decision, "
    "the mentor term fading, mentor_fade = 20) with the segment term (mentor_segments) and "
    "trial of untried own options where the mentor leads (mentor_trial). Chosen among four "
    "candidates (the four presets above, each with both terms) on held-out seeds 5000–5019 at "
    "the five conditions where the setting won, by the presets' rule "
    "(experiments/results/hierarchy/preset_choice.md). With every mentor state seen, the "
    "recommended imitator stays flat eq. 1 (README, 'Which method, when?').",
    **{
        **dict(MENTOR_FADE.settings),
        "mentor_segments": (
            True,
            "a mentor seen only at its subgoals or every k-th state moves several steps between "
            "the states the learner sees; the one-step term scores such a move as one step and "
            "overrates it (eq. 2 fell to 6 % of optimal at k = 5 on exp2), the segment term "
            "scores it with its duration's discount and the reward of its steps",
        ),
        "mentor_trial": (
            True,
            "where the mentor leads, the learner first tries its own options not yet tried "
            "there, so that the option reaching the mentor's observed successor is found (on "
            "exp1, where the learner lacks the mentor's skills, trial lifted eq. 2's greedy "
            "policy from 77 to 101 % of the mentor's rate)",
        ),
        "mentor_fade": (
            20.0,
            "chosen on held-out seeds: with fading the candidate's worst condition was 47.9 % "
            "of the optimum (Taxi), without it 31.4 % (exp2 at stride 20, where fading lifted "
            "eq. 2 from 31 to 98 %); the mentor's evidence counts as 20 own executions, so a "
            "mentor term read from coarse observations stops leading once the learner's own "
            "experience is larger",
        ),
    },
)

#: The presets by name.
PRESETS: Mapping[str, Preset] = MappingProxyType(
    {p.name: p for p in (PAPER, EXPLORE_GOALS, MENTOR_FADE, RECOMMENDED, SUBGOAL_MENTOR)}
)


def _preset_named(name: str) -> Preset:
    if name not in PRESETS:
        raise ValueError(f"unknown preset {name!r}; presets: {', '.join(PRESETS)}")
    return PRESETS[name]


def apply_preset(learner: LearnerConfig, name: str) -> LearnerConfig:
    """``learner`` with preset ``name``'s settings (its other fields kept)."""
    return replace(learner, **_preset_named(name).changes())


def preset_differences(learner: LearnerConfig, name: str) -> dict[str, tuple[Any, Any]]:
    """The fields where ``learner`` departs from preset ``name``: field → (its value, the
    preset's). Empty when ``learner`` follows the preset."""
    return {
        field: (getattr(learner, field), value)
        for field, value in _preset_named(name).changes().items()
        if getattr(learner, field) != value
    }


def check_preset(where: str, learner: LearnerConfig, name: str | None) -> None:
    """Refuse a configuration recorded as following preset ``name`` whose learner settings do
    not (``where`` names it in the message)."""
    if name is None:
        return
    differences = preset_differences(learner, name)
    if differences:
        listed = ", ".join(
            f"learner.{field}={mine!r} (the preset: {theirs!r})"
            for field, (mine, theirs) in differences.items()
        )
        raise ValueError(
            f"{where}: preset={name!r} but {listed}; drop the preset, or the settings that "
            f"change what it sets"
        )


def mentor_term_settings(config_class: type = LearnerConfig) -> tuple[str, ...]:
    """The settings of the mentor term, as the schema declares them (``setting(…,
    mentor_term=True)``): read only by agents with one (``AgentVariant.mentor``). Those the paper
    preset sets (every preset's base) come first, in its order (a record has always named
    them); then the others, in the schema's order (a later preset may set some of them:
    ``subgoal-mentor`` the segment term and trial)."""
    declared = [s.name for s in settings_of(config_class) if s.info.mentor_term]
    pinned = [k for k in PAPER.settings if k in declared]
    return (*pinned, *(k for k in declared if k not in pinned))


#: The settings of the mentor term (:func:`mentor_term_settings` of ``LearnerConfig``).
MENTOR_TERM_SETTINGS = mentor_term_settings()


def agent_settings(agent: str, learner: LearnerConfig) -> dict[str, Any]:
    """What agent ``agent`` of a run with settings ``learner`` actually ran with, of the
    settings the presets differ in: the exploration schedule (every agent) and the mentor
    term's settings (``None``: the agent has no mentor term and does not read them). A mentor
    term's setting that the paper preset does not set is named only where it is not at its
    default (so that records from before it existed read as they did).

    A preset applies to every agent of a run; this is how a record says which of its settings
    each agent used (``results.md`` of every run)."""
    if agent not in AGENTS:
        raise ValueError(f"unknown agent {agent!r}; agents: {', '.join(AGENTS)}")
    has_mentor = AGENTS[agent].mentor
    out: dict[str, Any] = {
        "eps_schedule": learner.eps_schedule,
        "eps_decay" if learner.eps_schedule == "decision" else "eps_goals": (
            learner.eps_decay if learner.eps_schedule == "decision" else learner.eps_goals
        ),
    }
    pinned = set(PAPER.settings)
    config_class: type = type(learner)
    defaults = {s.name: s.default for s in settings_of(config_class)}
    for name in mentor_term_settings(config_class):
        value = getattr(learner, name)
        if name in pinned or value != defaults[name]:
            out[name] = value if has_mentor else None
    return out


def agent_settings_text(agents: Sequence[str], learner: LearnerConfig) -> str:
    """One sentence per distinct agent: what :func:`agent_settings` says it ran with."""
    parts = []
    for agent in dict.fromkeys(agents):
        settings = agent_settings(agent, learner)
        mentor = AGENTS[agent].mentor
        used = ", ".join(
            f"`{k}={v}`"
            for k, v in settings.items()
            if mentor or k not in mentor_term_settings(type(learner))
        )
        if not mentor:
            used += " (no mentor term: the mentor settings are not read)"
        parts.append(f"`{agent}`: {used}")
    return "What each agent ran with: " + "; ".join(parts) + "."
