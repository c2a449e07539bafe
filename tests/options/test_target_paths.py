"""The compiled target search against the obvious one: Dijkstra over Python dicts and a heap of
tuples, then each cell's cheapest move with the tuple order of its tie-breaks."""

import heapq

import numpy as np
import pytest

from himit_torch.options.builders import _room_perimeter, doorway_options, target_policy
from himit_torch.worlds.multirooms import ACTION_DELTAS, MultiRooms


def _obvious(world, region, target, penalized, penalty):
    nxt, size = world._next.tolist(), world.size
    allowed = set(region) | {target}
    cost = {c: 1.0 + (penalty if c in penalized else 0.0) for c in allowed}
    dist = {target: 0.0}
    queue = [(0.0, target)]
    while queue:
        d, u = heapq.heappop(queue)
        if d > dist[u]:
            continue
        for v in nxt[u]:
            if v != u and v in allowed and v != target and d + cost[u] < dist.get(v, np.inf):
                dist[v] = d + cost[u]
                heapq.heappush(queue, (d + cost[u], v))
    tr, tc = divmod(target, size)
    policy = {}
    for s in region:
        r, c = divmod(s, size)
        keys = [
            (cost[v] + dist[v], -(abs(tr - r) if ACTION_DELTAS[a][0] else abs(tc - c)), a)
            for a, v in enumerate(nxt[s])
            if v != s and v in dist
        ]
        if keys:
            policy[s] = min(keys)[2]
    return policy


@pytest.mark.parametrize("penalty", [10.0, 2.5])
def test_random_regions_targets_and_penalties_give_the_obvious_policy(penalty):
    """Regions with holes (cells cut off from the target get no entry), targets inside and
    outside them, penalized cells including the target, on a world with walls and doorways."""
    world = MultiRooms(size=15, rooms=3, slip=0.0)
    rng = np.random.default_rng(5)
    open_cells = [s for s in range(world.num_states) if not world.wall_mask[s]]
    checked = 0
    for _ in range(150):
        # the open cells near a random centre, a fifth of them holes; the target among them
        # or anywhere
        center = divmod(int(rng.choice(open_cells)), world.size)
        reach = int(rng.integers(2, 9))
        near = [
            s
            for s in open_cells
            if abs(s // world.size - center[0]) + abs(s % world.size - center[1]) <= reach
        ]
        region = [s for s in near if rng.random() > 0.2]
        target = int(rng.choice(near if rng.random() < 0.8 else open_cells))
        penalized = frozenset(rng.choice(open_cells, size=30, replace=False).tolist())
        expected = _obvious(world, region, target, penalized, penalty)
        got = target_policy(world, region, target, penalized, penalty)
        assert list(got.items()) == list(expected.items())  # same entries, in region's order
        checked += len(expected)
    assert checked > 1000  # the regions were not all cut off from their targets


@pytest.mark.parametrize("style", ["direct", "walls"])
def test_every_doorway_option_is_the_obvious_policy_on_its_room(style):
    """Each doorway option, both styles (the mentor's keeps off the room's middle), is the
    obvious search's policy over its room and doorways."""
    world = MultiRooms(size=16, rooms=2, slip=0.1)
    options = doorway_options(world, style=style)
    checked = 0
    for room in range(world.num_rooms):
        cells, doors = world.room_cells(room), world.room_doorways(room)
        middle = set(cells) - _room_perimeter(world, cells) if style == "walls" else set()
        for target in doors:
            rr, rc = divmod(room, world.rooms)
            o = options.names.index(f"doorway room({rr},{rc})->door{world.coords(target)}")
            region = sorted((set(cells) | set(doors)) - {target, world.goal_state})
            expected = _obvious(world, region, target, frozenset(middle - {target}), 10.0)
            starts = options.initiation[o].nonzero().flatten().tolist()
            assert dict(zip(starts, options.policy[o, starts].tolist())) == expected
            checked += 1
    assert checked == options.num_options
