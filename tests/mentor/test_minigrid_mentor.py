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
