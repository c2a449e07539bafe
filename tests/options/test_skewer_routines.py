"""Skewer routines: found in a mentor's puzzle-box episodes, described relative to the skewer
they act on, and built for every skewer of a larger box — one the mentor never touched
included. Checked by hand on short episodes, and against the exact option models."""

import pytest
import torch

from himit_torch.exact.option_models import option_durations, option_models
from himit_torch.mentor.policy import record_demonstrations
from himit_torch.mentor.puzzle_box import organisation_mentor
from himit_torch.options.puzzle_box import intended_rollout
from himit_torch.options.skewer_routines import (
    SkewerRoutine,
    discover_skewer_routines,
    skewer_routine_options,
    skewer_segments,
)
from himit_torch.worlds.puzzle_box import PuzzleBox


@pytest.fixture(scope="module")
def mentor_box() -> PuzzleBox:
    """The mentor's box: 2 skewers of 2 steps (63 states)."""
    return PuzzleBox(skewers=2, steps=2)


@pytest.fixture(scope="module")
def learner_box() -> PuzzleBox:
    """The learner's box: a third skewer the mentor never touched (3 · 3³ … 270 states)."""
    return PuzzleBox(skewers=3, steps=2)


def _walk(box: PuzzleBox, plan: list[tuple]) -> list[int]:
    """States of a hand-written episode: each entry ``(levels, skewer or None, grasp)``."""
    return [box.encode(list(p), at, g) for p, at, g in plan]


def _skewer_by_skewer(box):
    """Skewer 1 out (two steps, hand home between), then skewer 2, in a pinch."""
    return _walk(box, [
        ((0, 0), None, "open"), ((0, 0), 0, "open"), ((0, 0), 0, "pinch"), ((1, 0), None, "open"),
        ((1, 0), 0, "open"), ((1, 0), 0, "pinch"), ((2, 0), None, "open"),
        ((2, 0), 1, "open"), ((2, 0), 1, "pinch"), ((2, 1), None, "open"),
        ((2, 1), 1, "open"), ((2, 1), 1, "pinch"), ((2, 2), None, "open"),
    ])  # fmt: skip


def _step_by_step(box):
    """Step 1 on skewers 1 and 2, then step 2 on each; skewer 2's second step undone by a slip
    once and done again (its segment's net change stays 1 → 2)."""
    return _walk(box, [
        ((0, 0), None, "open"), ((0, 0), 0, "open"), ((0, 0), 0, "pinch"), ((1, 0), None, "open"),
        ((1, 0), 1, "open"), ((1, 0), 1, "pinch"), ((1, 1), None, "open"),
        ((1, 1), 0, "open"), ((1, 1), 0, "pinch"), ((2, 1), None, "open"),
        ((2, 1), 1, "open"), ((2, 1), 1, "pinch"), ((2, 0), None, "open"),
        ((2, 0), 1, "open"), ((2, 0), 1, "pinch"), ((2, 1), None, "open"),
        ((2, 1), 1, "open"), ((2, 1), 1, "pinch"), ((2, 2), None, "open"),
    ])  # fmt: skip


def test_segments_split_where_the_hand_goes_to_another_skewer(mentor_box):
    """Hand-solved: the skewer-by-skewer episode is two segments (skewer 1: 0 → 2, skewer 2:
    0 → 2); the step-by-step one four, the undo inside skewer 2's last segment netted out."""
    assert skewer_segments(mentor_box, _skewer_by_skewer(mentor_box)) == [(0, 0, 2), (1, 0, 2)]
    assert skewer_segments(mentor_box, _step_by_step(mentor_box)) == [
        (0, 0, 1), (1, 0, 1), (0, 1, 2), (1, 1, 2),
    ]  # fmt: skip


def test_a_skewer_by_skewer_mentor_yields_the_whole_skewer(mentor_box):
    routines = discover_skewer_routines(mentor_box, [_skewer_by_skewer(mentor_box)] * 3)
    assert routines == (SkewerRoutine(0, 2, 6),)


def test_a_step_by_step_mentor_yields_one_routine_per_step(mentor_box):
    routines = discover_skewer_routines(mentor_box, [_step_by_step(mentor_box)])
    assert routines == (SkewerRoutine(0, 1, 2), SkewerRoutine(1, 2, 2))


@pytest.mark.slow  # (3 s: two mentors planned on the 4-skewer box; hand-made episodes above)
def test_the_organisation_mentors_recorded_episodes():
    """On the study's box (4 skewers of 4 steps), each seed's recorded episodes give the
    organisation's routines: 4 segments an episode per routine, slips and undos included."""
    box = PuzzleBox(4)
    for organisation, expected in (("skewer", [(0, 4)]), ("step", [(j, j + 1) for j in range(4)])):
        demos = record_demonstrations(box, organisation_mentor(box, organisation), 5, seed=3)
        routines = discover_skewer_routines(box, demos)
        assert [(r.start, r.end) for r in routines] == expected
        assert all(r.segments == 4 * 5 for r in routines)


def test_nothing_from_a_mentor_that_never_advances_a_skewer(mentor_box):
    """An episode that stays home, and one that reaches a skewer, grips it and withdraws: no
    segment advances a skewer, so no routine (and no options can be built from none)."""
    home = [0, 0, 0]
    touch = _walk(mentor_box, [((0, 0), None, "open"), ((0, 0), 1, "open"),
                               ((0, 0), 1, "power"), ((0, 0), None, "open")])  # fmt: skip
    assert skewer_segments(mentor_box, home) == []
    assert skewer_segments(mentor_box, touch) == [(1, 0, 0)]
    assert discover_skewer_routines(mentor_box, [home, touch]) == ()
    with pytest.raises(ValueError, match="no routines"):
        skewer_routine_options(mentor_box, ())


