"""Exact option models against Monte-Carlo rollouts and against the one-step model."""

from dataclasses import dataclass

import pytest
import torch

from himit_torch.exact.option_models import OptionModels, option_durations, option_models
from himit_torch.options.builders import doorway_options, primitive_options
from himit_torch.options.bundle import Options
from himit_torch.worlds.multirooms import MultiRooms

Z = 5.0  # tolerance in standard errors


@pytest.fixture
def generator() -> torch.Generator:
    return torch.Generator().manual_seed(2024)


@pytest.fixture
def world() -> MultiRooms:
    """8×8, 2×2 rooms; a large slip so options end in many states, a low γ so that discounting shows."""
    return MultiRooms(size=8, rooms=2, slip=0.3, gamma=0.9)


@dataclass
class Rollouts:
    start: torch.Tensor  # [B] start state
    end: torch.Tensor  # [B] termination state
    steps: torch.Tensor  # [B] primitive steps k
    ret: torch.Tensor  # [B] Σ_{j<k} γ^j r_{j+1}, float64


def rollout_option(
    world: MultiRooms,
    options: Options,
    o: int,
    starts: torch.Tensor,
    n: int,
    generator: torch.Generator,
    max_steps: int = 2000,
) -> Rollouts:
    """``n`` rollouts of option ``o`` from each of ``starts``, with the world's batched step.

    The option terminates on arriving in ``s'`` with probability β(s'), and always at the goal.
    """
    start = starts.repeat_interleave(n)
    pos, B = start.clone(), start.numel()
    active = torch.ones(B, dtype=torch.bool)
    steps = torch.zeros(B, dtype=torch.int64)
    ret = torch.zeros(B, dtype=torch.float64)
    discount = torch.ones(B, dtype=torch.float64)
    beta = options.termination[o].double()
    for _ in range(max_steps):
        if options.stochastic:
            actions = torch.multinomial(options.policy[o, pos], 1, generator=generator)[:, 0]
        else:
            actions = options.policy[o, pos]
        nxt, reward = world.step(pos, actions, generator=generator)
        ret += torch.where(active, discount * reward.double(), 0.0)
        discount = torch.where(active, discount * world.gamma, discount)
        steps += active.long()
        pos = torch.where(active, nxt, pos)
        stop = (torch.rand(B, generator=generator, dtype=torch.float64) < beta[nxt]) | (
            nxt == world.goal_state
        )
        active &= ~stop
        if not active.any():
            return Rollouts(start, pos, steps, ret)
    raise AssertionError("some rollouts did not terminate")


def model_rows(models: OptionModels, o: int) -> dict[int, int]:
    """``{start state: row}`` of option ``o``."""
    rows = (models.row_option == o).nonzero().flatten()
    return {int(models.row_state[r]): int(r) for r in rows}


def check_against_monte_carlo(
    world: MultiRooms,
    options: Options,
    o: int,
    starts: list[int],
    generator: torch.Generator,
    n: int = 20_000,
) -> None:
    models = option_models(world, options)
    durations = option_durations(world, options)
    rows, dense, dur_dense = (
        model_rows(models, o),
        models.transition.to_dense(),
        durations.transition.to_dense(),
    )
    mc = rollout_option(world, options, o, torch.tensor(starts), n, generator)
    gamma_k = torch.tensor(world.gamma, dtype=torch.float64) ** mc.steps
    for i, s in enumerate(starts):
        sel = slice(i * n, (i + 1) * n)
        row = rows[s]
        # Discounted reward r(s, o).
        ret = mc.ret[sel]
        assert abs(ret.mean() - models.reward[row]) <= Z * ret.std() / n**0.5 + 1e-12, s
        # Multi-time weights P^o[s, s'] = E[γ^k 1{end = s'}]; X ∈ [0, 1] so Var X ≤ E X.
        ends = mc.end[sel]
        weights = (
            torch.zeros(world.num_states, dtype=torch.float64).index_add_(0, ends, gamma_k[sel]) / n
        )
        exact = dense[row]
        tol = Z * (torch.maximum(exact, weights) / n).sqrt() + 1e-12
        assert ((weights - exact).abs() <= tol).all(), (s, (weights - exact).abs().max())
        assert weights.sum() > 0.2  # the test is not vacuous
        # Undiscounted: termination probabilities and the expected duration.
        freq = torch.bincount(ends, minlength=world.num_states).double() / n
        p = dur_dense[rows[s]]
        assert ((freq - p).abs() <= Z * (torch.maximum(p, freq) / n).sqrt() + 1e-12).all(), s
        assert p.sum().item() == pytest.approx(1.0, abs=1e-12)
        k = mc.steps[sel].double()
        assert abs(k.mean() - durations.reward[rows[s]]) <= Z * k.std() / n**0.5, s


