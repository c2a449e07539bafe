"""The puzzle box: its dynamics against a hand-solved small box, the two organisations optimal
and of equal cost by exact planning, the learner's and the mentor's low-level sequences, and the
state mapping of a smaller box's demonstrations into a larger one (footnote 2)."""

import math

import numpy as np
import pytest
import torch

import himit_torch as ht
from himit_torch.exact.option_models import option_durations, option_models
from himit_torch.exact.planning import expected_steps, smdp_value_iteration, value_iteration
from himit_torch.mentor.policy import record_demonstrations
from himit_torch.mentor.puzzle_box import map_demonstrations, map_states, organisation_mentor
from himit_torch.options.puzzle_box import intended_rollout, puzzle_box_options, step_options
from himit_torch.worlds.puzzle_box import (
    PuzzleBox,
    next_step,
    organisation_of,
    puzzle_box_size,
)
from himit_torch.worlds.table_world import table_probabilities, transition_support, world_model


@pytest.fixture(scope="module")
def small() -> PuzzleBox:
    """k = 2 skewers of n = 2 steps: 9 · 7 = 63 states, 7 actions."""
    return PuzzleBox(skewers=2, steps=2)


def outcomes(box: PuzzleBox, state: int, action: int) -> dict:
    """``{successor: (probability, reward)}`` of ``(state, action)`` from the dynamics table."""
    table = box.dynamics_table()
    prob = table_probabilities(table)[state, action].tolist()
    out: dict = {}
    for succ, p, r in zip(
        table.successors[state, action].tolist(), prob, table.rewards[state, action].tolist()
    ):
        if p > 0:
            q, r0 = out.get(succ, (0.0, r))
            assert r0 == r
            out[succ] = (q + p, r)
    return {s: (pytest.approx(p), r) for s, (p, r) in out.items()}


# ----------------------------------------------------------------------- the dynamics, by hand
def test_sizes_and_layout(small):
    assert small.num_states == 63 == puzzle_box_size(2, 2)
    assert small.action_names == (
        "reach 1", "reach 2", "withdraw", "power grip", "pinch grip", "motion 1", "motion 2",
    )  # fmt: skip
    assert [puzzle_box_size(k) for k in (2, 3, 4, 5)] == [175, 1250, 8125, 50_000]
    s = small.encode([1, 2], skewer=0, grasp="pinch")
    assert small.decode(s) == ((1, 2), 0, "pinch")
    assert small.decode(small.encode([2, 0])) == ((2, 0), None, None)
    assert small.start_state == small.encode([0, 0]) == 0
    terminal = small.terminal_mask.nonzero()[:, 0].tolist()
    assert terminal == [small.encode([2, 2]) + h for h in range(7)]  # all out, any hand


def test_dynamics_of_a_hand_solved_box(small):
    """Every case worked out by hand for k = 2, n = 2, slip 0.1 (motions slip to the one other
    motion; anything else fumbles)."""
    box, e = small, small.encode
    reach1, reach2, withdraw, power, pinch, m1, m2 = range(7)
    home = e([0, 0])
    # reaching from home: to the skewer, open, 0.9; a fumble stays home, 0.1
    assert outcomes(box, home, reach2) == {e([0, 0], 1, "open"): (0.9, -0.01), home: (0.1, -0.01)}
    # movements outside their posture do nothing
    for a in (withdraw, power, pinch, m1, m2):
        assert outcomes(box, home, a) == {home: (1.0, -0.01)}
    at = e([0, 0], 0, "open")
    assert outcomes(box, at, power) == {e([0, 0], 0, "power"): (0.9, -0.01), at: (0.1, -0.01)}
    assert outcomes(box, at, withdraw) == {home: (0.9, -0.01), at: (0.1, -0.01)}
    assert outcomes(box, at, reach2) == {at: (1.0, -0.01)}  # reach only from home
    # step 1 on skewer 1 (level 0): motion 1 does it (hand home); its slip, motion 2, does nothing
    held = e([0, 0], 0, "pinch")
    assert outcomes(box, held, m1) == {e([1, 0]): (0.9, -0.01), held: (0.1, -0.01)}
    # at level 1, motion 2 does step 2; its slip, motion 1, undoes step 1
    held = e([1, 0], 0, "power")
    assert outcomes(box, held, m2) == {e([2, 0]): (0.9, -0.01), e([0, 0]): (0.1, -0.01)}
    assert outcomes(box, held, m1) == {e([0, 0]): (0.9, -0.01), e([2, 0]): (0.1, -0.01)}
    # the last step opens the box: +1
    held = e([2, 1], 1, "power")
    assert outcomes(box, held, m2) == {e([2, 2]): (0.9, 1.0), e([2, 0]): (0.1, -0.01)}
    # a skewer that is out can be pushed back in (motion 2 at level 2 undoes step 2)
    held = e([2, 0], 0, "power")
    assert outcomes(box, held, m2) == {e([1, 0]): (0.9, -0.01), held: (0.1, -0.01)}


