"""MultiRooms: layout, true model, slip dynamics and argument checks on tiny worlds."""

import math

import numpy as np
import pytest
import torch

from himit_torch.worlds.multirooms import ACTION_DELTAS, MultiRooms

N, S, W, E = range(4)


@pytest.fixture
def world6() -> MultiRooms:
    """6×6, 2×2 rooms: wall row/col 3, doorways mid-segment (hand-drawn in test_render_ansi)."""
    return MultiRooms(size=6, rooms=2)


def cell(r: int, c: int, size: int = 6) -> int:
    return r * size + c


# ------------------------------------------------------------------------------------- layout
def test_render_ansi_matches_hand_drawn_picture(world6):
    # Walls at row 3 and col 3. Segment 0 spans cells 0..2 (middle 1), segment 1 spans 4..5
    # ((4 + 6) // 2 = 5), so the doorways are (3,1), (3,5), (1,3), (5,3).
    expected = "S..#..\n...+..\n...#..\n#+###+\n...#..\n...+.G\n"
    assert world6.render_ansi() == expected
    assert world6.render_ansi([cell(4, 4)]).splitlines()[4] == "...#A."


def test_render_ansi_8x8():
    world = MultiRooms(size=8, rooms=2, closed_doorways=[(2, 4)])
    expected = (
        "S...#...\n"
        "....#...\n"
        "....#...\n"  # (2, 4) closed
        "....#...\n"
        "##+###+#\n"
        "....#...\n"
        "....+...\n"
        "....#..G\n"
    )
    assert world.render_ansi() == expected


def test_walls_doorways_and_rooms(world6):
    wall = world6.wall_mask.view(6, 6)
    expected_wall = torch.zeros(6, 6, dtype=torch.bool)
    expected_wall[3, :] = True
    expected_wall[:, 3] = True
    for r, c in [(3, 1), (3, 5), (1, 3), (5, 3)]:
        expected_wall[r, c] = False
    assert torch.equal(wall, expected_wall)
    assert torch.equal(world6.free_mask, ~world6.wall_mask)
    assert world6.doorways.tolist() == [cell(1, 3), cell(3, 1), cell(3, 5), cell(5, 3)]
    assert world6.doorway_rooms == {
        cell(1, 3): (0, 1),
        cell(3, 1): (0, 2),
        cell(3, 5): (1, 3),
        cell(5, 3): (2, 3),
    }
    assert world6.doorway_mask.sum() == 4 and world6.doorway_mask[cell(1, 3)]
    expected_rooms = torch.tensor(
        [
            [0, 0, 0, -1, 1, 1],
            [0, 0, 0, -1, 1, 1],
            [0, 0, 0, -1, 1, 1],
            [-1, -1, -1, -1, -1, -1],
            [2, 2, 2, -1, 3, 3],
            [2, 2, 2, -1, 3, 3],
        ]
    )
    assert torch.equal(world6.room_of.view(6, 6), expected_rooms)
    assert [world6.room_doorways(r) for r in range(4)] == [
        [cell(1, 3), cell(3, 1)],
        [cell(1, 3), cell(3, 5)],
        [cell(3, 1), cell(5, 3)],
        [cell(3, 5), cell(5, 3)],
    ]
    assert world6.room_cells(3) == [cell(4, 4), cell(4, 5), cell(5, 4), cell(5, 5)]
    assert world6.num_rooms == 4
    assert (world6.start_state, world6.goal_state) == (0, 35)
    assert world6.terminal_mask.nonzero().flatten().tolist() == [35]


def test_ten_rooms_have_one_doorway_per_segment():
    world = MultiRooms(size=40, rooms=10)
    # 10 rows of rooms × 9 inner walls, horizontally and vertically.
    assert len(world.doorway_rooms) == 2 * 10 * 9
    corner, edge, inner = (world.room_doorways(r) for r in (0, 5, 55))
    assert (len(corner), len(edge), len(inner)) == (2, 3, 4)


def test_describe_round_trip():
    world = MultiRooms(size=8, rooms=2, slip=0.2, closed_doorways=[(2, 4)], start=(1, 1))
    again = MultiRooms.from_description(world.describe())
    assert again.describe() == world.describe()
    assert torch.equal(again.wall_mask, world.wall_mask)
    with pytest.raises(ValueError, match="not MultiRooms"):
        MultiRooms.from_description({"kind": "Other"})


