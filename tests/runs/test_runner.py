"""The runner core (``himit_torch.runs.runner``): the window loop, its hooks and checkpoints, and the
run-directory checks every experiment shares."""

import pytest
import torch

from himit_torch.learner.config import LearnerConfig
from himit_torch.learner.learner import Learner
from himit_torch.mentor.policy import record_demonstrations
from himit_torch.options.builders import learner_options, mentor_options
from himit_torch.runs.checkpoints import BatchShape
from himit_torch.runs.runner import (
    Checkpoints,
    Maps,
    batch_runs,
    check_run_dir,
    run_names,
    run_windows,
    watch_demonstrations,
)


def batch(world, window: int = 25) -> Learner:
    seeds, agents, run_seeds = batch_runs(("imitation", "options"), 3, 2)
    learner = Learner(
        world,
        learner_options(world),
        agents,
        run_seeds,
        config=LearnerConfig(window=window),
        engine="torch",
    )
    demos = {s: record_demonstrations(world, mentor_options(world), 2, seed=s) for s in seeds}
    watch_demonstrations(learner, demos)
    return learner


def test_batch_runs_are_agent_major_and_named_per_run():
    seeds, agents, run_seeds = batch_runs(("a", "b"), 3, 2)
    assert (seeds, agents, run_seeds) == ([3, 4], ["a", "a", "b", "b"], [3, 4, 3, 4])
    assert run_names("world8", agents, run_seeds) == [
        "world8__a__seed3",
        "world8__a__seed4",
        "world8__b__seed3",
        "world8__b__seed4",
    ]


def test_hooks_see_every_window_once_in_order_and_the_run_stops_at_its_step(world8):
    learner = batch(world8)
    seen = []
    run_windows(
        learner,
        90,
        on_window=[
            lambda lr, i: seen.append(("first", i, lr.views.t)),
            lambda lr, i: seen.append(("second", i, lr.views.t)),
        ],
    )
    assert learner.views.t == 90
    assert seen == [(h, i, 25 * (i + 1)) for i in range(3) for h in ("first", "second")]
    # going on from where it stopped: the window it was in, then the next ones
    run_windows(learner, 125, on_window=[lambda lr, i: seen.append(("later", i, lr.views.t))])
    assert seen[6:] == [("later", 3, 100), ("later", 4, 125)]


def test_a_run_advanced_in_pieces_is_the_run_advanced_at_once(world8):
    whole, pieces = batch(world8), batch(world8)
    run_windows(whole, 100)
    for stop in (25, 75, 100):
        run_windows(pieces, stop)
    assert whole.metrics.steps == pieces.metrics.steps
    assert torch.equal(whole.views.goals, pieces.views.goals)
    assert torch.equal(whole.views.state_values(), pieces.views.state_values())
    assert torch.equal(whole.views.visit_counts(), pieces.views.visit_counts())


def test_checkpoints_on_their_schedule_and_a_resumed_run_goes_on_as_if_never_stopped(
    world8, tmp_path
):
    learner = batch(world8)
    shape = BatchShape(tuple(learner.agents), tuple(learner.seeds), world8.num_states)
    saved = []
    checkpoints = Checkpoints(tmp_path / "world8.pt", shape, every=50)
    save = checkpoints.save
    checkpoints.save = lambda lr, elapsed: (saved.append(lr.views.t), save(lr, elapsed))  # type: ignore[method-assign]
    assert checkpoints.start(learner, resume=False) == 0.0
    run_windows(learner, 125, checkpoints=checkpoints)
    assert saved == [50, 100, 125]

    resumed = batch(world8)
    elapsed = Checkpoints(tmp_path / "world8.pt", shape, every=50).start(resumed, resume=True)
    assert resumed.views.t == 125 and elapsed > 0
    run_windows(learner, 175)
    assert run_windows(resumed, 175, elapsed=elapsed) >= elapsed
    assert torch.equal(learner.views.state_values(), resumed.views.state_values())
    assert torch.equal(learner.views.goals, resumed.views.goals)


def test_a_fresh_start_clears_the_generations_of_an_earlier_run(world8, tmp_path):
    learner = batch(world8)
    shape = BatchShape(tuple(learner.agents), tuple(learner.seeds), world8.num_states)
    checkpoints = Checkpoints(tmp_path / "world8.pt", shape, every=25)
    run_windows(learner, 50, checkpoints=checkpoints)
    fresh = batch(world8)
    Checkpoints(tmp_path / "world8.pt", shape, every=25).start(fresh, resume=False)
    assert Checkpoints(tmp_path / "world8.pt", shape, every=25).start(fresh, resume=True) == 0.0
    assert fresh.views.t == 0


def test_maps_need_a_logger(world8):
    with pytest.raises(ValueError, match="logger"):
        run_windows(batch(world8), 25, maps=Maps([0], 25))


def test_run_dir_checks(tmp_path):
    check_run_dir(tmp_path, force=False)  # empty: fine for every runner
    (tmp_path / "config.json").write_text("{}")
    check_run_dir(tmp_path, force=False)  # unfinished, a runner without resume: starts over
    check_run_dir(tmp_path, force=False, resume=True)
    with pytest.raises(ValueError, match="unfinished run; pass --resume"):
        check_run_dir(tmp_path, force=False, resume=False)
    (tmp_path / "results.md").write_text("done")
    for resume in (None, False):
        with pytest.raises(ValueError, match="already holds a finished run"):
            check_run_dir(tmp_path, force=False, resume=resume)
    check_run_dir(tmp_path, force=False, resume=True)
    check_run_dir(tmp_path, force=True, resume=False)
