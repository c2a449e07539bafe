"""Farama's MiniGrid tasks (DoorKey, Unlock, KeyCorridor, MultiRoom, FourRooms, …) as tabular
worlds, their table read from MiniGrid's own ``step``.

:func:`from_minigrid` resets the environment with one seed (one layout) and enumerates, breadth
first, every full state reachable from it with the six actions that change something (left,
right, forward, pickup, drop, toggle; MiniGrid's ``done`` does nothing in these tasks and is left
out). The successor of each ``(state, action)`` is whatever MiniGrid's own ``step`` does from
that state: the table is MiniGrid's dynamics, not a rewrite of them (tested on every pair of a
small task and a sample of a large one).

How a state is read and set
    A full state is the agent's cell and direction, and for each object that can change — every
    key, ball and box (where it lies: a cell, carried, or gone: a box opened, or a ball still
    inside its box) and every door (open, closed or locked) — its part. Walls, the goal, lava and
    floor never change. :class:`MiniGridWorld` reads these straight from the environment
    (``agent_pos``, ``agent_dir``, ``carrying``, the grid's cells, the doors' flags) and sets
    them back by writing the grid's cell list, the doors' flags and the agent's fields: a few
    microseconds, where deep-copying the environment costs milliseconds. While enumerating, the
    environment's ``gen_obs`` (the agent's partial view, ≈ 95 % of a ``step``'s time and no
    part of the state) is replaced by a no-op, and its random generator by a guard that raises:
    a ``step`` that draws a random number is stochastic and refused.

Reward and termination (as the library's other worlds, not MiniGrid's)
    −0.01 a step, +1 for the step that succeeds (MiniGrid's ``terminated`` with a positive
    reward: reaching the goal, opening the door in Unlock, picking up the target in
    KeyCorridor or UnlockPickup), and the episode ends there; a ``terminated`` step without
    reward (into lava) ends it too, at −0.01. MiniGrid pays ``1 − 0.9 · steps / max_steps`` at
    success and 0 otherwise, and truncates after ``max_steps``. Its reward depends on the step
    count, which is no part of a tabular state (keeping it would multiply the states by
    ``max_steps``), and its time limit ends episodes the learner runs as one continuing stream.
    With a discount ``γ < 1`` and a step cost, the optimum is still the shortest way to
    success, as under MiniGrid's reward.

The goal moved (optional)
    ``goal=(x, y)`` moves the task's one goal square to another empty floor cell after every
    reset: the same layout (walls, doors, keys, the agent's start) with a task that ends
    elsewhere, so that a mentor can demonstrate one task and a learner face another that shares
    its subgoals (transfer; :func:`~himit_torch.mentor.minigrid.demonstrations_in` carries
    demonstrations between two such worlds).

Slip (optional)
    With probability ``slip`` the chosen action fails and one of the other five is taken, each
    with ``slip / 5`` (the paper's slip, as in :class:`~himit_torch.MultiRooms`). Default 0:
    MiniGrid's own determinism.

Refused (``ValueError``)
    An id Gymnasium does not know, an environment that is not a MiniGrid one, more reachable
    states than ``max_states``, a ``step`` that draws random numbers (Dynamic-Obstacles), tasks
    whose goal is read from a language mission that changes per reset (GoToDoor, GoToObject,
    Fetch, PutNear and BabyAI's levels: the state does not say what to do), and tasks whose
    success needs the ``done`` action or cannot be reached at all.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from himit_torch.validation import as_float, as_int, check_memory
from himit_torch.worlds.table_world import TableWorld, table_fingerprint
from himit_torch.worlds.tabular import DynamicsTable

__all__ = [
    "MINIGRID_ACTION_NAMES",
    "MINIGRID_TASKS",
    "MiniGridWorld",
    "from_minigrid",
]

#: The world's actions: MiniGrid's own action numbers 0 … 5 (``done`` = 6 is left out).
MINIGRID_ACTION_NAMES = ("left", "right", "forward", "pickup", "drop", "toggle")

#: The key-and-door tasks this library describes (``himit info --minigrid ID``), current ids.
MINIGRID_TASKS = (
    "MiniGrid-DoorKey-5x5-v0",
    "MiniGrid-DoorKey-6x6-v0",
    "MiniGrid-DoorKey-8x8-v0",
    "MiniGrid-Unlock-v0",
    "MiniGrid-UnlockPickup-v0",
    "MiniGrid-KeyCorridorS3R1-v0",
    "MiniGrid-MultiRoom-N2-S4-v0",
    "MiniGrid-MultiRoom-N4-S5-v1",
    "MiniGrid-FourRooms-v0",
)

#: MiniGrid classes whose goal is read from a language mission that changes per reset.
_LANGUAGE_GOALS = {
    "GoToDoorEnv": "the mission names one of four doors",
    "GoToObjectEnv": "the mission names one of several objects",
    "FetchEnv": "the mission names one of several objects",
    "PutNearEnv": "the mission names the object to move and the one to put it near",
}
#: MiniGrid classes whose ``step`` moves things at random.
_STOCHASTIC = {"DynamicObstaclesEnv": "the obstacles move at random in every step"}

#: Objects that never change (left in the fixed grid) and those a state follows.
_STATIC = ("wall", "floor", "goal", "lava")
_MOVABLE = ("key", "ball", "box")

CARRIED, OFF_GRID = -1, -2
STEP_REWARD, GOAL_REWARD = -0.01, 1.0


def _import_minigrid():
    """``import minigrid`` (which registers its ids with Gymnasium), refused clearly when it is
    not installed. Imported here, not at the top: with pygame it takes ≈ 1 s."""
    os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
    try:
        import minigrid
    except ImportError:
        raise ValueError(
            "MiniGrid is not installed: pip install 'himit_torch[minigrid]' (or minigrid)"
        ) from None
    return minigrid


class _RandomGuard:
    """Stands in for an environment's ``np_random`` while its table is read: any draw raises."""

    def __getattr__(self, name):
        raise _DrewRandom(name)