# ------------------------------------------------------------------------------ true model
@pytest.mark.parametrize("slip", [0.0, 0.1, 0.5])
def test_transition_rows_sum_to_one_dense_equals_sparse(slip):
    world = MultiRooms(size=8, rooms=2, slip=slip, closed_doorways=[(2, 4)])
    sparse = world.transition_model()
    dense = world.transition_model(sparse=False)
    assert sparse.is_sparse and not dense.is_sparse
    assert dense.shape == (4, 64, 64) and dense.dtype == torch.float64
    assert torch.equal(sparse.to_dense(), dense)
    torch.testing.assert_close(
        dense.sum(-1), torch.ones(4, 64, dtype=torch.float64), rtol=0, atol=1e-12
    )
    assert (dense >= 0).all()


def test_transition_model_by_hand(world6):
    P = world6.transition_model(sparse=False)
    p, q = 0.9, 0.1 / 3
    # From (1,1) every direction is free.
    row = P[N, cell(1, 1)]
    assert row[cell(0, 1)] == pytest.approx(p)
    for target in (cell(2, 1), cell(1, 0), cell(1, 2)):
        assert row[target] == pytest.approx(q)
    # From (0,0) north and west hit the grid's edge: 0.9 + q (north) + q (west) stay.
    assert P[N, 0, 0] == pytest.approx(p + q)
    assert P[E, 0, 0] == pytest.approx(2 * q)
    # The goal and walls are absorbing.
    assert P[W, 35, 35] == 1.0 and P[S, cell(3, 0), cell(3, 0)] == 1.0


def test_reward_model_by_hand(world6):
    R = world6.reward_model()
    q = 0.1 / 3
    assert R.shape == (36, 4) and R.dtype == torch.float64
    # (5,4) east: 0.9 into the goal; slips N → (4,4), S → edge (stay), W → doorway (5,3).
    assert R[cell(5, 4), E] == pytest.approx(0.9 * 1.0 + 0.1 * -0.01)
    # (4,5) west: 0.9 to (4,4); slip S enters the goal, N the doorway (3,5), E stays.
    assert R[cell(4, 5), W] == pytest.approx(q * 1.0 + (1 - q) * -0.01)
    assert R[0, N] == pytest.approx(-0.01)
    assert R[cell(3, 0)].abs().max() == 0.0  # wall
    assert R[35].abs().max() == 0.0  # goal is absorbing with reward 0
    assert world6.state_reward[35] == 1.0 and world6.state_reward[0] == pytest.approx(-0.01)


# ------------------------------------------------------------------------------ dynamics
def test_slipped_actions_rule():
    world = MultiRooms(size=6, rooms=2, slip=0.3)
    actions = torch.tensor([N, N, N, N, E, E])
    # u < slip slips to (a + 1 + ⌊3u / slip⌋) mod 4; u ≥ slip keeps the action.
    uniforms = torch.tensor([0.05, 0.15, 0.25, 0.3, 0.29, 0.95])
    assert world.slipped_actions(actions, uniforms).tolist() == [S, W, E, N, (E + 3) % 4, E]


def test_slip_frequencies(generator):
    """Executed directions: 0.9 for the chosen one, 0.1/3 for each other (±5 binomial σ)."""
    world = MultiRooms(size=6, rooms=2, slip=0.1)
    n = 200_000
    centre = cell(1, 1)
    neighbours = torch.tensor([centre + dr * 6 + dc for dr, dc in ACTION_DELTAS])
    for action in range(4):
        nxt, reward = world.step(
            torch.full((n,), centre), torch.full((n,), action), generator=generator
        )
        executed = (nxt[:, None] == neighbours).int().argmax(1)
        assert (nxt[:, None] == neighbours).any(1).all()
        freq = torch.bincount(executed, minlength=4).double() / n
        expected = torch.full((4,), 0.1 / 3, dtype=torch.float64)
        expected[action] = 0.9
        sigma = (expected * (1 - expected) / n).sqrt()
        assert ((freq - expected).abs() <= 5 * sigma).all(), (action, freq)
        assert torch.allclose(reward, torch.tensor(-0.01, dtype=torch.float64))


