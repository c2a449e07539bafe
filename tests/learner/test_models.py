"""Dirichlet-count models: the posterior against scipy, the edge index against a Python dict, and
the SMDP model's posterior mean against the exact option models of the true dynamics."""

import math

import numpy as np
import pytest
import scipy.stats
import torch

from himit_torch.exact.option_models import option_models
from himit_torch.learner.models import (
    DenseEdgeIndex,
    DirichletMentorModel,
    DirichletSMDPModel,
    EdgeStore,
    SuccessorDirichlet,
)
from himit_torch.options.builders import learner_options
from himit_torch.worlds.multirooms import MultiRooms

Z = 5.0  # tolerance in standard errors
CPU = torch.device("cpu")


@pytest.fixture
def gen() -> torch.Generator:
    return torch.Generator().manual_seed(99)


def long(*xs):
    return torch.tensor(xs, dtype=torch.int64)


# ================================================================ SuccessorDirichlet vs scipy
def test_dirichlet_mean_and_variance_match_scipy(gen):
    alpha = torch.rand(6, 5, generator=gen, dtype=torch.float64) * 5 + 0.05
    post = SuccessorDirichlet(alpha, torch.arange(4).repeat(6, 1))
    for i in range(6):
        a = alpha[i].numpy()
        np.testing.assert_allclose(post.mean[i].numpy(), scipy.stats.dirichlet.mean(a), rtol=1e-12)
        np.testing.assert_allclose(
            post.variance[i].numpy(), scipy.stats.dirichlet.var(a), rtol=1e-12
        )
    np.testing.assert_allclose(post.total.numpy(), alpha.sum(-1).numpy(), rtol=1e-12)


def test_dirichlet_zero_concentration_categories(gen):
    """Padding / absent categories (α = 0) get mean 0 and variance 0; the others are the Dirichlet
    of the positive categories alone (scipy); a row with no mass at all is all zeros."""
    alpha = torch.tensor(
        [[2.0, 0.0, 3.0, 0.5], [0.0, 0.0, 0.0, 0.0], [0.0, 4.0, 0.0, 0.0]], dtype=torch.float64
    )
    successors = torch.tensor([[1, -1, 2], [-1, -1, -1], [-1, 5, -1]])
    post = SuccessorDirichlet(alpha, successors)
    keep = alpha[0] > 0
    np.testing.assert_allclose(
        post.mean[0][keep].numpy(), scipy.stats.dirichlet.mean(alpha[0][keep].numpy())
    )
    np.testing.assert_allclose(
        post.variance[0][keep].numpy(), scipy.stats.dirichlet.var(alpha[0][keep].numpy())
    )
    assert post.mean[0, 1].item() == 0.0 and post.variance[0, 1].item() == 0.0
    assert post.mean[1].tolist() == [0.0] * 4 and post.variance[1].tolist() == [0.0] * 4
    assert post.mean[2].tolist() == [0.0, 1.0, 0.0, 0.0] and post.variance[2].tolist() == [0.0] * 4


def test_dirichlet_sample_reproducible_and_leaves_global_rng_alone():
    alpha = torch.tensor([[1.0, 2.0, 0.0, 0.5]] * 3, dtype=torch.float64)
    post = SuccessorDirichlet(alpha, long(0, 1, -1).repeat(3, 1))
    before = torch.random.get_rng_state()
    a = post.sample(torch.Generator().manual_seed(5))
    b = post.sample(torch.Generator().manual_seed(5))
    c = post.sample(torch.Generator().manual_seed(6))
    assert torch.equal(torch.random.get_rng_state(), before)
    assert torch.equal(a, b)
    assert not torch.equal(a, c)
    assert a.shape == alpha.shape
    # The three rows are independent draws, not one draw repeated.
    assert not torch.equal(a[0], a[1])
    assert torch.allclose(a.sum(-1), torch.ones(3, dtype=torch.float64))
    assert (a[:, 2] == 0).all(), "a zero-concentration category must get probability 0"
    # A generator is consumed: two calls on the same one differ.
    g = torch.Generator().manual_seed(5)
    assert not torch.equal(post.sample(g), post.sample(g))


