"""Demonstrations to and from local Minari datasets: the round trip, and bad datasets refused
(generated here: other spaces, other worlds, out-of-range and impossible states, damaged
files, and metadata that would make Minari import a module). Never any network: every dataset
lives under a temporary MINARI_DATASETS_PATH."""

from __future__ import annotations

import json
import sys
import warnings

import numpy as np
import pytest
import torch
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

pytest.importorskip("minigrid")
minari = pytest.importorskip("minari")

import gymnasium  # noqa: E402
from minari.data_collector import EpisodeBuffer  # noqa: E402

import himit_torch as ht  # noqa: E402
from himit_torch.mentor.minari import (  # noqa: E402
    demonstrations_from_minari,
    demonstrations_to_minari,
)


@pytest.fixture(autouse=True)
def local_datasets(tmp_path, monkeypatch):
    """Datasets under a temporary folder; a download attempt fails the test."""
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "datasets"))

    def no_network(*args, **kwargs):
        raise AssertionError("Minari tried to download")

    monkeypatch.setattr(minari.storage.hosting, "download_dataset", no_network)
    return tmp_path / "datasets"


@pytest.fixture(scope="module")
def doorkey():
    return ht.from_minigrid("MiniGrid-DoorKey-5x5-v0")


@pytest.fixture(scope="module")
def mentor(doorkey):
    return ht.minigrid_mentor(doorkey)


_counter = iter(range(10**6))


def write(observations, space, actions=None, description=None) -> str:
    """A dataset of the given episodes' observations written by Minari itself; its id."""
    dataset_id = f"test/bad{next(_counter)}-v0"
    buffers = []
    for i, obs in enumerate(observations):
        T = len(obs) - 1 if isinstance(obs, list) else len(next(iter(obs.values()))) - 1
        buffers.append(
            EpisodeBuffer(
                id=i,
                observations=obs,
                actions=[0] * T if actions is None else actions,
                rewards=[0.0] * T,
                terminations=[False] * (T - 1) + [True],
                truncations=[False] * T,
                infos={},
            )
        )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        minari.create_dataset_from_buffers(
            dataset_id,
            buffers,
            observation_space=space,
            action_space=gymnasium.spaces.Discrete(6),
            description=description,
        )
    return dataset_id


def test_round_trip(doorkey, mentor, local_datasets):
    dataset = demonstrations_to_minari(doorkey, mentor, "himit/doorkey-v0", episodes=3)
    assert dataset.total_episodes == 3
    demos = demonstrations_from_minari("himit/doorkey-v0", doorkey)
    # the real env, stepped with the mentor's choices, made the mentor's own episodes
    rollout = ht.run_mentor(doorkey, mentor, episodes=3, seed=0)
    assert [e.tolist() for e in demos.episodes] == [e.tolist() for e in rollout.states]
    assert all(bool(doorkey.goal_mask[e[-1]]) for e in demos.episodes)
    # read by id, by folder and as the loaded dataset: the same
    folder = local_datasets / "himit" / "doorkey-v0"
    for source in (folder, folder / "data", dataset):
        again = demonstrations_from_minari(source, doorkey)
        assert [e.tolist() for e in again.episodes] == [e.tolist() for e in demos.episodes]
    assert len(demonstrations_from_minari(folder, doorkey, episodes=2).episodes) == 2
    # actions and rewards are Minari's usual fields, from the real env
    episode = next(iter(dataset.iterate_episodes([0])))
    assert episode.rewards[-1] > 0 and bool(episode.terminations[-1])


def test_round_trip_of_a_toy_text_world():
    taxi = ht.from_gymnasium("Taxi-v4")
    mentor = ht.mentor_policy(taxi, ht.primitive_options(taxi))
    demonstrations_to_minari(taxi, mentor, "himit/taxi-v0", episodes=4, seed=3)
    demos = demonstrations_from_minari("himit/taxi-v0", taxi)
    assert len(demos.episodes) == 4
    assert all(bool(taxi.terminal_mask[e[-1]]) for e in demos.episodes)
    starts = {int(e[0]) for e in demos.episodes}
    assert len(starts) > 1  # a reset seed per episode


def test_slip_is_the_worlds_in_recorded_episodes():
    world = ht.from_minigrid("MiniGrid-DoorKey-5x5-v0", slip=0.3)
    mentor = ht.minigrid_mentor(world)
    demonstrations_to_minari(world, mentor, "himit/slippery-v0", episodes=4, seed=1)
    demos = demonstrations_from_minari("himit/slippery-v0", world)  # every step checked
    plain = ht.run_mentor(ht.from_minigrid("MiniGrid-DoorKey-5x5-v0"), mentor, episodes=1)
    assert max(len(e) for e in demos.episodes) > len(plain.states[0])


# ------------------------------------------------------------------------------- refused
def test_another_worlds_dataset_is_refused(doorkey, mentor):
    demonstrations_to_minari(doorkey, mentor, "himit/plain-v0", episodes=1)
    slippery = ht.from_minigrid("MiniGrid-DoorKey-5x5-v0", slip=0.1)  # same S, other world
    with pytest.raises(ValueError, match="recorded in another world.*slip"):
        demonstrations_from_minari("himit/plain-v0", slippery)
    with pytest.raises(ValueError, match=r"Discrete\(270\) but the world has 1294"):
        demonstrations_from_minari("himit/plain-v0", ht.from_minigrid("MiniGrid-DoorKey-6x6-v0"))


