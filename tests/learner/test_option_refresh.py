"""Continuing a learner's runs with a new option set (himit_torch.learner.option_refresh): what is kept is
kept exactly, what changed starts empty, and a swap that changes nothing a run can use changes
nothing about the run — on both engines, and through a checkpoint."""

import pytest
import torch

from himit_torch import Learner, LearnerConfig, MultiRooms, Options, learner_options
from himit_torch.learner.option_refresh import (
    option_correspondence,
    row_correspondence,
    with_options,
)
from himit_torch.options.builders import primitive_options

pytest.importorskip("numba")

ENGINES = ["numba", "torch"]
#: The tests that run each engine on its own: the torch engine's runs (minutes of eager ticks) go
#: under -m slow; test_a_swap_moves_runs_between_engines_and_variants keeps it in the fast suite.
EACH_ENGINE = ["numba", pytest.param("torch", marks=[pytest.mark.slow, pytest.mark.extended])]
CONFIG = LearnerConfig(window=1000)
MIX = ["imitation", "options", "imitation_confident", "primitives", "imitation_primitives"]


def _state(learner: Learner) -> dict[str, torch.Tensor]:
    run, cache, model = learner.run_state, learner.cache, learner.model
    out = {name: getattr(run, name) for name in run._STATE}
    out.update(
        values=cache.values,
        q_numerator=cache.q_numerator,
        q_second=cache.q_second,
        mentor_numerator=cache.mentor_numerator,
        priority=learner.sweeper.queue.priority,
        pending=learner.sweeper.pending,
        row_count=model.row_count,
        row_reward=model.row_reward,
        state_tries=model.state_tries,
        num_edges=model.num_edges,
        curve=learner.metrics.curve(),
    )
    E = int(model.num_edges.max())
    for name in ("edge_row", "edge_successor", "edge_count", "edge_discount"):
        out[name] = getattr(model, name)[:, :E]
    return out


def assert_same(a: Learner, b: Learner) -> None:
    """Bit for bit: every counter, model entry, cache and queue entry. Rows are compared by their
    ``(state, option)`` where ``b``'s option set extends ``a``'s (its other rows must be empty)."""
    assert a.views.t == b.views.t
    sa, sb = _state(a), _state(b)
    if b.num_rows != a.num_rows:
        A = a.world.num_actions
        to_b = row_correspondence(a, b, option_correspondence(a.options, b.options, A))
        to_a = torch.full((b.num_rows + 1,), -1, dtype=torch.int64)
        to_a[to_b] = torch.arange(a.num_rows + 1)
        rest = torch.ones(b.num_rows + 1, dtype=torch.bool)
        rest[to_b] = False
        for name in ("row_count", "row_reward", "q_numerator", "q_second"):
            assert float(sb[name][:, rest].abs().sum()) == 0.0, name
            sb[name] = sb[name][:, to_b]
        sb["row"] = to_a[sb["row"]]
        sb["edge_row"] = torch.where(sb["edge_row"] >= 0, to_a[sb["edge_row"]], sb["edge_row"])
    for name in sa:
        assert torch.equal(sa[name], sb[name]), name


def _make(world, options, agents, demos, engine, seeds=None):
    return Learner(
        world,
        options,
        agents,
        list(range(len(agents))) if seeds is None else seeds,
        config=CONFIG,
        demonstrations=demos,
        engine=engine,
    )


@pytest.mark.parametrize("engine", EACH_ENGINE)
def test_swapping_to_the_same_options_continues_the_run_exactly(world12, mentor_demos12, engine):
    options = learner_options(world12)
    straight = _make(world12, options, MIX, mentor_demos12, engine)
    straight.run(3000)
    first = _make(world12, options, MIX, mentor_demos12, engine)
    first.run(1500)
    before = {k: v.clone() for k, v in _state(first).items()}
    swapped = with_options(first, options)
    assert_same(first, swapped)  # nothing changed at the swap itself
    swapped.run(1500)
    assert_same(straight, swapped)
    # the old learner is left as it was
    assert first.views.t == 1500 and all(
        torch.equal(before[k], v) for k, v in _state(first).items()
    )
    assert int(straight.views.goals.sum()) > 0


