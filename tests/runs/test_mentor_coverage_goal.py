"""Demonstrations that cover part of the way (``ExperimentConfig.mentor_coverage``) and a mentor
demonstrating another goal (``ExperimentConfig.mentor_goal``)."""

import math

import pytest
import torch

from himit_torch import Demonstrations, MultiRooms
from himit_torch.mentor.observation import first_part
from himit_torch.runs import experiment as experiment_module
from himit_torch.runs.config import ExperimentConfig, load_config
from himit_torch.runs.experiment import run_experiment


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


def _watched(tmp_path, monkeypatch, **changes):
    seen = {}
    real_watch = experiment_module.watch_demonstrations

    def watch(learner, demos, mentor=0):
        seen.update(demos)
        real_watch(learner, demos, mentor)

    monkeypatch.setattr(experiment_module, "watch_demonstrations", watch)
    config = ExperimentConfig(name="part", sizes=(16,), room_size=4, seeds=1, steps=1000,
                              window=1000, checkpoint_every=1000, mentor_episodes=3,
                              agents=("imitation",), **changes)  # fmt: skip
    run_experiment(config, tmp_path / "run", progress=False, workers=1)
    assert load_config(tmp_path / "run" / "config.json") == config
    return config, seen[0]


def test_coverage_keeps_the_first_part_of_each_route(tmp_path, monkeypatch):
    _, whole = _watched(tmp_path / "a", monkeypatch)
    config, half = _watched(tmp_path / "b", monkeypatch, mentor_coverage=0.5)
    goal = config.world(16).goal_state
    for full, part in zip(whole.episodes, half.episodes):
        assert torch.equal(part, full[: math.ceil(0.5 * full.numel())])
        assert goal not in part.tolist()


def test_another_goal_is_the_walk_to_the_top_right_corner(tmp_path, monkeypatch):
    config, demos = _watched(tmp_path, monkeypatch, mentor_goal="top-right")
    world = config.world(16)
    for episode in demos.episodes:
        assert int(episode[-1]) == 15  # the top-right corner cell (0, 15)
        assert world.goal_state not in episode.tolist()
    demos.check_world(world)  # shown in the learner's own world
