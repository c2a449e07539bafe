"""The stresses on the mentor's demonstrations (issue 26, part 2): a mentor that errs
(``noise``), a needless detour, coarse observation (``observe_every``) and observation at the
mentor's option ends (``observe_at_option_ends``)."""

from collections import deque

import numpy as np
import pytest
import torch
from scipy.stats import binomtest, chisquare

from himit_torch.learner.learner import Learner
from himit_torch.mentor.demonstrations import Demonstrations
from himit_torch.mentor.observation import (
    CoarseDemonstrations,
    observe_at_option_ends,
    observe_every,
    observed_indices,
)
from himit_torch.mentor.policy import (
    MentorPolicy,
    _nominal_ends,
    _on_cycles,
    mentor_detour,
    mentor_policy,
    record_demonstrations,
    run_mentor,
)
from himit_torch.options.builders import learner_options, mentor_options
from himit_torch.worlds.multirooms import MultiRooms, detour_waypoint, maze_doorways


@pytest.fixture(scope="module")
def world() -> MultiRooms:
    return MultiRooms(size=20, rooms=2, slip=0.1)


@pytest.fixture(scope="module")
def policy(world) -> MentorPolicy:
    return mentor_policy(world, mentor_options(world))


# ------------------------------------------------------------------------ a mentor that errs
@pytest.mark.parametrize("noise", [0.1, 0.3])
def test_the_noisy_mentors_error_rate_matches_its_setting(world, policy, noise):
    rollout = run_mentor(world, policy, episodes=150, seed=11, noise=noise)
    options = policy.options
    decisions = torch.cat(rollout.decisions)
    states = torch.cat(rollout.decision_states)
    randomised = torch.cat(rollout.randomised)
    n = decisions.numel()
    assert n > 1500 and states.shape == randomised.shape == (n,)
    # the share of random decisions: a 99.9 % Clopper-Pearson interval holds the setting
    ci = binomtest(int(randomised.sum()), n).proportion_ci(0.999)
    assert ci.low <= noise <= ci.high, (int(randomised.sum()), n)
    # the others are the policy's own options; the random ones primitives, uniform over the four
    own = policy.option[states]
    assert torch.equal(decisions[~randomised], own[~randomised])
    assert options.is_primitive[decisions[randomised]].all()
    counts = torch.bincount(decisions[randomised], minlength=4)[:4].numpy()
    assert chisquare(counts).pvalue > 1e-3, counts
    # Seen from outside (no flags): a decision differs from the policy's with probability
    # noise · (1 − 1/4 if the policy's own choice there is a primitive, else 1).
    p = noise * (1 - options.is_primitive[own].double() / 4)
    differs = (decisions != own).double()
    z = float((differs - p).sum() / (p * (1 - p)).sum().sqrt())
    assert abs(z) < 4, z


def test_noise_zero_is_the_mentor_without_noise(world, policy):
    g_plain, g_zero = torch.Generator().manual_seed(5), torch.Generator().manual_seed(5)
    plain = record_demonstrations(world, policy, 12, generator=g_plain)
    zero = record_demonstrations(world, policy, 12, generator=g_zero, noise=0.0)
    assert all(torch.equal(a, b) for a, b in zip(plain.episodes, zero.episodes, strict=True))
    # the same draws were used: the generators go on alike
    assert torch.equal(torch.rand(4, generator=g_plain), torch.rand(4, generator=g_zero))
    noisy = record_demonstrations(world, policy, 12, seed=5, noise=0.3)
    assert not all(torch.equal(a, b) for a, b in zip(plain.episodes, noisy.episodes))
    assert not torch.cat(run_mentor(world, policy, 12, seed=5).randomised).any()


@pytest.mark.parametrize("noise", [1.0, -0.1, float("nan"), "0.1"])
def test_noise_outside_zero_to_one_is_refused(world, policy, noise):
    with pytest.raises(ValueError, match="noise"):
        run_mentor(world, policy, 2, seed=0, noise=noise)


