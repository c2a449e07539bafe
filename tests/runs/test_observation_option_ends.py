"""A mentor seen only where its options end (``ExperimentConfig.observation = "option-ends"``):
the learner watches each seed's recorded episodes at the mentor's subgoals, and the setting is
refused, by name, beside a setting that changes what the mentor shows."""

import pytest
import torch

from himit_torch import mentor_options, mentor_policy, run_mentor
from himit_torch.runs.config import ExperimentConfig
from tests.runs.watching import watched_run


@pytest.mark.parametrize(
    "changes, message",
    [
        (dict(observation="doorways"), r"observation='doorways': use one of"),
        (dict(observation="option-ends", observation_stride=5), "observation='option-ends'.* "
         "cannot be combined with observation_stride=5"),
        (dict(observation="option-ends", mentor_noise=0.3), "observation='option-ends'.* "
         "cannot be combined with mentor_noise=0.3"),
        (dict(observation="option-ends", mentor_model="exact"), "mentor_model=.exact.* cannot "
         "show observation='option-ends'"),
    ],
)  # fmt: skip
def test_bad_settings_are_refused_by_name(changes, message):
    with pytest.raises(ValueError, match=f"ExperimentConfig.{message}"):
        ExperimentConfig(**changes)


def test_the_learner_sees_the_recorded_episodes_where_the_mentors_options_end(
    tmp_path, monkeypatch
):
    config, coarse = watched_run(tmp_path, monkeypatch, name="ends", observation="option-ends")
    world = config.world(16)
    # the episodes the run recorded for seed 0, with where each of the mentor's options began
    mentor = mentor_policy(world, mentor_options(world, corners=config.corner_options),
                           config.mentor_preference)  # fmt: skip
    rollout = run_mentor(world, mentor, 3, seed=0)
    assert coarse.num_episodes == 3
    for full, begun, kept in zip(rollout.states, rollout.decision_steps, coarse.episodes):
        ends = sorted({0, len(full) - 1, *begun.tolist()})
        assert kept.tolist() == full[ends].tolist()
        assert len(ends) < len(full)  # some steps unseen: an option of several steps ran
    # each observed move's duration is the option's steps; together the whole episode's
    assert int(coarse.durations().sum()) == sum(len(e) - 1 for e in rollout.states)
    assert torch.equal(coarse.full.episodes[0], rollout.states[0])
