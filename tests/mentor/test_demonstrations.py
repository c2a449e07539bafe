"""Demonstrations: states only, an exact .npz round trip, and every validation error."""

import json
import re

import numpy as np
import pytest
import torch

from himit_torch.mentor.demonstrations import DEMONSTRATIONS_FORMAT_VERSION, Demonstrations
from himit_torch.worlds.multirooms import MultiRooms

# 8×8 cells, 2×2 rooms: wall row 4 and wall column 4; doorways (4, 2), (2, 4), (4, 6), (6, 4).
N = 8


def cell(r: int, c: int) -> int:
    return r * N + c


# From the start (0, 0) down through doorway (4, 2), east through doorway (6, 4), to the goal;
# one bump into a wall (the repeated (0, 1)).
PATH = [
    (0, 0),
    (0, 1),
    (0, 1),
    (0, 2),
    (1, 2),
    (2, 2),
    (3, 2),
    (4, 2),
    (5, 2),
    (6, 2),
    (6, 3),
    (6, 4),
    (6, 5),
    (6, 6),
    (7, 6),
    (7, 7),
]
EPISODES = [[cell(*p) for p in PATH], [cell(0, 0), cell(1, 0), cell(1, 1)]]


@pytest.fixture
def world() -> MultiRooms:
    return MultiRooms(size=N, rooms=2, slip=0.1)


@pytest.fixture
def demos(world) -> Demonstrations:
    return Demonstrations(EPISODES, world.describe())


@pytest.fixture
def saved(demos, tmp_path):
    return demos.save(tmp_path / "demos.npz")


def rewrite(path, **changes):
    """Rewrite a saved file with some keys replaced (``None`` drops the key)."""
    with np.load(path) as npz:
        arrays = {k: npz[k] for k in npz.files}
    for key, value in changes.items():
        if value is None:
            arrays.pop(key)
        else:
            arrays[key] = value
    with open(path, "wb") as f:
        np.savez(f, **arrays)
    return path


def file_error(path, *parts: str) -> str:
    """A ``match`` pattern: the file's name, then each part, in order."""
    return re.escape(str(path)) + ".*" + ".*".join(re.escape(p) for p in parts)


# ---------------------------------------------------------------------------------- contents
def test_counts_and_transitions(demos):
    assert demos.num_episodes == 2 and len(demos) == 2
    assert demos.num_transitions == (len(PATH) - 1) + 2
    assert demos.episode_lengths.tolist() == [len(PATH) - 1, 2]
    froms, tos = demos.transitions()
    assert froms.dtype == tos.dtype == torch.int64
    expected = list(zip(EPISODES[0][:-1], EPISODES[0][1:])) + list(
        zip(EPISODES[1][:-1], EPISODES[1][1:])
    )
    assert list(zip(froms.tolist(), tos.tolist())) == expected
    # No pair runs from the first episode's goal into the second episode's start.
    assert (cell(7, 7), cell(0, 0)) not in expected


def test_visited_states(demos):
    assert demos.visited_states().tolist() == sorted(set(EPISODES[0]) | set(EPISODES[1]))


def test_episodes_are_int64_copies(world):
    source = [np.array(EPISODES[1], dtype=np.int32)]
    demos = Demonstrations(source, world)  # a world is accepted in place of its description
    source[0][0] = 99
    assert demos.episodes[0].dtype == torch.int64
    assert demos.episodes[0].tolist() == EPISODES[1]
    assert demos.world_description == world.describe()


# ---------------------------------------------------------------------------------- the file
def test_save_load_round_trip_is_exact(demos, saved, world):
    loaded = Demonstrations.load(saved, world=world)
    assert loaded.num_episodes == demos.num_episodes
    for a, b in zip(loaded.episodes, demos.episodes):
        assert a.dtype == torch.int64 and torch.equal(a, b)
    assert loaded.world_description == world.describe()


def test_file_schema_holds_states_only(saved):
    with np.load(saved) as npz:
        assert sorted(npz.files) == ["episode_starts", "format_version", "states", "world"]
        assert int(npz["format_version"]) == DEMONSTRATIONS_FORMAT_VERSION
        assert npz["states"].dtype == np.int64 and npz["episode_starts"].dtype == np.int64
        assert npz["episode_starts"].tolist() == [0, len(PATH)]
        assert npz["states"].tolist() == EPISODES[0] + EPISODES[1]
        assert json.loads(str(npz["world"]))["size"] == N
        assert not any("action" in k or "option" in k for k in npz.files)


