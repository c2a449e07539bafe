"""State-only demonstrations: what the learner may know about the mentor (the paper's Section II).

A demonstration is the sequence of states the mentor visited, nothing else: no actions, no
options, no rewards. The learner estimates its mentor model ``p_m(s' | s)`` from consecutive
pairs (:meth:`Demonstrations.transitions`).
"""

from __future__ import annotations

import json
import os
import zipfile
from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np
import torch

from himit_torch.validation import json_depth
from himit_torch.worlds.multirooms import MultiRooms
from himit_torch.worlds.table_world import describe_world, transition_support_matrix

__all__ = ["Demonstrations", "DEMONSTRATIONS_FORMAT_VERSION"]

#: Version of the ``.npz`` layout written by :meth:`Demonstrations.save`.
DEMONSTRATIONS_FORMAT_VERSION = 1

_NPZ_KEYS = ("format_version", "world", "states", "episode_starts")
#: How deeply a saved world description may nest (they nest 2 or 3: kwargs' lists of rows).
_MAX_WORLD_DEPTH = 8


class Demonstrations:
    """Episodes of mentor states in one world, and that world's description.

    Args:
        episodes: one 1-D sequence of integer states per episode (tensors, arrays or lists); an
            episode holds its first state and the state after every primitive step.
        world: the world — any world object (MultiRooms, a :class:`~himit_torch.TableWorld`
            such as a Gymnasium world, your own with a ``dynamics_table()`` or
            ``transition_model()``) — or its description dict (``world.describe()``) where that
            rebuilds it: MultiRooms, and Gymnasium worlds (by id and kwargs).

    Every episode is checked against the world: states lie in ``[0, S)``, each consecutive pair
    ``s → s'`` is a move the world can make in one primitive step (its transition support), and
    a terminal state, which ends an episode, can only be an episode's last state. In MultiRooms
    the messages speak of cells: no state is a wall cell, consecutive states are equal (a bump
    into a wall) or 4-adjacent. A violation raises ``ValueError`` naming the episode and the
    index within it.

    The description (:func:`~himit_torch.worlds.table_world.describe_world`: MultiRooms' fields;
    Gymnasium's id, kwargs, gamma and a fingerprint of the model; for your own world its class
    and a fingerprint of its dynamics) is saved with the states, and demonstrations are refused
    in a world with another description (:meth:`check_world`).

    File format (``.npz``, :meth:`save` / :meth:`load`), version
    :data:`DEMONSTRATIONS_FORMAT_VERSION` = 1, exactly these keys:

    ================  =============  =========================================================
    key               dtype, shape   meaning
    ================  =============  =========================================================
    format_version    int64, ()      1
    world             str, ()        JSON of the world's description (``world.describe()``)
    states            int64, [N]     every episode's states, concatenated in episode order
    episode_starts    int64, [E]     index in ``states`` of each episode's first state:
                                     ``episode_starts[0] == 0``, strictly increasing, all
                                     ``< N`` (so no episode is empty)
    ================  =============  =========================================================

    Episode ``e`` is ``states[episode_starts[e] : episode_starts[e + 1]]`` (the last one runs to
    the end). Nothing about the mentor's actions or options is stored, by design.
    """

    def __init__(self, episodes: Sequence, world, *, source: str | None = None):
        self._source = source or "Demonstrations"
        _check_world_argument(world, self._source)
        if isinstance(world, dict):
            description = world
            self._world = _world_from_description(json.loads(json.dumps(description)), self._source)
        else:
            description = describe_world(world)
            self._world = world
        self._world_description = json.loads(json.dumps(description))  # a plain, JSON-able copy
        if isinstance(episodes, (torch.Tensor, np.ndarray)) and episodes.ndim == 1:
            raise ValueError(
                f"{self._source}: episodes must be a list of 1-D state sequences, got one "
                "1-D sequence; wrap it in a list for a single episode"
            )
        if len(episodes) == 0:
            raise ValueError(
                f"{self._source}: no episodes; demonstrations need at least one episode"
            )
        self._episodes = tuple(_as_episode(e, i, self._source) for i, e in enumerate(episodes))
        self._check_states_in(self._world, strict=True)

    def _check_states_in(self, world, strict: bool) -> None:
        """Check every episode's states in the world *object* ``world`` (any TabularWorld):
        MultiRooms by its cells; other worlds by their transition support, or — where a world
        has neither ``dynamics_table()`` nor ``transition_model()`` and ``strict`` is off — by
        the state range and terminal states alone."""
        if isinstance(world, MultiRooms):
            wall, successors = world.wall_mask.numpy(), world.next_state_table.numpy()
            for i, ep in enumerate(self._episodes):
                _check_episode(ep.numpy(), i, world, wall, successors, self._source)
            return
        terminal = torch.as_tensor(world.terminal_mask, dtype=torch.bool).cpu().numpy()
        support = None
        if strict or hasattr(world, "dynamics_table") or hasattr(world, "transition_model"):
            support = transition_support_matrix(world)
        for i, ep in enumerate(self._episodes):
            if support is None:
                _check_range_and_end(ep.numpy(), i, int(world.num_states), terminal, self._source)
            else:
                _check_steps(ep.numpy(), i, support, terminal, self._source)

    # --------------------------------------------------------------------------------- queries
    @property
    def episodes(self) -> tuple[torch.Tensor, ...]:
        """Per episode an int64 ``[T_e + 1]`` tensor of states."""
        return self._episodes

    @property
    def world_description(self) -> dict:
        """The world's description dict (a copy)."""
        return json.loads(json.dumps(self._world_description))

    def make_world(self):
        """A fresh world built from the stored description (MultiRooms and Gymnasium worlds)."""
        return _world_from_description(self._world_description, self._source)

    @property
    def num_episodes(self) -> int:
        return len(self._episodes)

    @property
    def num_transitions(self) -> int:
        """Number of consecutive state pairs over all episodes (``Σ_e T_e``)."""
        return sum(len(e) - 1 for e in self._episodes)

    @property
    def episode_lengths(self) -> torch.Tensor:
        """``[E]`` int64: primitive steps per episode (states − 1)."""
        return torch.tensor([len(e) - 1 for e in self._episodes], dtype=torch.int64)

    def transitions(self) -> tuple[torch.Tensor, torch.Tensor]:
        """``(from [T], to [T])`` int64: every consecutive pair ``(s_t, s_{t+1})``, all episodes,
        in order. Pairs never cross from one episode into the next."""
        froms = [e[:-1] for e in self._episodes]
        tos = [e[1:] for e in self._episodes]
        return torch.cat(froms), torch.cat(tos)

    def visited_states(self) -> torch.Tensor:
        """Sorted unique int64 states seen in any episode."""
        return torch.unique(torch.cat(self._episodes))

    def __len__(self) -> int:
        return self.num_episodes

    def __getitem__(self, index: int) -> torch.Tensor:
        return self._episodes[index]

    def __iter__(self) -> Iterator[torch.Tensor]:
        return iter(self._episodes)

    def __repr__(self) -> str:
        d = self._world_description
        if d.get("kind") == "MultiRooms":
            what = f"{d.get('size')}×{d.get('size')}/{d.get('rooms')}"
        else:
            what = d.get("id") or d.get("class") or ""
        return (
            f"Demonstrations(episodes={self.num_episodes}, transitions={self.num_transitions}, "
            f"world={d.get('kind')} {what})"
        )

    def check_world(self, world) -> None:
        """Raise ``ValueError`` unless ``world`` (a world or its description dict) is the world
        these demonstrations were made in, naming each description field that differs.

        Given a world *object* (what a :class:`~himit_torch.Learner` passes), the episodes are
        also checked in that very object — states in range, every step one its dynamics can
        make, terminal states only at an episode's end — not only in a world rebuilt from the
        stored description (which may not be the one the learner runs in)."""
        _check_same_world(self._world_description, world, self._source)
        if not isinstance(world, dict) and world is not self._world:
            self._check_states_in(world, strict=False)

    # ------------------------------------------------------------------------------------ I/O
    def save(self, path: str | os.PathLike) -> Path:
        """Write the ``.npz`` file described in the class docstring; returns its path.

        The path is used as given (NumPy's habit of appending ``.npz`` is avoided).
        """
        path = Path(path)
        lengths = np.array([len(e) for e in self._episodes], dtype=np.int64)
        starts = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int64)
        with open(path, "wb") as f:
            np.savez_compressed(
                f,
                format_version=np.array(DEMONSTRATIONS_FORMAT_VERSION, dtype=np.int64),
                world=np.array(json.dumps(self._world_description, sort_keys=True)),
                states=torch.cat(self._episodes).numpy().astype(np.int64),
                episode_starts=starts,
            )
        return path

    @classmethod
    def load(cls, path: str | os.PathLike, world=None) -> Demonstrations:
        """Read and validate a file written by :meth:`save`.

        Args:
            path: the ``.npz`` file.
            world: if given, the file's world description must equal this world's, and the
                states are checked in it. Needed for worlds that cannot be rebuilt from their
                description (your own classes); MultiRooms and Gymnasium worlds are rebuilt.

        Raises:
            FileNotFoundError: no such file.
            ValueError: the file is not a valid demonstrations file; the message names the file,
                and the episode and index where a state is at fault. Each member's ``.npy``
                header is read first: a member that is no ``.npy`` array (raw bytes), holds
                objects, or announces more data than it holds (a few bytes announcing 2³³
                elements) is refused before anything is allocated.
            TypeError: ``world`` is neither a world nor a description dict (e.g. a number).
        """
        path = Path(path)
        src = str(path)
        if world is not None:
            _check_world_argument(world, src)
        if not path.exists():
            raise FileNotFoundError(f"{src}: no such demonstrations file")
        try:
            _check_members(path, src)
            with np.load(path, allow_pickle=False) as npz:
                arrays = {k: npz[k] for k in npz.files}
        except (zipfile.BadZipFile, OSError, ValueError, EOFError) as err:
            if str(err).startswith(f"{src}: "):  # _check_members' own refusal
                raise
            raise ValueError(f"{src}: not a readable .npz demonstrations file ({err})") from None
        missing = [k for k in _NPZ_KEYS if k not in arrays]
        if missing:
            raise ValueError(
                f"{src}: missing keys {missing}; a demonstrations file holds exactly "
                f"{list(_NPZ_KEYS)}"
            )
        extra = sorted(set(arrays) - set(_NPZ_KEYS))
        if extra:
            raise ValueError(
                f"{src}: unexpected keys {extra}; format version "
                f"{DEMONSTRATIONS_FORMAT_VERSION} holds exactly {list(_NPZ_KEYS)}"
            )
        version = arrays["format_version"]
        if version.shape != () or version.dtype.kind not in "iu":
            raise ValueError(
                f"{src}: format_version must be an integer scalar, got dtype "
                f"{version.dtype} shape {version.shape}"
            )
        if int(version) != DEMONSTRATIONS_FORMAT_VERSION:
            raise ValueError(
                f"{src}: unknown format_version {int(version)}; this version of "
                f"himit_torch reads format_version {DEMONSTRATIONS_FORMAT_VERSION}"
            )
        world_json = arrays["world"]
        if world_json.shape != () or world_json.dtype.kind != "U":
            raise ValueError(
                f"{src}: world must be a JSON string scalar, got dtype "
                f"{world_json.dtype} shape {world_json.shape}"
            )
        depth = json_depth(str(world_json))
        if depth > _MAX_WORLD_DEPTH:  # (Python's parser would recurse once per level)
            raise ValueError(
                f"{src}: world is JSON nested {depth} levels deep; a world description nests "
                f"at most {_MAX_WORLD_DEPTH}"
            )
        try:
            description = json.loads(str(world_json))
        except json.JSONDecodeError as err:
            raise ValueError(f"{src}: world is not valid JSON ({err})") from None
        if not isinstance(description, dict):
            raise ValueError(
                f"{src}: world must be a JSON object (a world description), got "
                f"{type(description).__name__}"
            )
        for key in ("states", "episode_starts"):
            a = arrays[key]
            if a.dtype != np.int64 or a.ndim != 1:
                raise ValueError(
                    f"{src}: {key} must be a 1-D int64 array, got dtype {a.dtype} shape {a.shape}"
                )
        states, starts = arrays["states"], arrays["episode_starts"]
        if starts.size == 0:
            raise ValueError(f"{src}: episode_starts is empty; the file holds no episode")
        if starts[0] != 0:
            raise ValueError(f"{src}: episode_starts[0] is {starts[0]}, must be 0")
        bad = np.flatnonzero(np.diff(starts) <= 0)
        if bad.size:
            e = int(bad[0]) + 1
            raise ValueError(
                f"{src}: episode {e} is empty or misordered: episode_starts[{e}] = "
                f"{starts[e]} is not greater than episode_starts[{e - 1}] = {starts[e - 1]}"
            )
        if starts[-1] >= states.size:
            raise ValueError(
                f"{src}: episode {starts.size - 1} is empty: it starts at "
                f"{starts[-1]} but states holds {states.size} entries"
            )
        episodes = np.split(states, starts[1:])
        if world is None:
            return cls(episodes, description, source=src)
        # The world's identity first (naming the fields that differ), then the states in it.
        _check_same_world(description, world, src)
        return cls(episodes, description if isinstance(world, dict) else world, source=src)