def test_step_matches_the_table_and_the_true_model(small):
    table = small.dynamics_table()
    S, A, K = table.successors.shape
    positions = torch.arange(S).repeat_interleave(A)
    actions = torch.arange(A).repeat(S)
    for u, slot in ((0.05, 0), (0.5, K - 1), (0.9999, K - 1)):  # slip 0.1, one slip slot
        nxt, reward = small.step(positions, actions, torch.full((S * A,), u, dtype=torch.float64))
        assert torch.equal(nxt, table.successors.view(S * A, K)[:, slot])
        assert torch.equal(reward, table.rewards.view(S * A, K)[:, slot])
    P, R = world_model(small)
    dense = P.to_dense()
    assert torch.allclose(dense.sum(-1), torch.ones(A, S, dtype=torch.float64))


def test_a_harder_pinch_slips_more(small):
    box = PuzzleBox(2, 2, pinch_slip=0.3)
    e = box.encode
    at = e([0, 0], 0, "open")
    assert outcomes(box, at, box.action_pinch) == {
        e([0, 0], 0, "pinch"): (0.7, -0.01),
        at: (0.3, -0.01),
    }
    held = e([1, 0], 0, "pinch")
    assert outcomes(box, held, box.action_motion(2)) == {
        e([2, 0]): (0.7, -0.01),
        e([0, 0]): (0.3, -0.01),
    }
    # the power grip keeps the world's slip
    assert outcomes(box, at, box.action_power) == outcomes(small, at, small.action_power)


def test_hand_solved_optimum(small):
    """n = 2, slip 0.1: a step-1 attempt costs reach + grip + motion, each geometric (10/3
    movements); step 2 costs 2/0.9 + 1 + 0.1·(10/3 + c2) for the motion that may undo step 1,
    so c2 = 320/81; opening two skewers: 2·(10/3 + 320/81) = 1180/81 movements. Without slips: 12
    movements, V*(start) = −0.01·Σ_{t<11} γ^t + γ^11."""
    P, R = world_model(small)
    plan = value_iteration(P, R, small.gamma)
    prims = ht.primitive_options(small)
    steps = expected_steps(option_durations(small, prims), plan.policy, 0, small.terminal_mask)
    assert steps == pytest.approx(1180 / 81, rel=1e-9)
    sure = PuzzleBox(2, 2, slip=0.0)
    P, R = world_model(sure)
    g = sure.gamma
    hand = -0.01 * sum(g**t for t in range(11)) + g**11
    assert float(value_iteration(P, R, g).values[0]) == pytest.approx(hand, abs=1e-9)


def test_primitives_are_usable_only_where_they_afford_something(small):
    prims = ht.primitive_options(small)
    assert torch.equal(prims.initiation, small.affordances)
    # an action outside its affordances does nothing at all
    table = small.dynamics_table()
    idle = ~small.affordances.T & ~small.terminal_mask[:, None]  # [S, A]
    stay = (table.successors == torch.arange(small.num_states)[:, None, None]).all(-1)
    assert bool(stay[idle].all())


