"""``himit run``: a flag for every setting of ExperimentConfig and LearnerConfig, generated from
their declarations; precedence (the experiment's defaults < --config < flags); bad values are
one line on stderr and exit status 2."""

from __future__ import annotations

import dataclasses
import json

import pytest

from himit_torch.cli import build_parser, main, plain_text
from himit_torch.learner.config import LearnerConfig
from himit_torch.runs.config import EXPERIMENTS, ExperimentConfig
from himit_torch.validation import settings_of

#: A flag value for every learner setting, each different from its default and from exp1's, and
#: the value the config must then hold (text → number by the config's own rules).
LEARNER_FLAGS = {
    "backups": ("12", 12),
    "sweep_rounds": ("3", 3),
    "plan_every": ("2", 2),
    "rng_chunk": ("64", 64),
    "priority_threshold": ("1e-4", 1e-4),
    "initial_value": ("0", 0.0),
    "untried_value": ("-0.5", -0.5),
    "concentration": ("0.5", 0.5),
    "mentor_concentration": ("2", 2.0),
    "confidence_z": ("1.96", 1.96),
    "mentor_override_after": ("7", 7),
    "mentor_fade": ("20", 20.0),
    "mentor_segments": (None, True),  # (None: a switch, given as --mentor-segments)
    "mentor_feasibility": ("3", 3),
    "mentors": ("2", 2),  # (with --second-mentor noisy: a second set to watch)
    "eps_start": ("0.5", 0.5),
    "eps_decay": ("0.99", 0.99),
    "eps_min": ("0.05", 0.05),
    "eps_schedule": ("goals", "goals"),
    "eps_goals": ("30", 30),
    "option_models": ("exact", "exact"),
    "exact_model_count": ("1e3", 1000.0),
    "mentor_choice": ("match", "match"),
    "mentor_trial": (None, True),
    "tie_break": ("first", "first"),
    "max_option_steps": ("500", 500),
    "resample_every": ("5", 5),
    "reward_bound_check": ("warn", "warn"),
    "bco_every": ("250", 250),
    "bco_inverse_model": ("counts", "counts"),
}
#: The same for the experiment's settings.
EXPERIMENT_FLAGS = {
    "name": (["mine"], "mine"),
    "sizes": (["16", "24"], (16, 24)),
    "room_size": (["8"], 8),
    "corner_options": ([], False),  # given as --no-corner-options (exp1 has them)
    "agents": (["options", "primitives"], ("options", "primitives")),
    "seeds": (["3"], 3),
    "first_seed": (["4"], 4),
    "steps": (["12000"], 12_000),
    "mentor_episodes": (["6"], 6),
    "mentor_reward": (["salience"], "salience"),
    "mentor_preference": (["0.25"], 0.25),
    "mentor_model": (["exact"], "exact"),
    "slip": (["0.2"], 0.2),
    "mentor_noise": (["0.3"], 0.3),
    "mentor_detour": ([], True),  # given as --mentor-detour
    "mentor_coverage": (["0.5"], 0.5),
    "mentor_goal": (["top-right"], "top-right"),
    "observation": (["option-ends"], "option-ends"),
    "second_mentor": (["noisy"], "noisy"),  # (learner.mentors derived: 2)
    "second_mentor_noise": (["0.3"], 0.3),
    "observation_stride": (["5"], 5),
    "layout": (["maze"], "maze"),
    "goal_needs_primitives": ([], True),
    "window": (["2000"], 2000),
    "checkpoint_every": (["10000"], 10_000),
    "greedy_every": (["20000"], 20_000),
    "device": (["cpu:0"], "cpu:0"),
    "engine": (["torch"], "torch"),
    "preset": (["recommended"], "recommended"),
}


def _flag(name: str) -> str:
    return "--" + name.replace("_", "-")


def test_every_setting_has_a_value_here():
    """The tables above cover every declared field (learner's window: the experiment's)."""
    assert set(LEARNER_FLAGS) == {s.name for s in settings_of(LearnerConfig)} - {"window"}
    assert set(EXPERIMENT_FLAGS) == {s.name for s in settings_of(ExperimentConfig)} - {"learner"}


def test_the_experiment_s_derived_learner_settings_are_no_flags(planned, capsys):
    """The learner's mentors follow --second-mentor (derived and recorded, as its window
    follows --window): --mentors is no flag of the paper's experiments."""
    (config,) = planned(["exp1", "--second-mentor", "noisy"])
    assert config.learner.mentors == 2
    with pytest.raises(SystemExit):
        planned(["exp1", "--mentors", "2"])
    assert "takes no --mentors" in capsys.readouterr().err


