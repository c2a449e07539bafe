"""Posterior sampling (the ``…_psrl`` agents): the sampler's distribution, its identity on both
engines, the sampled backups, the limit of many counts, determinism and checkpoints."""

import numpy as np
import pytest
import scipy.stats
import torch

from himit_torch import Learner, LearnerConfig, learner_options
from himit_torch.learner.posterior_sampling import (
    coupling_share,
    fixed_exp,
    fixed_log,
    gamma_draws,
    sample_keys,
)
from himit_torch.rng import seed_streams

numba = pytest.importorskip("numba")


def _streams(n: int, seed: int = 0, kind: int = 0):
    keys = sample_keys(seed_streams(torch.tensor([seed])), torch.tensor([0]), kind)
    return keys.expand(n).contiguous(), torch.arange(n)


def test_fixed_log_and_exp_match_libm_and_the_kernel_bit_for_bit():
    from himit_torch.learner.engines.kernel import sampling

    gen = torch.Generator().manual_seed(0)
    x = torch.cat(
        [
            torch.rand(2000, generator=gen, dtype=torch.float64),
            torch.rand(200, generator=gen, dtype=torch.float64) * 1e6,
            torch.tensor([2.0**-53, 0.5, 1.0, 1.0 - 2.0**-53, 1e-300]),
        ]
    )
    log = fixed_log(x)
    torch.testing.assert_close(log, torch.log(x), rtol=4e-16, atol=4e-16)
    assert fixed_log(torch.tensor([0.0])).item() == float("-inf")
    y = -torch.rand(2000, generator=gen, dtype=torch.float64) * 700
    torch.testing.assert_close(fixed_exp(y), torch.exp(y), rtol=1e-15, atol=0)
    assert fixed_exp(torch.tensor([float("-inf"), -800.0])).tolist() == [0.0, 0.0]
    kernel_log = np.array([sampling.flog(float(v)) for v in x[:300]])
    kernel_exp = np.array([sampling.fexp(float(v)) for v in y[:300]])
    assert np.array_equal(kernel_log, log[:300].numpy())
    assert np.array_equal(kernel_exp, fixed_exp(y[:300]).numpy())


@pytest.mark.parametrize("shape", [0.05, 0.3, 1.0, 2.5, 40.0, 1e6])
def test_gamma_draws_have_the_gamma_distribution(shape):
    n = 20000
    keys, slots = _streams(n, seed=int(shape * 100))
    g = gamma_draws(keys, slots, torch.full((n,), shape, dtype=torch.float64)).numpy()
    assert (g >= 0).all()
    # mean a and variance a, within 5 standard errors
    assert abs(g.mean() - shape) < 5 * np.sqrt(shape / n)
    var_se = np.sqrt((6 * shape + 2 * shape**2) / n)  # sd of the sample variance (kurtosis 6/a)
    assert abs(g.var() - shape) < 5 * var_se
    assert scipy.stats.kstest(g, scipy.stats.gamma(shape).cdf).pvalue > 1e-3


def test_gamma_draws_are_the_same_bits_in_the_kernel():
    from himit_torch.learner.engines.kernel import sampling

    shapes = torch.tensor([0.05, 0.5, 1.0, 3.0, 17.0, 1e4] * 500, dtype=torch.float64)
    keys, slots = _streams(shapes.numel(), seed=3)
    torch_draws = gamma_draws(keys, slots, shapes).numpy()
    key = np.uint64(keys[0].numpy().view(np.uint64))
    kernel = np.array([sampling.gamma_draw(key, int(s), float(a)) for s, a in zip(slots, shapes)])
    assert np.array_equal(torch_draws, kernel)
    assert gamma_draws(keys[:2], slots[:2], torch.tensor([0.0, -1.0])).tolist() == [0.0, 0.0]


def test_normalised_draws_match_the_dirichlet_moments():
    """``w = G / ΣG`` with ``G_k ~ Γ(α_k)``: the Dirichlet (scipy) mean and variance."""
    alpha = np.array([3.0, 1.0, 0.5, 7.0])
    n = 20000
    draws = []
    for k, a in enumerate(alpha):
        keys, slots = _streams(n, seed=11, kind=k)
        draws.append(gamma_draws(keys, slots, torch.full((n,), a, dtype=torch.float64)))
    g = torch.stack(draws, 1)
    w = (g / g.sum(1, keepdim=True)).numpy()
    dist = scipy.stats.dirichlet(alpha)
    se = np.sqrt(dist.var() / n)
    assert (np.abs(w.mean(0) - dist.mean()) < 5 * se).all()
    assert np.allclose(w.var(0), dist.var(), rtol=0.06)


