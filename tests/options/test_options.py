"""Options: the builders on tiny worlds, validation, and the bundle operations."""

import re

import pytest
import torch

from himit_torch.options.builders import (
    corner_options,
    doorway_options,
    learner_options,
    mentor_options,
    primitive_options,
)
from himit_torch.options.bundle import Options, action_dtype
from himit_torch.worlds.multirooms import MultiRooms


@pytest.fixture
def world6() -> MultiRooms:
    return MultiRooms(size=6, rooms=2, slip=0.0)


@pytest.fixture
def world16() -> MultiRooms:
    """Rooms of 8×8 and 7×7 free cells: room enough for wall-following to differ from direct."""
    return MultiRooms(size=16, rooms=2, slip=0.0)


def target_of(world: MultiRooms, name: str) -> int:
    """The target cell a builder writes at the end of an option's name, ``...(r, c)``."""
    r, c = map(int, re.search(r"\((\d+), (\d+)\)$", name).groups())
    return r * world.size + c


def follow(world: MultiRooms, options: Options, o: int, s: int, max_steps: int = 1000) -> list[int]:
    """Cells visited by option ``o`` from ``s`` without slips, until β = 1 or the goal."""
    table = world.next_state_table
    path = [s]
    for _ in range(max_steps):
        s = int(table[s, options.policy[o, s]])
        path.append(s)
        if options.termination[o, s] == 1 or s == world.goal_state:
            return path
    raise AssertionError(f"option {options.names[o]} did not terminate from {path[0]}")


def perimeter(world: MultiRooms) -> torch.Tensor:
    """``[S]`` bool: free cells with a wall or the grid's edge among their 8 neighbours."""
    wall = torch.nn.functional.pad(
        world.wall_mask.view(world.size, world.size).float(), (1, 1, 1, 1), value=1.0
    )
    near_wall = torch.nn.functional.max_pool2d(wall[None, None], 3, stride=1)[0, 0] > 0
    return near_wall.flatten() & world.free_mask


# ------------------------------------------------------------------------------ builders
def test_primitive_options(world6):
    prim = primitive_options(world6)
    assert len(prim) == 4 and prim.kinds == ("primitive",) * 4
    assert prim.is_primitive.all()
    usable = world6.free_mask & ~world6.terminal_mask
    assert torch.equal(prim.initiation, usable[None].expand(4, -1))
    assert (prim.termination == 1).all()
    assert torch.equal(prim.policy, torch.arange(4)[:, None].expand(4, 36))


@pytest.mark.parametrize("style", ["direct", "walls"])
def test_doorway_and_corner_counts(world6, style):
    doors = doorway_options(world6, style)
    assert len(doors) == sum(len(world6.room_doorways(r)) for r in range(world6.num_rooms)) == 8
    assert set(doors.kinds) == {"doorway"}
    corners = corner_options(world6, style)
    assert len(corners) == 8 * world6.num_rooms
    assert len(learner_options(world6)) == 4 + 8
    assert len(learner_options(world6, corners=True)) == 4 + 8 + 32
    assert len(learner_options(world6, doorways=False)) == 4
    assert len(mentor_options(world6, corners=True)) == 4 + 8 + 32


def test_doorway_targets_are_the_rooms_doorways(world6):
    doors = doorway_options(world6)
    targets = [target_of(world6, n) for n in doors.names]
    expected = [d for r in range(world6.num_rooms) for d in world6.room_doorways(r)]
    assert targets == expected


@pytest.mark.parametrize("build", [doorway_options, corner_options])
def test_initiation_and_termination(world6, build):
    opts = build(world6)
    for o, name in enumerate(opts.names):
        target = target_of(world6, name)
        init = opts.initiation[o]
        assert not init[target] and not init[world6.goal_state]
        assert not (init & world6.wall_mask).any()
        # β = 1 outside the initiation set, 0 inside: the option runs until it leaves the set.
        torch.testing.assert_close(opts.termination[o], (~init).float())


