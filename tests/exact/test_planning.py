"""Exact planners: hand-solved MDPs, fast paths against slow ones, expected trip lengths."""

import math
import warnings

import numpy as np
import pytest
import scipy.sparse as sp
import torch

from himit_torch.exact.option_models import (
    OptionModels,
    csr_from_scipy,
    option_durations,
    option_models,
)
from himit_torch.exact.planning import (
    expected_steps,
    greedy_option_policy,
    optimal_baseline,
    smdp_value_iteration,
    value_iteration,
)
from himit_torch.options.builders import learner_options, primitive_options
from himit_torch.worlds.multirooms import MultiRooms


@pytest.fixture
def small_world() -> MultiRooms:
    return MultiRooms(size=8, rooms=2, slip=0.1)


# --------------------------------------------------------------------- value iteration by hand
def three_state_mdp() -> tuple[torch.Tensor, torch.Tensor]:
    """States 0, 1 and an absorbing 2 (reward 0); actions 0 and 1.

    s0: a0 → s1, reward 0;               a1 → s2, reward 1.
    s1: a0 → s0 or s2 (½ each), reward 2; a1 → s1, reward 0.
    """
    P = torch.zeros(2, 3, 3, dtype=torch.float64)
    P[0, 0, 1] = 1.0
    P[1, 0, 2] = 1.0
    P[0, 1, 0] = P[0, 1, 2] = 0.5
    P[1, 1, 1] = 1.0
    P[:, 2, 2] = 1.0
    R = torch.tensor([[0.0, 1.0], [2.0, 0.0], [0.0, 0.0]], dtype=torch.float64)
    return P, R


def test_value_iteration_hand_solved():
    # With γ = 0.9 and the policy (a0, a0):
    #   V1 = 2 + γ·½·V0,  V0 = γ·V1  ⇒  V1 = 2 + ½γ²·V1  ⇒  V1 = 2 / (1 − 0.405) = 2 / 0.595,
    #   V0 = 0.9 · V1 = 1.8 / 0.595 ≈ 3.0252, V2 = 0.
    # It is optimal: at s0, a1 gives 1 < γ·V1 ≈ 3.025; at s1, a1 gives γ·V1 ≈ 3.025 < V1 ≈ 3.361.
    P, R = three_state_mdp()
    result = value_iteration(P, R, gamma=0.9, tol=1e-13)
    V1 = 2 / 0.595
    expected = torch.tensor([0.9 * V1, V1, 0.0], dtype=torch.float64)
    torch.testing.assert_close(result.values, expected, rtol=0, atol=1e-10)
    assert result.policy.tolist() == [0, 0, 0]
    q = torch.tensor([[0.9 * V1, 1.0], [V1, 0.9 * V1], [0.0, 0.0]], dtype=torch.float64)
    torch.testing.assert_close(result.q, q, rtol=0, atol=1e-10)
    assert 10 < result.iterations < 1000


def test_value_iteration_short_horizon_changes_the_choice():
    # With γ = 0.5: following (a0, a0) gives V1 = 2 / (1 − ⅛) = 16/7, V0 = 8/7 > 1, still a0 at s0;
    # with γ = 0.3: V1 = 2 / (1 − 0.045), γ·V1 ≈ 0.628 < 1, so s0 takes a1: V0 = 1 and
    # V1 = 2 + γ·½·V0 = 2.15 (a0 at s0 would now give γ·V1 = 0.645 < 1).
    P, R = three_state_mdp()
    torch.testing.assert_close(
        value_iteration(P, R, gamma=0.5, tol=1e-13).values,
        torch.tensor([8 / 7, 16 / 7, 0.0], dtype=torch.float64),
    )
    result = value_iteration(P, R, gamma=0.3, tol=1e-13)
    torch.testing.assert_close(result.values, torch.tensor([1.0, 2.15, 0.0], dtype=torch.float64))
    assert result.policy.tolist() == [1, 0, 0]


def test_dense_and_sparse_agree(small_world):
    R = small_world.reward_model()
    sparse = value_iteration(small_world.transition_model(sparse=True), R, small_world.gamma)
    dense = value_iteration(small_world.transition_model(sparse=False), R, small_world.gamma)
    torch.testing.assert_close(sparse.values, dense.values, rtol=0, atol=1e-12)
    assert torch.equal(sparse.policy, dense.policy)
    assert sparse.values[small_world.goal_state] == 0.0
    assert (sparse.values[small_world.free_mask] < 1).all()