# ------------------------------------------------------------------------------------ checks
def _check_members(path: Path, source: str) -> None:
    """Every member of the ``.npz`` file is a ``.npy`` array (not raw bytes, which ``np.load``
    would hand back as they are) of a plain dtype whose header announces no more data than the
    member holds — read from the headers alone, before ``np.load`` allocates what a header
    announces (2³³ elements of a few bytes' file would be a ``MemoryError``)."""
    with zipfile.ZipFile(path) as archive:
        for info in archive.infolist():
            name = info.filename
            if not name.endswith(".npy"):
                raise ValueError(
                    f"{source}: member {name!r} is not a NumPy array (.npy); a demonstrations "
                    f"file holds exactly the arrays {list(_NPZ_KEYS)}"
                )
            with archive.open(info) as member:
                version = np.lib.format.read_magic(member)
                if version not in ((1, 0), (2, 0)):
                    raise ValueError(f"{source}: member {name!r} has .npy version {version}")
                header = (
                    np.lib.format.read_array_header_1_0
                    if version == (1, 0)
                    else np.lib.format.read_array_header_2_0
                )
                shape, _, dtype = header(member)
                held = info.file_size - member.tell()
            if dtype.hasobject:
                raise ValueError(
                    f"{source}: not a readable .npz demonstrations file (member {name!r} holds "
                    "Python objects: Object arrays cannot be loaded; it holds plain arrays only)"
                )
            announced = int(np.prod(shape, dtype=object)) * dtype.itemsize
            if announced > held:
                raise ValueError(
                    f"{source}: member {name!r} announces shape {tuple(shape)} ({announced} "
                    f"bytes) but holds {held} bytes: the file is damaged or not one "
                    "Demonstrations.save wrote"
                )


