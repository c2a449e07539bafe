"""The shaping agents (``pbrs``, ``pbrs_primitives``; issue 26): potential-based shaping from the
demonstrations, carried out as start values ``v0 + Φ`` (Wiewiora 2003; see
:func:`himit_torch.learner.backups.shaped_option_backup`). Parity of the engines:
``tests/learner/engines/test_parity.py``; invariance of the optimal options:
``tests/exact/test_shaping_invariance.py``."""

from functools import partial

import pytest
import torch

from himit_torch import KnownReward, LearnerConfig, learner_options, with_options
from himit_torch.learner.backups import shaped_option_backup
from himit_torch.mentor.potential import shaping_potential
from tests.learner.helpers import build_learner

CONFIG = LearnerConfig(window=500)


make = partial(build_learner, config=CONFIG)


def test_without_demonstrations_shaping_is_the_unshaped_run(world12):
    """No demonstrations, Φ = 0: ``pbrs`` is ``options`` and ``pbrs_primitives`` is
    ``primitives``, bit for bit (same seeds)."""
    learner = make(
        world12, None, ["pbrs", "options", "pbrs_primitives", "primitives"], [3, 3, 4, 4]
    )
    learner.run(1500)
    assert bool((learner.cache.potential == 0).all())
    for a, b in ((0, 1), (2, 3)):
        assert torch.equal(learner.cache.values[a], learner.cache.values[b])
        assert torch.equal(learner.cache.q_numerator[a], learner.cache.q_numerator[b])
        assert int(learner.views.decisions[a]) == int(learner.views.decisions[b])
        assert int(learner.views.goals[a]) == int(learner.views.goals[b])
    assert int(learner.views.goals[2]) > 0


def test_shaped_runs_start_at_v0_plus_the_demonstrations_potential(world12, mentor_demos12):
    learner = make(world12, mentor_demos12, ["pbrs", "options", "imitation", "pbrs_primitives"])
    S, v0 = world12.num_states, CONFIG.initial_value
    # The potential recomputed from the demonstrations themselves (not the learner's model).
    src, dst = mentor_demos12.transitions()
    keep = ~world12.terminal_mask[src]
    src, dst = src[keep], dst[keep]
    phi = shaping_potential(
        src,
        dst,
        torch.ones(src.numel(), dtype=torch.float64),
        KnownReward(world12).transition_reward(src, dst),
        world12.gamma,
        world12.terminal_mask,
        v0,
    )
    assert int((phi > 0).sum()) > 10
    for b in (0, 3):
        torch.testing.assert_close(learner.cache.potential[b, :S], phi, atol=1e-12, rtol=0)
        expected = torch.where(world12.terminal_mask, 0.0, v0 + phi)
        torch.testing.assert_close(learner.cache.values[b, :S], expected, atol=1e-12, rtol=0)
    for b in (1, 2):  # the others start at v0 and hold no potential
        assert bool((learner.cache.potential[b] == 0).all())
        assert torch.equal(
            learner.cache.values[b, :S], torch.where(world12.terminal_mask, 0.0, v0).double()
        )
    # The mentor states where the chain's value is above v0 start above v0: the run is drawn there.
    assert bool((learner.cache.values[0, :S][phi > 0] > v0).all())


# plan() sweeps on torch ops to the threshold (≈ 6 s on either engine): under -m slow (CI); the
# fast suite's shaping checks are the hand-solved backups and the engines' parity.
@pytest.mark.slow
@pytest.mark.parametrize("engine", ["numba", "torch"])
def test_planned_values_solve_the_shaped_bellman_equation(world12, mentor_demos12, engine):
    """After learning and planning to the end, ``V' = V − Φ`` satisfies
    ``V'(s) = max_o shaped_option_backup(...)`` from the run's own option model at every state
    it has tried an option in (within the sweeping threshold)."""
    learner = make(world12, mentor_demos12, ["pbrs"], engine=engine)
    learner.run(700)
    learner.plan()
    model, phi, U = learner.model, learner.cache.potential[0], learner.cache.values[0]
    shaped_value = U - phi
    E = int(model.num_edges[0])
    rows, succ = model.edge_row[0, :E], model.edge_successor[0, :E]
    best: dict[int, float] = {}
    for row in rows.unique().tolist():
        n = float(model.row_count[0, row])
        mine = rows == row
        s = int(learner.rows.row_state[row])
        q = shaped_option_backup(
            model.row_reward[0, row] / n,
            model.edge_discount[0, :E][mine] / n,
            shaped_value[succ[mine]],
            phi[s],
            phi[succ[mine]],
        )
        best[s] = max(best.get(s, float("-inf")), float(q))
    assert len(best) > 20
    for s, v in best.items():
        if not bool(world12.terminal_mask[s]):
            assert float(shaped_value[s]) == pytest.approx(v, abs=1e-5), s


def test_checkpoints_and_new_options_keep_the_potential(world12, mentor_demos12):
    """A checkpoint read into a learner built without demonstrations, and a learner carried to
    an option set, record the potential the values hold (not moved a second time)."""
    first = make(world12, mentor_demos12, ["pbrs", "options"])
    first.run(400)
    second = make(world12, None, ["pbrs", "options"])
    second.load_state_dict(first.state_dict())
    assert torch.equal(second.cache.potential, first.cache.potential)
    carried = with_options(first, learner_options(world12))
    assert torch.equal(carried.cache.potential, first.cache.potential)
    first.run(400)
    second.run(400)
    assert torch.equal(first.cache.values, second.cache.values)
    # More demonstrations move V by the change of the potential only.
    before_v, before_phi = second.cache.values.clone(), second.cache.potential.clone()
    second.add_demonstrations(mentor_demos12)  # (twice the counts: the same p_m, the same Φ)
    torch.testing.assert_close(second.cache.potential, before_phi, atol=1e-12, rtol=0)
    torch.testing.assert_close(second.cache.values, before_v, atol=1e-12, rtol=0)


@pytest.mark.parametrize("settings", [{"concentration": 0.5}, {"untried_value": 0.0}])
def test_priors_the_shift_does_not_cover_are_refused(world12, settings):
    config = LearnerConfig(**settings)
    make(world12, None, ["options"], config=config)  # fine without shaping
    with pytest.raises(ValueError, match="concentration=0 and untried_value=None"):
        make(world12, None, ["options", "pbrs"], config=config)