def test_save_keeps_the_path_as_given(demos, tmp_path):
    path = demos.save(tmp_path / "mentor.demos")
    assert path.exists() and not (tmp_path / "mentor.demos.npz").exists()
    assert Demonstrations.load(path).num_episodes == 2


# ---------------------------------------------------------------------------- load: the file
def test_load_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="nope.npz"):
        Demonstrations.load(tmp_path / "nope.npz")


def test_load_not_an_npz(tmp_path):
    path = tmp_path / "text.npz"
    path.write_text("not a zip file")
    with pytest.raises(ValueError, match=file_error(path, "not a readable .npz")):
        Demonstrations.load(path)


def test_load_never_unpickles_an_object_array(saved, tmp_path, plants_marker):
    """A demonstrations file whose states are a pickled object array (its unpickling would run a
    shell command) is refused unread: ``np.load(allow_pickle=False)``."""
    marker = tmp_path / "marker"
    rewrite(saved, states=np.array([plants_marker(marker)], dtype=object))
    with pytest.raises(
        ValueError, match=file_error(saved, "not a readable .npz", "Object arrays cannot be loaded")
    ):
        Demonstrations.load(saved)
    assert not marker.exists()
    with np.load(saved, allow_pickle=True) as npz:  # control: the file is live
        npz["states"]
    assert marker.exists()


def test_load_unknown_format_version(saved):
    rewrite(saved, format_version=np.array(99, dtype=np.int64))
    with pytest.raises(ValueError, match=file_error(saved, "unknown format_version 99")):
        Demonstrations.load(saved)


def test_load_format_version_must_be_an_integer_scalar(saved):
    rewrite(saved, format_version=np.array([1.0]))
    with pytest.raises(
        ValueError, match=file_error(saved, "format_version must be an integer scalar")
    ):
        Demonstrations.load(saved)


def test_load_missing_keys(saved):
    rewrite(saved, episode_starts=None)
    with pytest.raises(ValueError, match=file_error(saved, "missing keys ['episode_starts']")):
        Demonstrations.load(saved)


def test_load_rejects_extra_keys_such_as_actions(saved):
    rewrite(saved, actions=np.zeros(3, dtype=np.int64))
    with pytest.raises(ValueError, match=file_error(saved, "unexpected keys ['actions']")):
        Demonstrations.load(saved)


@pytest.mark.parametrize(
    "key, value, what",
    [
        (
            "states",
            np.arange(4, dtype=np.float64),
            "states must be a 1-D int64 array, got dtype float64",
        ),
        (
            "states",
            np.zeros((2, 2), dtype=np.int64),
            "states must be a 1-D int64 array, got dtype int64 shape (2, 2)",
        ),
        (
            "episode_starts",
            np.array([0], dtype=np.int32),
            "episode_starts must be a 1-D int64 array, got dtype int32",
        ),
    ],
)
def test_load_wrong_dtype_or_shape(saved, key, value, what):
    rewrite(saved, **{key: value})
    with pytest.raises(ValueError, match=file_error(saved, what)):
        Demonstrations.load(saved)


def test_load_world_must_be_json(saved):
    rewrite(saved, world=np.array("{not json"))
    with pytest.raises(ValueError, match=file_error(saved, "world is not valid JSON")):
        Demonstrations.load(saved)


def test_load_world_kind_must_be_known(saved, world):
    rewrite(saved, world=np.array(json.dumps({**world.describe(), "kind": "Maze"})))
    with pytest.raises(ValueError, match=file_error(saved, "world kind 'Maze' is not supported")):
        Demonstrations.load(saved)


@pytest.mark.parametrize(
    "starts, what",
    [
        ([], "episode_starts is empty"),
        ([1], "episode_starts[0] is 1, must be 0"),
        ([0, 5, 5], "episode 2 is empty or misordered"),
        ([0, 19], "episode 1 is empty"),
    ],
)
def test_load_bad_episode_starts(saved, starts, what):
    rewrite(saved, episode_starts=np.array(starts, dtype=np.int64))
    with pytest.raises(ValueError, match=file_error(saved, what)):
        Demonstrations.load(saved)