def test_noise_needs_primitives_among_the_mentors_options(world):
    doorways_only = mentor_options(world).select(torch.arange(4, mentor_options(world).num_options))
    extended = MentorPolicy(
        doorways_only, torch.full((world.num_states,), -1), torch.zeros(world.num_states), 0.0
    )
    with pytest.raises(ValueError, match="hold none"):
        run_mentor(world, extended, 2, seed=0, noise=0.1)


# ---------------------------------------------------------------------------- the detour
def _distances(world: MultiRooms, source: int) -> np.ndarray:
    """Primitive steps from ``source`` to every cell, without slips (breadth first)."""
    nxt = world.next_state_table.numpy()
    dist = np.full(world.num_states, -1)
    dist[source] = 0
    queue = deque([source])
    while queue:
        s = queue.popleft()
        for t in nxt[s]:
            if dist[t] < 0:
                dist[t] = dist[s] + 1
                queue.append(int(t))
    return dist


@pytest.mark.parametrize("size, rooms", [(20, 2), (16, 4), (40, 10), (12, 6)])
def test_the_waypoint_lies_on_no_shortest_path_of_the_open_layout(size, rooms):
    w = MultiRooms(size=size, rooms=rooms)
    waypoint = detour_waypoint(w)
    assert w.coords(waypoint) == (0, size - 1)
    from_start = _distances(w, w.start_state)
    to_goal = _distances(w, w.goal_state)
    assert from_start[waypoint] + to_goal[waypoint] > from_start[w.goal_state]


def test_every_detouring_demonstration_passes_the_waypoint_and_ends_at_the_goal(world, policy):
    detour = mentor_detour(world)
    demos = record_demonstrations(world, policy, 15, seed=2, detour=detour)
    direct = record_demonstrations(world, policy, 15, seed=2)
    assert isinstance(demos, Demonstrations) and demos.num_episodes == 15
    for episode in demos.episodes:
        assert episode[0] == world.start_state and episode[-1] == world.goal_state
        assert (episode == detour.waypoint).any()
        assert not (episode[:-1] == world.goal_state).any()
    assert demos.episode_lengths.double().mean() > direct.episode_lengths.double().mean() + 5
    # from the seed: the same episodes again
    again = record_demonstrations(world, policy, 15, seed=2, detour=detour)
    assert all(torch.equal(a, b) for a, b in zip(demos.episodes, again.episodes))


def test_a_detour_in_a_maze_with_a_noisy_mentor_still_ends_at_the_goal():
    maze = MultiRooms(size=16, rooms=4, closed_doorways=maze_doorways(16, 4))
    mentor = mentor_policy(maze, mentor_options(maze))
    detour = mentor_detour(maze)
    demos = record_demonstrations(maze, mentor, 10, seed=0, detour=detour, noise=0.1)
    # (this maze's way to the top-right corner runs along the top rooms, far from the goal, so
    # no first leg can end at the goal)
    for episode in demos.episodes:
        assert episode[0] == maze.start_state and episode[-1] == maze.goal_state
        assert (episode == detour.waypoint).any()


def test_a_detour_made_for_another_world_is_refused(world, policy):
    other = MultiRooms(size=20, rooms=2, slip=0.2)
    with pytest.raises(ValueError, match="another world"):
        record_demonstrations(world, policy, 2, seed=0, detour=mentor_detour(other))
    with pytest.raises(ValueError, match="start or goal"):
        mentor_detour(world, waypoint=world.goal_state)


# ---------------------------------------------------------------------- coarse observation
@pytest.fixture(scope="module")
def grid() -> MultiRooms:
    return MultiRooms(size=4, rooms=1, slip=0.0)  # one 4×4 room: start 0, goal 15


@pytest.fixture(scope="module")
def walks(grid) -> Demonstrations:
    # cells: row · 4 + column; the second bumps into the top wall at its first step
    return Demonstrations([[0, 1, 2, 3, 7, 11, 15], [0, 0, 4, 8, 12, 13, 14, 15]], grid)