def test_routines_exist_for_a_skewer_the_mentor_never_touched(mentor_box, learner_box):
    demos = [_skewer_by_skewer(mentor_box)]
    assert {x for ep in demos for x, _, _ in skewer_segments(mentor_box, ep)} == {0, 1}
    options = skewer_routine_options(learner_box, discover_skewer_routines(mentor_box, demos))
    assert options.names == ("skewer 1: 0 → 2", "skewer 2: 0 → 2", "skewer 3: 0 → 2")
    assert options.kinds == ("subgoal",) * 3
    # usable where its skewer is in and the hand home, whatever the others hold
    start = learner_box.encode([2, 1, 0])
    assert bool(options.initiation[2, start])
    assert not bool(options.initiation[2, learner_box.encode([2, 1, 1])])
    assert not bool(options.initiation[2, learner_box.encode([0, 0, 0], 2, "open")])


def test_the_whole_skewer_routine_followed_takes_skewer_3_out(learner_box):
    """Hand-solved, without slips: reach 3, power grip, motion 1 (level 1, hand home), reach 3,
    power grip, motion 2 (out): six movements, the other skewers untouched, the learner's grip
    (power) only."""
    options = skewer_routine_options(learner_box, [SkewerRoutine(0, 2)])
    start = learner_box.encode([1, 0, 0])
    intended = learner_box.dynamics_table().successors[:, :, -1]
    s, path, actions = start, [start], []
    while float(options.termination[2, s]) < 1.0:
        a = int(options.policy[2, s])
        actions.append(learner_box.action_names[a])
        s = int(intended[s, a])
        path.append(s)
    assert actions == ["reach 3", "power grip", "motion 1", "reach 3", "power grip", "motion 2"]
    assert learner_box.decode(s) == ((1, 0, 2), None, None)
    assert learner_box.grasps_used(path) == ["power", "power"]


def test_the_lifted_routine_ends_only_on_its_skewers_target_with_slips(learner_box):
    """Exact option models (slips included, γ = 1): from every start, the routine on skewer 3
    ends with probability 1 at skewer 3 on level ``end``, the hand home and the other skewers as
    they were; its expected duration is the same on every skewer and whatever the others hold
    (the dynamics are local)."""
    options = skewer_routine_options(learner_box, [SkewerRoutine(0, 2), SkewerRoutine(1, 2)])
    models = option_models(learner_box, options, gamma=1.0)
    durations = option_durations(learner_box, options)
    levels = learner_box.progress(torch.arange(learner_box.num_states))
    transition = models.transition.to_dense()
    by_option: dict = {}
    for row in range(models.num_rows):
        o, s = int(models.row_option[row]), int(models.row_state[row])
        routine, skewer = divmod(o, learner_box.skewers)
        end = 2  # both routines end with the skewer out
        mass = transition[row]
        assert float(mass.sum()) == pytest.approx(1.0)
        landed = mass.nonzero()[:, 0]
        assert bool(learner_box.home_mask[landed].all())
        assert (levels[landed, skewer] == end).all()
        others = [x for x in range(learner_box.skewers) if x != skewer]
        assert (levels[landed][:, others] == levels[s, others]).all()
        by_option.setdefault(routine, set()).add(round(float(durations.reward[row]), 9))
    assert len(by_option[0]) == 1 and len(by_option[1]) == 1  # one duration per routine
    assert by_option[0].pop() > by_option[1].pop() > 3.0  # two steps take longer than one


def test_a_learner_with_routines_opens_the_larger_box(mentor_box, learner_box):
    """The rollout helper follows a policy of routines, one skewer after the other (slips off)."""
    options = skewer_routine_options(
        learner_box, discover_skewer_routines(mentor_box, [_skewer_by_skewer(mentor_box)])
    )
    policy = torch.full((learner_box.num_states,), -1)
    for s in range(learner_box.num_states):
        usable = options.initiation[:, s].nonzero()[:, 0]
        if usable.numel():
            policy[s] = int(usable[0])
    states, opened = intended_rollout(learner_box, options, policy)
    assert opened
    assert learner_box.subgoals(states) == [(0, 1), (0, 2), (1, 1), (1, 2), (2, 1), (2, 2)]


def test_bad_inputs(mentor_box, learner_box):
    with pytest.raises(TypeError, match="PuzzleBox"):
        discover_skewer_routines("box", [[0]])  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="at least one episode"):
        discover_skewer_routines(mentor_box, [])
    with pytest.raises(ValueError):
        discover_skewer_routines(mentor_box, [[0, mentor_box.num_states]])
    with pytest.raises(ValueError, match="list of episodes"):
        discover_skewer_routines(mentor_box, "episodes")
    with pytest.raises(TypeError, match="SkewerRoutine"):
        skewer_routine_options(learner_box, [(0, 2)])
    with pytest.raises(ValueError, match="beyond the box's 2 steps"):
        skewer_routine_options(learner_box, [SkewerRoutine(0, 4)])
    with pytest.raises(ValueError, match="start < end"):
        SkewerRoutine(2, 2)
    with pytest.raises(ValueError, match="whole number"):
        SkewerRoutine(0, 1.5)  # type: ignore[arg-type]