def test_moves_into_walls_and_edges_stay_put():
    world = MultiRooms(size=6, rooms=2, slip=0.0)
    table = world.next_state_table
    assert table[0, N] == 0 and table[0, W] == 0  # grid edge
    assert table[cell(0, 2), E] == cell(0, 2)  # wall (0,3)
    assert table[cell(2, 0), S] == cell(2, 0)  # wall (3,0)
    assert table[cell(1, 2), E] == cell(1, 3)  # into the doorway
    assert table[cell(1, 3), E] == cell(1, 4)  # through it
    assert table[cell(1, 3), N] == cell(1, 3)  # doorway's side walls
    positions = torch.tensor([0, 0, cell(0, 2), cell(1, 2)])
    actions = torch.tensor([N, W, E, E])
    nxt, reward = world.step(positions, actions, torch.zeros(4))
    assert nxt.tolist() == [0, 0, cell(0, 2), cell(1, 3)]
    nxt, reward = world.step(torch.tensor([cell(5, 4)]), torch.tensor([E]), torch.zeros(1))
    assert nxt.item() == 35 and reward.item() == 1.0


def test_closed_doorway_is_a_wall():
    world = MultiRooms(size=6, rooms=2, slip=0.0, closed_doorways=[(1, 3), cell(3, 5)])
    assert world.closed_doorways == (cell(1, 3), cell(3, 5))
    assert world.wall_mask[cell(1, 3)] and not world.doorway_mask[cell(1, 3)]
    assert world.doorways.tolist() == [cell(3, 1), cell(5, 3)]
    assert world.next_state_table[cell(1, 2), E] == cell(1, 2)
    assert world.room_doorways(0) == [cell(3, 1)]
    assert world.render_ansi().splitlines()[1] == "...#.."


def test_same_seed_same_trajectory():
    world = MultiRooms(size=8, rooms=2, slip=0.3)

    def rollout(seed: int) -> list[int]:
        g = torch.Generator().manual_seed(seed)
        pos = torch.zeros(16, dtype=torch.int64)
        path = []
        for _ in range(50):
            actions = torch.randint(4, (16,), generator=g)
            pos, _ = world.step(pos, actions, generator=g)
            path.append(pos.clone())
        return torch.stack(path).tolist()

    assert rollout(7) == rollout(7)
    assert rollout(7) != rollout(8)


# --------------------------------------------------------------------------- bad arguments
@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(size=7, rooms=2), "not a multiple of rooms"),
        (dict(size=3, rooms=3), "too small"),
        (dict(size=0, rooms=1), "positive whole number"),
        (dict(size=-4, rooms=2), "positive whole number"),
        (dict(size=8, rooms=0), "positive whole number"),
        (dict(size=True, rooms=1), "positive whole number"),
        (dict(size="8", rooms=2), "positive whole number"),
        (dict(size=8.0, rooms=2), "positive whole number"),
        (dict(size=6, rooms=2, start=(3, 0)), "start .* is a wall cell"),
        (dict(size=6, rooms=2, goal=cell(0, 3)), "goal .* is a wall cell"),
        (dict(size=6, rooms=2, start=(6, 0)), "outside the 6×6 grid"),
        (dict(size=6, rooms=2, goal=36), r"not a cell index in \[0, 36\)"),
        (dict(size=6, rooms=2, start="top-left"), "cell index or a \\(row, col\\) pair"),
        (dict(size=6, rooms=2, start=(2, 2), goal=cell(2, 2)), "same cell"),
        (dict(size=6, rooms=2, closed_doorways=[(1, 3), (3, 1)]), "cannot be reached"),
        (dict(size=6, rooms=2, closed_doorways=[(0, 0)]), "are not doorways"),
        (dict(size=6, rooms=2, closed_doorways=[(3, 3)]), "are not doorways"),
        (dict(size=6, rooms=2, slip=1.0), r"slip=1.0 must lie in \[0, 1\)"),
        (dict(size=6, rooms=2, slip=-0.1), r"must lie in \[0, 1\)"),
        (dict(size=6, rooms=2, gamma=0.0), r"gamma=0.0 must lie in \(0, 1\]"),
        (dict(size=6, rooms=2, gamma=1.5), r"must lie in \(0, 1\]"),
        (dict(size=6, rooms=2, step_reward=math.nan), "step_reward=nan must be a finite number"),
        (dict(size=6, rooms=2, goal_reward=math.inf), "goal_reward=inf must be a finite number"),
    ],
)
def test_bad_configurations_raise(kwargs, match):
    with pytest.raises(ValueError, match=match):
        MultiRooms(**kwargs)


def test_closing_one_path_keeps_goal_reachable():
    world = MultiRooms(size=6, rooms=2, closed_doorways=[(1, 3)])  # still via (3,1)
    assert world.goal_state == 35
    assert np.isfinite(world.reward_model().numpy()).all()
