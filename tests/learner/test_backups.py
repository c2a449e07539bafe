"""The Bellman backups of :mod:`himit_torch.learner.backups`: hand-solved tiny cases (derivations in the
comments) and the batched functions against naive Python loops over random tensors."""

import itertools
import math

import numpy as np
import pytest
import scipy.stats
import torch

from himit_torch.learner.backups import (
    augmented_option_backup,
    augmented_primitive_backup,
    confident_mentor,
    dirichlet_value_moments,
    mentor_backup,
    option_backup,
    options_only_backup,
    primitives_only_backup,
    shaped_option_backup,
)

NEG_INF = float("-inf")


@pytest.fixture
def gen() -> torch.Generator:
    return torch.Generator().manual_seed(1234)


def rand(gen, *shape):
    return torch.rand(*shape, generator=gen, dtype=torch.float64)


def randn(gen, *shape):
    return torch.randn(*shape, generator=gen, dtype=torch.float64)


def bools(gen, *shape, p=0.5):
    return torch.rand(*shape, generator=gen) < p


# ============================================================================ hand-solved cases
def test_option_backup_hand_case():
    # Q = r + Σ_k w_k V_k = −0.5 + (0.5·2 + 0.3·(−1) + 0·100) = −0.5 + 1.0 − 0.3 = 0.2
    # (the third slot is padding: weight 0, whatever its value).
    q = option_backup(
        torch.tensor(-0.5, dtype=torch.float64),
        torch.tensor([0.5, 0.3, 0.0], dtype=torch.float64),
        torch.tensor([2.0, -1.0, 100.0], dtype=torch.float64),
    )
    assert q.item() == pytest.approx(0.2, abs=1e-12)


def test_option_backup_two_rows():
    # Row 0: 1 + 0.9·10 = 10;  row 1: 0 + 0.45·(−2) + 0.45·4 = 0.9.
    q = option_backup(
        torch.tensor([1.0, 0.0]),
        torch.tensor([[0.9, 0.0], [0.45, 0.45]]),
        torch.tensor([[10.0, 5.0], [-2.0, 4.0]]),
    )
    assert torch.allclose(q, torch.tensor([10.0, 0.9]))


def test_mentor_backup_hand_case():
    # R_m + γ Σ p V = 0.1 + 0.9·(0.25·4 + 0.75·0) = 0.1 + 0.9 = 1.0
    m = mentor_backup(
        torch.tensor(0.1, dtype=torch.float64),
        torch.tensor([0.25, 0.75], dtype=torch.float64),
        torch.tensor([4.0, 0.0], dtype=torch.float64),
        gamma=0.9,
    )
    assert m.item() == pytest.approx(1.0, abs=1e-12)


def test_options_only_backup_hand_case():
    q = torch.tensor([[1.0, 5.0, 3.0], [1.0, 5.0, 3.0], [7.0, 8.0, 9.0]])
    avail = torch.tensor([[True, False, True], [True, True, True], [False, False, False]])
    # max over available: row 0 → max(1, 3) = 3 (5 is unavailable); row 1 → 5; row 2 → −inf.
    v = options_only_backup(q, avail)
    assert v.tolist() == [3.0, 5.0, NEG_INF]


def test_augmented_option_backup_hand_case():
    # own = max available Q = 3 in every row (the 5 is unavailable).
    q = torch.tensor([[1.0, 5.0, 3.0]]).expand(4, 3)
    avail = torch.tensor([True, False, True]).expand(4, 3)
    mentor = torch.tensor([4.0, 2.0, 10.0, NEG_INF])
    mentor_ok = torch.tensor([True, True, False, True])
    # row 0: max(3, 4) = 4;  row 1: max(3, 2) = 3;  row 2: mentor not observed → 3 (not 10);
    # row 3: max(3, −inf) = 3.
    v = augmented_option_backup(q, avail, mentor, mentor_ok)
    assert v.tolist() == [4.0, 3.0, 3.0, 3.0]


def test_augmented_option_backup_mentor_only_state():
    # No own option but the mentor was seen: V = the mentor term.
    v = augmented_option_backup(
        torch.tensor([[1.0, 2.0]], dtype=torch.float64),
        torch.tensor([[False, False]]),
        torch.tensor([-0.3], dtype=torch.float64),
        torch.tensor([True]),
    )
    assert v.tolist() == [-0.3]


