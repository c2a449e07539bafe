"""Presets (``himit_torch.learner.presets``): what each sets, that the paper preset is the
experiments' own settings, that a configuration never claims a preset it does not follow, and
``--preset`` on the command line and in sweeps."""

from __future__ import annotations

import dataclasses
import json

import pytest

from himit_torch.cli import main
from himit_torch.learner.config import LearnerConfig
from himit_torch.learner.presets import (
    PRESETS,
    agent_settings,
    agent_settings_text,
    apply_preset,
    check_preset,
    mentor_term_settings,
    preset_differences,
)
from himit_torch.runs.config import EXPERIMENTS, ExperimentConfig, load_config
from himit_torch.runs.gymnasium import GymExperimentConfig
from himit_torch.runs.sweep import _apply
from himit_torch.validation import setting, settings_of

LEARNER_FIELDS = {s.name for s in settings_of(LearnerConfig)}


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_every_preset_setting_is_a_learner_field_with_a_reason(name):
    preset = PRESETS[name]
    assert preset.name == name and preset.summary
    for field, (value, why) in preset.settings.items():
        assert field in LEARNER_FIELDS, field
        assert len(why) > 20, field
        LearnerConfig(**{field: value})  # a value the learner accepts


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_no_preset_sets_the_tie_rule_or_a_world_dependent_value(name):
    """The claims are answered under both tie rules, and each world has its own V0 and window."""
    assert not {"tie_break", "initial_value", "window", "plan_every"} & set(PRESETS[name].settings)


def test_the_paper_preset_is_what_the_experiments_already_run():
    for config in (*EXPERIMENTS.values(), GymExperimentConfig()):
        assert preset_differences(config.learner, "paper") == {}


def test_recommended_differs_from_paper_only_where_the_search_chose():
    paper, recommended = PRESETS["paper"].changes(), PRESETS["recommended"].changes()
    assert set(paper) == set(recommended)
    changed = {f for f in paper if paper[f] != recommended[f]}
    assert changed and changed <= {"mentor_fade", "eps_decay", "eps_schedule", "eps_goals"}


def test_apply_sets_exactly_the_preset_fields():
    base = LearnerConfig(plan_every=3, tie_break="first", mentor_fade=5.0)
    after = apply_preset(base, "recommended")
    assert preset_differences(after, "recommended") == {}
    assert after.plan_every == 3 and after.tie_break == "first"  # not the preset's
    assert preset_differences(base, "recommended")["mentor_fade"] == (5.0, 20.0)


def test_unknown_preset_is_refused_by_name():
    with pytest.raises(
        ValueError,
        match=r"unknown preset 'fancy'; presets: paper, explore-goals, mentor-fade, recommended, "
        r"subgoal-mentor",
    ):
        apply_preset(LearnerConfig(), "fancy")
    with pytest.raises(ValueError, match=r"preset='fancy'"):
        ExperimentConfig(preset="fancy")


def test_a_config_never_claims_a_preset_it_does_not_follow():
    config = EXPERIMENTS["exp2"].with_preset("recommended")
    assert config.preset == "recommended"
    with pytest.raises(ValueError, match=r"learner\.mentor_fade=5\.0 \(the preset: 20\.0\)"):
        dataclasses.replace(config, learner=dataclasses.replace(config.learner, mentor_fade=5.0))
    with pytest.raises(ValueError, match="GymExperimentConfig: preset='recommended'"):
        GymExperimentConfig(preset="recommended")
    check_preset("x", config.learner, None)  # no preset claimed: anything goes


def test_config_json_round_trip_keeps_the_preset(tmp_path):
    config = EXPERIMENTS["exp1"].with_preset("recommended")
    path = tmp_path / "config.json"
    path.write_text(config.to_json())
    assert load_config(path) == config
    data = json.loads(config.to_json())
    data["learner"]["mentor_fade"] = None
    path.write_text(json.dumps(data))
    with pytest.raises(ValueError, match=f"config file {path}.*preset='recommended'"):
        load_config(path)


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_run_preset_on_every_experiment(planned, name):
    for config in planned(["paper", "--preset", name, "--tie-break", "first"]):
        assert config.preset == name and config.learner.tie_break == "first"
        assert preset_differences(config.learner, name) == {}
        own = EXPERIMENTS[config.name]
        assert config.learner.plan_every == own.learner.plan_every and config.sizes == own.sizes


def test_a_flag_contradicting_the_preset_is_one_line_exit_2(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["run", "exp2", "--preset", "recommended", "--mentor-fade", "5"])
    assert exit_.value.code == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "preset='recommended'" in err and "mentor_fade=5.0" in err


def test_gymnasium_takes_preset_and_tie_rule(monkeypatch):
    from dataclasses import replace

    from himit_torch.runs.studies import STUDIES

    seen = []
    entry = replace(STUDIES["gymnasium"], run=lambda plans, flags: seen.extend(c for c, _ in plans))
    monkeypatch.setitem(STUDIES, "gymnasium", entry)
    argv = ["run", "gymnasium", "--preset", "recommended", "--tie-break", "first", "--seeds", "3"]
    assert main(argv) == 0
    (config,) = seen
    assert config.preset == "recommended" and config.learner.tie_break == "first"
    assert config.seeds == 3 and config.learner.window == 2000  # the comparison's own


