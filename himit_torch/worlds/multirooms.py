"""The multirooms gridworld of the paper (Section III), with batched torch dynamics.

Shapes used throughout the library: ``B`` independent runs, ``S`` states, ``A`` primitive actions.
A state is a cell index ``s = row * size + col`` over *all* N×N cells; wall cells are states no
one can occupy, which keeps indices equal to grid coordinates (the learner's storage grows with
what it has seen, so unused wall states cost nothing there).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

import numpy as np
import torch

from himit_torch.validation import as_float, as_int, check_memory
from himit_torch.worlds.tabular import DynamicsTable

__all__ = [
    "ACTION_NAMES",
    "ACTION_DELTAS",
    "STIMULUS_FEATURES",
    "MAZE_SEED",
    "MultiRooms",
    "maze_doorways",
    "primitives_only_goal",
    "detour_waypoint",
]

#: Primitive actions: 0 = north (row − 1), 1 = south, 2 = west (col − 1), 3 = east.
ACTION_NAMES = ("N", "S", "W", "E")
ACTION_DELTAS = ((-1, 0), (1, 0), (0, -1), (0, 1))

#: Columns of :meth:`MultiRooms.stimulus_features`: the normalised room id (0 = no room: a doorway
#: or wall cell), the doorway flag, and the user-settable "light" and "sound" channels.
STIMULUS_FEATURES = ("room", "doorway", "light", "sound")
_SETTABLE_STIMULI = ("light", "sound")


@dataclass(frozen=True)
class _Layout:
    wall: np.ndarray  # [N, N] bool
    room_of: np.ndarray  # [S] int, −1 on walls and doorways
    doorway_rooms: dict[int, tuple[int, int]] = field(default_factory=dict)


def _build_layout(size: int, rooms: int, closed: frozenset[int]) -> _Layout:
    room_size = size // rooms
    wall = np.zeros((size, size), dtype=bool)
    for k in range(1, rooms):
        wall[k * room_size, :] = True
        wall[:, k * room_size] = True
    doorway_rooms: dict[int, tuple[int, int]] = {}
    for i in range(rooms):
        # The i-th wall segment spans the room's free cells; its doorway sits in the middle.
        lo = i * room_size + (1 if i > 0 else 0)
        hi = (i + 1) * room_size
        mid = (lo + hi) // 2
        for k in range(1, rooms):
            horizontal = k * room_size * size + mid  # wall row k·rs, column mid
            vertical = mid * size + k * room_size  # row mid, wall column k·rs
            doorway_rooms[horizontal] = ((k - 1) * rooms + i, k * rooms + i)
            doorway_rooms[vertical] = (i * rooms + k - 1, i * rooms + k)
    for cell in list(doorway_rooms):
        if cell in closed:
            del doorway_rooms[cell]
        else:
            wall.flat[cell] = False
    rows, cols = np.divmod(np.arange(size * size), size)
    room_of = (rows // room_size) * rooms + cols // room_size
    room_of[wall.ravel()] = -1
    room_of[list(doorway_rooms)] = -1
    return _Layout(wall=wall, room_of=room_of, doorway_rooms=doorway_rooms)


#: The seed of :func:`maze_doorways`' default maze: fixed, so that every run (and every seed of a
#: batch) shares one world.
MAZE_SEED = 0


def maze_doorways(size: int, rooms: int, seed: int = MAZE_SEED) -> tuple[int, ...]:
    """The doorways to close (``MultiRooms(closed_doorways=…)``) that turn the world into a maze:
    the open ones join the rooms in a spanning tree, so every room is reachable from every other
    by exactly one sequence of rooms (the paper's "closing doorways to make the environment more
    maze-like", Section III).

    The tree is the minimum spanning tree (``scipy.sparse.csgraph.minimum_spanning_tree``) of the
    rooms' adjacency graph under weights drawn uniformly from ``numpy.random.default_rng(seed)``,
    one per doorway in cell order: the same ``(size, rooms, seed)`` always gives the same maze.
    Of the ``2·R·(R − 1)`` doorways, ``(R − 1)²`` are closed and ``R² − 1`` stay open.

    Args:
        size, rooms: as for :class:`MultiRooms` (``size`` a multiple of ``rooms``).
        seed: the maze's seed (:data:`MAZE_SEED` by default; never a run's seed).
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import minimum_spanning_tree

    size, rooms = _check_int("size", size), _check_int("rooms", rooms)
    if size % rooms or size // rooms < 2:
        raise ValueError(
            f"maze_doorways: size={size} must be a multiple of rooms={rooms} with rooms of at "
            "least 2 cells per side (as for MultiRooms)"
        )
    doorway_rooms = _build_layout(size, rooms, frozenset()).doorway_rooms
    cells = sorted(doorway_rooms)
    if not cells:  # one room: nothing to close
        return ()
    pairs = np.array([doorway_rooms[c] for c in cells])
    # weights in (1, 2): never 0, which a sparse matrix would read as "no edge"
    weights = 1.0 + np.random.default_rng(seed).random(len(cells))
    n = rooms * rooms
    tree = minimum_spanning_tree(coo_matrix((weights, (pairs[:, 0], pairs[:, 1])), shape=(n, n)))
    tree = tree.tocoo()
    kept = {(int(a), int(b)) for a, b in zip(tree.row, tree.col)}
    return tuple(c for c, (a, b) in zip(cells, pairs.tolist()) if (a, b) not in kept)