def test_primitives_only_backup_hand_case():
    # a0: −1 + 0.5·(1·10 + 0·0) = 4;  a1: 0 + 0.5·(0.5·4 + 0.5·2) = 1.5  →  V = 4.
    reward = torch.tensor([-1.0, 0.0])
    probs = torch.tensor([[1.0, 0.0], [0.5, 0.5]])
    values = torch.tensor([[10.0, 0.0], [4.0, 2.0]])
    assert primitives_only_backup(reward, probs, values, gamma=0.5).item() == pytest.approx(4.0)


def test_augmented_primitive_backup_hand_case():
    # Eq. 1: V = R_obs + γ max(max_a Σ p V, Σ p_m V).
    # own: a0 → 1·10 = 10, a1 → 0.5·4 + 0.5·2 = 3  → 10.
    # Case A, mentor Σ p_m V = 0.5·20 + 0.5·6 = 13 > 10: V = −0.01 + 0.9·13 = 11.69.
    # Case B, mentor not observed: V = −0.01 + 0.9·10 = 8.99.
    # Case C, mentor observed but worse (0.5·0 + 0.5·6 = 3): V = 8.99.
    probs = torch.tensor([[1.0, 0.0], [0.5, 0.5]]).expand(3, 2, 2)
    values = torch.tensor([[10.0, 0.0], [4.0, 2.0]]).expand(3, 2, 2)
    m_probs = torch.tensor([[0.5, 0.5]] * 3)
    m_values = torch.tensor([[20.0, 6.0], [20.0, 6.0], [0.0, 6.0]])
    m_ok = torch.tensor([True, False, True])
    v = augmented_primitive_backup(
        torch.full((3,), -0.01), probs, values, m_probs, m_values, m_ok, gamma=0.9
    )
    assert torch.allclose(v, torch.tensor([11.69, 8.99, 8.99]), atol=1e-6)


def test_backups_reject_mismatched_shapes():
    with pytest.raises(ValueError, match="option_backup"):
        option_backup(torch.zeros(3), torch.zeros(3, 2), torch.zeros(3, 4))
    with pytest.raises(ValueError, match="option_backup"):
        option_backup(torch.zeros(2), torch.zeros(3, 2), torch.zeros(3, 2))
    with pytest.raises(ValueError, match="mentor_backup"):
        mentor_backup(torch.zeros(3), torch.zeros(3, 2), torch.zeros(3, 5), 0.9)


# ====================================================================== fast path = naive loop
BATCH = (3, 5)


def test_option_backup_matches_loop(gen):
    K = 4
    r, w, v = randn(gen, *BATCH), rand(gen, *BATCH, K), randn(gen, *BATCH, K)
    got = option_backup(r, w, v)
    for i, j in itertools.product(range(BATCH[0]), range(BATCH[1])):
        expected = float(r[i, j]) + sum(float(w[i, j, k]) * float(v[i, j, k]) for k in range(K))
        assert got[i, j].item() == pytest.approx(expected, abs=1e-12)


def test_mentor_backup_matches_loop(gen):
    K, gamma = 6, 0.95
    r, p, v = randn(gen, *BATCH), rand(gen, *BATCH, K), randn(gen, *BATCH, K)
    p = p / p.sum(-1, keepdim=True)
    got = mentor_backup(r, p, v, gamma)
    for i, j in itertools.product(range(BATCH[0]), range(BATCH[1])):
        expected = float(r[i, j]) + gamma * sum(float(p[i, j, k] * v[i, j, k]) for k in range(K))
        assert got[i, j].item() == pytest.approx(expected, abs=1e-12)


def _loop_max(values, mask):
    best = NEG_INF
    for x, ok in zip(values, mask):
        if ok and x > best:
            best = x
    return best


def test_options_only_and_augmented_backup_match_loop(gen):
    J = 5
    q, avail = randn(gen, *BATCH, J), bools(gen, *BATCH, J, p=0.6)
    avail[0, 0] = False  # one state with no own option
    m, m_ok = randn(gen, *BATCH), bools(gen, *BATCH)
    m_ok[0, 0] = True
    own = options_only_backup(q, avail)
    aug = augmented_option_backup(q, avail, m, m_ok)
    for i, j in itertools.product(range(BATCH[0]), range(BATCH[1])):
        o = _loop_max(q[i, j].tolist(), avail[i, j].tolist())
        assert own[i, j].item() == o
        expected = max(o, m[i, j].item()) if m_ok[i, j] else o
        assert aug[i, j].item() == expected
    assert own[0, 0].item() == NEG_INF and aug[0, 0].item() == m[0, 0].item()


