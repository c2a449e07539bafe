"""The stresses as experiment settings (issue 26, part 2): validated fields of ExperimentConfig
that build the world, the mentor's demonstrations and what the learner observes of them, and are
recorded in config.json and results.md."""

import json
from dataclasses import replace

import pytest
import torch

from himit_torch.mentor.observation import CoarseDemonstrations
from himit_torch.runs import experiment as experiment_module
from himit_torch.runs.config import EXPERIMENTS, STRESS_SETTINGS, ExperimentConfig, load_config
from himit_torch.runs.experiment import run_experiment
from himit_torch.worlds.multirooms import maze_doorways, primitives_only_goal


@pytest.mark.parametrize(
    "changes, message",
    [
        (dict(observation_stride=0), "observation_stride=0 must be ≥ 1"),
        (dict(observation_stride=1.5), "observation_stride"),
        (dict(mentor_noise=1.0), r"mentor_noise=1.0 must lie in \[0, 1\)"),
        (dict(mentor_noise=-0.1), r"mentor_noise=-0.1 must lie in \[0, 1\)"),
        (dict(mentor_detour="yes"), "mentor_detour must be true or false"),
        (dict(layout="spiral"), r"layout='spiral': use one of \['open', 'maze'\]"),
        (dict(goal_needs_primitives=1), "goal_needs_primitives must be true or false"),
        (
            dict(mentor_model="exact", mentor_noise=0.1),
            "mentor_model=.exact.* cannot show mentor_noise=0.1",
        ),
        (
            dict(mentor_model="exact", mentor_detour=True),
            "mentor_model=.exact.* cannot show mentor_detour=True",
        ),
        (
            dict(mentor_model="exact", observation_stride=2),
            "mentor_model=.exact.* cannot show observation_stride=2",
        ),
        (
            dict(sizes=(12,), room_size=3, goal_needs_primitives=True),
            "goal_needs_primitives: .* 2 free columns",
        ),
    ],
)
def test_stress_settings_refuse_bad_values_by_name(changes, message):
    with pytest.raises(ValueError, match=f"ExperimentConfig.{message}"):
        ExperimentConfig(**changes)


def test_the_defaults_build_the_papers_world():
    config = EXPERIMENTS["exp2"]
    assert config.stresses() == {}
    world = config.world(40)
    assert world.closed_doorways == () and world.goal_state == 40 * 40 - 1


def test_layout_and_goal_settings_build_the_world():
    config = replace(EXPERIMENTS["exp1"], layout="maze", goal_needs_primitives=True)
    world = config.world(80)
    assert world.closed_doorways == tuple(sorted(maze_doorways(80, 10)))
    assert world.goal_state == primitives_only_goal(80, 10)
    assert config.stresses() == {"layout": "maze", "goal_needs_primitives": True}
    assert set(STRESS_SETTINGS) <= {f for f in json.loads(config.to_json())}


def tiny_stressed(**changes) -> ExperimentConfig:
    settings = dict(
        name="stressed",
        sizes=(16,),
        room_size=4,
        seeds=2,
        steps=2000,
        window=1000,
        checkpoint_every=1000,
        mentor_episodes=4,
        agents=("imitation", "options"),
        mentor_noise=0.2,
        mentor_detour=True,
        observation_stride=3,
        layout="maze",
        goal_needs_primitives=True,
    )
    settings.update(changes)
    return ExperimentConfig(**settings)


def test_a_run_with_every_stress_records_them_and_gives_the_learner_what_it_observed(
    tmp_path, monkeypatch
):
    config = tiny_stressed()
    watched = {}
    real_watch = experiment_module.watch_demonstrations

    def watch(learner, demos):
        watched.update(demos)
        real_watch(learner, demos)

    monkeypatch.setattr(experiment_module, "watch_demonstrations", watch)
    results = run_experiment(config, tmp_path / "run", progress=False, workers=1)
    assert load_config(tmp_path / "run" / "config.json") == config
    results_md = (tmp_path / "run" / "results.md").read_text()
    assert (
        "Stresses (docs/stresses.md): `mentor_noise=0.2`, `mentor_detour=True`, "
        "`observation_stride=3`, `layout=maze`, `goal_needs_primitives=True`." in results_md
    )
    assert results[0].steps == 2000
    world = config.world(16)
    assert sorted(watched) == [0, 1]
    for seen in watched.values():
        assert isinstance(seen, CoarseDemonstrations) and seen.stride == 3
        assert seen.full.num_episodes == 4
        for full, kept in zip(seen.full.episodes, seen.episodes):
            assert full[-1] == world.goal_state and kept[-1] == world.goal_state
            assert (full == world.size - 1).any()  # the detour's top-right corner
            assert torch.equal(kept, full[::3]) or torch.equal(kept[:-1], full[::3])
    # the two seeds were shown different episodes, each from its own generator
    assert not torch.equal(watched[0].full.episodes[0], watched[1].full.episodes[0])


def test_the_default_run_has_no_stress_line(tmp_path):
    config = tiny_stressed(
        mentor_noise=0.0,
        mentor_detour=False,
        observation_stride=1,
        layout="open",
        goal_needs_primitives=False,
        seeds=1,
        agents=("options",),
    )
    run_experiment(config, tmp_path / "run", progress=False, workers=1)
    assert "Stresses" not in (tmp_path / "run" / "results.md").read_text()


def test_the_stress_axes_are_sweep_factors(tmp_path):
    from himit_torch.runs.sweep import load_spec

    spec_path = tmp_path / "stress.toml"
    spec_path.write_text(
        'base = "exp2"\nseeds = 2\ndesign = "one-at-a-time"\n'
        "[grid]\nmentor_noise = [0.0, 0.1, 0.3]\nobservation_stride = [1, 2, 5]\n"
        'layout = ["open", "maze"]\nmentor_detour = [false, true]\n'
    )
    spec = load_spec(spec_path)
    stresses = [cell.config.stresses() for cell in spec.cells]
    assert stresses == [
        {},
        {"mentor_noise": 0.1},
        {"mentor_noise": 0.3},
        {"observation_stride": 2},
        {"observation_stride": 5},
        {"layout": "maze"},
        {"mentor_detour": True},
    ]
    spec_path.write_text('base = "exp2"\n[grid]\nobservation_stride = [1, 0]\n')
    with pytest.raises(ValueError, match="observation_stride=0 must be ≥ 1"):
        load_spec(spec_path)