@pytest.mark.parametrize(
    "kwargs",
    [
        {"skewers": 0},
        {"skewers": 2, "steps": 1},
        {"skewers": 2, "slip": 1.0},
        {"skewers": 2, "pinch_slip": -0.1},
        {"skewers": 2.5},
    ],
)
def test_bad_boxes_are_refused(kwargs):
    with pytest.raises(ValueError):
        PuzzleBox(**kwargs)


# ------------------------------------------------------------------ the two organisations
def test_next_step_and_organisations():
    assert next_step([4, 1, 0], "skewer") == (1, 2)
    assert next_step([4, 1, 0], "step") == (2, 1)
    assert next_step([2, 2, 2], "step") == (0, 3)
    with pytest.raises(ValueError):
        next_step([4, 4], "skewer")
    skewer = [(0, 1), (0, 2), (1, 1), (1, 2)]
    step = [(0, 1), (1, 1), (0, 2), (1, 2)]
    assert organisation_of(skewer, 2, 2) == "skewer"
    assert organisation_of(step, 2, 2) == "step"
    assert organisation_of([(1, 1), (1, 2), (0, 1), (0, 2)], 2, 2) == "skewer"  # any skewer order
    assert organisation_of([(0, 1), (1, 1), (1, 2), (0, 2)], 2, 2) == "step"
    assert organisation_of([(0, 1), (1, 1), (0, 2), (0, 3), (1, 2), (1, 3)], 2, 3) == "mixed"
    assert organisation_of(skewer[:3], 2, 2) == "incomplete"


# (4 skewers take ~30-60 s: left to make test-all; 3 skewers run in CI's slow suite)
@pytest.mark.parametrize(
    "skewers",
    [
        2,
        pytest.param(3, marks=pytest.mark.slow),
        pytest.param(4, marks=[pytest.mark.slow, pytest.mark.extended]),
    ],
)
def test_both_organisations_are_optimal_and_cost_the_same(skewers):
    """Exact planning: each organisation's mentor policy attains V* of the world (value
    iteration over the primitive actions) and of the learner's options, with the same expected
    number of movements; so does the learner's own style. With a harder pinch each style is still
    order-free, and the mentor's way is strictly slower."""
    for pinch_slip in (None, 0.25):
        box = PuzzleBox(skewers, pinch_slip=pinch_slip)
        P, R = world_model(box)
        v_star = float(value_iteration(P, R, box.gamma, tol=1e-12).values[0])
        values, lengths = {}, {}
        for style in ("mentor", "learner"):
            opts = puzzle_box_options(box, style)
            models, durations = option_models(box, opts), option_durations(box, opts)
            best = float(smdp_value_iteration(models, tol=1e-12).values[0])
            for org in ("skewer", "step"):
                policy = organisation_mentor(box, org, options=opts).option
                v = _policy_value(models, policy, box)
                values[style, org] = v
                lengths[style, org] = expected_steps(durations, policy, 0, box.terminal_mask)
                if style == "learner" or pinch_slip is None:
                    assert v == pytest.approx(best, abs=1e-8)
                else:  # a slower pinch: its primitives (the power grip) would do better
                    assert v < best - 1e-3
            assert values[style, "skewer"] == pytest.approx(values[style, "step"], abs=1e-10)
            assert lengths[style, "skewer"] == pytest.approx(lengths[style, "step"], rel=1e-9)
        # the learner's own style is optimal in the world
        assert values["learner", "skewer"] == pytest.approx(v_star, abs=1e-8)
        if pinch_slip is None:  # equal grips: the mentor's style is optimal too
            assert values["mentor", "step"] == pytest.approx(v_star, abs=1e-8)
        else:  # a harder pinch: the mentor's way is strictly slower
            assert lengths["mentor", "step"] > lengths["learner", "step"] + 0.5


