"""Subgoal discovery from state-only demonstrations and options built from a learned one-step model
(himit_torch.options.discovery) and its figure. The discovery experiment: tests/runs/test_discovery.py."""

import numpy as np
import pytest
import scipy.sparse as sp

from himit_torch.learner.learner import Learner
from himit_torch.mentor.policy import record_demonstrations
from himit_torch.options.builders import mentor_options, primitive_options
from himit_torch.options.discovery import (
    discover_subgoals,
    fewest_steps_policy,
    learned_subgoal_options,
    mentor_graph,
    one_step_counts,
)
from himit_torch.worlds.multirooms import MultiRooms


def two_rooms_episodes():
    """Two 2×2 'rooms' {0,1,2,3} and {5,6,7,8} (cycles 0-1-3-2-0, 5-6-8-7-5) joined only
    through state 4 (3-4-5); episodes start at 0 and end at 8, wandering differently in each
    room. The only bottleneck on every episode is 4 (3 and 5 are cut vertices too, but wider)."""
    return [
        np.array(e)
        for e in (
            [0, 1, 3, 4, 5, 6, 8],
            [0, 2, 3, 4, 5, 7, 8],
            [0, 1, 0, 2, 3, 4, 5, 6, 8, 7, 8],
            [0, 2, 3, 4, 5, 7, 5, 6, 8],
        )
    ]


def test_mentor_graph_has_the_observed_moves_only():
    g = mentor_graph(two_rooms_episodes())
    assert set(g.nodes) == set(range(9))
    assert set(map(frozenset, g.edges)) == {
        frozenset(e)
        for e in [(0, 1), (1, 3), (0, 2), (2, 3), (3, 4), (4, 5), (5, 6), (6, 8), (5, 7), (7, 8)]
    }


def test_the_bottleneck_of_a_hand_built_graph_is_found():
    sg = discover_subgoals(two_rooms_episodes(), separation=1)
    # cut vertices 3, 4, 5 (all on every episode); 4 is the narrowest (degree 2 vs 3), and it
    # suppresses its neighbours 3 and 5
    assert set(sg.candidates) == {3, 4, 5}
    assert sg.states == (4,)
    assert sg.degree[4] == 2 and sg.episode_share[4] == 1.0
    pr = sg.precision_recall([4, 99])
    assert pr == {"found": 1, "true": 1, "hits": 1, "precision": 1.0, "recall": 1.0}
    assert sg.precision_recall([4, 99], visited_only=False)["recall"] == 0.5
    # with no separation the wider cut vertices are kept too, narrowest first
    assert discover_subgoals(two_rooms_episodes(), separation=0).states == (4, 3, 5)


def test_a_state_off_some_episodes_is_no_subgoal():
    eps = two_rooms_episodes() + [np.array([0, 1, 3, 9, 5, 6, 8])]  # a way around 4, via 9
    sg = discover_subgoals(eps, separation=1)
    assert 4 not in sg.states and 4 not in sg.candidates
    # with a lower share, 4 is no cut vertex any more either: 3 and 5 are
    assert set(discover_subgoals(eps, separation=0, min_episode_share=0.5).states) == {3, 5}


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"separation": -1}, "separation"),
        ({"separation": 1.5}, "separation"),
        ({"min_episode_share": 0.0}, "min_episode_share"),
        ({"min_episode_share": 1.2}, "min_episode_share"),
    ],
)
def test_bad_settings_are_refused(kwargs, match):
    with pytest.raises(ValueError, match=match):
        discover_subgoals(two_rooms_episodes(), **kwargs)
    with pytest.raises(ValueError, match="at least one episode"):
        discover_subgoals([])