def test_help_lists_every_setting_with_its_doc():
    run = build_parser()._subparsers._group_actions[0].choices["run"]  # type: ignore[union-attr]
    exp1 = run._subparsers._group_actions[0].choices["exp1"]  # type: ignore[union-attr]
    text = " ".join(exp1.format_help().split())
    derived = set(ExperimentConfig.derived_learner)  # (the study's own flags set them)
    for cls, skip in ((LearnerConfig, derived), (ExperimentConfig, {"learner"})):
        for s in settings_of(cls):
            if s.name in skip:
                continue
            assert _flag(s.name) in text, s.name
            # the doc as a terminal shows it: its Sphinx markup stripped (cli.plain_text)
            assert " ".join(plain_text(s.info.doc).split()[:6]) in text, s.name


@pytest.mark.parametrize("field", sorted(set(LEARNER_FLAGS) - {"mentors"}))
def test_each_learner_flag_reaches_the_config_of_the_run(planned, field):
    text, expected = LEARNER_FLAGS[field]
    extra = {"sweep_rounds": ["--backups", "12"]}.get(field, [])
    (config,) = planned(["exp1", _flag(field), *([] if text is None else [text]), *extra])
    assert getattr(config.learner, field) == expected
    untouched = {k: v for k, v in dataclasses.asdict(config.learner).items() if k != field}
    reference = dataclasses.asdict(EXPERIMENTS["exp1"].learner)
    changed = {"backups": 12} if field == "sweep_rounds" else {}
    assert untouched == {k: reference[k] for k in untouched} | changed


@pytest.mark.parametrize("field", sorted(EXPERIMENT_FLAGS))
def test_each_experiment_flag_reaches_the_config_of_the_run(planned, field):
    values, expected = EXPERIMENT_FLAGS[field]
    flag = "--no-corner-options" if field == "corner_options" else _flag(field)
    extra = {
        "window": ["--checkpoint-every", "4000"],
        "room_size": ["--sizes", "16"],
    }
    (config,) = planned(["exp1", flag, *values, *extra.get(field, [])])
    assert getattr(config, field) == expected


def test_mentor_fade_and_tie_break_as_in_the_issue(planned):
    (config,) = planned(["exp1", "--mentor-fade", "20", "--tie-break", "first"])
    assert config.learner.mentor_fade == 20.0 and config.learner.tie_break == "first"
    assert config.learner.plan_every == 4 and config.learner.sweep_rounds == 1  # exp1's own
    assert dataclasses.replace(config, learner=EXPERIMENTS["exp1"].learner) == EXPERIMENTS["exp1"]


def test_precedence_defaults_experiment_config_file_flags(planned, tmp_path):
    file_config = dataclasses.replace(
        EXPERIMENTS["exp2"],
        seeds=3,
        learner=LearnerConfig(plan_every=2, mentor_fade=5, backups=8),
    )
    path = tmp_path / "config.json"
    path.write_text(file_config.to_json())
    (config,) = planned(["exp2", "--config", str(path), "--mentor-fade", "20", "--seeds", "4"])
    assert config.learner.mentor_fade == 20.0  # flag over file
    assert config.seeds == 4  # flag over file
    assert config.learner.plan_every == 2 and config.learner.backups == 8  # file over experiment
    assert config.learner.sweep_rounds == 2  # the file's, the library default, not exp2's 1
    (config,) = planned(["exp2"])
    assert config.learner.plan_every == 4 and config.learner.sweep_rounds == 1  # exp2's own
    assert config.learner.backups == LearnerConfig().backups  # library default


def test_quick_then_flags(planned):
    (config,) = planned(["exp2", "--quick", "--seeds", "5"])
    assert config.seeds == 5 and config.steps == EXPERIMENTS["exp2"].quick().steps


def test_steps_flag_keeps_a_checkpoint_before_the_end_unless_given(planned):
    (config,) = planned(["exp2", "--steps", "12000"])
    assert config.checkpoint_every == 10_000
    (config,) = planned(["exp2", "--steps", "12000", "--checkpoint-every", "5000"])
    assert config.checkpoint_every == 5000