# ------------------------------------------------------------------------ load: the states
def saved_with(tmp_path, world, episodes):
    """A file holding ``episodes`` exactly (written raw, bypassing the constructor's checks)."""
    path = tmp_path / "raw.npz"
    starts = np.cumsum([0] + [len(e) for e in episodes[:-1]]).astype(np.int64)
    with open(path, "wb") as f:
        np.savez(
            f,
            format_version=np.array(1, dtype=np.int64),
            world=np.array(json.dumps(world.describe())),
            states=np.concatenate(episodes).astype(np.int64),
            episode_starts=starts,
        )
    return path


def test_load_state_out_of_range(tmp_path, world):
    path = saved_with(tmp_path, world, [EPISODES[1], [0, 1, 64]])
    with pytest.raises(
        ValueError, match=file_error(path, "episode 1, index 2", "state 64 is out of range")
    ):
        Demonstrations.load(path)


def test_load_state_on_a_wall(tmp_path, world):
    path = saved_with(tmp_path, world, [[cell(3, 0), cell(4, 0), cell(5, 0)]])
    with pytest.raises(
        ValueError, match=file_error(path, "episode 0, index 1", "(4, 0) is a wall cell")
    ):
        Demonstrations.load(path)


def test_load_states_must_be_adjacent(tmp_path, world):
    path = saved_with(tmp_path, world, [EPISODES[1], [cell(0, 0), cell(1, 0), cell(2, 1)]])
    with pytest.raises(
        ValueError,
        match=file_error(path, "episode 1, index 2", "(2, 1) follows", "equal or 4-adjacent"),
    ):
        Demonstrations.load(path)


def test_load_goal_must_end_the_episode(tmp_path, world):
    path = saved_with(tmp_path, world, [[cell(7, 6), cell(7, 7), cell(7, 6)]])
    with pytest.raises(
        ValueError, match=file_error(path, "episode 0, index 1", "goal (7, 7) ends an episode")
    ):
        Demonstrations.load(path)


def test_load_checks_the_world(saved):
    other = MultiRooms(size=N, rooms=2, slip=0.2, goal=(7, 6))
    with pytest.raises(
        ValueError,
        match=file_error(
            saved, "different world", "goal (demonstrations: 63, given world: 62)", "slip"
        ),
    ):
        Demonstrations.load(saved, world=other)


def test_load_world_fields_that_do_not_make_a_world(saved, world):
    rewrite(saved, world=np.array(json.dumps({**world.describe(), "rooms": 3})))
    with pytest.raises(
        ValueError, match=file_error(saved, "invalid world description", "not a multiple")
    ):
        Demonstrations.load(saved)


# ---------------------------------------------------------------------------- constructor
@pytest.mark.parametrize(
    "episodes, what",
    [
        ([], "no episodes"),
        (torch.tensor(EPISODES[1]), "got one 1-D sequence"),
        ([EPISODES[1], []], "episode 1 is empty"),
        ([[0.0, 1.0]], "episode 0 must hold integer states, got dtype float64"),
        ([[[0, 1]]], "episode 0 must be a 1-D sequence"),
        ([EPISODES[1], [0, -1]], "episode 1, index 1: state -1 is out of range"),
        ([[cell(3, 4)]], "episode 0, index 0: state 28 (3, 4) is a wall cell"),
        ([[0, 1, 3]], "episode 0, index 2: state 3 (0, 3) follows 1 (0, 1)"),
    ],
)
def test_constructor_validates(world, episodes, what):
    # Without a file, messages name the class in place of the file.
    with pytest.raises(ValueError, match="^Demonstrations: .*" + re.escape(what)):
        Demonstrations(episodes, world.describe())


def test_constructor_needs_a_description(world):
    with pytest.raises(TypeError, match="world must be a world description dict"):
        Demonstrations(EPISODES, "MultiRooms 8x8")


