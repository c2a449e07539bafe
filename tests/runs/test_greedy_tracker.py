"""The greedy tracker's checkpoint state: a round trip restores it, and what a file could plant is
refused by name (DamagedState) before anything is kept."""

import math
from types import SimpleNamespace

import pytest
import torch

from himit_torch.runs.greedy import _FIELDS, GreedyTracker
from himit_torch.state_checks import DamagedState


def _tracker(every: int = 5000, window: int = 5000) -> GreedyTracker:
    # (only the evaluator's window is read when restoring)
    return GreedyTracker(SimpleNamespace(window=window), None, every=every, steps=10_000)  # type: ignore[arg-type]


def _state(batch: int = 3) -> dict:
    steps = [5000, 10_000]
    return {"steps": steps, **{f: [torch.rand(batch).double() for _ in steps] for f in _FIELDS}}


def _learner(batch: int = 3, t: int = 10_000) -> SimpleNamespace:
    # (only the restored learner's batch and its step, a view, are read)
    return SimpleNamespace(batch=batch, views=SimpleNamespace(t=t))


def test_a_saved_state_is_restored_as_it_was():
    state = _state()
    tracker = _tracker()
    tracker.load_state_dict(state)
    assert sorted(tracker.evaluations) == [5000, 10_000]
    again = tracker.state_dict()
    assert again["steps"] == state["steps"]
    for f in _FIELDS:
        for a, b in zip(again[f], state[f]):
            assert torch.equal(a, b)


@pytest.mark.parametrize(
    "plant, field",
    [
        (lambda s: s.pop("goals_per_window"), "greedy"),
        (lambda s: s.update(extra=1), "greedy"),
        (lambda s: s.update(steps=[5000, -1]), "greedy.steps"),
        (lambda s: s.update(steps=[5000, 1.5]), "greedy.steps"),
        (lambda s: s["value_start"].pop(), "greedy.value_start"),
        (lambda s: s["reach_share"].__setitem__(0, torch.zeros(3)), "greedy.reach_share[0]"),
        (lambda s: s["reach_share"].__setitem__(1, [0.0, 0.0, 0.0]), "greedy.reach_share[1]"),
        (
            lambda s: s["goal_probability"].__setitem__(1, torch.zeros(4).double()),
            "goal_probability",
        ),
    ],
    ids=["missing", "unknown", "negative step", "float step", "short", "dtype", "list", "batch"],
)
def test_a_planted_state_is_refused_by_name_and_nothing_is_kept(plant, field):
    _assert_refused(plant, field)


def _assert_refused(plant, field: str) -> None:
    """``plant`` applied to a good state makes it refused, naming ``field``; nothing is kept."""
    state = _state()
    plant(state)
    tracker = _tracker()
    with pytest.raises(DamagedState, match=field.replace("[", r"\[").replace("]", r"\]")):
        tracker.load_state_dict(state)
    assert tracker.evaluations == {}


def _set(field: str, index: int, value) -> object:
    """A plant that puts ``value`` at entry 0 of step ``index``'s ``field`` tensor."""

    def plant(s: dict) -> None:
        s[field][index] = s[field][index].clone()
        s[field][index][0] = value

    return plant


#: Values no evaluation writes, per field (a NaN rate, a reach share of 5, …).
_OUT_OF_RANGE = {
    "goal_probability": [math.nan, 1.5, -0.1, math.inf],
    "goals_per_window": [math.nan, -1.0, 5001.0, math.inf],
    "reach_share": [math.nan, 5.0, -0.5, math.inf],
    "steps_per_episode": [math.nan, -1.0, -math.inf],
    "value_start": [math.inf, -math.inf],
}
_VALUES = [
    pytest.param(_set(f, i, v), f"greedy.{f}[{i}]", id=f"{f}[{i}]={v}")
    for f, values in _OUT_OF_RANGE.items()
    for v in values
    for i in (0, 1)
]
#: Step lists no run writes: a repeat, out of order, past the run's end, zero, not ints.
_STEPS = [[5000, 5000], [10_000, 5000], [5000, 20_000], [0, 5000], [5000, True], (5000, 10_000)]