@pytest.mark.parametrize("engine", EACH_ENGINE)
def test_runs_that_cannot_use_the_new_options_are_not_changed(world12, mentor_demos12, engine):
    """Primitives-only runs, swapped to primitives + doorway options (which their variants do not
    use): the same run as without the swap; their primitive rows carried over as they were."""
    prims = primitive_options(world12)
    agents = ["primitives", "imitation_primitives"]
    straight = _make(world12, prims, agents, mentor_demos12, engine)
    straight.run(2400)
    first = _make(world12, prims, agents, mentor_demos12, engine)
    first.run(1200)
    richer = learner_options(world12)
    swapped = with_options(first, richer)
    assert swapped.num_options > first.num_options
    # the primitive rows hold what they held
    new_rows = swapped.rows
    key_new = new_rows.row_state[:-1] * swapped.num_options + new_rows.row_option[:-1]
    for r_old in range(first.num_rows):
        s, o = int(first.rows.row_state[r_old]), int(first.rows.row_option[r_old])
        r_new = int(torch.searchsorted(key_new, s * swapped.num_options + o))
        assert int(new_rows.row_state[r_new]) == s and int(new_rows.row_option[r_new]) == o
        assert torch.equal(swapped.model.row_count[:, r_new], first.model.row_count[:, r_old])
        assert torch.equal(swapped.model.row_reward[:, r_new], first.model.row_reward[:, r_old])
        assert torch.equal(swapped.cache.q_numerator[:, r_new], first.cache.q_numerator[:, r_old])
    assert torch.equal(
        swapped.model.edge_count, first.model.edge_count[:, : swapped.model.capacity]
    )
    swapped.run(1200)
    assert_same(straight, swapped)


@pytest.mark.parametrize("engine", EACH_ENGINE)
def test_changed_options_start_empty_and_an_option_in_flight_ends(world12, mentor_demos12, engine):
    options = learner_options(world12)
    first = _make(world12, options, ["imitation", "options"] * 3, mentor_demos12, engine)
    first.run(1000)
    # ten more ticks until some run is in the middle of an extended option
    for _ in range(200):
        in_flight = (first.run_state.duration > 0) & ~first.options.is_primitive[
            first.rows.row_option[first.run_state.row]
        ]
        if bool(in_flight.any()):
            break
        first.step()
    assert bool(in_flight.any())
    # change every extended option's policy at one state of its initiation set
    policy = options.policy.clone()
    changed = []
    for o in range(options.num_options):
        if options.kinds[o] != "primitive":
            s = int(options.initiation[o].nonzero()[0])
            policy[o, s] = (int(policy[o, s]) + 1) % world12.num_actions
            changed.append(o)
    altered = Options(options.initiation, options.termination, policy, options.names, options.kinds)
    corr = option_correspondence(options, altered, world12.num_actions)
    assert corr.tolist() == [o if o not in changed else -1 for o in range(options.num_options)]
    swapped = with_options(first, altered)
    ext_rows = ~altered.is_primitive[swapped.rows.row_option]
    assert float(swapped.model.row_count[:, ext_rows].abs().sum()) == 0.0
    assert float(swapped.cache.q_numerator[:, ext_rows].abs().sum()) == 0.0
    assert bool((swapped.model.row_count[:, ~ext_rows].sum(1) > 0).all())
    run = swapped.run_state
    assert torch.equal(run.duration[in_flight], torch.zeros_like(run.duration[in_flight]))
    assert torch.equal(run.option_start, run.position) or bool((run.duration == 0).any())
    assert torch.equal(swapped.rows.row_state[run.row[in_flight]], run.position[in_flight])
    # the rest of the run state is carried
    for name in ("goals", "episodes", "epsilon", "decisions", "visits", "first_goal_step"):
        assert torch.equal(getattr(run, name), getattr(first.run_state, name)), name
    assert torch.equal(swapped.views.state_values(), first.views.state_values())
    # carried Q numerators are what a recomputation from the models gives (up to rounding)
    q = swapped.cache.q_numerator.clone()
    swapped.cache.rebuild_options()
    torch.testing.assert_close(swapped.cache.q_numerator, q, atol=1e-9, rtol=0)
    swapped.cache.q_numerator.copy_(q)
    # deterministic: the same swap again gives the same continuation
    again = with_options(first, altered)
    swapped.run(800)
    again.run(800)
    assert_same(swapped, again)