def test_primitives_backups_match_loop(gen):
    A, K, gamma = 4, 3, 0.9
    r_sa = randn(gen, *BATCH, A)
    p = rand(gen, *BATCH, A, K)
    p = p / p.sum(-1, keepdim=True)
    v = randn(gen, *BATCH, A, K)
    r_obs = randn(gen, *BATCH)
    pm = rand(gen, *BATCH, K)
    pm = pm / pm.sum(-1, keepdim=True)
    vm = randn(gen, *BATCH, K) + 0.5  # so that the mentor wins sometimes
    m_ok = bools(gen, *BATCH)
    plain = primitives_only_backup(r_sa, p, v, gamma)
    aug = augmented_primitive_backup(r_obs, p, v, pm, vm, m_ok, gamma)
    mentor_won = 0
    for i, j in itertools.product(range(BATCH[0]), range(BATCH[1])):
        qs = [
            float(r_sa[i, j, a])
            + gamma * sum(float(p[i, j, a, k] * v[i, j, a, k]) for k in range(K))
            for a in range(A)
        ]
        assert plain[i, j].item() == pytest.approx(max(qs), abs=1e-12)
        own = max(sum(float(p[i, j, a, k] * v[i, j, a, k]) for k in range(K)) for a in range(A))
        ment = sum(float(pm[i, j, k] * vm[i, j, k]) for k in range(K))
        best = max(own, ment) if m_ok[i, j] else own
        mentor_won += bool(m_ok[i, j]) and ment > own
        assert aug[i, j].item() == pytest.approx(float(r_obs[i, j]) + gamma * best, abs=1e-12)
    assert mentor_won > 0, "the random case should exercise the mentor branch"


def test_eq2_reduces_to_eq1_for_primitive_options(gen):
    """With one-step primitive options, ``r(s,a) = R_obs`` and ``p^a = γ p``, and the mentor term
    with ``R_m = R_obs``, eq. 2 gives the same value as eq. 1."""
    A, K, gamma = 4, 3, 0.9
    p = rand(gen, *BATCH, A, K)
    p = p / p.sum(-1, keepdim=True)
    v = randn(gen, *BATCH, A, K)
    pm = rand(gen, *BATCH, K)
    pm = pm / pm.sum(-1, keepdim=True)
    vm = randn(gen, *BATCH, K)
    r_obs, m_ok = randn(gen, *BATCH), bools(gen, *BATCH)
    q = option_backup(r_obs[..., None].expand(*BATCH, A), gamma * p, v)
    m = mentor_backup(r_obs, pm, vm, gamma)
    eq2 = augmented_option_backup(q, torch.ones(*BATCH, A, dtype=torch.bool), m, m_ok)
    eq1 = augmented_primitive_backup(r_obs, p, v, pm, vm, m_ok, gamma)
    assert torch.allclose(eq2, eq1, atol=1e-12)


# ================================================================= Dirichlet value moments
def test_dirichlet_value_moments_hand_case():
    # α = (1, 1), u = (0, 1): Σ p u = p_1 ~ Beta(1, 1): mean 1/2, variance 1/12.
    # Formula: ᾱ = (1/2, 1/2), E = 1/2, Σ ᾱ u² = 1/2, var = (1/2 − 1/4) / 3 = 1/12.
    mean, var = dirichlet_value_moments(
        torch.tensor([1.0, 1.0], dtype=torch.float64), torch.tensor([0.0, 1.0], dtype=torch.float64)
    )
    assert mean.item() == pytest.approx(0.5)
    assert var.item() == pytest.approx(1 / 12)


def test_dirichlet_value_moments_match_covariance_quadratic_form(gen):
    """Var[Σ p_k u_k] = uᵀ Cov(p) u with scipy's Dirichlet moments (Cov_jk = −ᾱ_j ᾱ_k/(α₀+1) off the
    diagonal, scipy's ``var`` on it), on the categories with positive counts."""
    K = 5
    counts = rand(gen, 20, K) * 4
    counts[counts < 0.8] = 0.0  # absent outcomes
    counts[:, 0] += 0.5  # at least one present outcome per row
    u = randn(gen, 20, K)
    u_absent = torch.where(counts > 0, u, torch.full_like(u, 1e6))  # absent values must not matter
    mean, var = dirichlet_value_moments(counts, u_absent)
    for i in range(20):
        keep = (counts[i] > 0).numpy()
        a, x = counts[i].numpy()[keep], u[i].numpy()[keep]
        if a.size == 1:
            exp_mean, exp_var = x[0], 0.0
        else:
            dist_mean = scipy.stats.dirichlet.mean(a)
            dist_var = scipy.stats.dirichlet.var(a)
            a0 = a.sum()
            cov = -np.outer(a, a) / (a0**2 * (a0 + 1))
            np.fill_diagonal(cov, dist_var)
            exp_mean, exp_var = dist_mean @ x, x @ cov @ x
        assert mean[i].item() == pytest.approx(exp_mean, abs=1e-10)
        assert var[i].item() == pytest.approx(exp_var, abs=1e-10)