def test_doorways_of_a_multirooms_world_are_found():
    world = MultiRooms(24, 3, slip=0.1)  # rooms of 8 cells: 7×7 interiors
    demos = record_demonstrations(world, mentor_options(world), 20, seed=0)
    sg = discover_subgoals(demos, separation=world.size // world.rooms - 1)
    pr = sg.precision_recall(world.doorways)
    assert pr["true"] >= 2 and pr["recall"] == 1.0 and pr["precision"] >= 0.5
    assert sg.mask(world.num_states).sum() == len(sg.states)


def test_fewest_steps_policy_on_a_hand_solved_chain():
    # 4 states in a row, actions 0 = left, 1 = right (deterministic); state 3 is the target;
    # action 1 in state 0 was never tried.
    S, A = 4, 2
    rows, cols = [], []
    for s in range(S):
        rows.append(0 * S + s)
        cols.append(max(0, s - 1))
        if s != 0:
            rows.append(1 * S + s)
            cols.append(min(S - 1, s + 1))
    counts = sp.csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(A * S, S))
    target = np.array([False, False, False, True])
    policy, steps = fewest_steps_policy(counts, A, target, gamma=0.9)
    assert policy[1] == 1 and policy[2] == 1
    np.testing.assert_allclose(steps[1:], [2.0, 1.0, 0.0], atol=1e-6)
    assert steps[0] == np.inf  # only "left" was tried in 0: the model knows no way on


def test_options_from_a_learned_model_reach_their_subgoal_in_that_model(world8):
    prims = primitive_options(world8)
    learner = Learner(world8, prims, ["primitives"], [0])
    learner.run(3000)
    counts = one_step_counts(learner, 0)
    # every primitive decision is one count (primitives only: the model's rows are all one-step)
    assert counts.sum() == pytest.approx(float(learner.model.row_count[0].sum()))
    assert counts.shape == (world8.num_actions * world8.num_states, world8.num_states)
    goals = [int(d) for d in world8.doorways]
    opts = learned_subgoal_options(
        counts, world8.num_actions, goals, terminal=world8.terminal_mask, max_steps=8
    )
    assert opts is not None and set(opts.kinds) == {"subgoal"}
    S = world8.num_states
    P = counts.toarray().reshape(world8.num_actions, S, S)
    for o, name in enumerate(opts.names):
        g = int(name.split()[-1])
        assert not opts.initiation[o, g]
        for s0 in opts.initiation[o].nonzero().flatten().tolist():
            s, n = s0, 0
            while s != g and n < 20:  # the most likely successor in the learned model
                a = int(opts.policy[o, s])
                assert P[a, s].sum() > 0  # the policy only takes actions it has tried
                s = int(P[a, s].argmax())
                n += 1
            assert s == g, f"option {name} from {s0} does not reach its subgoal in the model"
    # nothing learned yet: no option can be built
    assert learned_subgoal_options(sp.csr_matrix(counts.shape), world8.num_actions, goals) is None
    with pytest.raises(ValueError, match="max_steps"):
        learned_subgoal_options(counts, world8.num_actions, goals, max_steps=0)


def test_learned_options_follow_the_evidence(world8):
    """Built again from more counts, the options' initiation sets grow (a pure function of them)."""
    learner = Learner(world8, primitive_options(world8), ["primitives"], [1])
    sizes = []
    for _ in range(3):
        learner.run(400)
        opts = learned_subgoal_options(
            one_step_counts(learner, 0),
            world8.num_actions,
            [int(d) for d in world8.doorways],
            terminal=world8.terminal_mask,
            max_steps=10,
        )
        sizes.append(0 if opts is None else int(opts.initiation.sum()))
    assert sizes[0] <= sizes[1] <= sizes[2] and sizes[2] > sizes[0]


def test_subgoal_figure(world8, tmp_path):
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from himit_torch.viz.plotting import plot_subgoals

    demos = record_demonstrations(world8, mentor_options(world8), 5, seed=0)
    sg = discover_subgoals(demos, separation=1)
    learner = Learner(world8, primitive_options(world8), ["primitives"], [0])
    learner.run(2000)
    opts = learned_subgoal_options(
        one_step_counts(learner, 0),
        world8.num_actions,
        sg,
        terminal=world8.terminal_mask,
        max_steps=6,
    )
    fig = plot_subgoals(world8, sg, demonstrations=demos, options=opts)
    FigureCanvasAgg(fig)
    fig.savefig(tmp_path / "s.png")
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert "subgoal: a doorway" in labels and (tmp_path / "s.png").stat().st_size > 1000
