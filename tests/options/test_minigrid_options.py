"""MiniGrid's "go to and face X" options, in the learner's and the mentor's styles."""

from __future__ import annotations

import pytest
import torch

pytest.importorskip("minigrid")

import himit_torch as ht  # noqa: E402
from himit_torch.worlds.minigrid import MINIGRID_ACTION_NAMES  # noqa: E402

LEFT = MINIGRID_ACTION_NAMES.index("left")


@pytest.fixture(scope="module")
def doorkey():
    return ht.from_minigrid("MiniGrid-DoorKey-5x5-v0")


def _follow(world, options, o, s, limit=200):
    """The states option ``o`` visits from ``s`` (deterministic world) until it terminates."""
    succ = world.dynamics_table().successors[:, :, -1]
    path = [s]
    for _ in range(limit):
        s = int(succ[s, int(options.policy[o, s])])
        path.append(s)
        if float(options.termination[o, s]) >= 1.0 or bool(world.terminal_mask[s]):
            return path
    raise AssertionError("the option did not terminate")


@pytest.mark.parametrize("style", ["learner", "mentor"])
def test_each_skill_ends_facing_its_object(doorkey, style):
    options = ht.minigrid_options(doorkey, style)
    targets = ht.minigrid_subgoals(doorkey)
    assert set(targets) == {"go to the yellow key", "go to the yellow door", "go to the goal"}
    front = doorkey.front_cell()
    for o, name in enumerate(options.names):
        if options.kinds[o] != "subgoal":
            continue
        mask = targets[name]
        assert not bool((options.initiation[o] & mask).any())  # usable outside its target
        for s in torch.nonzero(options.initiation[o]).flatten().tolist()[::7]:
            end = _follow(doorkey, options, o, s)[-1]
            assert bool(mask[end]), (name, s)
            cell = (
                doorkey.goal_cells[0]
                if name == "go to the goal"
                else int(doorkey.object_cell(name.removeprefix("go to the "))[end])
            )
            assert int(front[end]) == cell


def test_the_mentors_skills_never_turn_left_and_the_learners_do(doorkey):
    learner = ht.minigrid_options(doorkey, "learner")
    mentor = ht.minigrid_options(doorkey, "mentor")
    assert "primitive left" in learner.names and "primitive left" not in mentor.names
    m_skills = [o for o, k in enumerate(mentor.kinds) if k == "subgoal"]
    l_skills = [o for o, k in enumerate(learner.kinds) if k == "subgoal"]
    assert [mentor.names[o] for o in m_skills] == [learner.names[o] for o in l_skills]
    for o in m_skills:
        assert not bool((mentor.policy[o][mentor.initiation[o]] == LEFT).any())
    assert any(bool((learner.policy[o][learner.initiation[o]] == LEFT).any()) for o in l_skills)
    # the same subgoals through other states: somewhere the two styles' paths differ
    differ = 0
    for mo, lo in zip(m_skills, l_skills):
        common = torch.nonzero(mentor.initiation[mo] & learner.initiation[lo]).flatten()
        for s in common.tolist()[::5]:
            a, b = _follow(doorkey, mentor, mo, s), _follow(doorkey, learner, lo, s)
            differ += a != b
    assert differ > 0


def test_skills_need_primitives_in_between(doorkey):
    """From the start, the optimum with the learner's options uses skills and primitives."""
    options = ht.minigrid_options(doorkey)
    plan = ht.smdp_value_iteration(ht.option_models(doorkey, options))
    succ = doorkey.dynamics_table().successors[:, :, -1]
    s, kinds = doorkey.start_state, []
    while not bool(doorkey.terminal_mask[s]):
        o = int(plan.policy[s])
        kinds.append(options.kinds[o])
        s = (
            _follow(doorkey, options, o, s)[-1]
            if options.kinds[o] == "subgoal"
            else int(succ[s, int(options.policy[o, s])])
        )
    assert "subgoal" in kinds and "primitive" in kinds
    # the skills save decisions: fewer than the primitive steps the plan takes
    steps = ht.expected_steps(
        ht.option_durations(doorkey, options), plan.policy, 0, doorkey.terminal_mask
    )
    assert len(kinds) < steps


def test_refused(doorkey):
    with pytest.raises(ValueError, match="style"):
        ht.minigrid_options(doorkey, "robot")
    with pytest.raises(TypeError, match="from_minigrid"):
        ht.minigrid_options(ht.MultiRooms(10, 2))