@pytest.mark.parametrize(
    "argv, words",
    [
        (["exp1", "--mentor-fade", "inf"], "LearnerConfig.mentor_fade=inf must be a finite"),
        (["exp1", "--mentor-fade", "0"], "LearnerConfig.mentor_fade=0.0 must be > 0"),
        (["exp1", "--eps-goals", "2.5"], "LearnerConfig.eps_goals=2.5 is not a whole number"),
        (["exp1", "--backups", "1e30"], "LearnerConfig.backups=1000000000000000019884624838656"),
        (["exp1", "--backups", "ten"], "argument --backups: invalid whole number: 'ten'"),
        (["exp1", "--tie-break", "last"], "argument --tie-break: invalid choice: 'last'"),
        (["exp1", "--sweep-rounds", "20"], "sweep_rounds=20: must lie in 1…backups (10)"),
        (["exp1", "--eps-min", "0.9"], "eps_min=0.9: must not exceed eps_start=0.75"),
        (["exp1", "--sizes", "81"], "every size must be a positive multiple of room_size=8"),
        (["exp1", "--agents", "psrl"], "argument --agents: invalid choice: 'psrl'"),
        (["exp1", "--slip", "nan"], "ExperimentConfig.slip=nan must be a finite number"),
        (["exp1", "--untried-value", "nope"], "invalid number: 'nope' (or none)"),
        (["paper", "--name", "x"], "takes no --name"),
        (["gymnasium", "--sizes", "8"], "takes no --sizes"),
        (["gymnasium", "--workers", "2"], "takes no --workers"),
        (["puzzlebox", "--agents", "options"], "takes no --agents"),
        (["puzzlebox", "--slip", "1.5"], "PuzzleBoxConfig.slip=1.5"),
        (["discovery", "--device", "cpu"], "takes no --device"),
    ],
)
def test_bad_values_are_one_line_exit_2(capsys, tmp_path, argv, words):
    with pytest.raises(SystemExit) as exc:
        main(["run", *argv, "--logdir", str(tmp_path)])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("himit: error: "), err
    assert words in err


def test_none_turns_an_optional_setting_off(planned, tmp_path):
    path = tmp_path / "config.json"
    path.write_text(
        dataclasses.replace(EXPERIMENTS["exp2"], learner=LearnerConfig(mentor_fade=5)).to_json()
    )
    (config,) = planned(["exp2", "--config", str(path), "--mentor-fade", "none"])
    assert config.learner.mentor_fade is None


def test_a_flagged_run_resumes_only_with_the_configuration_it_started_with(capsys, tmp_path):
    """The run saves the configuration its flags made; ``--resume`` with the same flags, or with
    ``--config`` of that file, continues it; without them it is refused (exit 2)."""
    tiny = ["--sizes", "8", "--room-size", "4", "--agents", "primitives", "--seeds", "1"]
    tiny += ["--steps", "20", "--window", "10", "--mentor-episodes", "1", "--engine", "torch"]
    tiny += ["--logdir", str(tmp_path), "--quiet"]
    assert main(["run", "exp2", *tiny, "--mentor-fade", "20", "--tie-break", "first"]) == 0
    saved = json.loads((tmp_path / "exp2" / "config.json").read_text())
    assert saved["learner"]["mentor_fade"] == 20.0 and saved["learner"]["tie_break"] == "first"
    assert (
        main(["run", "exp2", *tiny, "--mentor-fade", "20", "--tie-break", "first", "--resume"]) == 0
    )
    config_file = str(tmp_path / "exp2" / "config.json")
    assert main(["run", "exp2", "--config", config_file, "--resume", *tiny[-3:]]) == 0
    capsys.readouterr()
    with pytest.raises(SystemExit) as exc:
        main(["run", "exp2", *tiny, "--resume"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "holds a different configuration" in err


@pytest.mark.parametrize("study", ["gymnasium", "puzzlebox"])
@pytest.mark.parametrize("field", sorted(LEARNER_FLAGS))
def test_each_learner_flag_reaches_the_learner_of_the_other_studies(study, field):
    """``himit run gymnasium`` and ``himit run puzzlebox`` take every learner setting as a flag
    (each study's own learner defaults otherwise); ``--mentors`` other than 1 is refused, as
    they show their learners one demonstration set."""
    from himit_torch.cli import build_parser, study_configs

    text, expected = LEARNER_FLAGS[field]
    extra = ["--backups", "12"] if field == "sweep_rounds" else []
    argv = ["run", study, _flag(field), *([] if text is None else [text]), *extra]
    if field == "mentors":
        with pytest.raises(ValueError, match="learner.mentors=2: .*mentors must be 1"):
            study_configs(build_parser().parse_args(argv))
        argv[3] = "1"
        expected = 1
    (config,) = study_configs(build_parser().parse_args(argv))
    assert getattr(config.learner, field) == expected