@pytest.mark.parametrize(
    "space, observations",
    [
        (
            gymnasium.spaces.Box(0, 255, (7, 7, 3), np.uint8),
            [[np.zeros((7, 7, 3), np.uint8)] * 3],
        ),
        (
            gymnasium.spaces.Dict({"direction": gymnasium.spaces.Discrete(4)}),
            [{"direction": [0, 1, 2]}],
        ),
        (gymnasium.spaces.Discrete(270, start=1), [[1, 2, 3]]),
        (gymnasium.spaces.Discrete(500), [[0, 1, 2]]),
    ],
    ids=["image", "dict", "discrete-from-1", "another-size"],
)
def test_observations_that_are_not_the_worlds_states(doorkey, space, observations):
    dataset_id = write(observations, space)
    with pytest.raises(ValueError, match="Discrete|states"):
        demonstrations_from_minari(dataset_id, doorkey)


@settings(
    max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(st.lists(st.integers(-5, 400), min_size=2, max_size=8))
def test_generated_observations_are_states_and_steps_of_the_world_or_refused(doorkey, values):
    """Whatever a dataset's observations hold: either demonstrations whose every step the world
    can make, or one ValueError."""
    dataset_id = write([values], gymnasium.spaces.Discrete(270))
    try:
        demos = demonstrations_from_minari(dataset_id, doorkey)
    except ValueError as err:
        assert str(err)
        return
    support = ht.transition_support(doorkey)
    (episode,) = demos.episodes
    assert all(bool(support[a, b]) for a, b in zip(episode[:-1].tolist(), episode[1:].tolist()))


def test_a_dataset_naming_an_environment_to_make_is_refused_unopened(doorkey, local_datasets):
    """Without its spaces in the metadata, Minari would gymnasium.make the env_spec, importing
    the module its entry point names: refused before Minari opens it."""
    dataset_id = write([[0, 1, 2]], gymnasium.spaces.Discrete(270))
    meta_path = local_datasets / "test" / dataset_id.split("/")[1] / "data" / "metadata.json"
    metadata = json.loads(meta_path.read_text())
    del metadata["observation_space"]
    metadata["env_spec"] = json.dumps(
        {"id": "Evil-v0", "entry_point": "himit_never_imported_module:Env", "kwargs": {}}
    )
    meta_path.write_text(json.dumps(metadata))
    with pytest.raises(ValueError, match="env_spec.*never done"):
        demonstrations_from_minari(dataset_id, doorkey)
    assert "himit_never_imported_module" not in sys.modules


@pytest.mark.parametrize(
    "damage, words",
    [
        (lambda d: (d / "metadata.json").write_text("{not json"), "metadata.json is damaged"),
        (lambda d: (d / "metadata.json").write_text("[1, 2]"), "not an object"),
        (lambda d: _edit_metadata(d, data_format="pickle"), "data_format 'pickle'"),
        (lambda d: _edit_metadata(d, observation_space="{oops"), "observation space is damaged"),
        (lambda d: (d / "main_data.hdf5").write_bytes(b"\x89HDF\r\n\x1a\n" + b"0" * 64), "Minari"),
        (lambda d: _truncate(d / "main_data.hdf5"), "Minari|damaged"),
    ],
    ids=["metadata-garbage", "metadata-list", "format", "space", "hdf5-garbage", "hdf5-cut"],
)
def test_damaged_datasets(doorkey, mentor, local_datasets, damage, words):
    demonstrations_to_minari(doorkey, mentor, "himit/damaged-v0", episodes=2)
    damage(local_datasets / "himit" / "damaged-v0" / "data")
    with pytest.raises(ValueError, match=words):
        demonstrations_from_minari("himit/damaged-v0", doorkey)


def _edit_metadata(data, **fields):
    metadata = json.loads((data / "metadata.json").read_text())
    metadata.update(fields)
    (data / "metadata.json").write_text(json.dumps(metadata))


def _truncate(path):
    raw = path.read_bytes()
    path.write_bytes(raw[: len(raw) // 3])


@pytest.mark.parametrize(
    "dataset, words",
    [
        ("himit/absent-v0", "no local Minari dataset.*never"),
        ("../../etc/passwd", "no Minari dataset at"),
        ("/no/such/folder", "no Minari dataset at"),
    ],
)
def test_missing_datasets_are_refused_without_a_download(doorkey, dataset, words):
    with pytest.raises(ValueError, match=words):
        demonstrations_from_minari(dataset, doorkey)


def test_wrong_kinds_of_argument(doorkey, mentor):
    with pytest.raises(TypeError, match="dataset must be"):
        demonstrations_from_minari(3, doorkey)
    with pytest.raises(TypeError, match="MentorPolicy"):
        demonstrations_to_minari(doorkey, mentor.options, "himit/x-v0")
    with pytest.raises(ValueError, match="dataset_id"):
        demonstrations_to_minari(doorkey, mentor, "../up-v0")
    with pytest.raises(ValueError, match="episodes"):
        demonstrations_to_minari(doorkey, mentor, "himit/x-v0", episodes=0)
    world = ht.TableWorld(
        doorkey.dynamics_table(),
        doorkey.start_distribution,
        doorkey.terminal_mask,
    )
    with pytest.raises(ValueError, match="real environment"):
        demonstrations_to_minari(world, mentor, "himit/x-v0")
    assert torch.equal(world.terminal_mask, doorkey.terminal_mask)
