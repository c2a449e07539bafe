"""The layout stresses (issue 26, part 2): doorways closed into a maze of rooms, and a goal no
option is aimed at (the paper's Section III names both)."""

import numpy as np
import pytest
import torch
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from himit_torch.options.builders import learner_options, mentor_options
from himit_torch.worlds.multirooms import (
    MAZE_SEED,
    MultiRooms,
    maze_doorways,
    primitives_only_goal,
)


def _room_graph_of_open_doorways(world: MultiRooms):
    pairs = np.array(list(world.doorway_rooms.values())).reshape(-1, 2)
    n = world.num_rooms
    return coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))


@pytest.mark.parametrize("size, rooms", [(16, 4), (24, 3), (40, 10), (80, 10)])
def test_the_maze_joins_the_rooms_in_a_spanning_tree(size, rooms):
    closed = maze_doorways(size, rooms)
    world = MultiRooms(size=size, rooms=rooms, closed_doorways=closed)
    assert len(closed) == (rooms - 1) ** 2
    assert len(world.doorway_rooms) == rooms * rooms - 1  # a tree's edge count ...
    components, _ = connected_components(_room_graph_of_open_doorways(world), directed=False)
    assert components == 1  # ... and connected: a spanning tree
    # every free cell is reachable from the start (the world's own check covers the goal)
    nxt = world.next_state_table.numpy()
    seen = np.zeros(world.num_states, dtype=bool)
    seen[world.start_state] = True
    frontier = [world.start_state]
    while frontier:
        reached = np.unique(nxt[frontier].ravel())
        frontier = reached[~seen[reached]].tolist()
        seen[reached] = True
    assert seen[world.free_mask.numpy()].all()


def test_the_maze_depends_on_its_seed_only():
    assert maze_doorways(40, 10) == maze_doorways(40, 10) == maze_doorways(40, 10, MAZE_SEED)
    assert maze_doorways(40, 10, seed=1) != maze_doorways(40, 10)
    assert maze_doorways(8, 1) == ()  # one room: nothing to close
    with pytest.raises(ValueError, match="multiple of rooms"):
        maze_doorways(10, 4)


def _options_stepping_into(world: MultiRooms, options) -> list[str]:
    """Names of the extended options whose policy steps into the goal from a cell of their
    initiation set (without slipping)."""
    nxt = world.next_state_table
    out = []
    for o in torch.nonzero(~options.is_primitive).flatten().tolist():
        cells = torch.nonzero(options.initiation[o]).flatten()
        targets = nxt[cells, options.policy[o, cells].long()]
        if (targets == world.goal_state).any():
            out.append(options.names[o])
    return out


@pytest.mark.parametrize("size, rooms", [(16, 4), (20, 4), (40, 5), (48, 4)])
def test_no_doorway_or_corner_option_is_aimed_at_the_primitives_only_goal(size, rooms):
    goal = primitives_only_goal(size, rooms)
    world = MultiRooms(size=size, rooms=rooms, goal=goal)
    row, col = world.coords(goal)
    room_size = size // rooms
    assert row == size - 1 and col > size - room_size + 1 and col < size - 1
    assert not world.doorway_mask[goal]
    for options in (learner_options(world, corners=True), mentor_options(world, corners=True)):
        assert _options_stepping_into(world, options) == []


def test_at_the_default_goal_a_corner_option_is_aimed_at_it():
    """The contrast: the bottom-right corner is a corner option's target (experiment 1's
    optimal solution ends with it)."""
    world = MultiRooms(size=16, rooms=4)
    assert _options_stepping_into(world, learner_options(world, corners=True))


def test_a_room_too_narrow_for_a_primitives_only_goal_is_refused():
    with pytest.raises(ValueError, match="needs ≥ 3"):
        primitives_only_goal(9, 3)  # rooms of 3 cells, wall included: 2 free columns
    assert primitives_only_goal(4, 1) == 3 * 4 + 1  # one 4×4 room: (3, 1)