def test_dirichlet_sample_moments_match_scipy(gen):
    n = 20_000
    a = np.array([0.7, 2.0, 3.5, 0.0, 1.0])
    post = SuccessorDirichlet(torch.tensor(a).repeat(n, 1), long(4, 7, 9, -1).repeat(n, 1))
    draws = post.sample(gen)
    keep = a > 0
    mean, var = scipy.stats.dirichlet.mean(a[keep]), scipy.stats.dirichlet.var(a[keep])
    emp_mean = draws.mean(0).numpy()[keep]
    emp_var = draws.var(0).numpy()[keep]
    assert (np.abs(emp_mean - mean) < Z * np.sqrt(var / n)).all(), (emp_mean, mean)
    # sd of a sample variance ≤ √(E[(p − μ)⁴] / n) ≤ √(var / n) since |p − μ| ≤ 1.
    assert (np.abs(emp_var - var) < Z * np.sqrt(var / n)).all(), (emp_var, var)
    assert (draws[:, 3] == 0).all()


def test_posterior_is_a_torch_dirichlet_with_batch_and_event_shapes():
    alpha = (
        torch.rand(2, 3, 5, generator=torch.Generator().manual_seed(1), dtype=torch.float64) + 0.1
    )
    post = SuccessorDirichlet(alpha, torch.zeros(2, 3, 4, dtype=torch.int64))
    assert isinstance(post, torch.distributions.Dirichlet)
    assert isinstance(post, torch.distributions.Distribution)
    assert post.batch_shape == (2, 3) and post.event_shape == (5,)
    draws = post.sample((7,), generator=torch.Generator().manual_seed(3))
    assert draws.shape == (7, 2, 3, 5)
    assert torch.allclose(draws.sum(-1), torch.ones(7, 2, 3, dtype=torch.float64))
    assert post.log_prob(draws).shape == (7, 2, 3)
    assert post.entropy().shape == (2, 3)
    expanded = post.expand((4, 2, 3))
    assert expanded.batch_shape == (4, 2, 3) and expanded.successors.shape == (4, 2, 3, 4)


def test_posterior_log_prob_and_entropy_match_scipy(gen):
    alpha = torch.rand(5, 4, generator=gen, dtype=torch.float64) * 4 + 0.2
    post = SuccessorDirichlet(alpha, torch.zeros(5, 3, dtype=torch.int64))
    x = post.sample(generator=gen)
    for i in range(5):
        a = alpha[i].numpy()
        assert post.log_prob(x)[i].item() == pytest.approx(
            scipy.stats.dirichlet.logpdf(x[i].numpy(), a), rel=1e-10
        )
        assert post.entropy()[i].item() == pytest.approx(
            scipy.stats.dirichlet.entropy(a), rel=1e-10
        )


def test_posterior_log_prob_with_zero_categories_is_the_positive_categories_dirichlet():
    alpha = torch.tensor([[2.0, 0.0, 3.0, 0.5], [0.0, 0.0, 0.0, 0.0]], dtype=torch.float64)
    post = SuccessorDirichlet(alpha, long(1, -1, 2, -1, -1, -1).view(2, 3))
    x = torch.tensor([[0.3, 0.0, 0.5, 0.2], [0.0, 0.0, 0.0, 0.0]], dtype=torch.float64)
    keep = [0, 2, 3]
    assert post.log_prob(x)[0].item() == pytest.approx(
        scipy.stats.dirichlet.logpdf(x[0, keep].numpy(), alpha[0, keep].numpy()), rel=1e-10
    )
    assert post.log_prob(x)[1].item() == 0.0
    assert post.entropy()[0].item() == pytest.approx(
        scipy.stats.dirichlet.entropy(alpha[0, keep].numpy()), rel=1e-10
    )
    # mass on a zero-concentration category is impossible
    y = torch.tensor([[0.3, 0.1, 0.4, 0.2], [1.0, 0.0, 0.0, 0.0]], dtype=torch.float64)
    assert post.log_prob(y).tolist() == [float("-inf"), float("-inf")]


def test_posterior_sample_keyword_generator_equals_positional_and_refuses_bad_concentration():
    post = SuccessorDirichlet(
        torch.tensor([[1.0, 2.0, 0.5]], dtype=torch.float64), long(3, 4)[None]
    )
    a = post.sample(generator=torch.Generator().manual_seed(8))
    b = post.sample(torch.Generator().manual_seed(8))
    assert torch.equal(a, b)
    with pytest.raises(ValueError, match="finite and ≥ 0"):
        SuccessorDirichlet(torch.tensor([[1.0, -1.0]]), long(0)[None])
    with pytest.raises(ValueError, match="finite and ≥ 0"):
        SuccessorDirichlet(torch.tensor([[1.0, float("nan")]]), long(0)[None])
    with pytest.raises(ValueError, match=r"\[\.\.\., K\]"):
        SuccessorDirichlet(torch.tensor([[1.0, 1.0]]), long(0, 1)[None])


