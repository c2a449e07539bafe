"""A second mentor in an experiment (``ExperimentConfig.second_mentor``): its own episodes, from
its own generator, watched as the learner's second mentor; the first mentor's episodes stay
those of a run without it (paired seeds)."""

from dataclasses import replace

import pytest
import torch

from himit_torch import LearnerConfig
from himit_torch.runs import experiment as experiment_module
from himit_torch.runs.config import ExperimentConfig, load_config
from himit_torch.runs.experiment import run_experiment


@pytest.mark.parametrize(
    "changes, message",
    [
        (dict(second_mentor="expert"), r"second_mentor='expert': use one of"),
        (
            dict(second_mentor="noisy", learner=LearnerConfig(mentors=2), second_mentor_noise=1),
            r"second_mentor_noise=1.0 must lie in \[0, 1\)",
        ),
        (
            dict(second_mentor="detour", learner=LearnerConfig(mentors=2), mentor_model="exact"),
            "mentor_model=.exact.* cannot show second_mentor='detour'",
        ),
    ],
)
def test_bad_second_mentor_settings_are_refused_by_name(changes, message):
    with pytest.raises(ValueError, match=f"ExperimentConfig.{message}"):
        ExperimentConfig(**changes)


@pytest.mark.parametrize(
    "second, given, mentors", [("noisy", 1, 2), ("detour", 1, 2), ("none", 2, 1), ("none", 1, 1)]
)
def test_the_learner_s_mentors_are_derived_from_the_second_mentor(second, given, mentors):
    """One policy for the learner settings a study derives (as its window): set by the study,
    whatever the learner held, and recorded in config.json."""
    config = ExperimentConfig(second_mentor=second, learner=LearnerConfig(mentors=given))
    assert config.learner.mentors == mentors
    assert f'"mentors": {mentors}' in config.to_json()


def _tiny(**changes) -> ExperimentConfig:
    settings = dict(
        name="two",
        sizes=(16,),
        room_size=4,
        seeds=2,
        steps=2000,
        window=1000,
        checkpoint_every=1000,
        mentor_episodes=3,
        agents=("imitation",),
    )
    settings.update(changes)
    return ExperimentConfig(**settings)


# (two tiny experiments each, ≈ 5 s: the fast suite runs the detour, CI both)
@pytest.mark.parametrize("kind", [pytest.param("noisy", marks=pytest.mark.slow), "detour"])
def test_the_second_mentor_is_watched_as_mentor_1(tmp_path, monkeypatch, kind):
    watched = {}
    real_watch = experiment_module.watch_demonstrations

    def watch(learner, demos, mentor=0):
        watched[mentor] = (learner, dict(demos))
        real_watch(learner, demos, mentor)

    monkeypatch.setattr(experiment_module, "watch_demonstrations", watch)
    config = _tiny(second_mentor=kind, learner=LearnerConfig(mentors=2))
    run_experiment(config, tmp_path / "two", progress=False, workers=1)
    assert load_config(tmp_path / "two" / "config.json") == config
    (learner, first), (_, second) = watched[0], watched[1]
    S = config.world(16).num_states
    assert float(learner.mentor.row_count[:, S:].sum()) > 0  # mentor 1's rows were filled
    for seed in (0, 1):
        assert not torch.equal(first[seed].episodes[0], second[seed].episodes[0])
    if kind == "detour":  # every episode passes the top-right corner
        assert all(bool((e == 15).any()) for e in second[0].episodes)
    alone = {}
    monkeypatch.setattr(
        experiment_module,
        "watch_demonstrations",
        lambda learner, demos, mentor=0: alone.update(demos),
    )
    run_experiment(replace(config, second_mentor="none", learner=LearnerConfig()),
                   tmp_path / "one", progress=False, workers=1)  # fmt: skip
    for seed in (0, 1):  # the first mentor shows what it shows without a second one
        for a, b in zip(alone[seed].episodes, first[seed].episodes):
            assert torch.equal(a, b)
