"""The config schema: every field of LearnerConfig and ExperimentConfig declared once, with
validation, the kernel's settings and JSON round trips generated from the declaration."""

from __future__ import annotations

import dataclasses
import json
import math

import pytest

from himit_torch.learner.config import (
    EPS_SCHEDULES,
    KERNEL_FIELDS,
    MENTOR_CHOICES,
    TIE_BREAKS,
    LearnerConfig,
    kernel_field_types,
    kernel_fields,
)
from himit_torch.runs.config import EXPERIMENTS, ExperimentConfig, load_config
from himit_torch.validation import COUNT_MAX, settings_of

#: What the kernel reads today (its cfg_f/cfg_i slots), by config field: the brief of the
#: KernelSettings rewrite. Written out here so that a field dropped from or added to the
#: kernel's declaration is a visible change, not a silent one.
EXPECTED_KERNEL_FIELDS = {
    "backups",
    "plan_every",
    "window",  # (the kernel closes each window at its last tick)
    "max_option_steps",
    "priority_threshold",
    "initial_value",
    "concentration",
    "mentor_concentration",
    "confidence_z",
    "eps_decay",
    "eps_min",
    "mentor_trial",
    "mentor_feasibility",
    "eps_goals",
    "eps_schedule",
    "mentor_fade",
    "mentor_override_after",
    "untried_value",
    "resample_every",
    "mentor_choice",
    "tie_break",
}


@pytest.mark.parametrize("cls", [LearnerConfig, ExperimentConfig])
def test_every_field_is_declared_with_a_doc(cls):
    declared = [s.name for s in settings_of(cls)]
    assert declared == [f.name for f in dataclasses.fields(cls)]
    for s in settings_of(cls):
        assert len(s.info.doc.split()) >= 3, s.name


# ------------------------------------------------------------------------ issue 23's cases
@pytest.mark.parametrize(
    "field, value, why",
    [
        ("mentor_fade", math.inf, "finite"),
        ("mentor_fade", True, "must be a number"),
        ("mentor_fade", -1.0, "> 0"),
        ("exact_model_count", math.inf, "finite"),
        ("exact_model_count", True, "must be a number"),
        ("eps_goals", 2.5, "not a whole number"),
        ("eps_goals", math.nan, "whole number"),
        ("eps_goals", True, "whole number"),
        ("backups", 2**63, "≤ 2147483647"),
        ("plan_every", 2**64, "≤ 2147483647"),
        ("max_option_steps", 2**63, "≤ 2147483647"),
        ("mentor_override_after", 2**63, "≤ 2147483647"),
        ("mentor_override_after", 1.5, "not a whole number"),
        ("untried_value", math.nan, "finite"),
        ("eps_schedule", 0, "use one of"),
        ("option_models", "given", "'exact'"),
    ],
)
def test_issue_23_config_values_are_refused_by_name(field, value, why):
    with pytest.raises(ValueError, match=f"LearnerConfig.{field}.*{why}"):
        LearnerConfig(**{field: value})


def test_counts_at_the_bound_are_kept_and_whole_floats_converted():
    config = LearnerConfig(backups=COUNT_MAX, sweep_rounds=1, eps_goals=3.0, mentor_fade=20)
    assert config.backups == COUNT_MAX
    assert config.eps_goals == 3 and type(config.eps_goals) is int
    assert config.mentor_fade == 20.0 and type(config.mentor_fade) is float


@pytest.mark.parametrize(
    "changes, message",
    [
        (dict(backups=2, sweep_rounds=3), r"sweep_rounds=3: must lie in 1…backups \(2\)"),
        (dict(eps_start=0.1, eps_min=0.2), "eps_min=0.2: must not exceed eps_start=0.1"),
    ],
)
def test_cross_field_rules(changes, message):
    with pytest.raises(ValueError, match=message):
        LearnerConfig(**changes)