@pytest.mark.parametrize(
    "stride, kept",
    [
        (2, ([0, 2, 7, 15], [0, 4, 12, 14, 15])),
        (3, ([0, 3, 15], [0, 8, 14, 15])),
        (4, ([0, 7, 15], [0, 12, 15])),
        (10, ([0, 15], [0, 15])),
    ],
)
def test_coarse_observation_keeps_every_kth_state_and_the_last(walks, stride, kept):
    coarse = observe_every(walks, stride)
    assert isinstance(coarse, CoarseDemonstrations) and coarse.stride == stride
    assert [e.tolist() for e in coarse.episodes] == list(kept)
    src, dst = coarse.transitions()
    pairs = [(a, b) for e in kept for a, b in zip(e[:-1], e[1:])]
    assert list(zip(src.tolist(), dst.tolist())) == pairs
    assert coarse.num_transitions == len(pairs)


def test_coarse_transitions_join_states_k_primitive_steps_apart(world, policy):
    demos = record_demonstrations(world, policy, 6, seed=4)
    k = 5
    coarse = observe_every(demos, k)
    for full, seen in zip(demos.episodes, coarse.episodes, strict=True):
        at = observed_indices(len(full), k)
        assert torch.equal(seen, full[at])
        gaps = at.diff()
        assert (gaps[:-1] == k).all() and 1 <= int(gaps[-1]) <= k


def test_stride_one_is_the_demonstrations_themselves_and_zero_is_refused(walks):
    assert observe_every(walks, 1) is walks
    assert observed_indices(1, 3).tolist() == [0]
    for bad in (0, -2, 1.5):
        with pytest.raises(ValueError, match="stride"):
            observe_every(walks, bad)


def test_a_learner_takes_coarse_demonstrations_into_its_mentor_model(world, policy):
    demos = record_demonstrations(world, policy, 4, seed=1)
    coarse = observe_every(demos, 3)
    learner = Learner(world, learner_options(world), ["imitation"], [0], engine="torch")
    learner.add_demonstrations(coarse)
    with pytest.raises(ValueError):  # the full episodes are checked against the world
        coarse.check_world(MultiRooms(size=20, rooms=2, slip=0.3))
    src, _ = coarse.transitions()
    S = world.num_states
    expected = torch.bincount(src[src != world.goal_state], minlength=S).double()
    assert torch.equal(learner.mentor.row_count[0, :S].cpu(), expected)
    # the mentor term exists where the learner saw the mentor leave, not at skipped states
    skipped = set(torch.cat(demos.episodes).tolist()) - set(torch.cat(coarse.episodes).tolist())
    assert skipped and not learner.mentor.observed()[0, sorted(skipped)].any()


def test_a_first_leg_that_enters_the_goal_ends_the_episode_there():
    # the goal on the top row, between the start and the top-right waypoint
    w = MultiRooms(size=20, rooms=2, slip=0.3, goal=(1, 5))
    mentor = mentor_policy(w, mentor_options(w))
    detour = mentor_detour(w)
    demos = record_demonstrations(w, mentor, 40, seed=0, detour=detour, noise=0.5)
    passed = [bool((e == detour.waypoint).any()) for e in demos.episodes]
    assert any(passed) and not all(passed)
    for episode in demos.episodes:  # one visit to the goal, at the end
        assert episode[-1] == w.goal_state and not (episode[:-1] == w.goal_state).any()


# ------------------------------------------------------------- the mentor's preference cycles
def _slip_free_path(world: MultiRooms, mentor: MentorPolicy, steps: int) -> list[int]:
    """The cells where the mentor decides, from the start, when nothing slips."""
    ends = _nominal_ends(world, mentor.options, mentor.option)
    path = [world.start_state]
    while path[-1] != world.goal_state and len(path) < steps:
        path.append(int(ends[path[-1]]))
    return path


