"""What a ``himit run gymnasium`` / ``minigrid`` run sees of its mentor
(``GymExperimentConfig.observation``, ``observation_stride``): the recorded episodes, every k-th
state of them, or the states where the mentor's options end."""

import pytest
import torch

from himit_torch import CoarseDemonstrations, Demonstrations, minigrid_mentor, run_mentor
from himit_torch.mentor.policy import record_demonstrations
from himit_torch.runs import gymnasium as gym_runs
from himit_torch.runs.gymnasium import GymExperimentConfig, MiniGridExperimentConfig


@pytest.fixture(scope="module")
def doorkey():
    world = gym_runs.TASKS["doorkey5x5"].world(0.99)
    return world, minigrid_mentor(world)


def test_bad_observations_are_refused_by_name():
    with pytest.raises(ValueError, match="observation='option-ends'.*observation_stride=5"):
        MiniGridExperimentConfig(observation="option-ends", observation_stride=5)
    with pytest.raises(ValueError, match="observation"):
        GymExperimentConfig(observation="doorways")
    with pytest.raises(ValueError, match="observation_stride"):
        GymExperimentConfig(observation_stride=0)


def test_every_state_is_the_recorded_demonstrations(doorkey):
    world, mentor = doorkey
    seen = gym_runs._observed(MiniGridExperimentConfig(mentor_episodes=3), world, mentor, 7)
    recorded = record_demonstrations(world, mentor, 3, seed=7)
    assert isinstance(seen, Demonstrations)
    assert all(torch.equal(a, b) for a, b in zip(seen.episodes, recorded.episodes))
    coarse = gym_runs._observed(
        MiniGridExperimentConfig(mentor_episodes=3, observation_stride=4), world, mentor, 7
    )
    assert isinstance(coarse, CoarseDemonstrations) and coarse.stride == 4
    assert [e.tolist() for e in coarse.episodes] == [
        e[sorted({*range(0, len(e), 4), len(e) - 1})].tolist() for e in recorded.episodes
    ]


def test_option_ends_are_the_mentors_subgoals_in_the_recorded_episodes(doorkey):
    world, mentor = doorkey
    config = MiniGridExperimentConfig(mentor_episodes=3, observation="option-ends")
    seen = gym_runs._observed(config, world, mentor, 7)
    rollout = run_mentor(world, mentor, 3, seed=7)
    recorded = record_demonstrations(world, mentor, 3, seed=7)
    for full, begun, kept in zip(recorded.episodes, rollout.decision_steps, seen.episodes):
        ends = sorted({0, len(full) - 1, *begun.tolist()})
        assert kept.tolist() == full[ends].tolist()
        assert len(kept) < len(full)  # its skills take several steps, unseen
    assert int(seen.durations().sum()) == sum(len(e) - 1 for e in recorded.episodes)
