"""The greedy tracker's checkpoint state: a round trip restores it, and what a file could plant is
refused by name (DamagedState) before anything is kept."""

from types import SimpleNamespace

import pytest
import torch

from himit_torch.runs.greedy import _FIELDS, GreedyTracker
from himit_torch.state_checks import DamagedState


def _tracker() -> GreedyTracker:
    # (only the evaluator's window is read when restoring)
    return GreedyTracker(SimpleNamespace(window=5000), None, every=0, steps=10_000)  # type: ignore[arg-type]


def _state(batch: int = 3) -> dict:
    steps = [5000, 10_000]
    return {"steps": steps, **{f: [torch.rand(batch).double() for _ in steps] for f in _FIELDS}}


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
    state = _state()
    plant(state)
    tracker = _tracker()
    with pytest.raises(DamagedState, match=field.replace("[", r"\[").replace("]", r"\]")):
        tracker.load_state_dict(state)
    assert tracker.evaluations == {}