def _policy_value(models, policy, box) -> float:
    """V^π(start) of an option policy, exactly: solve V = r_π + P_π V."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    rows = {
        (int(s), int(o)): i for i, (s, o) in enumerate(zip(models.row_state, models.row_option))
    }
    S = box.num_states
    T = models.transition.to_sparse_coo().coalesce()
    Tm = sp.csr_matrix((T.values().numpy(), tuple(T.indices().numpy())), shape=tuple(T.shape))
    pick = [(s, rows[s, int(policy[s])]) for s in range(S) if int(policy[s]) >= 0]
    select = sp.csr_matrix(
        (np.ones(len(pick)), ([s for s, _ in pick], [r for _, r in pick])), shape=(S, Tm.shape[0])
    )
    V = spla.spsolve(
        (sp.identity(S, format="csc") - select @ Tm).tocsc(), select @ models.reward.numpy()
    )
    return float(V[0])


# ----------------------------------------------------------- different low-level sequences
def test_learner_and_mentor_reach_the_same_subgoals_by_different_movements():
    box = PuzzleBox(3)
    learner, mentor = puzzle_box_options(box, "learner"), puzzle_box_options(box, "mentor")
    for org in ("skewer", "step"):
        mine, _ = intended_rollout(box, learner, organisation_mentor(box, org, learner).option)
        theirs, _ = intended_rollout(box, mentor, organisation_mentor(box, org, mentor).option)
        # the same steps in the same order, the same subgoal states (hand home, or open at a
        # skewer) …
        assert box.subgoals(mine) == box.subgoals(theirs)
        assert organisation_of(box.subgoals(mine), 3) == org
        shared = box.home_mask | box.grasp_mask("open")
        assert [s for s in mine.tolist() if shared[s]] == [s for s in theirs.tolist() if shared[s]]
        # … but never the same state between them: power grip against pinch
        between_mine = {s for s in mine.tolist() if not shared[s]}
        between_theirs = {s for s in theirs.tolist() if not shared[s]}
        assert between_mine and between_theirs and not between_mine & between_theirs
        assert set(box.grasps_used(mine)) == {"power"}
        assert set(box.grasps_used(theirs)) == {"pinch"}
        assert mine.tolist() != theirs.tolist()
    # recorded (state-only) demonstrations: the mentor never holds a power grip
    demos = record_demonstrations(box, organisation_mentor(box, "step"), 10, seed=0)
    visited = torch.cat(list(demos.episodes))
    assert not bool(box.grasp_mask("power")[visited].any())
    assert bool(box.grasp_mask("pinch")[visited].any())


def test_step_skills_do_or_undo_the_step_at_hand():
    box = PuzzleBox(2, 3)
    opts = step_options(box, "learner")
    e = box.encode
    step2 = 1
    assert bool(opts.initiation[step2, e([1, 0], 0, "open")])  # level 1: does step 2
    assert bool(opts.initiation[step2, e([2, 3], 0, "open")])  # level 2: undoes it
    assert not bool(opts.initiation[step2, e([0, 3], 0, "open")])  # level 0: no effect, not usable
    assert not bool(opts.initiation[step2, e([1, 0])])  # hand home
    assert int(opts.policy[step2, e([1, 0], 0, "open")]) == box.action_power
    assert int(opts.policy[step2, e([1, 0], 0, "power")]) == box.action_motion(2)
    assert not bool(opts.initiation[step2, e([1, 0], 0, "pinch")])  # not its grip
    with pytest.raises(ValueError):
        puzzle_box_options(box, "mentor", pinch=False)
    assert "primitive pinch grip" not in puzzle_box_options(box, pinch=False).names


# --------------------------------------------------------------------- the state mapping
def test_state_mapping_on_a_hand_checked_case():
    four, five = PuzzleBox(4), PuzzleBox(5)
    s = four.encode([1, 2, 0, 3], skewer=2, grasp="pinch")
    # mentor skewers 1, 2, 3, 4 → learner skewers 1, 2, 4, 5; learner skewer 3 held at level 2
    mapped = map_states(four, five, torch.tensor([s]), (0, 1, 3, 4), level=2)
    assert five.decode(int(mapped)) == ((1, 2, 2, 0, 3), 3, "pinch")
    plain = map_states(four, five, torch.tensor([s, four.encode([4, 4, 4, 4])]), (0, 1, 2, 3), 0)
    assert five.decode(int(plain[0])) == ((1, 2, 0, 3, 0), 2, "pinch")
    assert five.decode(int(plain[1])) == ((4, 4, 4, 4, 0), None, None)
    assert not bool(five.terminal_mask[plain[1]])  # the mentor's open box is not the learner's


def test_mapped_demonstrations_are_valid_and_cover_every_view():
    three, four = PuzzleBox(3), PuzzleBox(4)
    demos = record_demonstrations(three, organisation_mentor(three, "step"), 2, seed=1)
    plain = map_demonstrations(demos, three, four, "plain")
    views = map_demonstrations(demos, three, four, "any")
    assert plain.num_episodes == 2
    assert views.num_episodes == 2 * math.comb(4, 3) * 5
    ends = torch.stack([e[-1] for e in views.episodes])
    # only the views whose left-out skewer is already out end with the learner's box open
    assert int(four.terminal_mask[ends].sum()) == 2 * 4
    assert not bool(four.terminal_mask[torch.stack([e[-1] for e in plain.episodes])].any())
    with pytest.raises(ValueError):
        map_demonstrations(demos, four, three, "plain")  # into a smaller box
    with pytest.raises(ValueError):
        map_demonstrations(demos, three, PuzzleBox(4, slip=0.2), "plain")
    with pytest.raises(ValueError):
        map_demonstrations(demos, three, four, "sideways")


def test_the_mapping_keeps_every_transition_law():
    """Why eq. 2 stays sound: a source step under action a has the same probability as the
    mapped step under the relabelled action (reach c → reach ι(c)), for every state, action and
    view of a 2-skewer box in a 3-skewer one."""
    two, three = PuzzleBox(2, 2), PuzzleBox(3, 2)
    P2, P3 = world_model(two)[0].to_dense(), world_model(three)[0].to_dense()
    states = torch.arange(two.num_states)
    live = ~two.terminal_mask
    for chosen in ((0, 1), (0, 2), (1, 2)):
        for level in range(3):
            index = map_states(two, three, states, chosen, level)
            for a in range(two.num_actions):
                b = chosen[a] if a < 2 else a + 1  # reach c → reach ι(c); the rest shift by one
                mine = P2[a][live][:, live]
                theirs = P3[b][index[live]][:, index[live]]
                assert torch.allclose(mine, theirs), (chosen, level, two.action_names[a])
    assert transition_support(three).shape == (three.num_states, three.num_states)


def test_demonstrations_in_a_large_box_are_checked_sparsely():
    """A 5-skewer box has 50,000 states: its dense [S, S] support would be 2.5 GB. The
    demonstrations are checked against the sparse one, which equals the dense one where both fit."""
    from himit_torch.mentor.demonstrations import Demonstrations
    from himit_torch.worlds.table_world import transition_support_matrix

    small = PuzzleBox(2, 2)
    assert torch.equal(
        torch.from_numpy(transition_support_matrix(small).toarray()), transition_support(small)
    )
    rooms = ht.MultiRooms(8, 2)
    assert torch.equal(
        torch.from_numpy(transition_support_matrix(rooms).toarray()), transition_support(rooms)
    )
    five = PuzzleBox(5)
    support = transition_support_matrix(five)
    assert support.nnz < 20 * five.num_states
    e = five.encode
    good = [e([0] * 5), e([0] * 5, 4, "open"), e([0] * 5, 4, "pinch"), e([0, 0, 0, 0, 1])]
    assert Demonstrations([good], five).num_transitions == 3
    with pytest.raises(ValueError, match="index 1: state .* follows"):
        Demonstrations([[e([0] * 5), e([0, 0, 0, 0, 1])]], five)
