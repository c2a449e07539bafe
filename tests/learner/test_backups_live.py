"""The learner's live backups are the pure functions of :mod:`himit_torch.learner.backups`:
hand-solved cases of the functions the value cache calls (eq. 2's outer max, the override, the
fade, the confidence-gated backup, the edge-list form of the option backup), and the cache's
incrementally propagated numerators against the same sums computed from scratch."""

import pytest
import torch

from himit_torch.learner.backups import (
    MentorConfidence,
    augmented_backup,
    dirichlet_value_moments,
    dirichlet_variance,
    faded_mentor_term,
    mentor_override,
    option_backup,
    option_backup_edges,
    trusted_augmented_backup,
)
from himit_torch.learner.config import LearnerConfig
from himit_torch.learner.learner import Learner
from himit_torch.mentor.policy import record_demonstrations
from himit_torch.options.builders import learner_options, mentor_options

NEG_INF = float("-inf")


def f64(*x):
    return torch.tensor(x, dtype=torch.float64)


# ============================================================================ hand-solved cases
def test_option_backup_edges_hand_case():
    # Run 0: row 0 has edges w=0.5 → V=2 and w=0.25 → V=−4: 1 + 1 − 1 = 1; row 1 no edge: r = 3.
    # Run 1: row 1 has one edge w=0.9 → V=10: −1 + 9 = 8; row 0 no edge: 0.
    q = option_backup_edges(
        torch.tensor([[1.0, 3.0], [0.0, -1.0]], dtype=torch.float64),
        torch.tensor([0, 1, 0]),
        torch.tensor([0, 1, 0]),
        f64(0.5, 0.9, 0.25),
        f64(2.0, 10.0, -4.0),
    )
    assert q.tolist() == [[1.0, 3.0], [0.0, 8.0]]


def test_option_backup_edges_rejects_mismatched_shapes():
    with pytest.raises(ValueError, match="option_backup_edges"):
        option_backup_edges(
            torch.zeros(2, 3),
            torch.zeros(2).long(),
            torch.zeros(3).long(),
            torch.zeros(2),
            torch.zeros(2),
        )


def test_dirichlet_variance_hand_case():
    # mean 0.5, second moment 0.5, α_0 = 2: (0.5 − 0.25) / 3 = 1/12 (Beta(1, 1)); a second moment
    # rounded below mean² gives 0, not a negative variance.
    var = dirichlet_variance(f64(0.5, 1.0), f64(0.5, 1.0 - 1e-17), f64(2.0, 5.0))
    assert var[0].item() == pytest.approx(1 / 12) and var[1].item() == 0.0
    # the same as the moments from counts
    _, from_counts = dirichlet_value_moments(f64(1.0, 1.0), f64(0.0, 1.0))
    assert from_counts.item() == var[0].item()


def test_mentor_override_hand_case():
    observed = torch.tensor([True, True, False])
    tries = f64(2.0, 3.0, 0.0)
    # override after 3 own starts: state 0 (2 starts) keeps the term, state 1 (3) loses it.
    assert mentor_override(observed, tries, 3).tolist() == [True, False, False]
    assert mentor_override(observed, None, None).tolist() == [True, True, False]
    with pytest.raises(ValueError, match="own_tries"):
        mentor_override(observed, None, 3)


def test_faded_mentor_term_hand_case():
    # k = 2 (the mentor weighs as two executions), n = 2: (2·4 + 2·0) / 4 = 2; n = 0: the term;
    # no own value (−inf): the term.
    m = faded_mentor_term(f64(4.0, 4.0, 4.0), f64(0.0, 0.0, NEG_INF), f64(2.0, 0.0, 5.0), 2.0)
    assert m.tolist() == [2.0, 4.0, 4.0]


def test_augmented_backup_reports_the_winner():
    v, won = augmented_backup(
        f64(1.0, 1.0, 1.0, NEG_INF),
        f64(2.0, 0.5, 2.0, -3.0),
        torch.tensor([True, True, False, True]),
    )
    assert v.tolist() == [2.0, 1.0, 1.0, -3.0]
    assert won.tolist() == [True, False, False, True]