def test_dirichlet_value_moments_monte_carlo():
    torch.manual_seed(7)
    counts = torch.tensor([3.0, 0.5, 1.5, 5.0], dtype=torch.float64)
    u = torch.tensor([-1.0, 2.0, 0.5, 0.25], dtype=torch.float64)
    mean, var = dirichlet_value_moments(counts, u)
    draws = torch.distributions.Dirichlet(counts).sample((200_000,)) @ u
    n = draws.numel()
    # Standard errors: of the mean sd/√n; of the variance ≈ sd²·√(2/(n−1)) (near-normal draws,
    # inflated ×2 for the skew of a Dirichlet projection).
    assert abs(draws.mean().item() - mean.item()) < 5 * math.sqrt(var.item() / n)
    assert abs(draws.var().item() - var.item()) < 5 * 2 * var.item() * math.sqrt(2 / (n - 1))


def test_dirichlet_value_moments_degenerate_rows():
    counts = torch.tensor([[0.0, 0.0, 0.0], [0.0, 4.0, 0.0]], dtype=torch.float64)
    u = torch.tensor([[1.0, 2.0, 3.0], [5.0, -2.0, float("inf")]], dtype=torch.float64)
    mean, var = dirichlet_value_moments(counts, u)
    # No counts: no information → infinite variance. One outcome only: its value, no variance
    # (the inf of the absent outcome is ignored).
    assert var[0].item() == float("inf")
    assert mean[1].item() == -2.0 and var[1].item() == 0.0


# =========================================================================== confidence test
def test_confident_mentor_hand_cases():
    # Mentor: mean 1, sd 0.2, z = 2 → lower bound 0.6.
    m_mean = torch.tensor([1.0, 1.0, 1.0, 1.0], dtype=torch.float64)
    m_var = torch.full((4,), 0.04, dtype=torch.float64)
    own_mean = torch.tensor([[0.5, 0.2]] * 4, dtype=torch.float64)
    own_var = torch.tensor(
        [
            [0.0025, 0.09],  # upper bounds 0.6, 0.8 → max 0.8 > 0.6: not confident
            [0.0025, 0.0001],  # 0.6, 0.22 → 0.6: lower 0.6 is not *above* 0.6: not confident
            [0.0001, 0.0001],  # 0.52, 0.22 → 0.52 < 0.6: confident
            [0.0025, 0.09],  # as row 0 but no own option available: confident
        ],
        dtype=torch.float64,
    )
    avail = torch.tensor([[True, True], [True, True], [True, True], [False, False]])
    got = confident_mentor(m_mean, m_var, own_mean, own_var, avail, z=2.0)
    assert got.tolist() == [False, False, True, True]
    # Row 0 with only the first option available: upper 0.6 → still not strictly above.
    # With the second only (0.8): no. With z = 0 the test compares means: 1 > 0.5 → True.
    assert confident_mentor(
        m_mean[:1], m_var[:1], own_mean[:1], own_var[:1], torch.tensor([[True, False]]), z=2.0
    ).tolist() == [False]
    assert confident_mentor(m_mean, m_var, own_mean, own_var, avail, z=0.0).tolist() == [True] * 4


def test_confident_mentor_matches_loop(gen):
    J, z = 4, 1.5
    mm, mv = randn(gen, *BATCH) + 1.0, rand(gen, *BATCH) * 0.2
    om, ov, avail = randn(gen, *BATCH, J), rand(gen, *BATCH, J) * 0.2, bools(gen, *BATCH, J)
    got = confident_mentor(mm, mv, om, ov, avail, z)
    for i, j in itertools.product(range(BATCH[0]), range(BATCH[1])):
        uppers = [
            float(om[i, j, k]) + z * math.sqrt(float(ov[i, j, k]))
            for k in range(J)
            if avail[i, j, k]
        ]
        lower = float(mm[i, j]) - z * math.sqrt(float(mv[i, j]))
        assert got[i, j].item() == (lower > max(uppers, default=NEG_INF))
    assert 0 < got.sum() < got.numel(), "the random case should give both answers"