def test_the_coupling_turns_a_draw_into_a_draw_of_the_updated_posterior():
    """``w ~ Dir(c)``, ``s = U^{1/Σc}``: ``s·w + (1 − s)·δ_0 ~ Dir(c + δ_0)``."""
    alpha = np.array([2.0, 1.0, 0.5])
    n = 20000
    g = torch.stack(
        [
            gamma_draws(*_streams(n, seed=5, kind=k), torch.full((n,), a, dtype=torch.float64))
            for k, a in enumerate(alpha)
        ],
        1,
    )
    w = g / g.sum(1, keepdim=True)
    keys, slots = _streams(n, seed=6)
    from himit_torch.learner.posterior_sampling import stream_uniforms

    s = coupling_share(
        stream_uniforms(keys, slots, 0), torch.full((n,), alpha.sum(), dtype=torch.float64)
    )
    moved = w * s[:, None]
    moved[:, 0] += 1.0 - s
    dist = scipy.stats.dirichlet(alpha + np.array([1.0, 0.0, 0.0]))
    se = np.sqrt(dist.var() / n)
    assert (np.abs(moved.numpy().mean(0) - dist.mean()) < 5 * se).all()
    assert np.allclose(moved.numpy().var(0), dist.var(), rtol=0.06)
    assert coupling_share(torch.tensor([0.3]), torch.tensor([0.0])).item() == 0.0


def _psrl(world, agents, seeds, engine="numba", **config):
    from himit_torch import mentor_options, mentor_policy, record_demonstrations

    demos = record_demonstrations(world, mentor_policy(world, mentor_options(world)), 5, seed=0)
    return Learner(
        world,
        learner_options(world),
        agents,
        seeds,
        config=LearnerConfig(window=500, **config),
        demonstrations=demos,
        engine=engine,
    )


def test_a_sampled_backup_by_hand(world12):
    """One row with two successors, its sample set to ``w = (0.25, 0.75)``: the cached ``Q``
    is ``0.25·(r̄ + ḡ₁V₁) + 0.75·(r̄ + ḡ₂V₂)``, worked out by hand below."""
    L = _psrl(world12, ["options_psrl"], [0], engine="torch")
    L.run(600)
    model, sample = L.model, L.sample
    E = int(model.num_edges[0])
    rows, counts = torch.unique(model.edge_row[0, :E], return_counts=True)
    row = int(rows[counts == 2][0])
    e1, e2 = (model.edge_row[0, :E] == row).nonzero()[:, 0].tolist()
    s1, s2 = int(model.edge_successor[0, e1]), int(model.edge_successor[0, e2])
    # hand-chosen numbers: n = 4 executions, Σr = −2 → r̄ = −0.5; edge 1: c = 1, Σγ^k = 0.9;
    # edge 2: c = 3, Σγ^k = 2.4 (ḡ = 0.8); V(s1) = −0.2, V(s2) = −0.6
    model.row_count[0, row], model.row_reward[0, row] = 4.0, -2.0
    model.edge_count[0, e1], model.edge_discount[0, e1] = 1.0, 0.9
    model.edge_count[0, e2], model.edge_discount[0, e2] = 3.0, 2.4
    L.cache.values[0, s1], L.cache.values[0, s2] = -0.2, -0.6
    sample.option_w[0, e1], sample.option_w[0, e2] = 0.25, 0.75
    sample.option_unseen[0, row] = 0.0
    L.cache.apply_sample_rows(torch.tensor([0]), torch.tensor([row]))
    # 0.25·(−0.5 + 0.9·(−0.2)) + 0.75·(−0.5 + 0.8·(−0.6)) = 0.25·(−0.68) + 0.75·(−0.98) = −0.905
    q = L.cache.row_q(torch.tensor([0]), torch.tensor([row]))
    assert q.item() == pytest.approx(-0.905, abs=1e-12)
    # a change δ of V(s2) moves Q by the sampled weight 0.75·0.8·δ (not the mean's 2.4/4·δ)
    f64 = torch.float64
    L.cache._propagate_options(
        torch.tensor([0]),
        torch.tensor([s2]),
        torch.tensor([0.1], dtype=f64),
        torch.tensor([-0.6], dtype=f64),
    )
    q2 = L.cache.row_q(torch.tensor([0]), torch.tensor([row]))
    assert (q2 - q).item() == pytest.approx(0.75 * 0.8 * 0.1, abs=1e-12)