def test_room_options_start_in_their_room_and_other_doorways(world6):
    doors = doorway_options(world6)
    room0 = set(world6.room_cells(0))
    # Room (0,0) to (1,3): usable in room 0 and at its other doorway (3,1).
    o = doors.names.index("doorway room(0,0)->door(1, 3)")
    assert set(doors.initiation[o].nonzero().flatten().tolist()) == room0 | {19}


@pytest.mark.parametrize("build", [doorway_options, corner_options])
def test_direct_policy_reaches_target_by_shortest_path(world16, build):
    opts = build(world16, "direct")
    for o, name in enumerate(opts.names):
        target = target_of(world16, name)
        tr, tc = world16.coords(target)
        for s in opts.initiation[o].nonzero().flatten().tolist():
            path = follow(world16, opts, o, s)
            assert path[-1] == target, (name, world16.coords(s))
            r, c = world16.coords(s)
            # Rooms are rectangles, so the shortest path is the Manhattan distance.
            assert len(path) - 1 == abs(r - tr) + abs(c - tc), (name, world16.coords(s))


def test_walls_style_keeps_to_the_perimeter(world16):
    edge = perimeter(world16)
    off_wall = {}
    for style in ("direct", "walls"):
        opts = doorway_options(world16, style)
        count = 0
        for o, name in enumerate(opts.names):
            target = target_of(world16, name)
            for d in world16.doorways.tolist():  # start at the room's other doorways
                if not opts.initiation[o, d]:
                    continue
                path = follow(world16, opts, o, d)
                assert path[-1] == target
                count += sum(not edge[s] for s in path)
        off_wall[style] = count
    # Doorway to doorway, the walls style never leaves the perimeter; direct cuts across.
    assert off_wall["walls"] == 0
    assert off_wall["direct"] > 10


def test_bad_style(world6):
    with pytest.raises(ValueError, match="style='diagonal'"):
        doorway_options(world6, "diagonal")


# ------------------------------------------------------------------------------ validation
def make_tensors(O: int = 2, S: int = 5, A: int = 4):
    init = torch.ones(O, S, dtype=torch.bool)
    beta = torch.zeros(O, S)
    policy = torch.zeros(O, S, dtype=torch.int64)
    return init, beta, policy, tuple(f"o{i}" for i in range(O)), ("custom",) * O


@pytest.mark.parametrize(
    "change, match",
    [
        (lambda t: t.__setitem__(0, t[0].int()), r"initiation must be a \[O, S\] bool"),
        (lambda t: t.__setitem__(0, t[0][0]), r"initiation must be a \[O, S\] bool"),
        (lambda t: t.__setitem__(0, torch.ones(0, 5, dtype=torch.bool)), "at least one option"),
        (lambda t: t[0][1].fill_(False), "empty initiation set"),
        (lambda t: t.__setitem__(1, torch.zeros(2, 4)), r"termination must be a \[O, S\]"),
        (lambda t: t.__setitem__(1, torch.zeros(2, 5, dtype=torch.int64)), "termination must be"),
        (lambda t: t[1].__setitem__((0, 0), 1.5), r"probabilities in \[0, 1\]"),
        (lambda t: t[1].__setitem__((0, 0), -0.1), r"probabilities in \[0, 1\]"),
        (lambda t: t[1].__setitem__((0, 0), float("nan")), r"probabilities in \[0, 1\]"),
        (lambda t: t[1].__setitem__((1, 4), float("inf")), r"probabilities in \[0, 1\]"),
        (lambda t: t[1].__setitem__((1, 2), -float("inf")), r"probabilities in \[0, 1\]"),
        (lambda t: t.__setitem__(2, t[2].to(torch.uint8)), "integer actions"),
        (lambda t: t.__setitem__(2, t[2].bool()), "integer actions"),
        (lambda t: t.__setitem__(2, torch.zeros(2, 4, dtype=torch.int64)), "integer actions"),
        (lambda t: t[2].__setitem__((1, 1), -1), "negative action"),
        (lambda t: t.__setitem__(2, torch.zeros(2, dtype=torch.int64)), "2 or 3 dimensions"),
        (lambda t: t.__setitem__(2, torch.full((2, 5, 4), 0.3)), "sum to 1"),
        (
            lambda t: t.__setitem__(2, torch.tensor([1.5, -0.5, 0, 0]).repeat(2, 5, 1)),
            "≥ 0 and sum to 1",
        ),
        (
            lambda t: t.__setitem__(2, torch.ones(2, 5, 4, dtype=torch.int64)),
            "probabilities must be",
        ),
        (lambda t: t.__setitem__(3, ("only one",)), "one name and one kind"),
        (lambda t: t.__setitem__(4, ("custom", "bogus")), "unknown option kinds"),
    ],
)
def test_options_validation(change, match):
    tensors = list(make_tensors())
    change(tensors)
    with pytest.raises(ValueError, match=match):
        Options(*tensors)


