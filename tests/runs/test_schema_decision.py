"""A new setting needs a schema-version decision: :data:`CONFIG_SCHEMA_VERSION` is recorded in
every checkpoint, and a checkpoint of an older schema resumes with each newer setting at its
declared default. This test lists the fields of each schema version; adding a field to
:class:`LearnerConfig` fails it until the field is written under a version here — a new one
(bump ``CONFIG_SCHEMA_VERSION`` and say what it added in its comment) when an older
checkpoint would resume differently without it, or the current one when the field only
records what every older checkpoint already did at its default (say why, beside it)."""

from __future__ import annotations

import dataclasses

from himit_torch.learner.config import CONFIG_SCHEMA_VERSION, LearnerConfig

#: The fields each schema version added (1: before the schema was recorded).
ADDED_AT = {
    1: {
        "backups",
        "bco_every",
        "bco_inverse_model",
        "concentration",
        "confidence_z",
        "eps_decay",
        "eps_goals",
        "eps_min",
        "eps_schedule",
        "eps_start",
        "exact_model_count",
        "initial_value",
        "max_option_steps",
        "mentor_choice",
        "mentor_concentration",
        "mentor_fade",
        "mentor_override_after",
        "option_models",
        "plan_every",
        "priority_threshold",
        "resample_every",
        "reward_bound_check",
        "rng_chunk",
        "sweep_rounds",
        "tie_break",
        "untried_value",
        "window",
    },
    2: {"mentor_segments", "mentor_trial", "mentor_feasibility"},
    3: {"mentors"},
}


def _undecided(cls: type) -> list[str]:
    """The fields of ``cls`` no version of :data:`ADDED_AT` records."""
    return sorted({f.name for f in dataclasses.fields(cls)} - set().union(*ADDED_AT.values()))


def test_every_learner_field_has_a_schema_version_decision():
    fields = {f.name for f in dataclasses.fields(LearnerConfig)}
    decided = set().union(*ADDED_AT.values())
    new = _undecided(LearnerConfig)
    assert not new, (
        f"LearnerConfig has new fields {new} without a schema-version decision: write them "
        f"under a version in {__file__}'s ADDED_AT — CONFIG_SCHEMA_VERSION + 1 (and bump "
        "CONFIG_SCHEMA_VERSION, saying what it added) where an older checkpoint would resume "
        f"differently, or {CONFIG_SCHEMA_VERSION} where every older one ran as the default does"
    )
    assert not decided - fields, f"ADDED_AT names fields LearnerConfig lost: {decided - fields}"


def test_the_schema_version_is_the_newest_decided():
    assert max(ADDED_AT) == CONFIG_SCHEMA_VERSION, (
        f"CONFIG_SCHEMA_VERSION is {CONFIG_SCHEMA_VERSION}, but the fields are recorded up to "
        f"version {max(ADDED_AT)}: record what version {CONFIG_SCHEMA_VERSION} added in ADDED_AT"
    )


def test_a_new_field_without_a_decision_fails():
    """The check itself: a config class with one field more than recorded is caught."""

    @dataclasses.dataclass
    class Grown(LearnerConfig):
        brand_new: int = 0

    assert _undecided(Grown) == ["brand_new"]