def test_break_cycles_frees_the_mentor_of_experiment_1s_maze():
    maze = MultiRooms(size=80, rooms=10, closed_doorways=maze_doorways(80, 10))
    options = mentor_options(maze, corners=True)
    trapped = mentor_policy(maze, options)
    path = _slip_free_path(maze, trapped, 500)
    assert path[-1] != maze.goal_state  # it goes round a cycle for ever
    assert set(path[-4:]) <= set(_on_cycles(_nominal_ends(maze, options, trapped.option)))
    freed = mentor_policy(maze, options, break_cycles=True)
    assert _on_cycles(_nominal_ends(maze, options, freed.option)) == []
    assert _slip_free_path(maze, freed, 500)[-1] == maze.goal_state
    rollout = run_mentor(maze, freed, 3, seed=0)
    assert all(e[-1] == maze.goal_state for e in rollout.states)
    # only states on cycles changed, to the strict optimum; the values are the same
    changed = freed.option != trapped.option
    strict = mentor_policy(maze, options, prefer_extended_within=0.0).option
    assert changed.any() and torch.equal(freed.option[changed], strict[changed])
    assert torch.equal(freed.values, trapped.values)


def test_the_paper_worlds_mentor_keeps_its_cycles_off_its_path_by_default():
    world = MultiRooms(size=80, rooms=10)
    options = mentor_options(world, corners=True)
    mentor = mentor_policy(world, options)
    cells = sorted(
        world.coords(s) for s in _on_cycles(_nominal_ends(world, options, mentor.option))
    )
    assert cells == [(1, 18), (2, 18), (18, 1), (18, 2)]  # two 2-cycles, documented
    assert _slip_free_path(world, mentor, 500)[-1] == world.goal_state


def test_a_coarse_mentor_term_is_the_one_step_term_of_a_k_step_move(grid):
    """What the docstring of ``himit_torch.mentor.observation`` says eq. 2 then does, solved by
    hand on the 4×4 room (slip 0, −0.01 a step, γ = 0.99): seen every 2nd state, the mentor's
    walk 0 → 1 → 2 → 3 → 7 → 11 → 15 is 0 → 2 → 7 → 15, so p_m(2 | 0) = 1 and the mentor
    term at 0 is r(2) + γ V(2) = −0.01 + 0.99 V(2), where the move really takes two steps:
    −0.01 − 0.99 · 0.01 + 0.99² V(2). With V(2) = V*(2) = −0.01 · (1 + 0.99 + 0.99²) + 0.99³
    (three steps to the goal, +1 on entering it) the term is higher by 0.0099 + 0.0099 V(2)."""
    from himit_torch.learner.backups import mentor_backup
    from himit_torch.mentor.reward import KnownReward

    coarse = observe_every(Demonstrations([[0, 1, 2, 3, 7, 11, 15]], grid), 2)
    learner = Learner(grid, learner_options(grid, doorways=False), ["imitation"], [0])
    learner.add_demonstrations(coarse)
    successors, probs = learner.mentor.mean(torch.tensor([0]), torch.tensor([0]))
    real = successors >= 0
    assert successors[real].tolist() == [2] and probs[real].tolist() == [1.0]
    v2 = -0.01 * (1 + 0.99 + 0.99**2) + 0.99**3
    r = KnownReward(grid).transition_reward(torch.tensor([0]), torch.tensor([2]))
    term = mentor_backup(r, torch.tensor([[1.0]], dtype=torch.float64), torch.tensor([[v2]]), 0.99)
    two_steps = -0.01 - 0.99 * 0.01 + 0.99**2 * v2
    assert float(term[0]) == pytest.approx(-0.01 + 0.99 * v2)
    assert float(term[0]) - two_steps == pytest.approx(0.0099 + 0.0099 * v2)
    assert float(term[0]) > two_steps  # optimistic: no longer a lower bound