class _HeavyDemonstrations:
    """Mentor transitions each counted ``weight`` times (a mentor model of near-certainty)."""

    def __init__(self, demos, weight):
        self.src, self.dst = demos.transitions()
        self.counts = torch.full(self.src.shape, weight, dtype=torch.float64)

    def transitions(self):
        return self.src, self.dst


@pytest.mark.parametrize(
    "engine",
    [
        "numba",
        pytest.param("torch", marks=[pytest.mark.slow, pytest.mark.extended]),
    ],  # (the engines' parity
)  # tests hold torch equal to numba for sampling runs in the fast suite)
def test_with_counts_to_infinity_sampling_is_the_mean_agent(world12, engine):
    """Exact option models and a mentor model of 1e30 pseudo-counts: the posterior is a point
    mass, so a psrl run's sampled ``Q`` and mentor terms are its mean-model twin's (same seed),
    and planning to convergence gives the same values — at the start and again after 1500 ticks
    and a fresh draw. (Tick by tick the two runs may part: the sample moves priorities by an ulp,
    which reorders the sweep among exactly tied states.)"""
    from himit_torch import mentor_options, mentor_policy, record_demonstrations

    demos = record_demonstrations(
        world12, mentor_policy(world12, mentor_options(world12)), 5, seed=0
    )
    L = Learner(
        world12,
        learner_options(world12),
        ["options", "options_psrl", "imitation", "imitation_psrl"],
        [4, 4, 4, 4],
        config=LearnerConfig(
            window=500, option_models="exact", exact_model_count=1e30, priority_threshold=1e-13
        ),
        demonstrations=_HeavyDemonstrations(demos, 1e30),
        engine=engine,
    )
    S = world12.num_states
    runs = torch.arange(4)[:, None]
    states = torch.arange(S)[None].expand(4, -1)
    for phase in range(2):
        rows = L.rows.state_rows[:S][None].expand(4, -1, -1)
        q = L.cache.row_q(runs[..., None], rows)
        m = L.cache.mentor_term(runs, states)
        for mean, sampled in ((0, 1), (2, 3)):
            torch.testing.assert_close(q[sampled], q[mean], atol=1e-12, rtol=1e-12, equal_nan=True)
            torch.testing.assert_close(m[sampled], m[mean], atol=1e-12, rtol=1e-12, equal_nan=True)
        L.plan()
        for mean, sampled in ((0, 1), (2, 3)):
            torch.testing.assert_close(
                L.views.state_values()[sampled], L.views.state_values()[mean], atol=1e-9, rtol=0
            )
        if phase == 0:
            L.run(1500)
            assert int(L.sample.resamples[1]) > 2  # it drew again along the way (goals)
            L.resample(torch.tensor([1, 3]))


def test_sampling_is_deterministic_per_seed_and_differs_between_seeds(world12):
    a = _psrl(world12, ["imitation_psrl", "options_psrl"], [3, 4], concentration=0.5)
    b = _psrl(world12, ["imitation_psrl", "options_psrl"], [3, 4], concentration=0.5)
    c = _psrl(world12, ["imitation_psrl", "options_psrl"], [5, 6], concentration=0.5)
    for L in (a, b, c):
        L.run(2000)
    assert torch.equal(a.sample.option_w, b.sample.option_w)
    assert torch.equal(a.views.state_values(), b.views.state_values())
    assert torch.equal(a.run_state.visits, b.run_state.visits)
    assert not torch.equal(a.run_state.visits, c.run_state.visits)