# =================================================================== EdgeStore and its index
def _check_store(store: EdgeStore, run: int, expected: dict[tuple[int, int], int] | set) -> None:
    """Run ``run``'s edge list and every table of the dense index agree with the set of
    (row, successor) pairs it should hold."""
    pairs = set(expected)
    E = int(store.num_edges[run])
    assert E == len(pairs)
    got = {(int(r), int(s)) for r, s in zip(store.edge_row[run, :E], store.edge_successor[run, :E])}
    assert got == pairs
    assert (store.edge_row[run, E:] == -1).all()
    index = store.index()
    for e in range(E):
        r, s = int(store.edge_row[run, e]), int(store.edge_successor[run, e])
        fwd = index.forward[run, r, : index.forward_len[run, r]].tolist()
        rev = index.reverse[run, s, : index.reverse_len[run, s]].tolist()
        assert fwd.count(e) == 1 and rev.count(e) == 1
    assert int(index.forward_len[run].sum()) == E and int(index.reverse_len[run].sum()) == E
    # find() returns each edge's own id, and a rebuilt index equals the incremental one.
    runs = torch.full((E,), run)
    assert torch.equal(
        index.find(runs, store.edge_row[run, :E], store.edge_successor[run, :E]), torch.arange(E)
    )
    rebuilt = DenseEdgeIndex(store)
    for name in ("forward", "forward_len", "reverse", "reverse_len"):
        a, b = getattr(index, name), getattr(rebuilt, name)
        w = min(a.shape[-1], b.shape[-1])
        assert torch.equal(a[..., :w], b[..., :w]), name


def test_edge_store_find_or_add_is_per_run():
    store = EdgeStore(num_rows=5, num_states=10, batch=2, device=CPU, concentration=0.0)
    assert store.index().find(long(0, 1), long(0, 3), long(1, 2)).tolist() == [-1, -1]
    ids = store.find_or_add(long(0, 0, 0, 1), long(0, 3, 0, 0), long(1, 2, 1, 9))
    # (0, 1) appears twice for run 0 in one call: one edge, the same id both times; run 1's
    # first edge gets id 0 of its own list.
    assert ids[0] == ids[2] and ids[3] == 0 and store.num_edges.tolist() == [2, 1]
    again = store.find_or_add(long(1, 0), long(0, 3), long(9, 2))
    assert again.tolist() == [0, ids[1].item()] and store.num_edges.tolist() == [2, 1]
    _check_store(store, 0, {(0, 1), (3, 2)})
    _check_store(store, 1, {(0, 9)})


def test_edge_store_grows_capacity_width_and_fan_in():
    S, R = 400, 150
    store = EdgeStore(num_rows=R, num_states=S, batch=2, device=CPU, concentration=0.0, capacity=4)
    grown = []
    store.on_grow.append(grown.append)
    expected = set()
    start = 0
    for chunk in (1, 3, 37, 2, 60, 97):  # many successors of one row, in chunks
        succ = torch.arange(start, start + chunk)
        store.find_or_add(torch.ones(chunk, dtype=torch.int64), torch.full((chunk,), 7), succ)
        expected |= {(7, s) for s in range(start, start + chunk)}
        start += chunk
    store.find_or_add(torch.ones(R, dtype=torch.int64), torch.arange(R), torch.full((R,), 123))
    expected |= {(r, 123) for r in range(R)}  # many rows into one successor
    index = store.index()
    assert index.forward_len[1, 7] == 200 and index.reverse_len[1, 123] == R
    assert store.capacity >= len(expected) and int(store.num_edges[0]) == 0
    assert grown and grown[-1] == store.capacity and grown == sorted(grown)
    assert all(c & (c - 1) == 0 for c in grown), "capacity grows by doubling from 4"
    _check_store(store, 1, expected)
    _check_store(store, 0, set())