# -------------------------------------------------------- observation at the mentor's option ends
def test_given_positions_keep_those_states_and_both_ends(walks):
    """Positions in any order, repeats allowed; the first and the last state always kept."""
    coarse = CoarseDemonstrations(walks, positions=[[3, 1, 3], torch.tensor([5])])
    assert coarse.stride is None and "positions given" in repr(coarse)
    assert [e.tolist() for e in coarse.episodes] == [[0, 1, 3, 15], [0, 13, 15]]
    # (walks: [0, 1, 2, 3, 7, 11, 15] and [0, 0, 4, 8, 12, 13, 14, 15])
    assert coarse.durations().tolist() == [1, 2, 3, 5, 2]
    src, dst = coarse.transitions()
    assert list(zip(src.tolist(), dst.tolist())) == [(0, 1), (1, 3), (3, 15), (0, 13), (13, 15)]


@pytest.mark.parametrize(
    "kwargs, error, match",
    [
        ({}, ValueError, "either stride or positions"),
        ({"stride": 2, "positions": [[1], [1]]}, ValueError, "either stride or positions"),
        ({"positions": [[1]]}, ValueError, "1 lists of positions for 2 episodes"),
        ({"positions": [[1], [8]]}, ValueError, r"positions\[1\]"),  # (episode 1 has 8 states)
        ({"positions": [[-1], [1]]}, ValueError, r"positions\[0\]"),
        ({"positions": [[1.5], [1]]}, ValueError, r"positions\[0\]"),
        ({"positions": [[True], [1]]}, ValueError, r"positions\[0\]"),
        ({"positions": "01"}, TypeError, "one sequence of positions per episode"),
        ({"positions": torch.tensor([[1], [1]])}, TypeError, "one sequence of positions"),
    ],
)
def test_bad_positions_are_refused(walks, kwargs, error, match):
    with pytest.raises(error, match=match):
        CoarseDemonstrations(walks, **kwargs)
    assert CoarseDemonstrations(walks, positions=[[1], [7]]).num_transitions == 3  # a valid one


@pytest.mark.parametrize("corners", [False, True])
def test_the_learner_sees_the_mentor_where_its_options_end(corners):
    """Each observed move is one of the mentor's options, from where it began to where it ended:
    the option may end there (β > 0), the first state is the start, the last the goal, and the
    moves' durations add up to the episode's steps."""
    world = MultiRooms(32, 4, slip=0.1)
    options = mentor_options(world, corners=corners)
    rollout = run_mentor(world, mentor_policy(world, options), episodes=5, seed=3)
    seen = observe_at_option_ends(rollout, world)
    assert seen.num_transitions < sum(len(s) - 1 for s in rollout.states)  # (fewer than all)
    for e, (states, steps, chosen) in enumerate(
        zip(rollout.states, rollout.decision_steps, rollout.decisions, strict=True)
    ):
        assert torch.equal(states[steps], rollout.decision_states[e])
        ends = torch.cat([steps[1:], torch.tensor([len(states) - 1])])
        assert torch.equal(seen.episodes[e], states[torch.cat([steps[:1], ends])])
        assert (options.termination[chosen, states[ends]] > 0).all()
        # between one option's start and its end, no state where it had to stop (β = 1) …
        for o, a, b in zip(chosen.tolist(), steps.tolist(), ends.tolist()):
            assert (options.termination[o, states[a + 1 : b]] < 1).all()
    assert int(seen.durations().sum()) == sum(len(s) - 1 for s in rollout.states)
    learner = Learner(world, learner_options(world), ["imitation"], [0], engine="torch")
    learner.add_demonstrations(seen)  # (with its durations: the segment term reads them)
    assert learner.mentor.observed()[0, seen.visited_states()[:-1]].any()


def test_observe_at_option_ends_takes_a_rollout(world, policy):
    demos = record_demonstrations(world, policy, 2, seed=0)
    with pytest.raises(TypeError, match="MentorRollout"):
        observe_at_option_ends(demos, world)
    rollout = run_mentor(world, policy, 2, seed=0)
    import dataclasses

    with pytest.raises(ValueError, match="decision_steps"):
        observe_at_option_ends(dataclasses.replace(rollout, decision_steps=()), world)
    assert observe_at_option_ends(rollout, world).num_episodes == 2