def test_a_psrl_run_really_samples(world12):
    """Its planning values differ from the mean model's: the sample is not the mean."""
    L = _psrl(world12, ["options_psrl"], [0], concentration=1.0)
    L.run(1500)
    E = int(L.model.num_edges[0])
    rows = L.model.edge_row[0, :E]
    n = L.model.row_count[0].index_select(0, rows)
    mean_w = L.model.edge_count[0, :E] / (n + 1.0)
    assert (L.sample.option_w[0, :E] - mean_w).abs().max() > 0.05
    assert int(L.sample.resamples[0]) > 1


# (the torch engine's run: -m slow; the fast suite's parity runs check its sampling)
@pytest.mark.parametrize(
    "engine", ["numba", pytest.param("torch", marks=[pytest.mark.slow, pytest.mark.extended])]
)
def test_checkpoint_resume_continues_the_same_sampling_run(world12, engine):
    make = lambda: _psrl(  # noqa: E731
        world12,
        ["imitation_psrl", "options", "primitives_psrl"],
        [1, 2, 3],
        engine=engine,
        mentor_concentration=1.0,
        resample_every=5,
    )
    straight, first = make(), make()
    straight.run(1500)
    first.run(700)
    state = first.state_dict()
    second = make()
    second.load_state_dict(state)
    second.run(800)
    for name in ("option_w", "option_unseen", "mentor_w", "mentor_unseen", "resamples"):
        x, y = getattr(straight.sample, name), getattr(second.sample, name)
        k = min(x.shape[-1], y.shape[-1]) if x.dim() > 1 else None
        assert torch.equal(x[:, :k] if k else x, y[:, :k] if k else y), name
    assert torch.equal(straight.views.state_values(), second.views.state_values())
    assert torch.equal(straight.run_state.visits, second.run_state.visits)


def test_resample_every_is_checked():
    with pytest.raises(ValueError, match="resample_every"):
        LearnerConfig(resample_every=-1)
    with pytest.raises(ValueError, match="resample_every"):
        LearnerConfig(resample_every=2.5)


def test_a_sampling_run_does_not_depend_on_other_runs_demonstrations(world12):
    """Demonstrations given to run 1 leave run 0 alone — its draws, its caches and its queue —
    whether they come before run 0 has learned anything or later (two regressions: they used to
    redraw every sampling run, then to rebuild every run's mentor terms from the posterior
    means, overwriting run 0's draw; in both, a psrl run in a batch of seeds, each with its own
    demonstrations, was not the run alone)."""
    from himit_torch.mentor.policy import mentor_policy, record_demonstrations
    from himit_torch.options.builders import mentor_options

    options = learner_options(world12)
    policy = mentor_policy(world12, mentor_options(world12))
    d0 = record_demonstrations(world12, policy, 3, seed=0)
    d1 = record_demonstrations(world12, policy, 3, seed=1)
    alone = Learner(world12, options, ["imitation_psrl"], [0], engine="numba")
    alone.add_demonstrations(d0, runs=[0])
    pair = Learner(world12, options, ["imitation_psrl", "imitation_psrl"], [0, 1], engine="numba")
    pair.add_demonstrations(d0, runs=[0])
    pair.add_demonstrations(d1, runs=[1])
    k = int(alone.mentor.num_edges[0])
    assert torch.equal(alone.sample.mentor_w[0, :k], pair.sample.mentor_w[0, :k])
    assert int(alone.sample.resamples[0]) == int(pair.sample.resamples[0])
    alone.run(300)
    pair.run(300)
    assert not torch.all(
        alone.views.state_values()[0] == alone.views.state_values()[0, 0]
    )  # V is no longer flat
    pair.add_demonstrations(d1, runs=[1])  # later evidence for run 1 only
    assert torch.equal(alone.cache.mentor_numerator[0], pair.cache.mentor_numerator[0])
    assert torch.equal(alone.cache.q_numerator[0], pair.cache.q_numerator[0])
    assert torch.equal(alone.sweeper.queue.priority[0], pair.sweeper.queue.priority[0])
    alone.run(2000)
    pair.run(2000)
    assert int(alone.views.decisions[0]) > 100  # it ran
    assert torch.equal(alone.views.state_values()[0], pair.views.state_values()[0])
    assert int(alone.views.decisions[0]) == int(pair.views.decisions[0])
    assert int(alone.sample.resamples[0]) == int(pair.sample.resamples[0])
