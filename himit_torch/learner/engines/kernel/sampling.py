"""Posterior sampling (:mod:`himit_torch.learner.posterior_sampling`, operation for operation):
the fixed-polynomial log and exp, the gamma draws, and a run's resample."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from himit_torch.learner import posterior_sampling as _ps
from himit_torch.learner.engines.kernel.backup import backup_state
from himit_torch.learner.engines.kernel.heap import push
from himit_torch.learner.engines.kernel.jit import ix, phase
from himit_torch.learner.engines.kernel.streams import splitmix, uniform

_INF = np.inf
_LN2 = _ps.LN2
_SQRT_HALF = _ps.SQRT_HALF
_ATANH = np.array(_ps.ATANH_COEFFS)
_INV_LN2 = _ps.INV_LN2
_LN2_HI = _ps.LN2_HI
_LN2_LO = _ps.LN2_LO
_EXPC = np.array(_ps.EXP_COEFFS)
_MAX_ATTEMPTS = _ps.MAX_ATTEMPTS
_BOOST_LANE = _ps.BOOST_LANE
_SAMPLE_TAG = np.uint64(_ps.SAMPLE_TAG)


@njit(inline="always")
def flog(x):
    """:func:`himit_torch.learner.posterior_sampling.fixed_log` (x ≥ 0)."""
    if x == 0.0:
        return -_INF
    m, e = math.frexp(x)
    ef = float(e)
    if m < _SQRT_HALF:
        m = m * 2.0
        ef = ef - 1.0
    else:
        ef = ef - 0.0
    z = (m - 1.0) / (m + 1.0)
    z2 = z * z
    p = _ATANH[12]
    for j in range(11, -1, -1):
        p = p * z2 + _ATANH[j]
    return ef * _LN2 + (2.0 * z) * p


@njit(inline="always")
def fexp(x):
    """:func:`himit_torch.learner.posterior_sampling.fixed_exp`."""
    if x < -708.0:
        return 0.0
    if x > 709.0:
        return _INF
    k = np.floor(x * _INV_LN2 + 0.5)
    r = (x - k * _LN2_HI) - k * _LN2_LO
    p = _EXPC[13]
    for j in range(12, -1, -1):
        p = p * r + _EXPC[j]
    return math.ldexp(p, int(k))


@njit(inline="always")
def sample_key(key, event, kind):
    """:func:`himit_torch.learner.posterior_sampling.sample_keys`."""
    return splitmix(key ^ splitmix(np.uint64(event * 8 + kind) + _SAMPLE_TAG))


@njit
def gamma_draw(key, slot, shape):
    """:func:`himit_torch.learner.posterior_sampling.gamma_draws` for one element."""
    if not shape > 0:
        return 0.0
    boost = shape < 1.0
    a = shape + 1.0 if boost else shape
    d = a - 1.0 / 3.0
    c = 1.0 / np.sqrt(9.0 * d)
    g = d
    for i in range(_MAX_ATTEMPTS):
        x1 = 2.0 * uniform(key, slot, 3 * i) - 1.0
        x2 = 2.0 * uniform(key, slot, 3 * i + 1) - 1.0
        s = x1 * x1 + x2 * x2
        if not (s < 1.0 and s > 0.0):
            continue
        x = x1 * np.sqrt(-2.0 * flog(s) / s)
        v = 1.0 + c * x
        if not v > 0.0:
            continue
        v = v * v * v
        u = uniform(key, slot, 3 * i + 2)
        xx = x * x
        if u < 1.0 - 0.0331 * xx * xx:
            g = d * v
            break
        if flog(u) < 0.5 * xx + d * (1.0 - v + flog(v)):
            g = d * v
            break
    if boost:
        g = g * fexp(flog(uniform(key, slot, _BOOST_LANE)) / shape)
    return g


@njit(inline="always")
def sampled_row_q(st, cache, model, sample, b, row):
    """``ValueCache.apply_sample_rows`` for one row: ``q_num = (n + α) Q̃ − α v0``."""
    conc = st.concentration
    v0 = st.initial_value
    values = cache.values
    n = model.row_count[b, ix(row)]
    rbar = model.row_reward[b, ix(row)] / n if n > 0 else 0.0
    acc = 0.0
    e = model.row_head[b, ix(row)]
    while e >= 0:
        acc += sample.w_opt[b, ix(e)] * (
            rbar
            + (model.edge_disc[b, ix(e)] / model.edge_count[b, ix(e)])
            * values[b, ix(model.edge_succ[b, ix(e)])]
        )
        e = model.row_next[b, ix(e)]
    q = acc + sample.wu_opt[b, ix(row)] * v0
    cache.q_num[b, ix(row)] = (n + conc) * q - conc * v0


@njit(inline="always")
def _draw_row(k_edge, k_unseen, conc, b, row, heads, nexts, counts, row_count, w, wu):
    """One Dirichlet row of ``PosteriorSample.draw`` (the option model's or the mentor's, by
    the arrays given): gamma draws over the row's edges and its unseen successor, normalised
    into ``w[b, e]`` and ``wu[b, row]``."""
    total = 0.0
    e = heads[b, ix(row)]
    while e >= 0:
        gd = gamma_draw(k_edge, e, counts[b, ix(e)])
        w[b, ix(e)] = gd
        total += gd
        e = nexts[b, ix(e)]
    gu = gamma_draw(k_unseen, row, conc) if conc > 0 else 0.0
    total += gu
    n = row_count[b, ix(row)]
    e = heads[b, ix(row)]
    while e >= 0:
        if total > 0:
            w[b, ix(e)] = w[b, ix(e)] / total
        else:
            w[b, ix(e)] = counts[b, ix(e)] / max(n + conc, 1e-300)
        e = nexts[b, ix(e)]
    if total > 0:
        wu[b, ix(row)] = gu / total
    elif n + conc > 0:
        wu[b, ix(row)] = conc / max(n + conc, 1e-300)
    else:
        wu[b, ix(row)] = 0.0
    return n


@phase
def resample(st, world, rows, cache, model, mentor, sweep, sample, key, b):
    """``BatchState.resample`` for run ``b``: fresh draws (``PosteriorSample.draw``), the caches
    rebuilt from them (``ValueCache.apply_sample``), the states whose eq. 2 changed queued."""
    conc = st.concentration
    mconc = st.mentor_concentration
    v0 = st.initial_value
    values = cache.values
    M = cache.q_num.shape[1] - 1
    S = world.terminal.shape[0] - 1
    ev = sample.resamples[b]
    k_edge = sample_key(key, ev, 0)
    k_unseen = sample_key(key, ev, 1)
    for row in range(M):
        _draw_row(
            k_edge,
            k_unseen,
            conc,
            b,
            row,
            model.row_head,
            model.row_next,
            model.edge_count,
            model.row_count,
            sample.w_opt,
            sample.wu_opt,
        )
        sampled_row_q(st, cache, model, sample, b, row)
    if rows.use_mentor[b]:
        k_edge = sample_key(key, ev, 2)
        k_unseen = sample_key(key, ev, 3)
        w_m, wu_m = sample.w_m, sample.wu_m
        for s in range(mentor.row_count.shape[1] - 1):  # each mentor row (one mentor: states)
            n = _draw_row(
                k_edge,
                k_unseen,
                mconc,
                b,
                s,
                mentor.row_head,
                mentor.row_next,
                mentor.edge_count,
                mentor.row_count,
                w_m,
                wu_m,
            )
            if n > 0:
                acc = 0.0
                e = mentor.row_head[b, ix(s)]
                while e >= 0:
                    acc += w_m[b, ix(e)] * (
                        cache.m_edge_reward[b, ix(e)]
                        + cache.m_edge_disc[b, ix(e)] * values[b, ix(mentor.edge_succ[b, ix(e)])]
                    )
                    e = mentor.row_next[b, ix(e)]
                m = acc + wu_m[b, ix(s)] * v0
                cache.m_num[b, ix(s)] = (n + mconc) * m - mconc * v0
    sample.resamples[b] += 1
    thr = st.priority_threshold
    for s in range(S):
        best, has_value, _ = backup_state(st, world, rows, cache, model, mentor, b, s)
        if has_value:
            p = abs(best - values[b, ix(s)])
            if p > thr:
                push(sweep, b, s, p)