class _DrewRandom(Exception):
    pass


@dataclass(frozen=True)
class _Layout:
    """What changes in one environment object, found right after its reset: the movable objects
    (keys, balls, boxes, box contents), the doors, and the grid's cells without the movables.
    States are tuples ``(x, y, direction, *where each movable is, *each door's state)``, the
    movables and doors in the order of a row-major scan of the reset grid (a box's content
    right after its box), so two environments reset alike agree on them."""

    movables: tuple
    doors: tuple
    door_cells: tuple
    base: tuple
    width: int

    @staticmethod
    def of(env) -> _Layout:
        grid = env.grid
        movables, doors, door_cells, base = [], [], [], list(grid.grid)
        for index, obj in enumerate(grid.grid):
            if obj is None or obj.type in _STATIC:
                continue
            if obj.type == "door":
                doors.append(obj)
                door_cells.append(index)
            elif obj.type in _MOVABLE:
                movables.append(obj)
                base[index] = None
                inner = getattr(obj, "contains", None)
                while inner is not None:  # a box's content: off the grid until the box opens
                    movables.append(inner)
                    inner = getattr(inner, "contains", None)
            else:
                raise ValueError(
                    f"from_minigrid: the grid holds a {obj.type!r}; a world is made of walls, "
                    "floor, goals, lava, doors, keys, balls and boxes only"
                )
        if env.carrying is not None:
            raise ValueError("from_minigrid: the agent carries something after reset")
        return _Layout(tuple(movables), tuple(doors), tuple(door_cells), tuple(base), grid.width)

    def read(self, env) -> tuple:
        cells, width = env.grid.grid, self.width
        x, y = (int(v) for v in env.agent_pos)
        key = [x, y, int(env.agent_dir)]
        carrying = env.carrying
        for obj in self.movables:
            if obj is carrying:
                key.append(CARRIED)
                continue
            pos = obj.cur_pos
            if pos is not None and pos[0] >= 0:
                index = int(pos[1]) * width + int(pos[0])
                if cells[index] is obj:
                    key.append(index)
                    continue
            # (a box's content just let out: MiniGrid does not set its cur_pos)
            key.append(next((i for i, c in enumerate(cells) if c is obj), OFF_GRID))
        for door in self.doors:
            key.append(0 if door.is_open else 2 if door.is_locked else 1)
        return tuple(key)

    def write(self, env, key: tuple) -> None:
        cells = list(self.base)
        width = self.width
        carrying = None
        n = len(self.movables)
        for obj, where in zip(self.movables, key[3 : 3 + n]):
            if where >= 0:
                cells[where] = obj
                obj.cur_pos = np.array([where % width, where // width])
            elif where == CARRIED:
                carrying = obj
                obj.cur_pos = np.array([-1, -1])
        for door, state in zip(self.doors, key[3 + n :]):
            door.is_open, door.is_locked = state == 0, state == 2
        env.grid.grid = cells
        env.carrying = carrying
        env.agent_pos = (key[0], key[1])
        env.agent_dir = key[2]
        env.step_count = 0

    def names(self) -> tuple[str, ...]:
        """``"yellow key"``, ``"red door"``, … for the movables then the doors (numbered where
        two share a name)."""
        raw = [f"{o.color} {o.type}" for o in self.movables + self.doors]
        return tuple(
            f"{name} {raw[:i].count(name) + 1}" if raw.count(name) > 1 else name
            for i, name in enumerate(raw)
        )


class MiniGridWorld(TableWorld):
    """A MiniGrid task for one reset seed as a :class:`~himit_torch.TableWorld` (made by
    :func:`from_minigrid`; the module docstring says how).

    Beyond a TableWorld's members:

    Attributes:
        env: the unwrapped environment the table was read from.
        env_id, env_kwargs, seed, slip: how it was made.
        object_names: the objects a state follows (movables, then doors), e.g. ``("yellow
            key", "yellow door")``.
        goal_cells: the cell index ``y · width + x`` of each goal square.
        goal: the cell ``(x, y)`` the goal was moved to (``from_minigrid``'s ``goal``), or
            ``None`` where it is where MiniGrid puts it.
    """

    env: Any
    env_id: str | None
    env_kwargs: dict
    seed: int
    slip: float
    goal: tuple[int, int] | None

    def _init_minigrid(self, env, env_id, env_kwargs, seed, slip, layout, keys, goal) -> None:
        self.env, self.env_id, self.env_kwargs = env, env_id, dict(env_kwargs)
        self.seed, self.slip, self.goal = int(seed), float(slip), goal
        self._layout = layout
        self._keys = keys
        self._index = {k: i for i, k in enumerate(keys)}
        self._layouts: dict[int, tuple[Any, _Layout]] = {id(env): (env, layout)}
        self.object_names = layout.names()
        self.width, self.height = int(env.grid.width), int(env.grid.height)
        self.goal_cells = tuple(
            i for i, c in enumerate(env.grid.grid) if c is not None and c.type == "goal"
        )
        self._state_array = np.asarray(keys, dtype=np.int64)

    # ----------------------------------------------------------------------------- the states
    @property
    def state_table(self) -> np.ndarray:
        """``[S, 3 + movables + doors]`` int64: each state's ``(x, y, direction, where each
        movable is — a cell index y·width + x, −1 carried, −2 off the grid —, each door's state
        — 0 open, 1 closed, 2 locked)``, in :attr:`object_names`' order (a copy)."""
        return self._state_array.copy()

    def agent(self, states: torch.Tensor | None = None) -> torch.Tensor:
        """``[S, 3]`` (or ``[B, 3]`` for ``states``) int64: the agent's x, y and direction."""
        table = torch.from_numpy(self._state_array[:, :3])
        return table if states is None else table[torch.as_tensor(states)]

    def front_cell(self) -> torch.Tensor:
        """``[S]`` int64: the cell index in front of the agent in each state."""
        dx = torch.tensor([1, 0, -1, 0])
        dy = torch.tensor([0, 1, 0, -1])
        x, y, d = self.agent().unbind(1)
        return (y + dy[d]) * self.width + x + dx[d]

    def object_cell(self, name: str) -> torch.Tensor:
        """``[S]`` int64: where the named object (:attr:`object_names`) is in each state: its
        cell index, −1 carried, −2 off the grid (doors never move: their cell)."""
        names = self.object_names
        if name not in names:
            raise ValueError(f"{self.name}: no object {name!r}; the world has {list(names)}")
        i = names.index(name)
        moving = len(self._layout.movables)
        if i < moving:
            return torch.from_numpy(self._state_array[:, 3 + i].copy())
        cell = self._layout.door_cells[i - moving]
        return torch.full((self.num_states,), cell, dtype=torch.int64)

    def door_state(self, name: str) -> torch.Tensor:
        """``[S]`` int64 state of the named door: 0 open, 1 closed, 2 locked."""
        names = self.object_names
        moving = len(self._layout.movables)
        if name not in names[moving:]:
            raise ValueError(f"{self.name}: no door {name!r}; its doors: {list(names[moving:])}")
        return torch.from_numpy(self._state_array[:, 3 + names.index(name)].copy())

    def state_key(self, state: int) -> tuple:
        """The full state of index ``state`` as its tuple (:attr:`state_table`'s row)."""
        return self._keys[int(state)]

    def states_from(self, other: MiniGridWorld, states) -> torch.Tensor:
        """``[T]`` int64: this world's index of each of ``other``'s ``states``, matched by the
        full state (:meth:`state_key`) — for two worlds of one layout, e.g. a task and the same
        task with its goal moved (``from_minigrid``'s ``goal``).

        Raises:
            TypeError: ``other`` is not a :class:`MiniGridWorld`.
            ValueError: the worlds' objects differ, or a state of ``other`` is not one of this
                world's (in this world it lies past a goal, say).
        """
        if not isinstance(other, MiniGridWorld):
            raise TypeError(
                f"{self.name}.states_from needs a world made by from_minigrid, got "
                f"{type(other).__name__}"
            )
        if other.object_names != self.object_names or other.width != self.width:
            raise ValueError(
                f"{self.name}.states_from: {other.name}'s objects {list(other.object_names)} "
                f"on {other.width}×{other.height} cells are not this world's "
                f"({list(self.object_names)} on {self.width}×{self.height}): give a world of "
                "the same layout"
            )
        out = []
        for s in torch.as_tensor(states).reshape(-1).tolist():
            index = self._index.get(other.state_key(s))
            if index is None:
                raise ValueError(
                    f"{self.name}.states_from: {other.name}'s state {s} "
                    f"({other.describe_state(s)}) is not reachable in this world"
                )
            out.append(index)
        return torch.tensor(out, dtype=torch.int64)

    # ------------------------------------------------------------------ encoder and decoder
    def make_env(self, render_mode: str | None = None):
        """A fresh environment of this task (``gymnasium.make`` with the world's id and kwargs),
        reset to the world's layout (:meth:`reset_env`). Needs an id."""
        if self.env_id is None:
            raise ValueError(
                f"{self.name} was made from an environment object without an id; reset your "
                "own environment with world.reset_env(env)"
            )
        import gymnasium

        env = gymnasium.make(self.env_id, render_mode=render_mode, **self.env_kwargs)
        self.reset_env(env)
        return env

    def reset_env(self, env) -> int:
        """``env.reset(seed=world.seed)``: the world's layout, and its start state (returned).
        After this, :meth:`state_of` and :meth:`set_state` work on ``env``."""
        env.reset(seed=self.seed)
        raw = env.unwrapped
        if self.goal is not None:
            _move_goal(raw, self.goal, self.name)
        layout = _Layout.of(raw)
        key = layout.read(raw)
        if key != self._keys[self.start_state] or len(layout.doors) != len(self._layout.doors):
            raise ValueError(
                f"{self.name}: the environment reset with seed {self.seed} is not this world's "
                "layout (another task, size or MiniGrid version?)"
            )
        self._layouts[id(raw)] = (raw, layout)
        return self.start_state

    def _layout_of(self, env) -> tuple[Any, _Layout]:
        raw = env.unwrapped
        found = self._layouts.get(id(raw))
        if found is None or found[0] is not raw:
            raise ValueError(
                f"{self.name}: this environment has not been reset by the world; call "
                "world.reset_env(env) (or make it with world.make_env()) first"
            )
        return found

    def state_of(self, env) -> int:
        """The world's state index of the environment's current state (the encoder).

        Raises:
            ValueError: the environment was not reset by :meth:`reset_env`, or is in a state the
                world does not hold (after an episode's end, say).
        """
        raw, layout = self._layout_of(env)
        key = layout.read(raw)
        index = self._index.get(key)
        if index is None:
            raise ValueError(f"{self.name}: the environment's state {key} is not in the world")
        return index

    def set_state(self, env, state: int) -> None:
        """Put the environment in the world's state ``state`` (the decoder), e.g. to render it
        or to step it from there. Its step counter is set to 0."""
        raw, layout = self._layout_of(env)
        state = as_int(f"{self.name}: state", state, 0, self.num_states - 1)
        layout.write(raw, self._keys[state])

    def render(self, state: int, tile_size: int = 32) -> np.ndarray:
        """``[H, W, 3]`` uint8: the whole grid in state ``state`` as MiniGrid draws it (its own
        renderer, the agent's view not highlighted), drawn in :attr:`env`, which is left in
        that state."""
        state = as_int(f"{self.name}: state", state, 0, self.num_states - 1)
        self._layout.write(self.env, self._keys[state])
        return self.env.get_frame(highlight=False, tile_size=int(tile_size))

    def cell_center(self, states: torch.Tensor | Iterable[int], tile_size: int = 32) -> np.ndarray:
        """``[T, 2]`` pixel coordinates (x, y) of the agent's cell in each state, on a
        :meth:`render` image of that tile size: to draw paths over the grid."""
        xy = self.agent(
            torch.as_tensor(list(states) if not isinstance(states, torch.Tensor) else states)
        )[:, :2]
        return (xy.numpy() + 0.5) * tile_size

    def describe_state(self, state: int) -> str:
        """One line: the agent's cell and direction, what it carries, each door's state."""
        key = self._keys[as_int(f"{self.name}: state", state, 0, self.num_states - 1)]
        x, y, d = key[:3]
        n = len(self._layout.movables)
        names = self.object_names
        carried = [names[i] for i in range(n) if key[3 + i] == CARRIED]
        doors = [
            f"{names[n + j]} {('open', 'closed', 'locked')[s]}" for j, s in enumerate(key[3 + n :])
        ]
        return (
            f"agent ({x}, {y}) facing {('east', 'south', 'west', 'north')[d]}, carrying "
            f"{carried[0] if carried else 'nothing'}" + "".join(f", {d}" for d in doors)
        )


def from_minigrid(
    env: Any,
    seed: int = 0,
    slip: float = 0.0,
    max_states: int = 100_000,
    gamma: float = 0.99,
    goal: tuple[int, int] | None = None,
    **kwargs,
) -> MiniGridWorld:
    """A MiniGrid task for one reset seed as a tabular world (module docstring).

    Args:
        env: a MiniGrid id (``"MiniGrid-DoorKey-6x6-v0"``) made with ``gymnasium.make(env,
            **kwargs)``, or an environment object (its ``unwrapped`` is read and reset).
        seed: the reset seed: one layout, whose reachable states are the world.
        slip: the probability in ``[0, 1)`` that an action fails and one of the other five is
            taken at random.
        max_states: refuse a task with more reachable states than this.
        gamma: the discount, in ``(0, 1]``.
        goal: ``(x, y)``: move the task's one goal square there after each reset (an empty
            floor cell, not the agent's start; module docstring); ``None``: MiniGrid's own.
        **kwargs: keyword arguments of ``gymnasium.make`` (only with an id).

    Returns:
        A :class:`MiniGridWorld`: state 0 is the start; ``describe()`` holds the id, kwargs,
        seed, slip, gamma, the moved goal (if any) and a fingerprint of the table.

    Raises:
        ValueError: an unknown id or keyword, an environment that is not MiniGrid's, more than
            ``max_states`` reachable states, a stochastic ``step``, a language-goal task, a task
            whose success cannot be reached with the six actions, arguments out of range, or a
            ``goal`` in a task without exactly one goal square or on a cell that is not empty.
    """
    seed = as_int("from_minigrid: seed", seed, 0, 2**63 - 1)
    slip = as_float("from_minigrid: slip", slip, 0.0, 1.0, high_open=True)
    max_states = as_int("from_minigrid: max_states", max_states, 1, 2**31 - 1)
    gamma = as_float("from_minigrid: gamma", gamma, 0.0, 1.0, low_open=True)
    if goal is not None:
        if isinstance(goal, (str, bytes)) or not hasattr(goal, "__len__") or len(goal) != 2:
            raise ValueError(f"from_minigrid: goal={goal!r}: give a cell (x, y) or None")
        goal = (
            as_int("from_minigrid: goal x", goal[0], 0),
            as_int("from_minigrid: goal y", goal[1], 0),
        )
    minigrid = _import_minigrid()
    if isinstance(env, str):
        env_id: str | None = env
        env = _make(env, kwargs)
    elif kwargs:
        raise ValueError(
            f"from_minigrid: keyword arguments {sorted(kwargs)} are for gymnasium.make and "
            "need an environment id, not an environment object"
        )
    else:
        spec = getattr(env, "spec", None)
        env_id = spec.id if spec is not None else None
    spec = getattr(env, "spec", None)
    made_kwargs = {
        k: v for k, v in dict(spec.kwargs if spec is not None else {}).items() if k != "render_mode"
    }
    raw = getattr(env, "unwrapped", env)
    label = env_id or type(raw).__name__
    if not isinstance(raw, minigrid.minigrid_env.MiniGridEnv):
        raise ValueError(
            f"from_minigrid({label}): {type(raw).__name__} is not a MiniGrid environment; "
            "Gymnasium's toy-text tasks go through from_gymnasium"
        )
    _refuse_kind(raw, label)
    raw.reset(seed=seed)
    if goal is not None:
        _move_goal(raw, goal, label)
    layout = _Layout.of(raw)
    keys, successors, success, ended = _enumerate(raw, layout, label, max_states)
    world = _table_world(keys, successors, success, ended, slip, gamma, label)
    try:
        json.dumps(made_kwargs)
    except TypeError:
        raise ValueError(
            f"from_minigrid({label}): keyword arguments {made_kwargs!r} are not JSON-able"
        ) from None
    description = {
        "kind": "minigrid",
        "id": env_id,
        "kwargs": made_kwargs,
        "seed": seed,
        "slip": slip,
        "gamma": gamma,
        **({"goal": list(goal)} if goal is not None else {}),
        "fingerprint": table_fingerprint(
            world.dynamics_table(), world.terminal_mask, world.start_distribution
        ),
    }
    world._description = description
    world._init_minigrid(raw, env_id, made_kwargs, seed, slip, layout, keys, goal)
    layout.write(raw, keys[0])
    return world


def _move_goal(raw, goal: tuple[int, int], label: str) -> None:
    """Move the reset grid's one goal square to the empty cell ``goal``."""
    from minigrid.core.world_object import Goal

    grid = raw.grid
    goals = [i for i, c in enumerate(grid.grid) if c is not None and c.type == "goal"]
    if len(goals) != 1:
        raise ValueError(
            f"from_minigrid({label}): goal={goal} moves the task's one goal square, and this "
            f"task has {len(goals)}; give goal=None"
        )
    x, y = goal
    if (x, y) == (goals[0] % grid.width, goals[0] // grid.width):
        return
    here = grid.get(x, y) if x < grid.width and y < grid.height else "outside the grid"
    if here is not None or (x, y) == tuple(int(v) for v in raw.agent_pos):
        what = getattr(here, "type", here) if here is not None else "the agent's start"
        raise ValueError(
            f"from_minigrid({label}): goal={goal}: that cell is {what}; give an empty floor "
            f"cell of the {grid.width}×{grid.height} grid"
        )
    grid.grid[goals[0]] = None
    raw.put_obj(Goal(), x, y)


def _make(env_id: str, kwargs: dict):
    import gymnasium

    try:
        return gymnasium.make(env_id, **kwargs)
    except Exception as err:
        given = "".join(f", {k}={v!r}" for k, v in kwargs.items())
        raise ValueError(
            f"from_minigrid({env_id!r}{given}): gymnasium.make failed with "
            f"{type(err).__name__}: {err}; give a MiniGrid id such as "
            "'MiniGrid-DoorKey-6x6-v0' (himit_torch.worlds.minigrid.MINIGRID_TASKS lists the "
            "key-and-door tasks)"
        ) from err


def _refuse_kind(raw, label: str) -> None:
    names = [cls.__name__ for cls in type(raw).__mro__]
    for name, why in _STOCHASTIC.items():
        if name in names:
            raise ValueError(
                f"from_minigrid({label}): {name} is stochastic ({why}); a table holds "
                "deterministic MiniGrid tasks (give slip= for noise of the library's own)"
            )
    for name, why in _LANGUAGE_GOALS.items():
        if name in names:
            raise ValueError(
                f"from_minigrid({label}): {name}'s goal is read from a language mission that "
                f"changes per reset ({why}), which no state of the world holds; use a task "
                "whose goal is in the grid (MINIGRID_TASKS)"
            )
    if type(raw).__module__.startswith("minigrid.envs.babyai"):
        raise ValueError(
            f"from_minigrid({label}): BabyAI levels read their goal from a language mission "
            "that changes per reset; use a task whose goal is in the grid (MINIGRID_TASKS)"
        )


def _enumerate(raw, layout: _Layout, label: str, max_states: int):
    """Breadth first from the reset state over MiniGrid's own ``step``: the states' keys,
    ``successors [S, 6]``, and per state whether entering it succeeded / ended the episode."""
    actions = range(len(MINIGRID_ACTION_NAMES))
    keys = [layout.read(raw)]
    index = {keys[0]: 0}
    successors: list[list[int]] = []
    success = [False]
    ended = [False]
    saved_obs, saved_random = raw.__dict__.get("gen_obs"), raw._np_random
    raw.gen_obs = lambda: None  # the agent's view: no part of the state, most of step's time
    raw._np_random = _RandomGuard()
    try:
        s = 0
        while s < len(keys):
            row = []
            key = keys[s]
            if ended[s]:  # never left: the true model makes it absorbing
                successors.append([s] * len(actions))
                s += 1
                continue
            for a in actions:
                layout.write(raw, key)
                try:
                    _, reward, terminated, _, _ = raw.step(a)
                except _DrewRandom:
                    raise ValueError(
                        f"from_minigrid({label}): MiniGrid's step drew a random number "
                        f"(action {MINIGRID_ACTION_NAMES[a]}): the task is stochastic, and a "
                        "table holds deterministic tasks (give slip= for noise of the "
                        "library's own)"
                    ) from None
                nxt = layout.read(raw)
                t = index.get(nxt)
                won = bool(terminated) and float(reward) > 0
                if t is None:
                    t = index[nxt] = len(keys)
                    keys.append(nxt)
                    success.append(won)
                    ended.append(bool(terminated))
                    if len(keys) > max_states:
                        raise ValueError(
                            f"from_minigrid({label}): more than max_states={max_states:,} "
                            "reachable states; raise max_states if the memory allows, or "
                            "use a smaller task"
                        )
                elif ended[t] != bool(terminated) or success[t] != won:
                    raise ValueError(
                        f"from_minigrid({label}): state {nxt} is entered both with and without "
                        "the episode ending; a world ends episodes per state entered"
                    )
                row.append(t)
            successors.append(row)
            s += 1
    finally:
        if saved_obs is None:
            del raw.gen_obs
        else:  # pragma: no cover - an instance attribute of the env's own
            raw.gen_obs = saved_obs
        raw._np_random = saved_random
    if not any(success):
        raise ValueError(
            f"from_minigrid({label}): no reachable state succeeds with the actions "
            f"{', '.join(MINIGRID_ACTION_NAMES)} (a task that ends by 'done', or whose goal "
            "the mission names); use a task whose success is in the grid (MINIGRID_TASKS)"
        )
    return keys, np.asarray(successors, dtype=np.int64), np.asarray(success), np.asarray(ended)


def _table_world(keys, successors, success, ended, slip, gamma, label) -> MiniGridWorld:
    S, A = successors.shape
    check_memory(f"from_minigrid({label}): {S:,} states", S * A * A * 24, "use a smaller task")
    won = success[successors]  # [S, A]
    reward = np.where(won, GOAL_REWARD, STEP_REWARD)
    if slip == 0:
        succ = successors[:, :, None]
        cdf = np.ones((S, A, 1))
        rew = reward[:, :, None]
    else:
        # slot k < A − 1: the other action (a + 1 + k) mod A, each with slip / (A − 1); last slot:
        # the chosen action (MultiRooms' layout of a slip)
        order = (np.arange(A)[:, None] + 1 + np.arange(A)) % A  # [A, A]: last column = a
        succ = successors[:, order]
        rew = reward[:, order]
        steps = np.append(np.arange(1, A) * slip / (A - 1), 1.0)
        cdf = np.broadcast_to(steps, (S, A, A)).copy()
    table = DynamicsTable(
        torch.from_numpy(np.ascontiguousarray(succ)),
        torch.from_numpy(np.ascontiguousarray(cdf, dtype=np.float64)),
        torch.from_numpy(np.ascontiguousarray(rew, dtype=np.float64)),
    )
    start = torch.zeros(S, dtype=torch.float64)
    start[0] = 1.0
    world = MiniGridWorld.__new__(MiniGridWorld)
    TableWorld.__init__(
        world,
        table,
        start,
        torch.from_numpy(ended.copy()),
        gamma=gamma,
        action_names=MINIGRID_ACTION_NAMES,
        name=label,
    )
    return world
