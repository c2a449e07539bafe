"""Every ``himit run STUDY`` takes its flags from its configuration class: each declared setting
(the learner's too, where the study has one) is a flag of that study, listed by its ``--help``;
a flag of another study's is refused in one line (exit status 2)."""

import argparse
import dataclasses

import pytest

from himit_torch.cli import build_parser, main, study_configs
from himit_torch.learner.config import LearnerConfig
from himit_torch.runs.studies import STUDIES
from himit_torch.validation import settings_of


def _study_parser(name: str) -> argparse.ArgumentParser:
    parser = build_parser()
    run = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    studies = next(
        a for a in run.choices["run"]._actions if isinstance(a, argparse._SubParsersAction)
    )
    return studies.choices[name]


def _expected_flags(name: str) -> set[str]:
    study = STUDIES[name]
    config_class = study.config_class
    names = {
        s.name
        for s in settings_of(config_class)
        if s.name not in study.skip and not dataclasses.is_dataclass(s.kind)
    }
    if any(f.name == "learner" for f in dataclasses.fields(config_class)):
        derived = config_class.derived_learner
        names |= {s.name for s in settings_of(LearnerConfig) if s.name not in derived}
    return {"--" + n.replace("_", "-") for n in names}


@pytest.mark.parametrize("name", sorted(STUDIES))
def test_help_lists_every_setting_of_the_study(name):
    text = _study_parser(name).format_help()
    missing = sorted(f for f in _expected_flags(name) if f not in text)
    assert not missing, f"himit run {name} --help lacks {missing}"


@pytest.mark.parametrize("name", sorted(STUDIES))
def test_the_study_parser_has_exactly_its_settings(name):
    parser = _study_parser(name)
    flags = {o for a in parser._actions for o in a.option_strings if o.startswith("--")}
    run_flags = {"--help", "--quick", "--logdir", "--force", "--quiet", "--config"}
    run_flags |= {"--resume", "--workers"}
    settings = {f for f in flags - run_flags if not f.startswith("--no-")}
    assert settings == _expected_flags(name)


def test_gymnasium_help_is_the_gymnasium_study_s():
    text = _study_parser("gymnasium").format_help()
    assert "GymExperimentConfig" in text and "--tasks" in text and "--gamma" in text
    assert "--sizes" not in text and "--room-size" not in text


def test_gymnasium_takes_a_learner_setting():
    args = build_parser().parse_args(["run", "gymnasium", "--mentor-fade", "20"])
    config = study_configs(args)[0]
    assert config.learner.mentor_fade == 20.0 and config.learner.window == config.window


def test_puzzlebox_takes_a_preset():
    args = build_parser().parse_args(["run", "puzzlebox", "--preset", "recommended"])
    config = study_configs(args)[0]
    assert config.preset == "recommended"
    assert config == type(config)().with_preset("recommended")


def test_puzzlebox_takes_its_own_settings():
    argv = ["run", "puzzlebox", "--skewers", "3", "--variants", "no_pinch", "--window", "1000"]
    (config,) = study_configs(build_parser().parse_args(argv))
    assert (config.skewers, config.variants, config.learner.window) == (3, ("no_pinch",), 1000)


@pytest.mark.parametrize(
    "argv, flag",
    [
        (["gymnasium", "--sizes", "8"], "--sizes"),
        (["discovery", "--observation-stride", "2"], "--observation-stride"),
        (["puzzlebox", "--workers", "2"], "--workers"),
        (["puzzlebox", "--tasks=taxi"], "--tasks"),
        (["paper", "--name", "x"], "--name"),
    ],
)
def test_a_flag_of_another_study_is_refused_in_one_line(capsys, argv, flag):
    with pytest.raises(SystemExit) as exc:
        main(["run", *argv])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("himit: error: "), err
    assert f"himit run {argv[0]} takes no {flag}" in err