@pytest.mark.parametrize("plant, field", _VALUES)
def test_a_value_no_evaluation_writes_is_refused_by_name(plant, field):
    _assert_refused(plant, field)


@pytest.mark.parametrize("steps", _STEPS, ids=repr)
def test_a_step_no_run_evaluates_at_is_refused(steps):
    state = _state()
    state["steps"] = steps
    tracker = _tracker()
    with pytest.raises(DamagedState, match="greedy.steps.*distinct step numbers"):
        tracker.load_state_dict(state)
    assert tracker.evaluations == {}


@pytest.mark.parametrize(
    "learner, says",
    [
        (_learner(batch=4), r"greedy.value_start\[0\].*not \[4\]"),  # 3 runs' tensors, 4 runs
        (_learner(batch=1), r"greedy.value_start\[0\].*not \[1\]"),
        (_learner(t=5000), r"greedy.steps.*reached, 5000"),  # an evaluation after the checkpoint
    ],
    ids=["batch of 4", "batch of 1", "a step never reached"],
)
def test_a_state_that_does_not_fit_the_restored_learner_is_refused(learner, says):
    tracker = _tracker()
    with pytest.raises(DamagedState, match=says):
        tracker.load_state_dict(_state(), learner)
    assert tracker.evaluations == {}


def test_what_evaluations_do_write_is_accepted():
    """NaN values (not solved), ``inf`` steps (an episode may never end), a zero rate, a rate of
    one goal a step, round-off past 1, and a state that fits its learner."""
    state = _state()
    state["value_start"][0][:] = math.nan
    state["steps_per_episode"][0][0] = math.inf
    state["goals_per_window"][0][0] = 0.0
    state["goals_per_window"][1][0] = 5000.0
    state["reach_share"][1][1] = 1 + 1e-12
    state["goal_probability"][1][2] = -1e-15
    tracker = _tracker()
    tracker.load_state_dict(state, _learner(batch=3, t=10_000))
    assert sorted(tracker.evaluations) == [5000, 10_000]
    assert math.isnan(tracker.evaluations[5000].value_start[0])


#: (every, window, steps saved): evaluations a tracker of that schedule never makes — not a
#: window's end, a window's end the schedule skips, any step but the end with every = 0.
_OFF_SCHEDULE = [
    (5000, 5000, [2500, 10_000]),
    (10_000, 5000, [5000, 10_000]),
    (0, 5000, [5000, 10_000]),
    (5000, 2000, [5000, 10_000]),
    (4000, 2000, [2000, 4000, 10_000]),
]
#: Their valid neighbours: the same trackers' own schedules.
_ON_SCHEDULE = [
    (5000, 5000, [5000, 10_000]),
    (10_000, 5000, [10_000]),
    (0, 5000, [10_000]),
    (5000, 2000, [6000, 10_000]),
    (4000, 2000, [4000, 8000, 10_000]),
]


@pytest.mark.parametrize("every, window, steps", _OFF_SCHEDULE)
def test_a_step_off_the_trackers_schedule_is_refused_naming_it(every, window, steps):
    state = _state()
    state = {"steps": steps, **{f: [state[f][0]] * len(steps) for f in _FIELDS}}
    tracker = _tracker(every, window)
    with pytest.raises(DamagedState, match=r"greedy.steps.*off this tracker's schedule") as err:
        tracker.load_state_dict(state)
    off = [s for s in steps if s != 10_000 and s not in dict.fromkeys(_own_schedule(every, window))]
    assert str(off[:1])[1:-1] in str(err.value) and f"every={every}" in str(err.value)
    assert tracker.evaluations == {}


def _own_schedule(every: int, window: int) -> list[int]:
    return next(s for e, w, s in _ON_SCHEDULE if (e, w) == (every, window))


@pytest.mark.parametrize("every, window, steps", _ON_SCHEDULE)
def test_the_trackers_own_schedule_is_restored(every, window, steps):
    state = _state()
    state = {"steps": steps, **{f: [state[f][0]] * len(steps) for f in _FIELDS}}
    tracker = _tracker(every, window)
    tracker.load_state_dict(state)
    assert sorted(tracker.evaluations) == steps