def test_experiment_cross_field_rules_and_nested_learner():
    with pytest.raises(ValueError, match="multiple of room_size=4"):
        ExperimentConfig(sizes=(10,))
    with pytest.raises(ValueError, match="multiple of window=1000"):
        ExperimentConfig(window=1000, checkpoint_every=1500)
    with pytest.raises(ValueError, match="ExperimentConfig.learner: unknown fields \\['fade'\\]"):
        ExperimentConfig(learner={"fade": 2})
    with pytest.raises(ValueError, match="ExperimentConfig.agents\\[1\\]='psrl'"):
        ExperimentConfig(agents=("options", "psrl"))
    config = ExperimentConfig(window=1000, checkpoint_every=2000, learner={"mentor_fade": 5})
    assert config.learner == LearnerConfig(mentor_fade=5.0, window=1000)


# ------------------------------------------------------------------------ the kernel's settings
def test_kernel_fields_are_the_settings_the_kernel_reads():
    assert set(KERNEL_FIELDS) == EXPECTED_KERNEL_FIELDS
    assert list(kernel_fields(LearnerConfig())) == list(KERNEL_FIELDS)
    assert list(kernel_field_types()) == list(KERNEL_FIELDS)


def test_kernel_fields_encode_choices_as_indices_and_none_as_sentinels():
    defaults = kernel_fields(LearnerConfig())
    assert math.isnan(defaults["untried_value"])  # None: no value, told apart from 0.0
    assert defaults["mentor_override_after"] == -1 and defaults["mentor_fade"] == 0.0
    assert (defaults["eps_schedule"], defaults["mentor_choice"], defaults["tie_break"]) == (0, 0, 0)
    given = kernel_fields(
        LearnerConfig(
            untried_value=0,
            mentor_override_after=7,
            mentor_fade=20,
            eps_schedule="paper",
            mentor_choice="match",
            tie_break="first",
            backups=12,
            sweep_rounds=1,
        )
    )
    assert given["untried_value"] == 0.0 and given["mentor_override_after"] == 7
    assert given["mentor_fade"] == 20.0 and given["backups"] == 12
    assert given["eps_schedule"] == EPS_SCHEDULES.index("paper") == 3
    assert given["mentor_choice"] == MENTOR_CHOICES.index("match") == 1
    assert given["tie_break"] == TIE_BREAKS.index("first") == 1


def test_kernel_field_values_have_their_declared_number_types():
    """A Numba-compiled NamedTuple is typed by its values: each field must keep one type."""
    types = kernel_field_types()
    for config in (LearnerConfig(), LearnerConfig(initial_value=0, mentor_fade=3, untried_value=1)):
        for name, value in kernel_fields(config).items():
            assert type(value) is types[name], name


# ------------------------------------------------------------------------ JSON round trip
@pytest.mark.parametrize("name", sorted(EXPERIMENTS))
def test_config_json_config_round_trip(tmp_path, name):
    config = dataclasses.replace(
        EXPERIMENTS[name],
        mentor_preference=0.5,
        learner=LearnerConfig(
            mentor_fade=20, untried_value=0.0, tie_break="first", eps_schedule="goals"
        ),
    )
    path = tmp_path / "config.json"
    path.write_text(config.to_json())
    loaded = load_config(path)
    assert loaded == config
    assert json.loads(loaded.to_json()) == json.loads(config.to_json())


def test_asdict_keeps_the_field_order_and_defaults_checkpoints_compare():
    """Checkpoints and config.json hold ``asdict(config)``: its keys and defaults are the
    learner's settings as they were before the schema."""
    assert list(dataclasses.asdict(LearnerConfig())) == [
        "backups", "sweep_rounds", "plan_every", "rng_chunk", "priority_threshold",
        "initial_value", "untried_value", "concentration", "mentor_concentration",
        "confidence_z", "mentor_override_after", "mentor_fade", "mentor_segments",
        "mentor_feasibility", "mentors", "eps_start", "eps_decay", "eps_min", "eps_schedule", "eps_goals", "option_models",
        "exact_model_count", "mentor_choice", "mentor_trial", "tie_break", "window", "max_option_steps", "resample_every",
        "reward_bound_check", "bco_every", "bco_inverse_model",
    ]  # fmt: skip
    defaults = dataclasses.asdict(LearnerConfig())
    assert (defaults["backups"], defaults["exact_model_count"], defaults["mentor_fade"]) == (
        10,
        1e6,
        None,
    )