def test_primitive_models_are_one_step(world):
    prim = primitive_options(world)
    models = option_models(world, prim)
    P, R = world.transition_model(sparse=False), world.reward_model()
    usable = prim.initiation[0].nonzero().flatten()
    assert models.num_rows == 4 * usable.numel() and models.num_options == 4
    dense_T = models.transition.to_dense()
    for row in range(models.num_rows):
        s, a = int(models.row_state[row]), int(models.row_option[row])
        torch.testing.assert_close(dense_T[row], world.gamma * P[a, s], rtol=0, atol=1e-14)
        assert models.reward[row] == pytest.approx(R[s, a].item(), abs=1e-14)
    P_o, r_o = models.dense()
    torch.testing.assert_close(P_o[:, usable], world.gamma * P[:, usable], rtol=0, atol=1e-14)
    assert (P_o[:, world.goal_state] == 0).all() and (r_o[:, world.goal_state] == 0).all()
    durations = option_durations(world, prim)
    assert torch.equal(durations.reward, torch.ones(models.num_rows, dtype=torch.float64))


def test_doorway_option_into_goal_room_matches_monte_carlo(world, generator):
    """Room (1,1) holds the goal: slips end the option there, at the target, or outside."""
    doors = doorway_options(world)
    o = doors.names.index("doorway room(1,1)->door(6, 4)")
    starts = [5 * 8 + 5, 7 * 8 + 5, 5 * 8 + 7, 4 * 8 + 6]  # (5,5), (7,5), (5,7), doorway (4,6)
    assert all(doors.initiation[o, s] for s in starts)
    check_against_monte_carlo(world, doors, o, starts, generator)


def test_doorway_option_far_from_goal_matches_monte_carlo(world, generator):
    doors = doorway_options(world)
    o = doors.names.index("doorway room(0,0)->door(2, 4)")
    check_against_monte_carlo(world, doors, o, [0, 3 * 8 + 3, 4 * 8 + 2], generator)


def test_stochastic_option_with_partial_termination_matches_monte_carlo(world, generator):
    """A random walk in room 0 that also stops with β = 0.1 at every step inside it."""
    room = torch.zeros(world.num_states, dtype=torch.bool)
    room[world.room_cells(0)] = True
    policy = torch.tensor([0.4, 0.1, 0.2, 0.3]).repeat(world.num_states, 1)
    beta = torch.where(room, 0.1, 1.0)
    walk = Options.from_policy(room, policy, termination=beta, name="walk")
    check_against_monte_carlo(world, walk, 0, [0, 2 * 8 + 3], generator)


def test_durations_without_slip_are_path_lengths():
    world = MultiRooms(size=8, rooms=2, slip=0.0)
    doors = doorway_options(world)
    durations = option_durations(world, doors)
    o = doors.names.index("doorway room(0,0)->door(2, 4)")
    rows = model_rows(durations, o)
    assert durations.reward[rows[0]] == pytest.approx(2 + 4)  # (0,0) → (2,4)
    assert durations.transition.to_dense()[rows[0], 2 * 8 + 4] == pytest.approx(1.0)
    models = option_models(world, doors)
    assert models.transition.to_dense()[rows[0], 2 * 8 + 4] == pytest.approx(0.99**6)
    # r = −0.01 · (1 + γ + … + γ⁵)
    assert models.reward[rows[0]] == pytest.approx(-0.01 * (1 - 0.99**6) / (1 - 0.99))