def test_stochastic_policy_only_checked_inside_initiation():
    init, beta, _, names, kinds = make_tensors()
    init[:, 0] = False
    policy = torch.full((2, 5, 4), 0.25)
    policy[:, 0] = 0.0  # outside I: anything non-negative goes
    opts = Options(init, beta, policy, names, kinds)
    assert opts.stochastic and opts.num_options == 2 and opts.num_states == 5


# ------------------------------------------------------------------------------ operations
def test_concat_select_and_add(world6):
    prim, doors = primitive_options(world6), doorway_options(world6)
    both = Options.concat(prim, doors)
    assert len(both) == 12 and both.names == prim.names + doors.names
    assert both.kinds == ("primitive",) * 4 + ("doorway",) * 8
    assert torch.equal(both.policy[4:], doors.policy)
    assert torch.equal((prim + doors).initiation, both.initiation)
    picked = both.select([5, 0])
    assert picked.names == (both.names[5], both.names[0])
    assert torch.equal(picked.termination, both.termination[[5, 0]])
    assert torch.equal(both.select(torch.tensor([2])).policy, prim.policy[[2]])
    assert both.is_primitive.tolist() == [True] * 4 + [False] * 8
    with pytest.raises(ValueError, match="at least one bundle"):
        Options.concat()
    other = primitive_options(MultiRooms(size=8, rooms=2))
    with pytest.raises(ValueError, match="different state counts"):
        Options.concat(prim, other)


def test_from_policy_and_concat_with_stochastic(world6):
    room = torch.zeros(36, dtype=torch.bool)
    room[world6.room_cells(0)] = True
    uniform = torch.full((36, 4), 0.25)
    walk = Options.from_policy(room, uniform, name="random walk")
    assert walk.names == ("random walk",) and walk.kinds == ("custom",)
    torch.testing.assert_close(walk.termination[0], (~room).float())
    assert walk.stochastic
    joined = primitive_options(world6) + walk
    assert joined.stochastic and joined.policy.shape == (5, 36, 4)
    # Deterministic policies become one-hot rows.
    assert torch.equal(joined.policy[2, 0], torch.tensor([0.0, 0.0, 1.0, 0.0]))
    torch.testing.assert_close(joined.policy[4], uniform)
    onehot = primitive_options(world6).action_probabilities(4)
    assert onehot.shape == (4, 36, 4) and (onehot.sum(-1) == 1).all()
    custom_beta = Options.from_policy(
        room, torch.zeros(36, dtype=torch.int64), termination=torch.full((36,), 0.5)
    )
    assert (custom_beta.termination == 0.5).all() and not custom_beta.stochastic


# ------------------------------------------------------------------- any world: list and kind
class Corridor:
    """Five states in a row, not a MultiRooms: action 1 right, 0 left; state 4 ends."""

    num_states, num_actions, start_state, gamma = 5, 2, 0, 0.9
    terminal_mask = torch.tensor([False, False, False, False, True])

    def step(self, positions, actions, uniforms):
        nxt = (positions + torch.where(actions == 1, 1, -1)).clamp(0, 4)
        return nxt, torch.where(nxt == 4, 1.0, -0.1).double()