def _check_world_argument(world, source: str) -> None:
    """``TypeError`` unless ``world`` is a description dict or a world object (``num_states``,
    ``terminal_mask``): a number or a string here is not a world of any kind."""
    if not isinstance(world, dict) and not (
        hasattr(world, "num_states") and hasattr(world, "terminal_mask")
    ):
        raise TypeError(
            f"{source}: world must be a world description dict (world.describe()) or a world "
            f"object (num_states, terminal_mask, step), got {type(world).__name__}"
        )


def _check_same_world(mine: dict, world, source: str) -> None:
    """``ValueError`` naming each description field that differs between ``mine`` and ``world``
    (a world or a description dict)."""
    given = json.loads(json.dumps(world if isinstance(world, dict) else describe_world(world)))
    fields = sorted(set(mine) | set(given))
    diff = [
        f"{k} (demonstrations: {mine.get(k, '<missing>')!r}, given world: "
        f"{given.get(k, '<missing>')!r})"
        for k in fields
        if mine.get(k) != given.get(k)
    ]
    if diff:
        raise ValueError(
            f"{source}: recorded in a different world; fields that differ: " + "; ".join(diff)
        )


def _world_from_description(description: dict, source: str):
    kind = description.get("kind")
    if kind == "gymnasium":
        from himit_torch.worlds.gymnasium import world_from_description

        try:
            return world_from_description(description)
        except KeyError as err:
            raise ValueError(f"{source}: world description lacks field {err}") from None
        except ValueError as err:
            raise ValueError(f"{source}: {err}") from None
        except Exception as err:  # gymnasium.make's own errors (unknown id, bad kwargs)
            raise ValueError(
                f"{source}: cannot make the Gymnasium world {description.get('id')!r} "
                f"with kwargs {description.get('kwargs')}: {err}"
            ) from None
    if kind != "MultiRooms":
        raise ValueError(
            f"{source}: world kind {kind!r} is not supported here: only MultiRooms and "
            "Gymnasium worlds are rebuilt from a description; pass the world object "
            "itself (Demonstrations(episodes, world), Demonstrations.load(path, world=…))"
        )
    try:
        return MultiRooms.from_description(description)
    except KeyError as err:
        raise ValueError(f"{source}: world description lacks field {err}") from None
    except (TypeError, ValueError) as err:
        raise ValueError(f"{source}: invalid world description: {err}") from None