def test_check_world_names_the_fields(demos, world):
    demos.check_world(world)  # the same world passes
    demos.check_world(world.describe())
    # Only the differing fields, each with both values (slip, start, gamma … agree).
    with pytest.raises(
        ValueError,
        match=r"fields that differ: goal \(demonstrations: 63, given world: "
        r"255\); rooms \(demonstrations: 2, given world: 4\); "
        r"size \(demonstrations: 8, given world: 16\)$",
    ):
        demos.check_world(MultiRooms(size=16, rooms=4))


# ---------------------------------------------------------------------------- any world
@pytest.fixture(scope="module")
def taxi():
    from himit_torch.worlds.gymnasium import from_gymnasium

    return from_gymnasium("Taxi-v4")


def taxi_state(world, row, col, passenger, destination):
    return world.env.encode(row, col, passenger, destination)


def test_gymnasium_demonstrations_are_checked_saved_and_refused_elsewhere(taxi, tmp_path):
    s = lambda *x: taxi_state(taxi, *x)  # noqa: E731
    # the taxi at (2, 2), passenger at R, destination G: north twice, then north into the edge
    ok = [s(2, 2, 0, 1), s(1, 2, 0, 1), s(0, 2, 0, 1), s(0, 2, 0, 1)]
    demos = Demonstrations([ok], taxi)
    assert demos.world_description["id"] == "Taxi-v4" and demos.world_description["kwargs"] == {}
    # A jump of two cells, and a passenger appearing in the taxi away from its landmark:
    with pytest.raises(
        ValueError,
        match=r"^Demonstrations: episode 1, index 2: state \d+ follows "
        r"\d+, but no action leads",
    ):
        Demonstrations([ok, [s(2, 2, 0, 1), s(1, 2, 0, 1), s(3, 2, 0, 1)]], taxi)
    with pytest.raises(ValueError, match="episode 0, index 1: .*no action leads"):
        Demonstrations([[s(2, 2, 0, 1), s(2, 2, 4, 1)]], taxi)
    delivered = s(0, 4, 1, 1)  # at G with the passenger
    with pytest.raises(ValueError, match="episode 0, index 1: state .* is terminal"):
        Demonstrations([[s(0, 4, 4, 1), delivered, s(1, 4, 1, 1)]], taxi)
    with pytest.raises(ValueError, match="index 1: state 500 is out of range"):
        Demonstrations([[0, 500]], taxi)
    # saved with its id and kwargs: loaded alone (rebuilt with gymnasium.make), refused elsewhere
    path = demos.save(tmp_path / "taxi.npz")
    loaded = Demonstrations.load(path)
    assert [e.tolist() for e in loaded] == [
        ok
    ] and loaded.make_world().describe() == taxi.describe()
    from himit_torch.worlds.gymnasium import from_gymnasium

    with pytest.raises(
        ValueError,
        match=file_error(
            path,
            "different world",
            "id (demonstrations: 'Taxi-v4', given world: 'CliffWalking-v1')",
        ),
    ):
        Demonstrations.load(path, world=from_gymnasium("CliffWalking-v1"))
    with pytest.raises(ValueError, match="different world.*gamma"):
        Demonstrations.load(path, world=from_gymnasium("Taxi-v4", gamma=0.9))


class Ring:
    """A hand-written world: 6 states on a ring, action 0 forward, 1 stays; state 5 ends.
    It has a dynamics table but no describe()."""

    num_states, num_actions, start_state, gamma = 6, 2, 0, 0.95

    def __init__(self, forward: int = 1):
        from himit_torch.worlds.tabular import DynamicsTable

        s = torch.arange(6)
        succ = torch.stack([(s + forward) % 6, s], 1)[..., None]
        self.table = DynamicsTable(
            succ,
            torch.ones(6, 2, 1, dtype=torch.float64),
            torch.full((6, 2, 1), -1.0, dtype=torch.float64),
        )
        self.terminal_mask = s == 5

    def dynamics_table(self):
        return self.table

    def step(self, positions, actions, uniforms):
        return self.table.step(positions, actions, uniforms)