def test_smdp_with_primitive_options_equals_value_iteration(small_world):
    vi = value_iteration(
        small_world.transition_model(), small_world.reward_model(), small_world.gamma, tol=1e-12
    )
    models = option_models(small_world, primitive_options(small_world))
    smdp = smdp_value_iteration(models, tol=1e-12)
    torch.testing.assert_close(smdp.values, vi.values, rtol=0, atol=1e-8)
    torch.testing.assert_close(smdp.q, vi.q[models.row_state, models.row_option], rtol=0, atol=1e-8)
    usable = primitive_options(small_world).initiation[0]
    assert (smdp.policy[~usable] == -1).all()
    # Wherever the best action wins clearly, both planners pick it.
    top2 = vi.q.topk(2, dim=1).values
    clear = usable & (top2[:, 0] - top2[:, 1] > 1e-9)
    assert clear.sum() > 10
    assert torch.equal(smdp.policy[clear], vi.policy[clear])


def test_options_cannot_beat_primitives(small_world):
    """Options are built from primitive moves: with them in the set, V* stays the same."""
    vi = value_iteration(
        small_world.transition_model(), small_world.reward_model(), small_world.gamma, tol=1e-12
    )
    smdp = smdp_value_iteration(
        option_models(small_world, learner_options(small_world, corners=True)), tol=1e-12
    )
    torch.testing.assert_close(smdp.values, vi.values, rtol=0, atol=1e-8)


# -------------------------------------------------------------------------- greedy choice
def hand_models() -> OptionModels:
    """3 states, 3 options; state 2 has none. Only rewards matter for the greedy choice."""
    row_state = torch.tensor([0, 0, 0, 1, 1])
    row_option = torch.tensor([0, 1, 2, 1, 0])
    transition = csr_from_scipy(sp.csr_matrix((5, 3), dtype=np.float64))
    return OptionModels(
        row_state=row_state,
        row_option=row_option,
        reward=torch.zeros(5, dtype=torch.float64),
        transition=transition,
        num_options=3,
    )


def test_greedy_option_policy_tolerance():
    models = hand_models()
    q = torch.tensor([1.0, 0.5, 0.95, 0.3, 0.3], dtype=torch.float64)
    values = torch.tensor([1.0, 0.3, 0.0], dtype=torch.float64)
    preferred = torch.tensor([False, False, True])
    # Plain argmax; tie at state 1 between options 1 and 0 goes to the lower index.
    assert greedy_option_policy(models, q, values).tolist() == [0, 0, -1]
    assert greedy_option_policy(models, q, values, preferred, tolerance=0.0).tolist() == [0, 0, -1]
    # Option 2 is 0.05 below the best: preferred within 0.1, not within 0.01.
    assert greedy_option_policy(models, q, values, preferred, tolerance=0.1).tolist() == [2, 0, -1]
    assert greedy_option_policy(models, q, values, preferred, tolerance=0.01).tolist() == [0, 0, -1]
    # A preferred option that is also the best is chosen with or without tolerance.
    q_best = torch.tensor([0.9, 0.5, 1.0, 0.3, 0.3], dtype=torch.float64)
    assert greedy_option_policy(models, q_best, values).tolist()[0] == 2


def test_smdp_value_iteration_on_hand_models():
    # State 0: option 0 ends in state 1 with weight 0.9 and reward 0; option 1 gives reward 0.5
    # and ends nowhere (E[γ^k] = 0). State 1: option 0 gives 1 and stops. So V1 = 1 and
    # V0 = max(0 + 0.9·1, 0.5) = 0.9.
    T = sp.csr_matrix(np.array([[0.0, 0.9], [0.0, 0.0], [0.0, 0.0]]))
    models = OptionModels(
        row_state=torch.tensor([0, 0, 1]),
        row_option=torch.tensor([0, 1, 0]),
        reward=torch.tensor([0.0, 0.5, 1.0], dtype=torch.float64),
        transition=csr_from_scipy(T),
        num_options=2,
    )
    result = smdp_value_iteration(models)
    torch.testing.assert_close(result.values, torch.tensor([0.9, 1.0], dtype=torch.float64))
    assert result.policy.tolist() == [0, 0]
    torch.testing.assert_close(result.q, torch.tensor([0.9, 0.5, 1.0], dtype=torch.float64))