def test_edge_store_matches_dict_under_random_inserts(gen):
    S, R, B = 50, 30, 3
    store = EdgeStore(num_rows=R, num_states=S, batch=B, device=CPU, concentration=0.0, capacity=1)
    reference: list[dict[tuple[int, int], int]] = [{} for _ in range(B)]
    for _ in range(40):
        n = int(torch.randint(1, 40, (1,), generator=gen))
        runs = torch.randint(0, B, (n,), generator=gen)
        rows = torch.randint(0, R, (n,), generator=gen)
        succ = torch.randint(0, S, (n,), generator=gen)
        ids = store.find_or_add(runs, rows, succ)
        for b, r, s, e in zip(runs.tolist(), rows.tolist(), succ.tolist(), ids.tolist()):
            # ids are stable: an edge keeps its id forever
            assert reference[b].setdefault((r, s), e) == e
    assert sum(map(len, reference)) > 300
    for b in range(B):
        _check_store(store, b, reference[b])


def test_edge_index_incoming_matches_reverse_lists(gen):
    S, R = 30, 20
    store = EdgeStore(num_rows=R, num_states=S, batch=2, device=CPU, concentration=0.0)
    store.find_or_add(
        torch.randint(0, 2, (200,), generator=gen),
        torch.randint(0, R, (200,), generator=gen),
        torch.randint(0, S, (200,), generator=gen),
    )
    runs, states = torch.tensor([0, 1, 0, 1, 0]), torch.tensor([3, 0, 3, 29, 7])
    owner, edges = store.index().incoming(runs, states)
    got = sorted(zip(owner.tolist(), edges.tolist()))
    expected = sorted(
        (i, e)
        for i, (b, s) in enumerate(zip(runs.tolist(), states.tolist()))
        for e in range(int(store.num_edges[b]))
        if int(store.edge_successor[b, e]) == s
    )
    assert got == expected and len(expected) > 0
    owner, edges = store.index().incoming(
        torch.zeros(0, dtype=torch.int64), torch.zeros(0, dtype=torch.int64)
    )
    assert owner.numel() == 0 and edges.numel() == 0


# ===================================================================== DirichletSMDPModel
def test_smdp_model_hand_case():
    # Run 0, row 2: three executions ending in 5, 5, 7 after 1, 2, 1 steps (γ = 0.5) with
    # discounted rewards 1, 2, 3.  n = 3, Σr = 6 → r̄ = 2;
    # Σγ^k: s'=5 → 0.5 + 0.25 = 0.75, s'=7 → 0.5.  α = 0: weights 0.75/3 = 0.25 and 0.5/3.
    # α = 1: weights 0.75/4 and 0.5/4 (the prior's outcome takes the rest); reward unchanged.
    for alpha, denom in ((0.0, 3.0), (1.0, 4.0)):
        model = DirichletSMDPModel(num_rows=4, num_states=10, batch=2, concentration=alpha)
        for run, row, end, k, r in ((0, 2, 5, 1, 1.0), (0, 2, 5, 2, 2.0), (0, 2, 7, 1, 3.0)):
            model.update(
                long(run), long(row), long(0), long(end), torch.tensor([0.5**k]), torch.tensor([r])
            )
        reward, succ, w = model.mean(long(0, 1), long(2, 2))
        assert reward.tolist() == [pytest.approx(2.0), 0.0]  # run 1 saw nothing
        k5, k7 = succ[0].tolist().index(5), succ[0].tolist().index(7)
        assert w[0, k5].item() == pytest.approx(0.75 / denom)
        assert w[0, k7].item() == pytest.approx(0.5 / denom)
        assert w[0].sum().item() == pytest.approx(1.25 / denom)
        assert (w[1] == 0).all()
        post = model.posterior(long(0, 1), long(2, 2))
        assert post.concentration[0, k5].item() == 2.0 and post.concentration[0, k7].item() == 1.0
        assert post.concentration[0, -1].item() == alpha
        assert post.concentration[1, :-1].sum().item() == 0.0  # run 1 has no edges
        assert (
            post.successors[0].tolist().count(5) == 1 and post.successors[0].tolist().count(7) == 1
        )
        # An untried row: no edges, reward 0.
        r3, s3, w3 = model.mean(long(0), long(3))
        assert r3.item() == 0.0 and (s3 == -1).all() and (w3 == 0).all()