def test_sweep_cells_take_a_preset_first_then_their_settings():
    config = _apply(EXPERIMENTS["exp2"], {"preset": "recommended", "learner.tie_break": "first"})
    assert config.preset == "recommended" and config.learner.tie_break == "first"
    with pytest.raises(ValueError, match="preset='recommended'"):
        _apply(EXPERIMENTS["exp2"], {"preset": "recommended", "learner.mentor_fade": 5.0})


def test_recommended_is_its_two_named_parts_over_the_paper():
    # explore-goals changes only the exploration schedule, mentor-fade only the mentor term,
    # and recommended is exactly both (the fair factorial's four cells are the four presets)
    paper = PRESETS["paper"].changes()
    goals = PRESETS["explore-goals"].changes()
    fade = PRESETS["mentor-fade"].changes()
    both = PRESETS["recommended"].changes()
    assert {k for k in goals if goals[k] != paper[k]} == {"eps_schedule"}
    assert {k for k in fade if fade[k] != paper[k]} == {"mentor_fade"}
    changed = {k: v for part in (goals, fade) for k, v in part.items() if v != paper[k]}
    assert both == {**paper, **changed}
    assert both["eps_schedule"] == "goals" and both["mentor_fade"] == 20.0


def test_agent_settings_say_who_reads_the_mentor_term():
    learner = apply_preset(LearnerConfig(), "recommended")
    assert agent_settings("imitation", learner)["mentor_fade"] == 20.0
    assert agent_settings("imitation_primitives", learner)["mentor_fade"] == 20.0
    for agent in ("options", "primitives", "pbrs", "bco"):
        settings = agent_settings(agent, learner)
        assert settings["mentor_fade"] is None and settings["eps_schedule"] == "goals"
    text = agent_settings_text(["imitation", "options", "imitation"], learner)
    assert text.count("`imitation`") == 1 and "`mentor_fade=20.0`" in text
    assert "`options`: `eps_schedule=goals`, `eps_goals=10` (no mentor term" in text
    paper = apply_preset(LearnerConfig(), "paper")
    assert "`eps_decay=0.999`" in agent_settings_text(["primitives"], paper)
    with pytest.raises(ValueError, match="unknown agent 'robot'"):
        agent_settings("robot", learner)


def test_the_mentor_term_settings_come_from_their_declarations():
    """No hand list: a setting declared ``mentor_term=True`` (docs/extending.md's recipe) is a
    setting of the mentor term — named in a run's records for the agents with a mentor term,
    ``None`` for the others, and left out where a preset does not set it and it is at its
    default (older records read as they did)."""
    # the ones the presets set lead, in the presets' order (the committed pages' order)
    assert mentor_term_settings()[:3] == ("mentor_fade", "mentor_override_after", "mentor_choice")
    assert {"mentor_segments", "mentor_trial", "mentor_feasibility"} <= set(mentor_term_settings())
    assert "eps_schedule" not in mentor_term_settings()

    @dataclasses.dataclass
    class ToyConfig(LearnerConfig):  # a new setting, declared the recipe's way
        mentor_toy: float | None = setting(
            None, gt=0.0, mentor_term=True, doc="A toy weight of the mentor term."
        )

    assert mentor_term_settings(ToyConfig)[-1] == "mentor_toy"
    assert "mentor_toy" not in mentor_term_settings()  # (LearnerConfig itself unchanged)
    toy = ToyConfig(mentor_toy=3.0)
    assert agent_settings("imitation", toy)["mentor_toy"] == 3.0
    assert agent_settings("options", toy)["mentor_toy"] is None
    assert "mentor_toy" not in agent_settings("imitation", ToyConfig())
    text = agent_settings_text(["imitation", "options"], toy)
    assert "`imitation`: " in text and "`mentor_toy=3.0`" in text
    assert text.count("mentor_toy") == 1  # not said of options, which does not read it


def test_subgoal_mentor_is_mentor_fade_with_the_segment_term_and_trial():
    """The hierarchy study's choice (experiments/results/hierarchy/preset_choice.json): the
    mentor-fade preset, both hierarchical mentor terms on; nothing else differs."""
    fade, subgoal = PRESETS["mentor-fade"].changes(), PRESETS["subgoal-mentor"].changes()
    assert {k: v for k, v in subgoal.items() if fade.get(k, v) != v or k not in fade} == {
        "mentor_segments": True,
        "mentor_trial": True,
    }
    assert subgoal["mentor_fade"] == 20.0 and subgoal["eps_schedule"] == "decision"
    learner = apply_preset(LearnerConfig(), "subgoal-mentor")
    assert learner.mentor_segments and learner.mentor_trial
    # a run under it names both terms for the imitators, none for the others; a record under
    # another preset still names neither (they are at their defaults there)
    assert agent_settings("imitation", learner)["mentor_segments"] is True
    assert agent_settings("options", learner)["mentor_trial"] is None
    assert "mentor_segments" not in agent_settings(
        "imitation", apply_preset(LearnerConfig(), "paper")
    )
    config = EXPERIMENTS["exp2"].with_preset("subgoal-mentor")
    with pytest.raises(ValueError, match=r"learner\.mentor_trial=False \(the preset: True\)"):
        dataclasses.replace(config, learner=dataclasses.replace(config.learner, mentor_trial=False))