def test_trusted_augmented_backup_hand_cases():
    # Own options Q = (0.5, 0.2), both available → own 0.5. Mentor term 1.0 observed everywhere.
    q = f64(0.5, 0.2).expand(4, 2)
    avail = torch.ones(4, 2, dtype=torch.bool)
    m, seen = torch.full((4,), 1.0, dtype=torch.float64), torch.ones(4, dtype=torch.bool)
    tries = f64(0.0, 5.0, 1.0, 0.0)
    # plain eq. 2: the mentor wins everywhere
    v, won = trusted_augmented_backup(q, avail, m, seen)
    assert v.tolist() == [1.0] * 4 and won.all()
    # override after 2 starts: state 1 (5 starts) falls back to own 0.5
    v, won = trusted_augmented_backup(q, avail, m, seen, tries, override_after=2)
    assert v.tolist() == [1.0, 0.5, 1.0, 1.0] and won.tolist() == [True, False, True, True]
    # fade k = 1: state 2 (n = 1): (1·1 + 1·0.5) / 2 = 0.75; state 1 (n = 5): (1 + 2.5)/6 = 7/12
    v, _ = trusted_augmented_backup(q, avail, m, seen, tries, fade=1.0)
    assert v.tolist() == pytest.approx([1.0, 0.5 + 1 / 12, 0.75, 1.0])
    # confidence z = 2: mentor sd 0.2 → lower bound 0.6; own sd 0.05 → upper bounds 0.6, 0.3:
    # 0.6 is not above 0.6, so the tested states (0, 1) keep own 0.5; untested states pass.
    conf = MentorConfidence(
        own_var=torch.full((4, 2), 0.0025, dtype=torch.float64),
        mentor_var=torch.full((4,), 0.04, dtype=torch.float64),
        tested=torch.tensor([True, True, False, False]),
        z=2.0,
    )
    v, won = trusted_augmented_backup(q, avail, m, seen, confidence=conf)
    assert v.tolist() == [0.5, 0.5, 1.0, 1.0] and won.tolist() == [False, False, True, True]
    # the confidence test looks at the unfaded term: with fade the failed states stay own
    v, _ = trusted_augmented_backup(q, avail, m, seen, tries, confidence=conf, fade=1.0)
    assert v.tolist() == pytest.approx([0.5, 0.5, 0.75, 1.0])


# ============================================== incremental caches = the sums from scratch
@pytest.fixture(scope="module")
def torch_learner(world8):
    """400 ticks on the torch engine (≈ 4 s), shared by the tests below."""
    demos = record_demonstrations(world8, mentor_options(world8), episodes=5, seed=0)
    agents = ["imitation", "imitation_confident", "options", "imitation_primitives_confident"]
    learner = Learner(
        world8,
        learner_options(world8),
        agents,
        seeds=[1, 2, 3, 4],
        config=LearnerConfig(window=500),
        demonstrations=demos,
        engine="torch",
    )
    learner.run(400)
    return learner


def test_propagated_option_numerators_equal_the_edge_sums(torch_learner):
    """``q_numerator`` (built by add_outcome and the propagation of every ``δV``) equals
    :func:`option_backup_edges` over the model's edge lists with today's ``V``; the second
    moments likewise for the confidence-tested runs."""
    learner = torch_learner
    model, cache = learner.model, learner.cache
    valid = torch.arange(model.capacity) < model.num_edges[:, None]
    runs, slots = valid.nonzero(as_tuple=True)
    rows, succ = model.edge_row[runs, slots], model.edge_successor[runs, slots]
    g, c = model.edge_discount[runs, slots], model.edge_count[runs, slots]
    v = cache.values[runs, succ]
    assert runs.numel() > 100, "the learner should have some experience"
    scratch = option_backup_edges(model.row_reward, runs, rows, g, v)
    torch.testing.assert_close(cache.q_numerator, scratch, rtol=0, atol=1e-9)
    tested = learner.rows.use_confidence[runs]
    second = option_backup_edges(
        torch.zeros_like(model.row_reward),
        runs[tested],
        rows[tested],
        (g * g / c * v)[tested],
        v[tested],
    )
    torch.testing.assert_close(cache.q_second, second, rtol=0, atol=1e-9)
    assert bool(cache.q_second[~learner.rows.use_confidence].eq(0).all())