def _as_episode(episode, index: int, source: str) -> torch.Tensor:
    if isinstance(episode, torch.Tensor):
        a = episode.detach().cpu().numpy()
    else:
        a = np.asarray(episode)
    if a.ndim != 1:
        raise ValueError(
            f"{source}: episode {index} must be a 1-D sequence of states, got shape {a.shape}"
        )
    if a.size == 0:
        raise ValueError(
            f"{source}: episode {index} is empty; an episode holds at least its first state"
        )
    if a.dtype.kind not in "iu":
        raise ValueError(f"{source}: episode {index} must hold integer states, got dtype {a.dtype}")
    return torch.from_numpy(a.astype(np.int64, copy=True))


def _check_episode(
    states: np.ndarray,
    index: int,
    world: MultiRooms,
    wall: np.ndarray,
    successors: np.ndarray,
    source: str,
) -> None:
    """``wall [S]`` and ``successors [S, A]`` are the world's, passed in to build them once."""
    where = f"{source}: episode {index}"
    S = world.num_states
    out = np.flatnonzero((states < 0) | (states >= S))
    if out.size:
        i = int(out[0])
        raise ValueError(
            f"{where}, index {i}: state {states[i]} is out of range [0, {S}) for the "
            f"{world.size}×{world.size} world"
        )
    on_wall = np.flatnonzero(wall[states])
    if on_wall.size:
        i = int(on_wall[0])
        raise ValueError(
            f"{where}, index {i}: state {states[i]} {world.coords(states[i])} is a wall cell"
        )
    if states.size > 1:
        nxt = successors[states[:-1]]  # [T, A]
        ok = (states[1:] == states[:-1]) | (nxt == states[1:, None]).any(1)
        jump = np.flatnonzero(~ok)
        if jump.size:
            i = int(jump[0]) + 1
            raise ValueError(
                f"{where}, index {i}: state {states[i]} {world.coords(states[i])} "
                f"follows {states[i - 1]} {world.coords(states[i - 1])}; consecutive "
                "states must be equal or 4-adjacent (one primitive move)"
            )
    goal_early = np.flatnonzero(states[:-1] == world.goal_state)
    if goal_early.size:
        i = int(goal_early[0])
        raise ValueError(
            f"{where}, index {i}: the goal {world.coords(world.goal_state)} ends an "
            f"episode but {states.size - 1 - i} more state(s) follow it"
        )