# ---------------------------------------------------------------------- expected steps
def test_expected_steps_closed_form_with_slip():
    """2×2 world, goal east of the start: the agent heads for the goal, or north from (1,0).

    With slip p and q = 1 − 2p/3 (chance of staying put at (0,0) or (1,1) is 2p/3):
      t(0,0) = 1 + (2p/3)·t(0,0) + (p/3)·t(1,0),    t(1,1) = t(0,0) by symmetry,
      t(1,0) = 1 + (1 − p)·t(0,0) + (2p/3)·t(1,0) + (p/3)·t(1,1)  ⇒  t(1,0) = 1/q + t(0,0),
      ⇒ (1 − p)·t(0,0) = 1 + p/(3q).
    """
    p = 0.1
    world = MultiRooms(size=2, rooms=1, slip=p, goal=(0, 1))
    durations = option_durations(world, primitive_options(world))
    policy = torch.tensor([3, -1, 0, 0])  # (0,0) east; (1,0) and (1,1) north
    q = 1 - 2 * p / 3
    t00 = (1 + p / (3 * q)) / (1 - p)
    assert expected_steps(durations, policy, 0, world.terminal_mask) == pytest.approx(
        t00, rel=1e-12
    )
    assert expected_steps(durations, policy, 2, world.terminal_mask) == pytest.approx(
        1 / q + t00, rel=1e-12
    )
    assert expected_steps(durations, policy, 1, world.terminal_mask) == 0.0


def test_expected_steps_without_slip_is_the_shortest_path():
    world = MultiRooms(size=6, rooms=2, slip=0.0)
    prim = primitive_options(world)
    vi = value_iteration(world.transition_model(), world.reward_model(), world.gamma)
    policy = torch.where(prim.initiation[0], vi.policy, -1)
    # Start (0,0) to goal (5,5) through either pair of doorways: 10 moves, the Manhattan distance.
    assert expected_steps(
        option_durations(world, prim), policy, 0, world.terminal_mask
    ) == pytest.approx(10.0, abs=1e-9)
    opts = learner_options(world)
    plan = smdp_value_iteration(option_models(world, opts))
    assert expected_steps(
        option_durations(world, opts), plan.policy, 0, world.terminal_mask
    ) == pytest.approx(10.0, abs=1e-9)


def test_expected_steps_is_infinite_when_the_goal_is_never_reached():
    world = MultiRooms(size=2, rooms=1, slip=0.0, goal=(0, 1))
    durations = option_durations(world, primitive_options(world))
    north_forever = torch.tensor([0, -1, 0, 0])
    assert expected_steps(durations, north_forever, 0, world.terminal_mask) == math.inf
    # A state without an option on the way.
    assert (
        expected_steps(durations, torch.tensor([1, -1, -1, 0]), 0, world.terminal_mask) == math.inf
    )


def test_expected_steps_on_the_papers_40x40_world():
    """Optimal primitive policy: ≈ 91.4 steps a trip; the paper's 53.2 goals / 5000 steps ≈ 94."""
    world = MultiRooms(size=40, rooms=10)
    prim = primitive_options(world)
    vi = value_iteration(world.transition_model(), world.reward_model(), world.gamma)
    policy = torch.where(prim.initiation[0], vi.policy, -1)
    steps = expected_steps(
        option_durations(world, prim), policy, world.start_state, world.terminal_mask
    )
    assert steps == pytest.approx(91.37, abs=0.05)
    assert abs(steps - 5000 / 53.2) / (5000 / 53.2) < 0.1
    assert vi.values[world.start_state] == pytest.approx(-0.192, abs=0.001)


def test_optimal_baseline_without_slip_is_the_shortest_path_by_hand():
    # 6×6, 2×2 rooms, no slip: 10 moves from (0,0) to (5,5); 9 pay −0.01 and the last +1.
    best = optimal_baseline(MultiRooms(size=6, rooms=2, slip=0.0))
    gamma = 0.99
    assert best.steps_to_goal == pytest.approx(10.0, abs=1e-9)
    assert best.value_start == pytest.approx(
        -0.01 * (1 - gamma**9) / (1 - gamma) + gamma**9, abs=1e-9
    )
    assert best.goals_per(5000) == pytest.approx(500.0)


def test_optimal_baseline_of_the_papers_40x40_world_is_ours_not_the_papers():
    """The curves' reference line: 54.7 goals per 5000 steps (the paper reports ≈ 53.2)."""
    best = optimal_baseline(MultiRooms(size=40, rooms=10))
    assert best.goals_per(5000) == pytest.approx(54.72, abs=0.01)
    assert best.value_start == pytest.approx(-0.1923, abs=1e-4)


# ---------------------------------------------------------------------------- bad inputs
@pytest.mark.parametrize(
    "make, match",
    [
        (lambda P, R: (P[0], R, 0.9), r"P must be \[A, S, S\]"),
        (lambda P, R: (P[:, :, :2], R, 0.9), r"P must be \[A, S, S\]"),
        (lambda P, R: (P, R.T, 0.9), r"R must be \[S, A\] = \[3, 2\]"),
        (lambda P, R: (P, R, 1.0), r"gamma=1.0 must lie in \[0, 1\)"),
        (lambda P, R: (P, R, -0.1), r"must lie in \[0, 1\)"),
        (
            lambda P, R: (
                P,
                R.index_put(
                    (torch.tensor([0]), torch.tensor([0])),
                    torch.tensor([math.nan], dtype=torch.float64),
                ),
                0.9,
            ),
            "NaN",
        ),
        (lambda P, R: (P, R + math.inf, 0.9), "infinite"),
    ],
)
def test_value_iteration_bad_inputs(make, match):
    P, R, gamma = make(*three_state_mdp())
    with pytest.raises(ValueError, match=match):
        value_iteration(P, R, gamma)