def test_hand_written_worlds_are_described_by_class_and_fingerprint(tmp_path):
    ring = Ring()
    demos = Demonstrations([[0, 1, 1, 2, 3, 4, 5]], ring)
    d = demos.world_description
    assert d["kind"] == "custom" and d["class"].endswith("Ring") and len(d["fingerprint"]) == 16
    with pytest.raises(ValueError, match="episode 0, index 2: state 3 follows 1"):
        Demonstrations([[0, 1, 3]], ring)
    path = demos.save(tmp_path / "ring.npz")
    with pytest.raises(
        ValueError,
        match=file_error(
            path, "world kind 'custom' is not supported here", "pass the world object"
        ),
    ):
        Demonstrations.load(path)
    assert Demonstrations.load(path, world=ring).num_transitions == 6
    with pytest.raises(ValueError, match=file_error(path, "different world", "fingerprint")):
        Demonstrations.load(path, world=Ring(forward=2))  # other dynamics


def test_a_world_without_a_model_cannot_check_demonstrations():
    class StepOnly:
        num_states, num_actions, start_state, gamma = 3, 1, 0, 0.9
        terminal_mask = torch.tensor([False, False, True])

        def step(self, positions, actions, uniforms):
            return (positions + 1).clamp(max=2), torch.zeros(positions.shape, dtype=torch.float64)

    with pytest.raises(ValueError, match="StepOnly has no true model to read"):
        Demonstrations([[0, 1, 2]], StepOnly())


# ------------------------------------------------------------------ nothing read runs code
@pytest.fixture
def lake_file(tmp_path):
    """A FrozenLake demonstrations file (one episode: the start state)."""
    from himit_torch.worlds.gymnasium import from_gymnasium

    return Demonstrations([[0]], from_gymnasium("FrozenLake-v1")).save(tmp_path / "lake.npz")


def with_world(path, **changes):
    """Rewrite the file's world description with ``changes``."""
    with np.load(path) as npz:
        description = json.loads(str(npz["world"]))
    return rewrite(path, world=np.array(json.dumps({**description, **changes})))


@pytest.fixture
def planted_module(tmp_path, monkeypatch):
    """``(name, marker)``: an importable module (on ``sys.path``) whose import creates
    ``marker`` — what a file naming ``"name:FrozenLake-v1"`` would make Gymnasium import."""
    name = f"planted_{tmp_path.name.replace('-', '_')}"
    marker = tmp_path / "marker"
    (tmp_path / f"{name}.py").write_text(f"open({str(marker)!r}, 'w').close()\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    return name, marker


def test_a_gymnasium_id_naming_a_module_is_refused_and_the_module_never_runs(
    lake_file, planted_module
):
    import gymnasium

    name, marker = planted_module
    with_world(lake_file, id=f"{name}:FrozenLake-v1")
    with pytest.raises(
        ValueError,
        match=file_error(lake_file, f"'{name}:FrozenLake-v1' names a module to import", "pass it"),
    ):
        Demonstrations.load(lake_file)
    assert not marker.exists()
    # the same file with the world given: its description is compared, nothing is made
    with pytest.raises(ValueError, match=file_error(lake_file, "different world", "id")):
        from himit_torch.worlds.gymnasium import from_gymnasium

        Demonstrations.load(lake_file, world=from_gymnasium("FrozenLake-v1"))
    assert not marker.exists()
    # control: the id is live — Gymnasium itself imports the module it names
    gymnasium.make(f"{name}:FrozenLake-v1")
    assert marker.exists()


@pytest.mark.parametrize(
    "changes, what",
    [
        ({"id": "NoSuchEnv-v0"}, "'NoSuchEnv-v0' is not registered with Gymnasium here"),
        ({"id": 5}, "id 5 is not a string"),
        ({"id": "GymV26Environment-v0"}, "makes another environment named in its kwargs"),
        ({"kwargs": {"render_mode": "human"}}, "not a description's (a dict without render_mode)"),
        ({"kwargs": [1]}, "not a description's"),
    ],
)
def test_a_described_gymnasium_world_is_made_only_from_a_plain_registered_id(
    lake_file, changes, what
):
    with_world(lake_file, **changes)
    with pytest.raises(ValueError, match=file_error(lake_file, what, "pass it")):
        Demonstrations.load(lake_file)


def test_a_world_description_nested_too_deep_is_refused_unparsed(saved):
    rewrite(saved, world=np.array('{"kind": ' + "[" * 100_000 + "]" * 100_000 + "}"))
    with pytest.raises(
        ValueError, match=file_error(saved, "world is JSON nested 100001 levels deep")
    ):
        Demonstrations.load(saved)
