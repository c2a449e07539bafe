"""The compiled engine closes each window inside its kernel: the records are the same however a
run's steps are split into calls (a window's end inside a call, at its end, or between calls),
with a progress bar or without, and with edge lists that grow on the way."""

import pytest
import torch

from himit_torch import Learner, LearnerConfig, learner_options

pytest.importorskip("numba")

AGENTS = ["imitation", "options", "primitives", "imitation_confident"]


def _learner(world, demos) -> Learner:
    return Learner(
        world,
        learner_options(world),
        AGENTS,
        [0, 1, 2, 3],
        config=LearnerConfig(window=500),
        demonstrations=demos,
        engine="numba",
    )


def _records(learner: Learner) -> dict:
    m = learner.metrics.state_dict()
    return {k: v if k == "steps" else torch.stack(v) for k, v in m.items()}


def _assert_same(a: dict, b: dict) -> None:
    assert a["steps"] == b["steps"]
    for name in a:
        if name != "steps":
            torch.testing.assert_close(a[name], b[name], rtol=0, atol=0, equal_nan=True)


@pytest.mark.parametrize(
    "chunks",
    [[3100, 1900], [500] * 10, [1, 499, 1499, 3001], [97] * 52],
    ids=["across", "at-ends", "odd", "small"],
)
def test_windows_do_not_depend_on_how_a_run_is_split(world12, mentor_demos12, chunks):
    whole = _learner(world12, mentor_demos12)
    whole.run(sum(chunks))
    split = _learner(world12, mentor_demos12)
    for ticks in chunks:
        split.run(ticks)
    a, b = _records(whole), _records(split)
    assert a["steps"] == [500 * (i + 1) for i in range(sum(chunks) // 500)]
    _assert_same(a, b)
    # the window counters were reset at the last window's end: what is left is the open window
    assert torch.equal(whole.run_state.window_goals, split.run_state.window_goals)
    # something was recorded: goals, and the mentor term's share where a mentor was seen
    assert int(a["goals_in_window"].sum()) > 0
    assert a["mentor_term_wins"][-1, 0].isfinite()
    assert a["mentor_term_wins"][:, 1:3].isnan().all()  # options, primitives: no mentor term


def test_a_progress_bar_records_the_same_windows(world12, mentor_demos12):
    quiet, shown = _learner(world12, mentor_demos12), _learner(world12, mentor_demos12)
    quiet.run(1500)
    shown.run(1500, progress=True)
    _assert_same(_records(quiet), _records(shown))


def test_the_records_are_those_of_the_run_state_at_each_windows_end(world12, mentor_demos12):
    """A call that ends at a window's end leaves the run state as the kernel recorded it: each
    record is the run state's counters there, the window counters reset, and the windows' goals
    add up to the run's."""
    learner = _learner(world12, mentor_demos12)
    for w in range(1, 9):
        learner.run(500 if w % 2 else 499)
        if learner.views.t % 500:
            learner.run(1)
        m, run = learner.metrics, learner.run_state
        assert m.steps[-1] == 500 * w == learner.views.t
        assert torch.equal(m.episodes[-1], run.episodes)
        assert torch.equal(m.backups[-1], run.backups_done)
        assert torch.equal(m.decisions[-1], run.decisions)
        assert torch.equal(m.epsilon[-1], run.epsilon)
        assert int(run.window_goals.abs().sum() + run.window_episodes.abs().sum()) == 0
        assert torch.equal(torch.stack(m.goals_in_window).sum(0), run.goals)
    assert int(run.goals.sum()) > 0


def test_the_linked_lists_kept_across_growths_are_those_a_rebuild_gives(world12, mentor_demos12):
    """The kernel links each edge it adds into the engine's lists as it goes, across the edge
    lists' growths: at the end they must be the lists :func:`link_edges` builds from the edges."""
    import numpy as np

    learner = _learner(world12, mentor_demos12)
    model = learner.state.model
    capacities = {model.capacity}
    for _ in range(12):
        learner.run(500)
        capacities.add(model.capacity)
    assert len(capacities) >= 3, capacities  # it grew at least twice on the way
    engine = learner.engine
    kept = engine._linked("model", model)
    assert kept[1].shape[1] == model.capacity
    engine.invalidate()  # (forgets the lists: the next call relinks every edge)
    rebuilt = engine._linked("model", model)
    assert kept[1] is not rebuilt[1]
    for a, b in zip(kept, rebuilt):
        np.testing.assert_array_equal(a, b)