def test_smdp_model_counts_are_per_run():
    model = DirichletSMDPModel(num_rows=3, num_states=6, batch=3)
    for run, end, k, r in ((0, 4, 1, -1.0), (2, 4, 1, 0.5), (2, 5, 1, 0.5), (0, 4, 3, -3.0)):
        model.update(
            long(run),
            long(1),
            long(0),
            long(end),
            torch.tensor([0.9**k], dtype=torch.float64),
            torch.tensor([r], dtype=torch.float64),
        )
    assert model.state_tries[:, 0].tolist() == [2.0, 0.0, 2.0]
    assert model.row_count[:, 1].tolist() == [2.0, 0.0, 2.0]
    assert model.row_reward[:, 1].tolist() == [-4.0, 0.0, 1.0]
    reward, succ, w = model.mean(long(0, 1, 2), long(1, 1, 1))
    assert reward.tolist() == [pytest.approx(-2.0), 0.0, pytest.approx(0.5)]
    k4 = succ[0].tolist().index(4)
    assert w[0, k4].item() == pytest.approx((0.9 + 0.9**3) / 2)
    assert w[2, k4].item() == pytest.approx(0.9 / 2)


def test_models_reject_bad_arguments():
    with pytest.raises(ValueError, match="batch"):
        DirichletSMDPModel(num_rows=3, num_states=6, batch=0)
    with pytest.raises(ValueError, match="concentration"):
        DirichletMentorModel(num_states=6, batch=1, concentration=-1.0)


def _execute(world, options, option, start, n, gen):
    """Run ``option`` ``n`` times from ``start`` in the true world: (end [n], k [n], Σγ^{t} r [n])."""
    pos = torch.full((n,), start, dtype=torch.int64)
    steps = torch.zeros(n, dtype=torch.int64)
    ret = torch.zeros(n, dtype=torch.float64)
    done = torch.zeros(n, dtype=torch.bool)
    terminal = world.terminal_mask
    beta = options.termination[option].double()
    while not bool(done.all()):
        live = ~done
        action = options.policy[option, pos[live]]
        nxt, r = world.step(pos[live], action, generator=gen)
        ret[live] += world.gamma ** steps[live].double() * r.double()
        steps[live] += 1
        pos[live] = nxt
        stop = terminal[nxt] | (
            torch.rand(nxt.shape, generator=gen, dtype=torch.float64) < beta[nxt]
        )
        idx = live.nonzero()[:, 0]
        done[idx[stop]] = True
    return pos, steps, ret


def test_smdp_posterior_mean_converges_to_exact_option_model(gen):
    """Feed the model executions drawn from the true dynamics (world.step); its posterior-mean
    multi-time weights p^o_{ss'} and rewards r(s, o) approach :func:`option_models` within
    Monte-Carlo error: |ŵ − w| ≤ Z·√(w/n) (the sample γ^k·1[s'] lies in [0, 1], so its variance
    is at most w), |r̂ − r| ≤ Z·sd(returns)/√n."""
    world = MultiRooms(8, 2, slip=0.3, gamma=0.9)
    options = learner_options(world)
    exact = option_models(world, options)
    P = exact.transition.to_dense()
    names = options.names
    door = {name: i for i, name in enumerate(names)}
    cases = [
        (9, 0),
        (9, 3),
        (3, 3),
        (55, 1),  # primitives (3→E hits a wall)
        (0, door["doorway room(0,0)->door(2, 4)"]),
        (9, door["doorway room(0,0)->door(4, 2)"]),
        (54, door["doorway room(1,1)->door(4, 6)"]),
    ]  # may slip into the goal
    n = 1000  # (the tolerances below scale with 1/√n; 3000 took ≈ 8 s)
    model = DirichletSMDPModel(num_rows=len(cases), num_states=world.num_states, batch=1)
    stds = []
    for row, (s, o) in enumerate(cases):
        assert bool(options.initiation[o, s])
        end, k, ret = _execute(world, options, o, s, n, gen)
        for j in range(n):  # update() takes one outcome per run at a time
            model.update(
                long(0),
                long(row),
                long(s),
                end[j : j + 1],
                world.gamma ** k[j : j + 1].double(),
                ret[j : j + 1],
            )
        stds.append(ret.std().item())
    reward, succ, w = model.mean(
        torch.zeros(len(cases), dtype=torch.int64), torch.arange(len(cases))
    )
    multi_step = 0
    for row, (s, o) in enumerate(cases):
        m = int(((exact.row_state == s) & (exact.row_option == o)).nonzero()[0, 0])
        est = torch.zeros(world.num_states, dtype=torch.float64)
        keep = succ[row] >= 0
        est[succ[row][keep]] = w[row][keep]
        tol = Z * torch.sqrt(torch.clamp(P[m], min=1.0 / n) / n)
        assert (est - P[m]).abs().le(tol).all(), (names[o], s, (est - P[m]).abs().max())
        assert (P[m][succ[row][keep]] > 0).all(), "a successor the true model rules out"
        r_tol = Z * stds[row] / math.sqrt(n) + 1e-12
        assert abs(reward[row].item() - exact.reward[m].item()) <= r_tol, (names[o], s)
        multi_step += int(P[m].sum() < world.gamma - 1e-6)
    assert multi_step >= 2, "the doorway options should run several steps (Σ p^o < γ)"
    assert int(model.row_count[0, : len(cases)].sum()) == n * len(cases)