def test_concat_takes_a_list_as_well(world6):
    prim, doors = primitive_options(world6), doorway_options(world6)
    listed, spread = Options.concat([prim, doors]), Options.concat(prim, doors)
    assert listed.names == spread.names and torch.equal(listed.policy, spread.policy)
    assert Options.concat((prim,)).names == prim.names
    with pytest.raises(ValueError, match=r"joins Options bundles, got \['list'\]"):
        Options.concat(prim, [doors])
    with pytest.raises(ValueError, match="at least one bundle"):
        Options.concat([])


def test_from_policy_kind():
    usable = torch.tensor([True, True, True, True, False])
    left = Options.from_policy(
        usable, torch.zeros(5, dtype=torch.int64), name="left", kind="primitive"
    )
    assert left.kinds == ("primitive",) and bool((left.termination == 1).all())  # β = 1 by default
    assert Options.from_policy(usable, torch.ones(5, dtype=torch.int64)).kinds == ("custom",)
    with pytest.raises(ValueError, match=r"kind='macro' is unknown; use one of \('primitive'"):
        Options.from_policy(usable, torch.zeros(5, dtype=torch.int64), kind="macro")
    with pytest.raises(ValueError, match="termination must be 1 in every state"):
        Options.from_policy(
            usable,
            torch.zeros(5, dtype=torch.int64),
            termination=(~usable).float(),
            kind="primitive",
        )
    with pytest.raises(ValueError, match="one fixed action"):
        Options.from_policy(usable, torch.tensor([0, 1, 0, 1, 0]), kind="primitive")
    with pytest.raises(ValueError, match="one fixed action"):
        Options.from_policy(usable, torch.full((5, 2), 0.5), kind="primitive")


def test_own_primitives_run_the_primitives_agent_on_any_world():
    """Primitives built with from_policy(kind="primitive") are what the ``primitives`` agent
    uses (with kind "custom" it would have no usable option)."""
    from himit_torch.learner.config import LearnerConfig
    from himit_torch.learner.learner import Learner

    world = Corridor()
    usable = ~world.terminal_mask
    own = Options.concat(
        [
            Options.from_policy(usable, torch.full((5,), a), name=n, kind="primitive")
            for a, n in enumerate(("left", "right"))
        ]
    )
    builtin = primitive_options(world)
    assert builtin.names == ("primitive 0", "primitive 1") and builtin.kinds == own.kinds
    assert torch.equal(builtin.initiation, own.initiation) and torch.equal(
        builtin.policy, own.policy
    )
    learner = Learner(world, own, ["primitives"], [0], config=LearnerConfig(window=200))
    learner.run(600)
    assert int(learner.views.goals[0]) > 20
    custom = Options.from_policy(usable, torch.ones(5, dtype=torch.int64))
    with pytest.raises(ValueError, match="no usable option"):
        Learner(world, custom, ["primitives"], [0])


@pytest.mark.parametrize("corners", [False, True])
def test_sets_written_once_equal_the_joined_parts(world6, corners):
    """learner_options/mentor_options write their tables once (memory); the result must be what
    joining the separately built parts gives, in the smallest action dtype."""
    for style, build in (
        ("direct", lambda: learner_options(world6, corners=corners)),
        ("walls", lambda: mentor_options(world6, corners=corners)),
    ):
        parts = [primitive_options(world6), doorway_options(world6, style)]
        if corners:
            parts.append(corner_options(world6, style))
        joined, built = Options.concat(parts), build()
        assert built.policy.dtype == torch.int8 and joined.policy.dtype == torch.int8
        assert built.names == joined.names and built.kinds == joined.kinds
        assert torch.equal(built.initiation, joined.initiation)
        assert torch.equal(built.termination, joined.termination)
        assert torch.equal(built.policy, joined.policy)
        # β: 1 outside each room option's initiation set, 0 inside; its policy 0 outside
        room = torch.tensor([k != "primitive" for k in built.kinds])
        assert torch.equal(built.termination[room], (~built.initiation[room]).float())
        assert (built.policy[room][~built.initiation[room]] == 0).all()


def test_action_dtype():
    assert action_dtype(4) == torch.int8 and action_dtype(128) == torch.int8
    assert action_dtype(129) == torch.int16 and action_dtype(40_000) == torch.int32
