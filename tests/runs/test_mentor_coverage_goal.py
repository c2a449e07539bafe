"""Demonstrations that cover part of the way (``ExperimentConfig.mentor_coverage``) and a mentor
demonstrating another goal (``ExperimentConfig.mentor_goal``)."""

import math

import pytest
import torch

from himit_torch import Demonstrations, MultiRooms
from himit_torch.mentor.observation import first_part
from himit_torch.runs.config import ExperimentConfig
from tests.runs.watching import watched_run


def test_first_part_keeps_the_start_of_each_episode():
    world = MultiRooms(8, 2)
    demos = Demonstrations([torch.tensor([0, 1, 9, 10, 18]), torch.tensor([0, 1, 9])], world)
    assert [e.tolist() for e in first_part(demos, 0.5).episodes] == [[0, 1, 9], [0, 1]]
    assert [e.tolist() for e in first_part(demos, 0.01).episodes] == [[0, 1], [0, 1]]
    assert [e.tolist() for e in first_part(demos, 1.0).episodes] == [
        e.tolist() for e in demos.episodes
    ]
    for bad in (0, 1.5, -0.1, "half", True):
        with pytest.raises(ValueError, match="coverage"):
            first_part(demos, bad)


@pytest.mark.parametrize(
    "changes, message",
    [
        (dict(mentor_coverage=0), r"mentor_coverage=0.0 must lie in \(0, 1\]"),
        (dict(mentor_goal="bottom-left"), r"mentor_goal='bottom-left': use one of"),
        (dict(mentor_goal="top-right", mentor_detour=True), "mentor_goal=.top-right.: .* detour"),
        (
            dict(mentor_model="exact", mentor_coverage=0.5),
            "mentor_model=.exact.* cannot show mentor_coverage=0.5",
        ),
    ],
)
def test_bad_settings_are_refused_by_name(changes, message):
    with pytest.raises(ValueError, match=f"ExperimentConfig.{message}"):
        ExperimentConfig(**changes)


def test_coverage_keeps_the_first_part_of_each_route(tmp_path, monkeypatch):
    _, whole = watched_run(tmp_path / "a", monkeypatch)
    config, half = watched_run(tmp_path / "b", monkeypatch, mentor_coverage=0.5)
    goal = config.world(16).goal_state
    for full, part in zip(whole.episodes, half.episodes):
        assert torch.equal(part, full[: math.ceil(0.5 * full.numel())])
        assert goal not in part.tolist()


def test_another_goal_is_the_walk_to_the_top_right_corner(tmp_path, monkeypatch):
    config, demos = watched_run(tmp_path, monkeypatch, mentor_goal="top-right")
    world = config.world(16)
    for episode in demos.episodes:
        assert int(episode[-1]) == 15  # the top-right corner cell (0, 15)
        assert world.goal_state not in episode.tolist()
    demos.check_world(world)  # shown in the learner's own world