# ================================================================== DirichletMentorModel
def test_mentor_model_counts_and_means():
    mentor = DirichletMentorModel(num_states=6, batch=3, capacity=1)
    assert not mentor.observed().any()
    mentor.observe(long(), long())
    assert int(mentor.num_edges.sum()) == 0
    # 0→1 twice, 0→2 once, 3→0 once, for all runs.
    mentor.observe(long(0, 0, 0, 3), long(1, 2, 1, 0))
    assert mentor.row_count[:, 0].tolist() == [3.0] * 3
    assert mentor.row_count[:, 3].tolist() == [1.0] * 3
    assert mentor.observed().tolist() == [[True, False, False, True, False, False]] * 3
    succ, p = mentor.mean(long(0, 1), long(0, 0))
    for b in range(2):
        d = {int(s): float(q) for s, q in zip(succ[b], p[b]) if s >= 0}
        assert d == {1: pytest.approx(2 / 3), 2: pytest.approx(1 / 3)}
    # Only run 1 sees 4→5 (twice) and one more 0→2.
    mentor.observe(long(4, 4, 0), long(5, 5, 2), runs=long(1))
    assert mentor.observed()[:, 4].tolist() == [False, True, False]
    assert mentor.row_count[:, 4].tolist() == [0.0, 2.0, 0.0]
    succ, p = mentor.mean(long(0, 1, 2), long(0, 0, 0))
    got = [
        {int(s): round(float(q), 12) for s, q in zip(succ[b], p[b]) if s >= 0 and q > 0}
        for b in range(3)
    ]
    assert got[0] == got[2] == {1: round(2 / 3, 12), 2: round(1 / 3, 12)}
    assert got[1] == {1: 0.5, 2: 0.5}
    _check_store(mentor, 0, {(0, 1), (0, 2), (3, 0)})
    _check_store(mentor, 1, {(0, 1), (0, 2), (3, 0), (4, 5)})


def test_mentor_model_prior_concentration():
    # α = 2 on the unseen outcome: counts (3 → 1, 1 → 2) give means 3/6, 1/6 and 2/6 unseen.
    mentor = DirichletMentorModel(num_states=4, batch=1, concentration=2.0)
    mentor.observe(long(0, 0, 0, 0), long(1, 1, 1, 2))
    post = mentor.posterior(long(0), long(0))
    succ = post.successors[0].tolist()
    mean = post.mean[0]
    assert mean[succ.index(1)].item() == pytest.approx(0.5)
    assert mean[succ.index(2)].item() == pytest.approx(1 / 6)
    assert mean[-1].item() == pytest.approx(1 / 3)
    _, p = mentor.mean(long(0), long(0))
    assert p.sum().item() == pytest.approx(2 / 3)


def test_a_subnormal_prior_concentration_still_gives_a_distribution():
    """A prior mass as small as a float can be (5e-324, which hypothesis found) is still a
    Dirichlet: its mean is the unseen outcome with probability 1, not 5e-324 / 1e-300."""
    tiny = 5e-324
    post = SuccessorDirichlet(
        torch.tensor([[0.0, 0.0, tiny], [2.0, 1.0, tiny]], dtype=torch.float64),
        torch.tensor([[-1, -1], [3, 4]]),
    )
    assert post.mean.sum(-1).tolist() == [1.0, 1.0]
    assert post.mean[0].tolist() == [0.0, 0.0, 1.0]
    assert bool((post.variance >= 0).all()) and bool(torch.isfinite(post.variance).all())