def _check_range_and_end(
    states: np.ndarray, index: int, S: int, terminal: np.ndarray, source: str
) -> None:
    """A world without a known transition support: states in range, terminal only at the end."""
    _check_steps(
        states,
        index,
        np.ones((1, 1), dtype=bool),
        terminal,
        source,
        num_states=S,
        check_moves=False,
    )


def _check_steps(
    states: np.ndarray,
    index: int,
    support,
    terminal: np.ndarray,
    source: str,
    num_states: int | None = None,
    check_moves: bool = True,
) -> None:
    """Any world: states in range, each step in the world's transition support ``[S, S]``
    (dense, or a scipy sparse matrix), a terminal state only at an episode's end."""
    where = f"{source}: episode {index}"
    S = support.shape[0] if num_states is None else num_states
    out = np.flatnonzero((states < 0) | (states >= S))
    if out.size:
        i = int(out[0])
        raise ValueError(f"{where}, index {i}: state {states[i]} is out of range [0, {S})")
    ended = np.flatnonzero(terminal[states[:-1]])
    if ended.size:
        i = int(ended[0])
        raise ValueError(
            f"{where}, index {i}: state {states[i]} is terminal and ends an episode, "
            f"but {states.size - 1 - i} more state(s) follow it"
        )
    if check_moves and states.size > 1:
        possible = np.asarray(support[states[:-1], states[1:]]).ravel().astype(bool)
        bad = np.flatnonzero(~possible)
        if bad.size:
            i = int(bad[0]) + 1
            raise ValueError(
                f"{where}, index {i}: state {states[i]} follows {states[i - 1]}, but "
                f"no action leads from {states[i - 1]} to {states[i]} in one step "
                "in this world"
            )