def test_q_values_and_dense(world):
    models = option_models(world, doorway_options(world))
    values = torch.linspace(-1, 1, world.num_states, dtype=torch.float64)
    expected = models.reward + models.transition.to_dense() @ values
    torch.testing.assert_close(models.q_values(values), expected)
    P_o, r_o = models.dense()
    torch.testing.assert_close(
        P_o[models.row_option, models.row_state], models.transition.to_dense()
    )
    torch.testing.assert_close(r_o[models.row_option, models.row_state], models.reward)


def test_never_terminating_option_is_rejected():
    world = MultiRooms(size=6, rooms=2, slip=0.0)
    # Always push north from the top row of room 0: never leaves, β = 0 everywhere.
    init = torch.zeros(36, dtype=torch.bool)
    init[0] = True
    stuck = Options.from_policy(
        init, torch.zeros(36, dtype=torch.int64), termination=torch.zeros(36)
    )
    with pytest.raises(ValueError, match="may never terminate"):
        option_durations(world, stuck)
    models = option_models(world, stuck)  # discounted, it is fine: r = −0.01 / (1 − γ)
    assert models.reward[0] == pytest.approx(-0.01 / (1 - 0.99))
    assert models.transition.to_dense().abs().sum() == 0


def test_options_over_wrong_state_count():
    with pytest.raises(ValueError, match="options are over 36 states"):
        option_models(MultiRooms(size=8, rooms=2), primitive_options(MultiRooms(size=6, rooms=2)))


@pytest.mark.parametrize("dense_limit, batch", [(16, 8), (1, 1)])
def test_many_small_chains_solved_apart_equal_one_solve(monkeypatch, dense_limit, batch):
    """An option whose continuing states fall apart into many chains that never meet (the puzzle
    box's "do step j on the skewer at hand": one short chain per skewer and level) is solved
    chain group by chain group — dense groups of a few chains, or each chain alone by a sparse
    LU — and must give the models of one solve over all of them (the slow path)."""
    import himit_torch.exact.option_models as om
    from himit_torch.options.puzzle_box import step_options
    from himit_torch.worlds.puzzle_box import PuzzleBox

    box = PuzzleBox(3, slip=0.2)
    options = step_options(box)  # 300 continuing states per option: one dense solve by default
    reference = option_models(box, options)
    monkeypatch.setattr(om, "_DENSE_LIMIT", dense_limit)
    monkeypatch.setattr(om, "_CHAIN_BATCH", batch)
    assert len(om._chains(*_chain_edges(box, options))) > 1
    apart = option_models(box, options)
    assert torch.equal(apart.row_state, reference.row_state)
    assert torch.equal(apart.row_option, reference.row_option)
    torch.testing.assert_close(apart.reward, reference.reward, rtol=0, atol=1e-12)
    torch.testing.assert_close(
        apart.transition.to_dense(), reference.transition.to_dense(), rtol=0, atol=1e-12
    )


def _chain_edges(box, options):
    """Edges between the continuing states of the first option (C-local indices), and their
    number."""
    import numpy as np

    cont = (options.initiation[0] & (options.termination[0] < 1)).nonzero()[:, 0].numpy()
    local = {int(s): i for i, s in enumerate(cont)}
    succ = box.dynamics_table().successors.numpy()
    pol = options.policy[0].numpy()
    edges = [(local[s], local[int(t)]) for s in cont for t in succ[s, pol[s]] if int(t) in local]
    a = np.array(edges, dtype=np.int64)
    return a[:, 0], a[:, 1], cont.size