def _expected_steps_by_search(durations, policy, start, terminal) -> float:
    """expected_steps written plainly: a breadth-first search over dicts from the start, the
    states that can finish by walking back from the terminal ones, then the same solve."""
    import scipy.sparse.linalg as spla

    key = (durations.row_state * durations.num_options + durations.row_option).tolist()
    lookup = {k: i for i, k in enumerate(key)}
    Tm = sp.csr_matrix(durations.transition.to_dense().numpy())
    term = terminal.numpy()
    if term[start]:
        return 0.0
    seen, frontier, rows, parents = {start}, [start], {}, {}
    while frontier:
        nxt = []
        for s in frontier:
            if term[s]:
                continue
            row = lookup.get(s * durations.num_options + max(int(policy[s]), 0))
            if row is None or policy[s] < 0:
                return math.inf
            rows[s] = row
            for t in Tm.indices[Tm.indptr[row] : Tm.indptr[row + 1]].tolist():
                parents.setdefault(t, []).append(s)
                if t not in seen:
                    seen.add(t)
                    nxt.append(t)
        frontier = nxt
    finishing = [s for s in seen if term[s]]
    can_finish = set(finishing)
    while finishing:
        for p in parents.get(finishing.pop(), ()):
            if p not in can_finish:
                can_finish.add(p)
                finishing.append(p)
    if len(can_finish) < len(seen):
        return math.inf
    states = sorted(rows)
    pos = {s: i for i, s in enumerate(states)}
    sub = Tm[[rows[s] for s in states]].tocoo()
    keep = np.isin(sub.col, states)
    n = len(states)
    system = sp.identity(n, format="csr") - sp.csr_matrix(
        (sub.data[keep], (sub.row[keep], [pos[c] for c in sub.col[keep]])), shape=(n, n)
    )
    t = spla.spsolve(system.tocsc(), durations.reward.numpy()[[rows[s] for s in states]])
    value = float(np.atleast_1d(t)[pos[start]])
    return value if np.isfinite(value) and value > 0 else math.inf


@pytest.mark.parametrize("size, rooms, slip", [(8, 2, 0.0), (20, 4, 0.1), (40, 10, 0.1)])
def test_expected_steps_equals_the_search_over_dicts(size, rooms, slip):
    """expected_steps (array masks and scipy's breadth-first search) gives the plain search's
    answer to the bit: optimal policies over primitives and over options, and random policies
    (closed loops: inf; states without an option on the way: inf; some that finish)."""
    world = MultiRooms(size=size, rooms=rooms, slip=slip)
    terminal, S = world.terminal_mask, world.num_states
    cases = []
    if slip == 0.0:  # a closed loop: west into the wall at the start, forever
        west = smdp_value_iteration(option_models(world, primitive_options(world))).policy.clone()
        west[world.start_state] = primitive_options(world).names.index("primitive W")
        cases.append((option_durations(world, primitive_options(world)), west, world.start_state))
    for options in (primitive_options(world), learner_options(world)):
        durations = option_durations(world, options)
        plan = smdp_value_iteration(option_models(world, options))
        cases.append((durations, plan.policy, world.start_state))
        cases.append((durations, plan.policy, int(torch.nonzero(terminal)[0])))  # (at the goal)
        gen = torch.Generator().manual_seed(size)
        for _ in range(6):
            # the plan's option, replaced at random states by a random available one or none
            policy = plan.policy.clone()
            where = torch.rand(S, generator=gen) < 0.05
            for s in torch.nonzero(where).flatten().tolist():
                available = torch.nonzero(options.initiation[:, s]).flatten()
                pick = int(torch.randint(len(available) + 1, (1,), generator=gen))
                policy[s] = available[pick] if pick < len(available) else -1
            cases.append((durations, policy, world.start_state))
    answers = []
    for durations, policy, start in cases:
        with warnings.catch_warnings():  # (a closed loop is answered before a singular solve)
            warnings.simplefilter("error")
            got = expected_steps(durations, policy, start, terminal)
        assert got == _expected_steps_by_search(durations, policy, start, terminal)
        answers.append(got)
    assert (
        any(math.isinf(a) for a in answers)
        and sum(math.isfinite(a) and a > 0 for a in answers) >= 2
    )
