"""The ``bco`` agent (behavioural cloning from observation; issue 26): its cloned policy on a
small world, how it acts on it, when it is refitted, and its checkpoints. The pure functions:
``tests/mentor/test_cloning.py``; the engines' parity: ``tests/learner/engines/test_parity.py``."""

from functools import partial

import pytest
import torch

from himit_torch import (
    Learner,
    LearnerConfig,
    MultiRooms,
    learner_options,
    mentor_options,
    mentor_policy,
    record_demonstrations,
    with_options,
)
from himit_torch.learner.choice import greedy_rows
from himit_torch.state_checks import DamagedState
from tests.learner.helpers import build_learner

CONFIG = LearnerConfig(window=500, bco_every=100)


@pytest.fixture(scope="module")
def still_world():
    """8×8, 2×2 rooms, no slip: each move to a neighbouring cell has exactly one action."""
    return MultiRooms(8, 2, slip=0.0)


@pytest.fixture(scope="module")
def still_demos(still_world):
    return record_demonstrations(
        still_world, mentor_policy(still_world, mentor_options(still_world)), 5, seed=0
    )


make = partial(build_learner, config=CONFIG)


def _own_moves(learner: Learner, b: int) -> set[tuple[int, int]]:
    """The ``(s, s')`` run ``b`` has made with a primitive (its primitive rows' edges)."""
    model, rows = learner.model, learner.rows
    E = int(model.num_edges[b])
    edge_row = model.edge_row[b, :E]
    primitive = learner.cloning.row_action[edge_row] >= 0
    return set(
        zip(
            rows.row_state[edge_row][primitive].tolist(),
            model.edge_successor[b, :E][primitive].tolist(),
        )
    )


@pytest.mark.parametrize("inverse", ["counts", "likelihood"])
def test_cloned_policy_is_the_mentors_action_where_own_experience_explains_it(
    still_world, still_demos, inverse
):
    """Without slip, the mentor's move ``s → s'`` has one action ``a`` (``step(s, a) = s'``).
    Wherever the run has made that move itself, its cloned action at ``s`` is ``a``; where it has
    made none of the mentor's moves out of ``s``, it has none."""
    config = LearnerConfig(window=500, bco_every=100, bco_inverse_model=inverse)
    learner = make(still_world, still_demos, ["bco", "bco"], config=config)
    assert bool((learner.cloning.action == -1).all())  # no own experience yet
    learner.run(1500)
    world, S, A = still_world, still_world.num_states, still_world.num_actions
    src, dst = still_demos.transitions()
    keep = ~world.terminal_mask[src]
    mentor_moves = set(zip(src[keep].tolist(), dst[keep].tolist()))
    states = torch.arange(S)
    successor = torch.stack(
        [
            world.step(states, torch.full((S,), a), torch.full((S,), 0.5, dtype=torch.float64))[0]
            for a in range(A)
        ],
        1,
    )  # [S, A] the deterministic successors
    for b in range(2):
        own = _own_moves(learner, b)
        cloned = learner.cloning.action[b, :S]
        explained = 0
        for s in range(S):
            moves = [(x, y) for x, y in mentor_moves if x == s and (x, y) in own]
            if not moves:
                assert int(cloned[s]) == -1, s
                continue
            # this mentor's moves out of s are one each (it is deterministic without slip)
            (_, s2), *_ = moves
            actions = (successor[s] == s2).nonzero()[:, 0].tolist()
            assert actions == [int(cloned[s])], (s, s2, actions)
            explained += 1
        assert explained > 10  # the check covered much of the mentor's path


def test_without_demonstrations_bco_is_the_primitives_run(world12):
    """Nothing to clone: ``bco`` is ``primitives`` bit for bit (same seed)."""
    learner = make(world12, None, ["bco", "primitives"], [3, 3])
    learner.run(1200)
    assert bool((learner.cloning.action == -1).all())
    assert torch.equal(learner.cache.values[0], learner.cache.values[1])
    assert torch.equal(learner.run_state.visits[0], learner.run_state.visits[1])
    assert int(learner.views.goals[0]) == int(learner.views.goals[1]) > 0


def test_greedy_choice_is_the_cloned_action(world12, mentor_demos12):
    """Where a run has a cloned action its greedy policy takes that primitive with probability 1
    (and the greedy option table names it); elsewhere it is the primitives run's choice."""
    learner = make(world12, mentor_demos12, ["bco"])
    learner.run(1000)
    S = world12.num_states
    cloned = learner.cloning.action[0, :S]
    defined = (cloned >= 0).nonzero()[:, 0]
    assert defined.numel() > 10
    policy = learner.views.greedy_policy()
    options = learner.views.greedy_options()[0]
    for s in defined.tolist():
        row = int(learner.rows.primitive_rows[s, cloned[s]])
        option = int(learner.rows.row_option[row])
        j = policy.option[s].tolist().index(option)
        assert float(policy.probability[0, s, j]) == 1.0
        assert int(options[s]) == option
    # elsewhere: the greedy rule of the run's own values
    live = (~world12.terminal_mask & (cloned < 0)).nonzero()[:, 0]
    _, greedy, _ = greedy_rows(learner.cache, torch.zeros_like(live), live)
    p = greedy.double() / greedy.sum(1, keepdim=True).clamp(min=1)  # (walls: no rows)
    assert torch.equal(policy.probability[0, live], p)