def test_propagated_mentor_numerators_equal_the_edge_sums(torch_learner):
    """``mentor_numerator = Σ_e c_e (R_m(e) + γ V(s'_e))`` per observed state of the imitating
    runs, from scratch."""
    learner = torch_learner
    mentor, cache = learner.mentor, learner.cache
    valid = torch.arange(mentor.capacity) < mentor.num_edges[:, None]
    valid &= learner.rows.use_mentor[:, None]
    runs, slots = valid.nonzero(as_tuple=True)
    src, dst = mentor.edge_row[runs, slots], mentor.edge_successor[runs, slots]
    u = cache.mentor_edge_reward[runs, slots] + learner.gamma * cache.values[runs, dst]
    scratch = option_backup_edges(
        torch.zeros_like(cache.mentor_numerator), runs, src, mentor.edge_count[runs, slots], u
    )
    # (runs without a mentor term never read it, so it is not kept up to date for them)
    imitating = learner.rows.use_mentor
    assert bool(cache.mentor_numerator[imitating].ne(0).any())
    torch.testing.assert_close(
        cache.mentor_numerator[imitating], scratch[imitating], rtol=0, atol=1e-9
    )


def test_state_backup_is_eq2_from_model_means(torch_learner):
    """The cache's backup of every state equals eq. 2 evaluated from the models' posterior
    means (α = 0: ``Q = r̄ + Σ p^o V``, ``M = Σ_s' p_m(s'|s) (R_m + γ V(s'))``) by the pure
    functions, on the runs without the confidence test."""
    learner = torch_learner
    model, mentor, cache, rows = learner.model, learner.mentor, learner.cache, learner.rows
    untested = (~rows.use_confidence).nonzero()[:, 0]
    B, S = untested.numel(), learner.num_states
    states = torch.arange(S).expand(B, S)
    runs = untested[:, None]
    got, has_value, _ = cache.state_backup(runs, states)
    state_rows = rows.state_rows[:S][None].expand(B, -1, -1)
    reward, succ, weights = model.mean(runs[..., None].expand_as(state_rows), state_rows)
    v = cache.values.index_select(0, untested)
    v_succ = v.gather(1, succ.clamp(min=0).flatten(1)).view_as(succ)
    q = option_backup(reward, weights, torch.where(succ >= 0, v_succ, torch.zeros(())).double())
    n = model.row_count[runs[..., None], state_rows]
    usable = rows.row_enabled[runs[..., None], state_rows] & (n > 0)
    # the mentor term from the mentor model's counts and the cache's edge rewards
    edges = mentor.index().forward[runs.expand(B, S), states]
    e, ok = edges.clamp(min=0), edges >= 0
    r3 = runs[..., None].expand_as(e)
    p_m = torch.where(ok, mentor.edge_count[r3, e], torch.zeros((), dtype=torch.float64))
    n_m = mentor.row_count[runs, states]
    p_m = p_m / n_m.clamp(min=1)[..., None]
    v_m = v.gather(1, mentor.edge_successor[r3, e].clamp(min=0).flatten(1)).view_as(e)
    m = (p_m * (cache.mentor_edge_reward[r3, e] + learner.gamma * v_m)).sum(-1)
    observed = rows.use_mentor[runs] & (n_m > 0)
    want, _ = trusted_augmented_backup(q, usable, m, observed)
    assert int(has_value.sum()) > 20 and bool(observed.any())
    torch.testing.assert_close(got[has_value], want[has_value], rtol=0, atol=1e-9)