def test_a_swap_moves_runs_between_engines_and_variants(world12, mentor_demos12):
    """Carry some runs to a new learner with new variants; the engines continue identically."""
    prims = primitive_options(world12)
    first = _make(
        world12,
        prims,
        ["primitives", "imitation_primitives", "primitives"],
        mentor_demos12,
        "numba",
    )
    first.run(1500)
    richer = learner_options(world12)
    out = {
        engine: with_options(
            first, richer, runs=[2, 1], agents=["options", "imitation"], engine=engine
        )
        for engine in ENGINES
    }
    assert out["numba"].agents == ["options", "imitation"] and out["numba"].seeds == [2, 1]
    assert torch.equal(out["numba"].views.state_values(), first.views.state_values()[[2, 1]])
    for learner in out.values():
        learner.run(600)  # (the torch engine's ticks are the test's cost)
    assert_same(out["numba"], out["torch"])
    ext = ~richer.is_primitive[out["numba"].rows.row_option]
    assert float(out["numba"].model.row_count[:, ext].sum()) > 0  # the new options were used


@pytest.mark.parametrize("engine", EACH_ENGINE)
def test_checkpoint_after_a_swap_resumes_exactly(world12, mentor_demos12, engine):
    prims = primitive_options(world12)
    richer = learner_options(world12)
    first = _make(world12, prims, ["primitives", "imitation_primitives"], mentor_demos12, engine)
    first.run(1000)
    swapped = with_options(first, richer, agents=["options", "imitation"])
    swapped.run(700)
    resumed = Learner(
        world12, richer, ["options", "imitation"], [0, 1], config=CONFIG, engine=engine
    )
    resumed.load_state_dict(swapped.state_dict())
    swapped.run(800)
    resumed.run(800)
    assert_same(swapped, resumed)


def test_bad_swaps_are_refused(world12, mentor_demos12):
    options = learner_options(world12)
    learner = _make(world12, options, ["imitation", "primitives"], mentor_demos12, "torch")
    learner.run(50)
    with pytest.raises(ValueError, match="another world"):
        with_options(learner, learner_options(MultiRooms(8, 2)))
    other = MultiRooms(12, 3)  # same number of states, other walls
    with pytest.raises(ValueError, match="same primitives"):
        with_options(learner, learner_options(other))
    extended = options.select([o for o, k in enumerate(options.kinds) if k != "primitive"])
    with pytest.raises(ValueError, match="start with the learner's 4 primitive"):
        with_options(learner, Options.concat(extended, primitive_options(world12)))
    with pytest.raises(ValueError, match="start with the learner's 4 primitive"):
        with_options(learner, extended)
    with pytest.raises(ValueError, match="mentor term"):
        with_options(learner, options, agents=["options", "primitives"])
    with pytest.raises(ValueError, match="distinct run indices"):
        with_options(learner, options, runs=[0, 0])
    with pytest.raises(ValueError, match="one per carried run"):
        with_options(learner, options, runs=[0], agents=["imitation", "options"])
    with pytest.raises(ValueError, match="Options bundle"):
        with_options(learner, "doorways")
    with pytest.raises(ValueError, match="posterior-sampling"):
        with_options(learner, options, agents=["imitation_psrl", "primitives"])
    sampling = Learner(world12, options, ["options_psrl"], [0])
    with pytest.raises(ValueError, match="posterior-sampling"):
        with_options(sampling, options)
    exact = Learner(
        world12,
        options,
        ["options"],
        [0],
        config=LearnerConfig(option_models="exact", exact_model_count=10.0),
    )
    with pytest.raises(ValueError, match="exact"):
        with_options(exact, options)