def test_shaped_option_backup_telescopes_over_two_options_by_hand():
    """γ = 0.9, Φ(s) = 0.5. Shaping adds γ Φ(s_{t+1}) − Φ(s_t) to each step's reward.

    o1: s → x → s1 in 2 steps, −0.01 each; Φ(x) = 0.7, Φ(s1) = 1.0, V'(s1) = 0.2.
      step by step: (−0.01 + 0.9·0.7 − 0.5) + 0.9·(−0.01 + 0.9·1.0 − 0.7) = 0.12 + 0.171 = 0.291,
      telescoped: −0.01 − 0.009 + 0.81·1.0 − 0.5 = 0.291; plus 0.81·V'(s1) = 0.162 → 0.453.
    o2: to s2 in 1 step (−0.01; Φ = 0.2, V' = 0.4) with probability ½, or to the goal s3 in
      3 steps (−0.01, −0.01, +1; Φ = 0, V' = 0) otherwise:
      r = ½(−0.01) + ½(−0.01 − 0.009 + 0.81) = 0.3905, weights ½·0.9 = 0.45 and ½·0.729 = 0.3645;
      the 3-step branch step by step: (−0.01 + 0.9Φ(y) − 0.5) + 0.9(−0.01 + 0.9Φ(z) − Φ(y))
      + 0.81(1 + 0.9·0 − Φ(z)) = 0.791 − 0.5 whatever Φ(y), Φ(z) are;
      Q' = 0.3905 + 0.45·(0.4 + 0.2) + 0.3645·0 − 0.5 = 0.1605.
    """
    gamma, phi_s, phi_x, phi_y, phi_z = 0.9, 0.5, 0.7, 0.33, -0.4
    by_steps_o1 = (-0.01 + gamma * phi_x - phi_s) + gamma * (-0.01 + gamma * 1.0 - phi_x)
    assert by_steps_o1 == pytest.approx(0.291, abs=1e-12)
    by_steps_o2_long = (
        (-0.01 + gamma * phi_y - phi_s)
        + gamma * (-0.01 + gamma * phi_z - phi_y)
        + gamma**2 * (1.0 + gamma * 0.0 - phi_z)
    )
    assert by_steps_o2_long == pytest.approx(0.791 - 0.5, abs=1e-12)
    q = shaped_option_backup(
        torch.tensor([-0.019, 0.3905], dtype=torch.float64),
        torch.tensor([[0.81, 0.0], [0.45, 0.3645]], dtype=torch.float64),
        torch.tensor([[0.2, 0.0], [0.4, 0.0]], dtype=torch.float64),
        torch.tensor([phi_s, phi_s], dtype=torch.float64),
        torch.tensor([[1.0, 0.0], [0.2, 0.0]], dtype=torch.float64),
    )
    torch.testing.assert_close(q, torch.tensor([0.453, 0.1605], dtype=torch.float64))
    # o1 wins shaped; unshaped, with V = V' + Φ (1.2 at s1, 0.6 at s2), Q = Q' + Φ(s) = 0.953
    # and 0.6605: the same winner, each option moved by the same Φ(s).
    plain = option_backup(
        torch.tensor([-0.019, 0.3905], dtype=torch.float64),
        torch.tensor([[0.81, 0.0], [0.45, 0.3645]], dtype=torch.float64),
        torch.tensor([[1.2, 0.0], [0.6, 0.0]], dtype=torch.float64),
    )
    torch.testing.assert_close(plain, torch.tensor([0.953, 0.6605], dtype=torch.float64))


def test_shaped_backup_of_shaped_values_is_the_plain_backup_less_the_potential(gen):
    """V' = V − Φ ⇒ Q'(s, ·) = Q(s, ·) − Φ(s), on random tensors (6 states, 3 options each)."""
    reward, weights, values = randn(gen, 6, 3), rand(gen, 6, 3, 4) * 0.2, randn(gen, 6, 3, 4)
    phi_s, phi_next = randn(gen, 6, 1).expand(6, 3), randn(gen, 6, 3, 4)
    shaped = shaped_option_backup(reward, weights, values - phi_next, phi_s, phi_next)
    torch.testing.assert_close(shaped, option_backup(reward, weights, values) - phi_s)
    assert shaped.argmax(-1).equal(option_backup(reward, weights, values).argmax(-1))
    with pytest.raises(ValueError, match="potential"):
        shaped_option_backup(reward, weights, values, phi_s[:, :2], phi_next)
