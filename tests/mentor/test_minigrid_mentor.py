"""The MiniGrid mentor: optimal for its own right-handed skills, reaching the goal."""

from __future__ import annotations

import pytest

pytest.importorskip("minigrid")

import himit_torch as ht  # noqa: E402


@pytest.fixture(scope="module")
def doorkey():
    return ht.from_minigrid("MiniGrid-DoorKey-5x5-v0")


def test_mentor_is_optimal_for_its_options_and_reaches_the_goal(doorkey):
    mentor = ht.minigrid_mentor(doorkey)
    options = mentor.options
    assert "primitive left" not in options.names
    rollout = ht.run_mentor(doorkey, mentor, episodes=3, seed=0)
    for states in rollout.states:
        assert bool(doorkey.goal_mask[states[-1]])
    counts = rollout.decision_counts()
    assert counts["subgoal"] > 0 and counts["primitive"] > 0
    # its expected steps are the optimum of its own options (within one step's cost of value)
    durations = ht.option_durations(doorkey, options)
    best = ht.smdp_value_iteration(ht.option_models(doorkey, options))
    mine = ht.expected_steps(durations, mentor.option, 0, doorkey.terminal_mask)
    optimum = ht.expected_steps(durations, best.policy, 0, doorkey.terminal_mask)
    assert mine == pytest.approx(optimum)
    # and never better than the learner's, who can also turn left
    learner = ht.minigrid_options(doorkey)
    plan = ht.smdp_value_iteration(ht.option_models(doorkey, learner))
    assert float(plan.values[0]) >= float(best.values[0]) - 1e-12
    demos = ht.record_demonstrations(doorkey, mentor, episodes=2, seed=1)
    assert len(demos.episodes) == 2


def test_refused():
    with pytest.raises(TypeError, match="from_minigrid"):
        ht.minigrid_mentor(ht.MultiRooms(10, 2))


def test_demonstrations_in_another_task_of_the_same_layout(doorkey):
    moved = ht.from_minigrid("MiniGrid-DoorKey-5x5-v0", goal=(3, 2))
    mentor = ht.minigrid_mentor(moved)
    demos = ht.record_demonstrations(moved, mentor, 3, seed=0)
    seen = ht.demonstrations_in(doorkey, demos, moved)
    assert isinstance(seen, ht.Demonstrations) and seen.num_episodes == 3
    for before, after in zip(demos.episodes, seen.episodes):
        assert [moved.state_key(s) for s in before.tolist()] == [
            doorkey.state_key(s) for s in after.tolist()
        ]
        # the mentor's goal (3, 2) is a floor cell of the learner's task: no goal reached
        assert not bool(doorkey.terminal_mask[after].any())
        assert doorkey.state_key(int(after[-1]))[:2] == (3, 2)
    # coarse demonstrations keep their positions and durations
    rollout = ht.run_mentor(moved, mentor, 2, seed=1)
    ends = ht.observe_at_option_ends(rollout, moved)
    seen_ends = ht.demonstrations_in(doorkey, ends, moved)
    assert seen_ends.durations().tolist() == ends.durations().tolist()
    assert [len(e) for e in seen_ends.episodes] == [len(e) for e in ends.episodes]
    assert doorkey.states_from(moved, ends.episodes[0]).tolist() == seen_ends.episodes[0].tolist()


def test_demonstrations_in_refused(doorkey):
    moved = ht.from_minigrid("MiniGrid-DoorKey-5x5-v0", goal=(3, 2))
    # MiniGrid's mentor walks through (3, 2) to (3, 3): not a route of the moved task
    own = ht.record_demonstrations(doorkey, ht.minigrid_mentor(doorkey), 1, seed=0)
    with pytest.raises(ValueError, match="not reachable"):
        ht.demonstrations_in(moved, own, doorkey)
    with pytest.raises(TypeError, match="Demonstrations"):
        ht.demonstrations_in(doorkey, [[0, 1]], moved)
    with pytest.raises(TypeError, match="from_minigrid"):
        ht.demonstrations_in(ht.MultiRooms(8, 2), own, doorkey)