def test_with_an_exact_inverse_model_and_no_exploration_bco_walks_the_mentors_path(
    still_world, still_demos
):
    """Exact option models (``option_models="exact"``) give the run the exact inverse model
    before its first step, so the mentor's whole path is cloned at once; with ε = 0 and no slip
    the run walks it: its first goal comes after exactly the mentor's episode's steps, and every
    state it visits on the way is one of the mentor's."""
    config = LearnerConfig(
        window=500, eps_start=0.0, eps_min=0.0, option_models="exact", exact_model_count=10.0
    )
    learner = make(still_world, still_demos, ["bco"], config=config)
    src, dst = still_demos.transitions()
    on_path = set(src.tolist()) | set(dst.tolist())
    cloned = learner.cloning.action[0, : still_world.num_states]
    assert {s for s in range(still_world.num_states) if int(cloned[s]) >= 0} == {
        s for s in set(src.tolist()) if not bool(still_world.terminal_mask[s])
    }
    learner.run(200)
    mentor_steps = len(still_demos[0]) - 1  # (every episode alike: no slip, one best path)
    assert all(len(episode) - 1 == mentor_steps for episode in still_demos)
    assert int(learner.views.first_goal_step[0]) == mentor_steps
    visited = set((learner.run_state.visits[0, :-1] > 0).nonzero()[:, 0].tolist())
    assert visited <= on_path


def test_refitted_every_bco_every_ticks(world12, mentor_demos12):
    """The cloned policy changes only at multiples of ``bco_every`` (100 here), and is then the
    one the models give at that tick."""
    learner = make(world12, mentor_demos12, ["bco", "imitation"])
    learner.run(100)
    at_100 = learner.cloning.action.clone()
    learner.run(99)
    assert torch.equal(learner.cloning.action, at_100)
    learner.run(101)  # passes 200 and ends at 300, a refit
    now = learner.cloning.action.clone()
    learner.refit_cloned_policy()
    assert torch.equal(learner.cloning.action, now)
    assert int((now[0] >= 0).sum()) > int((at_100[0] >= 0).sum())  # more explained by now
    assert bool((now[1] == -1).all())  # the imitator clones nothing


def test_one_refit_of_all_runs_equals_the_functions_run_by_run(world12, mentor_demos12):
    """``ClonedPolicy.refit`` does every run in one call of each function (states offset per
    run); it equals the obvious computation, the three functions called run by run on each run's
    own edges, exactly (slip: different own experience per seed; both inverse models)."""
    from himit_torch.mentor.cloning import clone_policy, inverse_model, relabel

    for kind in ("likelihood", "counts"):
        config = LearnerConfig(window=500, bco_every=100, bco_inverse_model=kind)
        learner = make(world12, mentor_demos12, ["bco", "imitation", "bco", "bco"], config=config)
        learner.run(700)
        model, mentor, cloning = learner.model, learner.mentor, learner.cloning
        S = world12.num_states
        for b in (0, 2, 3):
            E, Em = int(model.num_edges[b]), int(mentor.num_edges[b])
            edge_row = model.edge_row[b, :E]
            act = cloning.row_action[edge_row]
            own = act >= 0
            inverse = inverse_model(
                learner.rows.row_state[edge_row][own],
                act[own],
                model.edge_successor[b, :E][own],
                model.edge_count[b, :E][own],
                kind,
            )
            sources = mentor.edge_row[b, :Em]
            labels = relabel(inverse, sources, mentor.edge_successor[b, :Em])
            expected = clone_policy(
                sources, labels, mentor.edge_count[b, :Em], S, world12.num_actions
            )
            assert torch.equal(cloning.action[b, :S], expected), (kind, b)
            assert int((expected >= 0).sum()) > 0  # something was cloned to compare
        assert bool((cloning.action[1] == -1).all())


@pytest.mark.parametrize("engine", ["numba", "torch"])
def test_checkpoint_round_trip(world12, mentor_demos12, engine):
    """A state_dict mid-way (between refits) continues exactly, on either engine."""
    agents = ["bco", "primitives", "imitation"]
    first = make(world12, mentor_demos12, agents, engine="numba")
    first.run(250)
    state = first.state_dict()
    assert torch.equal(state["cloning"]["action"], first.cloning.action)
    second = make(world12, None, agents, engine=engine)
    second.load_state_dict(state)
    assert torch.equal(second.cloning.action, first.cloning.action)
    first.run(200)
    second.run(200)
    assert torch.equal(first.cloning.action, second.cloning.action)
    assert torch.equal(first.cache.values, second.cache.values)
    assert torch.equal(first.run_state.visits, second.run_state.visits)


def test_damaged_cloned_policy_is_refused(world12, mentor_demos12):
    learner = make(world12, mentor_demos12, ["bco", "primitives"])
    learner.run(200)
    good = learner.state_dict()
    other = make(world12, None, ["bco", "primitives"])

    def damaged(change) -> dict:
        state = learner.state_dict()
        change(state["cloning"]["action"])
        return state

    cases = [
        (lambda a: a.__setitem__((1, 0), 0), "does not clone"),
        (lambda a: a.__setitem__((0, 0), 4), "an action"),
        (lambda a: a.__setitem__((0, -1), 0), "padding"),
    ]
    for change, message in cases:
        with pytest.raises(DamagedState, match=message):
            other.load_state_dict(damaged(change))
    missing = dict(good)
    del missing["cloning"]
    with pytest.raises(ValueError, match="cloned policy"):
        other.load_state_dict(missing)
    other.load_state_dict(good)  # the refusals left it loadable
    assert torch.equal(other.cloning.action, learner.cloning.action)


def test_with_options_carries_the_cloned_policy(world12, mentor_demos12):
    learner = make(world12, mentor_demos12, ["bco", "primitives"])
    learner.run(300)
    new = with_options(learner, learner_options(world12))
    assert torch.equal(new.cloning.action, learner.cloning.action)
    with pytest.raises(ValueError, match="cloning"):
        with_options(learner, learner_options(world12), agents=["primitives", "primitives"])