def primitives_only_goal(size: int, rooms: int) -> int:
    """A goal cell that no doorway or corner option is aimed at: the middle cell of the bottom
    row of the bottom-right room, ``(size − 1, (c0 + c1) // 2)`` with ``c0 … c1`` that room's
    free columns (the paper's "moving the position of the goal to a location that can only be
    reached by executing primitive options", Section III).

    Why no option reaches it: doorway options head for doorways (in the walls, never on the
    grid's edge), corner options for a room's four corner cells and the four cells diagonally
    inward from them (:func:`~himit_torch.options.builders.corner_options`), and every option's
    path is planned around the goal cell. Only primitives step into it on purpose; an option
    executing next to it can still slip into it.

    Raises:
        ValueError: the bottom-right room is narrower than 3 free columns (then its bottom row
            holds only corner cells).
    """
    size, rooms = _check_int("size", size), _check_int("rooms", rooms)
    room_size = size // rooms
    c0 = size - room_size + (1 if rooms > 1 else 0)  # the room's first free column
    c1 = size - 1
    if c1 - c0 + 1 < 3:
        raise ValueError(
            f"primitives_only_goal: the bottom-right room of size={size}, rooms={rooms} has "
            f"{c1 - c0 + 1} free columns; its bottom row needs ≥ 3 for a cell that is not a "
            "corner (use rooms of ≥ 4 cells per side, wall included)"
        )
    return (size - 1) * size + (c0 + c1) // 2


def detour_waypoint(world: MultiRooms) -> int:
    """The cell a detouring mentor visits before the goal: the top-right corner ``(0, N − 1)``.

    With the default start (top-left) and goal (bottom-right) and all doorways open it lies on
    no shortest path: every doorway sits in the middle of its wall, so reaching the corner of
    the top row and leaving it again costs steps a direct route does not take. (In a maze the
    only route may pass near it; the detour is then shorter.)

    Raises:
        ValueError: ``world`` is not a :class:`MultiRooms` (another world has no top-right
            corner: give that world's waypoint state yourself; as
            :func:`~himit_torch.mentor.policy.mentor_detour` refuses it), or the corner is the
            world's start or goal.
    """
    if not isinstance(world, MultiRooms):
        raise ValueError(
            f"detour_waypoint: world must be a MultiRooms grid (its top-right corner is the "
            f"waypoint), got {type(world).__name__}; for another world name the waypoint state "
            "itself"
        )
    cell = world.size - 1
    if cell in (world.start_state, world.goal_state):
        raise ValueError(
            f"detour_waypoint: the top-right corner {world.coords(cell)} is the world's start "
            "or goal; a detour through it would not be one"
        )
    return cell


class MultiRooms:
    """An N×N gridworld split into R×R rooms joined by single-cell doorways.

    Description
        Rows and columns ``k·N/R`` (k = 1…R−1) are wall cells, except one doorway cell in the
        middle of each wall segment between two neighbouring rooms. Doorways can be closed (they
        become wall) to make a maze. The agent starts at ``start`` (top-left by default) and the
        episode ends when it enters ``goal`` (bottom-right by default).

    Action space
        Four primitive actions, :data:`ACTION_NAMES` = N, S, W, E.

    Dynamics (slip)
        With probability ``1 − slip`` the chosen action is executed; with probability ``slip`` it
        is replaced by one of the *other three* directions, uniformly (so each other direction has
        probability ``slip / 3``). A move into a wall or off the grid leaves the agent in place.
        One uniform number ``u`` per step decides both: ``u < slip`` slips, to the direction
        ``(a + 1 + k) mod 4`` for ``k·slip/3 ≤ u < (k+1)·slip/3``.

    Rewards
        ``step_reward`` (−0.01) for entering any state but the goal, ``goal_reward`` (+1.0) for
        entering the goal; discount ``gamma`` (0.99). The goal is absorbing with reward 0 in the
        true model ``P``, so its value is 0.

    Termination
        Entering the goal ends the episode; the caller restarts at ``start``.

    Stimulus features
        :meth:`stimulus_features` gives per state what an observer perceives (columns
        :data:`STIMULUS_FEATURES`): the room it is in, whether it is a doorway, and a "light" and a
        "sound" channel (0 everywhere unless set with ``stimuli={"light": [S]}`` or
        :meth:`set_stimulus`). They feed :class:`~himit_torch.SalienceReward`; the dynamics and
        the reward never depend on them.
    """

    num_actions = 4
    #: Bytes a state costs when a world is built (layout, successor and dynamics tables): what
    #: the up-front size check multiplies by the number of states.
    BYTES_PER_STATE = 512

    def __init__(
        self,
        size: int = 40,
        rooms: int = 10,
        slip: float = 0.1,
        start: int | tuple[int, int] | None = None,
        goal: int | tuple[int, int] | None = None,
        closed_doorways: Iterable[int | tuple[int, int]] = (),
        step_reward: float = -0.01,
        goal_reward: float = 1.0,
        gamma: float = 0.99,
        stimuli: Mapping[str, object] | None = None,
    ):
        size, rooms = _check_int("size", size), _check_int("rooms", rooms)
        if size % rooms != 0:
            raise ValueError(
                f"size={size} is not a multiple of rooms={rooms}: each of the "
                f"{rooms}×{rooms} rooms must be size/rooms cells wide (e.g. size="
                f"{rooms * max(2, round(size / rooms))})"
            )
        if size // rooms < 2:
            raise ValueError(
                f"size/rooms = {size // rooms} is too small: each room needs at least "
                f"2 cells per side (one wall row and one free row); use size ≥ {2 * rooms}"
            )
        check_memory(
            f"MultiRooms(size={size}) ({size * size:,} states)",
            size * size * self.BYTES_PER_STATE,
            f"about {self.BYTES_PER_STATE} bytes a state; choose a smaller size",
        )
        slip = as_float("MultiRooms slip", slip, 0.0, 1.0, high_open=True)
        gamma = as_float("MultiRooms gamma", gamma, 0.0, 1.0, low_open=True)
        step_reward = as_float("MultiRooms step_reward", step_reward)
        goal_reward = as_float("MultiRooms goal_reward", goal_reward)
        if isinstance(closed_doorways, (str, bytes)) or not isinstance(closed_doorways, Iterable):
            raise ValueError(
                f"closed_doorways must be a list of cells (indices or (row, col) "
                f"pairs), got {closed_doorways!r}"
            )
        self.size, self.rooms, self.room_size = size, rooms, size // rooms
        self.slip, self.gamma = float(slip), float(gamma)
        self.step_reward, self.goal_reward = float(step_reward), float(goal_reward)
        self.num_states = size * size
        closed = frozenset(
            self._cell("closed doorway", c, allow_wall=True) for c in closed_doorways
        )
        layout = _build_layout(size, rooms, frozenset())
        unknown = sorted(closed - set(layout.doorway_rooms))
        if unknown:
            raise ValueError(
                f"closed_doorways {[self.coords(c) for c in unknown]} are not doorways; "
                f"doorways are {sorted(self.coords(c) for c in layout.doorway_rooms)[:6]}…"
            )
        layout = _build_layout(size, rooms, closed)
        self.closed_doorways = tuple(sorted(closed))
        self._wall = layout.wall
        self._room_of = layout.room_of
        self.doorway_rooms = dict(sorted(layout.doorway_rooms.items()))
        self.start_state = self._cell("start", 0 if start is None else start)
        self.goal_state = self._cell("goal", self.num_states - 1 if goal is None else goal)
        if self.start_state == self.goal_state:
            raise ValueError(
                f"start and goal are the same cell {self.coords(self.start_state)}; "
                "choose two different free cells"
            )
        self._next = self._successor_table()
        self._check_reachable()
        self._tables: dict[torch.device, DynamicsTable] = {}
        self._table: DynamicsTable | None = None
        self._transition: torch.Tensor | None = None  # built on first use; the world is immutable
        self._stimuli: dict[str, torch.Tensor] = {}  # perception only: never used by the dynamics
        for name, values in (stimuli or {}).items():
            self.set_stimulus(name, values)

    # ----------------------------------------------------------------------------- layout
    def _cell(self, what: str, cell, allow_wall: bool = False) -> int:
        if isinstance(cell, (tuple, list)):
            if len(cell) != 2:
                raise ValueError(f"{what} must be a cell index or a (row, col) pair, got {cell!r}")
            r, c = (as_int(f"{what} {name}", v) for name, v in zip(("row", "column"), cell))
            if not (0 <= r < self.size and 0 <= c < self.size):
                raise ValueError(
                    f"{what} {tuple(cell)} lies outside the {self.size}×{self.size} grid"
                )
            cell = r * self.size + c
        elif isinstance(cell, (int, np.integer)) and not isinstance(cell, bool):
            cell = int(cell)
            if not (0 <= cell < self.num_states):
                raise ValueError(f"{what} {cell} is not a cell index in [0, {self.num_states})")
        else:
            raise ValueError(
                f"{what} must be a cell index or a (row, col) pair of integers, got {cell!r}"
            )
        if not allow_wall and self._wall.flat[cell]:
            raise ValueError(
                f"{what} {self.coords(cell)} is a wall cell; choose a free cell "
                f"(rows/columns that are multiples of {self.room_size} are walls)"
            )
        return cell

    def coords(self, state: int) -> tuple[int, int]:
        """``(row, col)`` of a state index."""
        return divmod(int(state), self.size)

    def _successor_table(self) -> np.ndarray:
        rows, cols = np.divmod(np.arange(self.num_states), self.size)
        table = np.empty((self.num_states, 4), dtype=np.int64)
        for a, (dr, dc) in enumerate(ACTION_DELTAS):
            nr, nc = rows + dr, cols + dc
            inside = (nr >= 0) & (nr < self.size) & (nc >= 0) & (nc < self.size)
            target = np.where(inside, nr * self.size + nc, 0)
            blocked = ~inside | self._wall.ravel()[target]
            table[:, a] = np.where(blocked, np.arange(self.num_states), target)
        return table

    def _check_reachable(self) -> None:
        seen = np.zeros(self.num_states, dtype=bool)
        seen[self.start_state] = True
        queue = deque([self.start_state])
        while queue:
            s = queue.popleft()
            for t in self._next[s]:
                if not seen[t]:
                    seen[t] = True
                    queue.append(int(t))
        if not seen[self.goal_state]:
            raise ValueError(
                f"goal {self.coords(self.goal_state)} cannot be reached from start "
                f"{self.coords(self.start_state)} (closed_doorways={len(self.closed_doorways)} "
                "cut every path); open a doorway on some path between them"
            )

    @property
    def wall_mask(self) -> torch.Tensor:
        """``[S]`` bool, True on wall cells (and closed doorways)."""
        return torch.from_numpy(self._wall.ravel().copy())

    @property
    def free_mask(self) -> torch.Tensor:
        """``[S]`` bool, True on cells an agent can occupy."""
        return ~self.wall_mask

    @property
    def room_of(self) -> torch.Tensor:
        """``[S]`` int64 room id ``room_row · R + room_col``; −1 on walls and doorway cells."""
        return torch.from_numpy(self._room_of.copy())

    @property
    def doorways(self) -> torch.Tensor:
        """``[D]`` int64 doorway cells (open ones), sorted."""
        return torch.tensor(list(self.doorway_rooms), dtype=torch.int64)

    @property
    def doorway_mask(self) -> torch.Tensor:
        """``[S]`` bool, True on open doorway cells."""
        mask = torch.zeros(self.num_states, dtype=torch.bool)
        mask[self.doorways] = True
        return mask

    def room_doorways(self, room: int) -> list[int]:
        """The open doorway cells of ``room``, sorted."""
        return [d for d, pair in self.doorway_rooms.items() if room in pair]

    def room_cells(self, room: int) -> list[int]:
        """The interior (non-doorway) free cells of ``room``, sorted."""
        return np.flatnonzero(self._room_of == room).tolist()

    @property
    def num_rooms(self) -> int:
        return self.rooms * self.rooms

    @property
    def terminal_mask(self) -> torch.Tensor:
        """``[S]`` bool, True at the goal: entering it ends the episode."""
        mask = torch.zeros(self.num_states, dtype=torch.bool)
        mask[self.goal_state] = True
        return mask

    @property
    def next_state_table(self) -> torch.Tensor:
        """``[S, A]`` int64: the cell reached by executing action ``a`` without slipping."""
        return torch.from_numpy(self._next.copy())

    @property
    def state_reward(self) -> torch.Tensor:
        """``[S]`` float64: reward for *entering* each state."""
        r = torch.full((self.num_states,), self.step_reward, dtype=torch.float64)
        r[self.goal_state] = self.goal_reward
        return r

    def describe(self) -> dict:
        """A JSON-able description that identifies the world (saved with demonstrations)."""
        return {
            "kind": "MultiRooms",
            "size": self.size,
            "rooms": self.rooms,
            "slip": self.slip,
            "start": self.start_state,
            "goal": self.goal_state,
            "closed_doorways": list(self.closed_doorways),
            "step_reward": self.step_reward,
            "goal_reward": self.goal_reward,
            "gamma": self.gamma,
        }

    @classmethod
    def from_description(cls, desc: dict) -> MultiRooms:
        """The world a :meth:`describe` dict names.

        Raises:
            TypeError: ``desc`` is not a dict.
            ValueError: a description of another kind of world, one that lacks a field (naming
                it), or a field the world refuses.
        """
        if not isinstance(desc, dict):
            raise TypeError(
                f"MultiRooms.from_description: give a MultiRooms.describe() dict, got "
                f"{type(desc).__name__}"
            )
        if desc.get("kind") != "MultiRooms":
            raise ValueError(f"description is of a {desc.get('kind')!r} world, not MultiRooms")
        fields = (
            "size",
            "rooms",
            "slip",
            "start",
            "goal",
            "closed_doorways",
            "step_reward",
            "goal_reward",
            "gamma",
        )
        missing = [name for name in fields if name not in desc]
        if missing:
            raise ValueError(
                f"MultiRooms description lacks {missing}; a MultiRooms.describe() dict holds "
                f"{['kind', *fields]}"
            )
        return cls(
            size=desc["size"],
            rooms=desc["rooms"],
            slip=desc["slip"],
            start=desc["start"],
            goal=desc["goal"],
            closed_doorways=desc["closed_doorways"],
            step_reward=desc["step_reward"],
            goal_reward=desc["goal_reward"],
            gamma=desc["gamma"],
        )

    def __repr__(self) -> str:
        return (
            f"MultiRooms(size={self.size}, rooms={self.rooms}, slip={self.slip}, "
            f"start={self.coords(self.start_state)}, goal={self.coords(self.goal_state)}, "
            f"closed_doorways={len(self.closed_doorways)})"
        )

    # ----------------------------------------------------------------------------- dynamics
    def slipped_actions(self, actions: torch.Tensor, uniforms: torch.Tensor) -> torch.Tensor:
        """The action actually executed, given the chosen ``actions [B]`` and ``uniforms [B]``
        (the slot rule of :meth:`dynamics_table`)."""
        cdf = self.dynamics_table().cdf[0, 0].to(uniforms.device)
        slot = (cdf <= uniforms.to(torch.float64)[:, None]).sum(1).clamp(max=3)
        return torch.where(slot < 3, (actions + 1 + slot) % 4, actions)

    def dynamics_table(self) -> DynamicsTable:
        """The dynamics as a :class:`DynamicsTable`: slot ``k < 3`` is the slip to direction
        ``(a + 1 + k) mod 4`` (``cdf`` steps of ``slip / 3``), slot 3 the chosen action."""
        if self._table is None:
            nxt = torch.from_numpy(self._next)
            actions = torch.arange(4)
            dirs = torch.stack([(actions + 1 + k) % 4 for k in range(3)] + [actions], 1)  # [A, K]
            successors = nxt[:, dirs]  # [S, A, K]
            cdf = torch.tensor(
                [self.slip / 3, 2 * self.slip / 3, self.slip, 1.0], dtype=torch.float64
            )
            self._table = DynamicsTable(
                successors.contiguous(),
                cdf.expand_as(successors).contiguous(),
                self.state_reward[successors].contiguous(),
            )
        return self._table

    def _device_table(self, device: torch.device) -> DynamicsTable:
        table = self._tables.get(device)
        if table is None:
            table = self._tables[device] = self.dynamics_table().to(device)
        return table

    def step(
        self,
        positions: torch.Tensor,
        actions: torch.Tensor,
        uniforms: torch.Tensor | None = None,
        generator: torch.Generator | None = None,
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Advance ``B`` agents one primitive step (by :meth:`dynamics_table`).

        Args:
            positions: ``[B]`` int64 current states.
            actions: ``[B]`` int64 chosen actions in ``0…3``.
            uniforms: ``[B]`` floats in [0, 1) that decide slips (``u < slip`` slips to direction
                ``(a + 1 + k) mod 4`` for ``k·slip/3 ≤ u < (k+1)·slip/3``); drawn from
                ``generator`` if omitted.
            generator: a ``torch.Generator`` on the positions' device.

        Returns:
            ``(next_positions [B] int64, rewards [B] float64)``.
        """
        if uniforms is None:
            uniforms = torch.rand(positions.shape, generator=generator, device=positions.device)
        return self._device_table(positions.device).step(positions, actions, uniforms)

    # ----------------------------------------------------------------------------- true model
    def transition_model(self, sparse: bool = True) -> torch.Tensor:
        """The true dynamics ``P [A, S, S]`` (float64), MDP-toolbox convention ``P[a, s, s']``.

        Walls and the goal are absorbing (self-loops), so every row sums to 1.
        Returned as a sparse COO tensor unless ``sparse=False``; each call returns a fresh copy.
        """
        if self._transition is None:
            self._transition = self._build_transition_model()
        P = (
            self._transition.clone()
        )  # cheap next to the coalesce in the build (planners call often)
        return P if sparse else P.to_dense()

    def _build_transition_model(self) -> torch.Tensor:
        S, A = self.num_states, self.num_actions
        idx_a, idx_s, idx_t, vals = [], [], [], []
        absorbing = self._wall.ravel().copy()
        absorbing[self.goal_state] = True
        states = np.arange(S)
        for a in range(A):
            for b in range(A):
                p = (1.0 - self.slip) if a == b else self.slip / 3.0
                if p == 0.0:
                    continue
                target = np.where(absorbing, states, self._next[:, b])
                idx_a.append(np.full(S, a))
                idx_s.append(states)
                idx_t.append(target)
                vals.append(np.where(absorbing, 1.0 if a == b else 0.0, p))
        indices = torch.from_numpy(
            np.stack([np.concatenate(idx_a), np.concatenate(idx_s), np.concatenate(idx_t)])
        )
        return torch.sparse_coo_tensor(
            indices, torch.from_numpy(np.concatenate(vals)), (A, S, S), check_invariants=False
        ).coalesce()

    def reward_model(self) -> torch.Tensor:
        """Expected reward ``R [S, A]`` (float64) of each action; 0 at walls and the goal."""
        # Sparse on purpose: the dense [A, S, S] model is 1.3 GB at 80×80 and 6.6 GB at 120×120.
        P = self.transition_model(sparse=True)
        A, S = self.num_actions, self.num_states
        a, s, t = P.indices()
        r = self.state_reward.double()
        R = torch.zeros(A * S, dtype=torch.float64).index_add_(0, a * S + s, P.values() * r[t])
        R = R.view(A, S).T.contiguous()
        absorbing = torch.from_numpy(self._wall.ravel().copy())
        absorbing[self.goal_state] = True
        R[absorbing] = 0.0
        return R

    # ----------------------------------------------------------------------------- stimuli
    @property
    def stimulus_feature_names(self) -> tuple[str, ...]:
        """Names of the columns of :meth:`stimulus_features`: :data:`STIMULUS_FEATURES`."""
        return STIMULUS_FEATURES

    def set_stimulus(self, name: str, values) -> None:
        """Set the ``"light"`` or ``"sound"`` channel: ``values`` is ``[S]`` finite numbers (one
        per state, e.g. 1.0 where a lamp is on), or ``None`` to switch the channel off (all 0).

        Only what an observer perceives changes; dynamics, rewards and :meth:`describe` do not.
        """
        if name not in _SETTABLE_STIMULI:
            raise ValueError(
                f"MultiRooms.set_stimulus: unknown channel {name!r}; the settable "
                f"channels are {list(_SETTABLE_STIMULI)}"
            )
        if values is None:
            self._stimuli.pop(name, None)
            return
        v = torch.as_tensor(values, dtype=torch.float64).detach().cpu().clone()
        if v.shape != (self.num_states,):
            raise ValueError(
                f"MultiRooms.set_stimulus({name!r}): got shape {tuple(v.shape)}, "
                f"expected [S] = [{self.num_states}] (one value per state)"
            )
        if not bool(torch.isfinite(v).all()):
            raise ValueError(f"MultiRooms.set_stimulus({name!r}): values hold NaN or infinity")
        self._stimuli[name] = v

    def stimulus_features(self) -> torch.Tensor:
        """``[S, 4]`` float64 stimulus features, columns :data:`STIMULUS_FEATURES`:

        * ``room``: ``(room id + 1) / num_rooms`` in (0, 1] inside a room, 0 on doorway and wall
          cells (no room);
        * ``doorway``: 1.0 on open doorway cells, else 0;
        * ``light``, ``sound``: the channels set with :meth:`set_stimulus` (0 when unset).
        """
        room = torch.from_numpy(self._room_of.astype(np.float64))
        room = torch.where(room >= 0, (room + 1.0) / self.num_rooms, torch.zeros_like(room))
        zeros = torch.zeros(self.num_states, dtype=torch.float64)
        columns = [room, self.doorway_mask.double()]
        columns += [self._stimuli.get(name, zeros) for name in _SETTABLE_STIMULI]
        return torch.stack(columns, dim=1)

    def render_ansi(self, positions: Iterable[int] = ()) -> str:
        """Text picture: ``#`` wall, ``+`` doorway, ``S`` start, ``G`` goal, ``A`` agents."""
        grid = np.where(self._wall, "#", ".").astype("<U1")
        for d in self.doorway_rooms:
            grid.flat[d] = "+"
        grid.flat[self.start_state] = "S"
        grid.flat[self.goal_state] = "G"
        for p in positions:
            grid.flat[int(p)] = "A"
        return "\n".join("".join(row) for row in grid) + "\n"


def _check_int(name: str, value) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{name} must be a positive whole number, got {value!r}")
    if value <= 0:
        raise ValueError(f"{name}={value} must be a positive whole number")
    return int(value)
