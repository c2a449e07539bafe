"""The compiled tick loop (Numba): the algorithm of :class:`~himit_torch.learner.engines.TorchEngine`,
one run at a time (:func:`_run`; the engine runs a batch's runs on parallel threads, the loop
releases the GIL).

Every array is allocated by the caller (:mod:`himit_torch.learner.engines.numba_engine`) and worked on in
place: the learner's tensors' memory, plus the engine's own derived structures — linked lists
over each run's model edges and an indexed max-heap over its sweep priorities. Helpers take whole
arrays and indices (never slices), so the hot loop makes no allocations and no reference-counting
calls.

The arithmetic follows the torch engine operation for operation (same formulas, same order of
additions into each cache entry, the same uniforms), so that both engines take the same
decisions and their values agree to rounding.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from himit_torch.learner import posterior_sampling as _ps

_INF = np.inf
_TIE = 1e-12
_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MUL1 = np.uint64(0xBF58476D1CE4E5B9)
_MUL2 = np.uint64(0x94D049BB133111EB)
_TWO_POW_MINUS_53 = 1.0 / 9007199254740992.0

# Indices of the scalar settings in ``cfg_f`` (float64) and ``cfg_i`` (int64).
F_GAMMA, F_EPS_DECAY, F_EPS_MIN, F_THRESHOLD, F_V0, F_CONC, F_MCONC, F_UNTRIED, F_Z = range(9)
(
    I_BACKUPS,
    I_ROUND,
    I_PLAN_EVERY,
    I_MAX_STEPS,
    I_UNTRIED_MODE,
    I_OVERRIDE,
    I_MATCH,
    I_TIE_FIRST,
    I_ANY_CONF,
    I_ANY_MENTOR,
    I_STOCHASTIC,
    I_START,
) = range(12)
# (appended settings, issue 11) ε schedule: 0 decision, 1 step, 2 goals, 3 paper
# (``learner.EPS_SCHEDULES``), and the goals of the "goals" schedule.
I_EPS_SCHEDULE, I_EPS_GOALS = 12, 13
# (appended, issue 11) the mentor term's fading weight (LearnerConfig.mentor_fade; 0 = off)
F_FADE = 9
N_CFG_F = 10
# (appended, issue 9 part 2) posterior sampling: LearnerConfig.resample_every (0 = per episode)
I_RESAMPLE_EVERY = 14
N_CFG_I = 15

# ---- posterior sampling (himit_torch.learner.posterior_sampling, operation for operation) ------------
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
def _splitmix(x):
    z = x + _GOLDEN
    z = (z ^ (z >> np.uint64(30))) * _MUL1
    z = (z ^ (z >> np.uint64(27))) * _MUL2
    return z ^ (z >> np.uint64(31))


@njit(inline="always")
def _uniform(key, counter, lane):
    """Lane ``lane`` of draw ``counter`` of the stream ``key`` (:func:`himit_torch.rng.uniforms`)."""
    salt = _splitmix(np.uint64(counter * 1024 + lane))
    return np.float64(_splitmix(key ^ salt) >> np.uint64(11)) * _TWO_POW_MINUS_53


@njit(inline="always")
def _flog(x):
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
def _fexp(x):
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
def _skey(key, event, kind):
    """:func:`himit_torch.learner.posterior_sampling.sample_keys`."""
    return _splitmix(key ^ _splitmix(np.uint64(event * 8 + kind) + _SAMPLE_TAG))


@njit
def _gamma(key, slot, shape):
    """:func:`himit_torch.learner.posterior_sampling.gamma_draws` for one element."""
    if not shape > 0:
        return 0.0
    boost = shape < 1.0
    a = shape + 1.0 if boost else shape
    d = a - 1.0 / 3.0
    c = 1.0 / np.sqrt(9.0 * d)
    g = d
    for i in range(_MAX_ATTEMPTS):
        x1 = 2.0 * _uniform(key, slot, 3 * i) - 1.0
        x2 = 2.0 * _uniform(key, slot, 3 * i + 1) - 1.0
        s = x1 * x1 + x2 * x2
        if not (s < 1.0 and s > 0.0):
            continue
        x = x1 * np.sqrt(-2.0 * _flog(s) / s)
        v = 1.0 + c * x
        if not v > 0.0:
            continue
        v = v * v * v
        u = _uniform(key, slot, 3 * i + 2)
        xx = x * x
        if u < 1.0 - 0.0331 * xx * xx:
            g = d * v
            break
        if _flog(u) < 0.5 * xx + d * (1.0 - v + _flog(v)):
            g = d * v
            break
    if boost:
        g = g * _fexp(_flog(_uniform(key, slot, _BOOST_LANE)) / shape)
    return g


@njit(inline="always")
def _sampled_row_q(
    cfg_f,
    b,
    row,
    values,
    q_num,
    edge_succ,
    edge_count,
    edge_disc,
    row_count,
    row_reward,
    row_head,
    row_next,
    w_opt,
    wu_opt,
):
    """``ValueCache.apply_sample_rows`` for one row: ``q_num = (n + α) Q̃ − α v0``."""
    conc = cfg_f[F_CONC]
    v0 = cfg_f[F_V0]
    n = row_count[b, row]
    rbar = row_reward[b, row] / n if n > 0 else 0.0
    acc = 0.0
    e = row_head[b, row]
    while e >= 0:
        acc += w_opt[b, e] * (
            rbar + (edge_disc[b, e] / edge_count[b, e]) * values[b, edge_succ[b, e]]
        )
        e = row_next[b, e]
    q = acc + wu_opt[b, row] * v0
    q_num[b, row] = (n + conc) * q - conc * v0


@njit(cache=True, error_model="numpy")
def _resample(
    b,
    key,
    cfg_f,
    cfg_i,
    row_begin,
    terminal,
    use_mentor,
    use_conf,
    row_enabled,
    values,
    q_num,
    q_sec,
    m_num,
    m_sec,
    m_edge_reward,
    edge_succ,
    edge_count,
    edge_disc,
    row_count,
    row_reward,
    state_tries,
    row_head,
    row_next,
    m_edge_succ,
    m_edge_count,
    m_row_count,
    m_row_head,
    m_row_next,
    w_opt,
    wu_opt,
    w_m,
    wu_m,
    resamples,
    heap,
    hkey,
    hpos,
    hsize,
    prio,
):
    """``Learner.resample`` for run ``b``: fresh draws (``PosteriorSample.draw``), the caches
    rebuilt from them (``ValueCache.apply_sample``), changed states queued."""
    conc = cfg_f[F_CONC]
    mconc = cfg_f[F_MCONC]
    v0 = cfg_f[F_V0]
    gamma = cfg_f[F_GAMMA]
    M = q_num.shape[1] - 1
    S = terminal.shape[0] - 1
    ev = resamples[b]
    k_edge = _skey(key, ev, 0)
    k_unseen = _skey(key, ev, 1)
    for row in range(M):
        total = 0.0
        e = row_head[b, row]
        while e >= 0:
            gd = _gamma(k_edge, e, edge_count[b, e])
            w_opt[b, e] = gd
            total += gd
            e = row_next[b, e]
        gu = _gamma(k_unseen, row, conc) if conc > 0 else 0.0
        total += gu
        n = row_count[b, row]
        e = row_head[b, row]
        while e >= 0:
            if total > 0:
                w_opt[b, e] = w_opt[b, e] / total
            else:
                w_opt[b, e] = edge_count[b, e] / max(n + conc, 1e-300)
            e = row_next[b, e]
        if total > 0:
            wu_opt[b, row] = gu / total
        elif n + conc > 0:
            wu_opt[b, row] = conc / max(n + conc, 1e-300)
        else:
            wu_opt[b, row] = 0.0
        _sampled_row_q(
            cfg_f,
            b,
            row,
            values,
            q_num,
            edge_succ,
            edge_count,
            edge_disc,
            row_count,
            row_reward,
            row_head,
            row_next,
            w_opt,
            wu_opt,
        )
    if use_mentor[b]:
        k_edge = _skey(key, ev, 2)
        k_unseen = _skey(key, ev, 3)
        for s in range(S):
            total = 0.0
            e = m_row_head[b, s]
            while e >= 0:
                gd = _gamma(k_edge, e, m_edge_count[b, e])
                w_m[b, e] = gd
                total += gd
                e = m_row_next[b, e]
            gu = _gamma(k_unseen, s, mconc) if mconc > 0 else 0.0
            total += gu
            n = m_row_count[b, s]
            e = m_row_head[b, s]
            while e >= 0:
                if total > 0:
                    w_m[b, e] = w_m[b, e] / total
                else:
                    w_m[b, e] = m_edge_count[b, e] / max(n + mconc, 1e-300)
                e = m_row_next[b, e]
            if total > 0:
                wu_m[b, s] = gu / total
            elif n + mconc > 0:
                wu_m[b, s] = mconc / max(n + mconc, 1e-300)
            else:
                wu_m[b, s] = 0.0
            if n > 0:
                acc = 0.0
                e = m_row_head[b, s]
                while e >= 0:
                    acc += w_m[b, e] * (m_edge_reward[b, e] + gamma * values[b, m_edge_succ[b, e]])
                    e = m_row_next[b, e]
                m = acc + wu_m[b, s] * v0
                m_num[b, s] = (n + mconc) * m - mconc * v0
    resamples[b] += 1
    thr = cfg_f[F_THRESHOLD]
    for s in range(S):
        best, has_value, _ = _state_backup(
            cfg_f,
            cfg_i,
            row_begin,
            terminal,
            use_mentor,
            use_conf,
            q_num,
            q_sec,
            row_count,
            row_reward,
            row_enabled,
            state_tries,
            m_num,
            m_sec,
            m_row_count,
            b,
            s,
        )
        if has_value:
            p = abs(best - values[b, s])
            if p > thr:
                _push(heap, hkey, hpos, hsize, prio, b, s, p)


# ================================================================================ the heap
# Per run: ``heap[b, i]`` the state in slot i, ``hkey[b, i]`` its priority (kept beside it, so
# that comparisons read the heap's own memory), ``hpos[b, s]`` the slot of state s (−1: not
# queued), ``hsize[b]``; ``prio[b, s]`` is the learner's priority array, kept equal.
@njit(inline="always")
def _before(k1, s1, k2, s2):
    """Pop order: priority descending, then state ascending (the torch queue's order).

    A strict total order over the queued states (each state is queued at most once), so the pop
    sequence does not depend on how the heap is laid out. Bitwise ``|``/``&``, not ``or``/``and``:
    one condition without short-circuit branches, which the compiler can turn into a select
    where the heap picks a child (a coin flip for the branch predictor)."""
    return (k1 > k2) | ((k1 == k2) & (s1 < s2))


@njit(inline="always")
def _sift_up(heap, hkey, hpos, b, i):
    s = heap[b, i]
    k = hkey[b, i]
    while i > 0:
        parent = (i - 1) >> 1
        p = heap[b, parent]
        kp = hkey[b, parent]
        if not _before(k, s, kp, p):
            break
        heap[b, i] = p
        hkey[b, i] = kp
        hpos[b, p] = i
        i = parent
    heap[b, i] = s
    hkey[b, i] = k
    hpos[b, s] = i


@njit(inline="always")
def _sift_down(heap, hkey, hpos, hsize, b, i):
    n = hsize[b]
    s = heap[b, i]
    k = hkey[b, i]
    while True:
        child = 2 * i + 1
        if child >= n:
            break
        if child + 1 < n:
            # the child that comes first, by arithmetic on the index rather than a branch
            # (which child wins is a coin flip for the branch predictor)
            child += np.int64(
                _before(hkey[b, child + 1], heap[b, child + 1], hkey[b, child], heap[b, child])
            )
        c = heap[b, child]
        kc = hkey[b, child]
        if not _before(kc, c, k, s):
            break
        heap[b, i] = c
        hkey[b, i] = kc
        hpos[b, c] = i
        i = child
    heap[b, i] = s
    hkey[b, i] = k
    hpos[b, s] = i


@njit(inline="always")
def _push(heap, hkey, hpos, hsize, prio, b, s, p):
    """Raise the priority of ``s`` to at least ``p`` (a scatter-max, as the torch queue)."""
    if p > prio[b, s]:
        _raise(heap, hkey, hpos, hsize, prio, b, s, p)


@njit(inline="always")
def _raise(heap, hkey, hpos, hsize, prio, b, s, p):
    """Set the priority of ``s`` to ``p``, which is above its priority now."""
    prio[b, s] = p
    i = hpos[b, s]
    n = hsize[b]
    new = i < 0  # (not queued: a new slot at the end; without a branch)
    i = n if new else i
    hsize[b] = n + np.int64(new)
    heap[b, i] = s
    hkey[b, i] = p
    _sift_up(heap, hkey, hpos, b, i)


@njit(inline="always")
def _pop(heap, hkey, hpos, hsize, prio, b):
    s = heap[b, 0]
    hsize[b] -= 1
    n = hsize[b]
    hpos[b, s] = -1
    prio[b, s] = 0.0
    if n > 0:
        last = heap[b, n]
        heap[b, 0] = last
        hkey[b, 0] = hkey[b, n]
        hpos[b, last] = 0
        _sift_down(heap, hkey, hpos, hsize, b, 0)
    return s


@njit(inline="always")
def _heapify(heap, hkey, hpos, hsize, prio, b, num):
    n = 0
    for s in range(num):
        hpos[b, s] = -1
        if prio[b, s] > 0.0:
            heap[b, n] = s
            hkey[b, n] = prio[b, s]
            hpos[b, s] = n
            n += 1
    hsize[b] = n
    for i in range((n >> 1) - 1, -1, -1):
        _sift_down(heap, hkey, hpos, hsize, b, i)


# ========================================================================== eq. 2 at a state
@njit(inline="always")
def _row_q(conc, v0, q_num, row_count, b, row):
    """Q of one cached row: ``(numerator + concentration · v0) / (n + concentration)``
    (``ValueCache.row_q``)."""
    return (q_num[b, row] + conc * v0) / (row_count[b, row] + conc)


@njit(inline="always")
def _row_value(cfg_f, cfg_i, q_num, row_count, row_enabled, b, row):
    """``(Q, usable, enabled)`` of one cached row (``ValueCache.own_values``)."""
    n = row_count[b, row]
    q = _row_q(cfg_f[F_CONC], cfg_f[F_V0], q_num, row_count, b, row)
    enabled = row_enabled[b, row]
    mode = cfg_i[I_UNTRIED_MODE]  # 0: prior (concentration > 0), 1: skip, 2: a value
    if mode == 0:
        usable = enabled
    elif mode == 1:
        usable = enabled and n > 0
    else:
        if not n > 0:
            q = cfg_f[F_UNTRIED]
        usable = enabled
    return q, usable, enabled


@njit(inline="always")
def _state_backup(
    cfg_f,
    cfg_i,
    row_begin,
    terminal,
    use_mentor,
    use_conf,
    q_num,
    q_sec,
    row_count,
    row_reward,
    row_enabled,
    state_tries,
    m_num,
    m_sec,
    m_row_count,
    b,
    s,
):
    """Eq. 2 at ``s`` for run ``b`` (``ValueCache.state_backup``): ``(best, has_value, won)``."""
    conc = cfg_f[F_CONC]
    v0 = cfg_f[F_V0]
    z = cfg_f[F_Z]
    confident_run = use_conf[b]
    own = -_INF
    upper = -_INF
    if cfg_i[I_UNTRIED_MODE] == 1 and not confident_run:
        # The common case (untried rows left out, no confidence test), without a branch per
        # row: whether each of a state's rows has been tried goes either way.
        for row in range(row_begin[s], row_begin[s + 1]):
            q = _row_q(conc, v0, q_num, row_count, b, row)
            # + (−0.0) leaves every q as it is (−0.0 included); + (−∞) leaves it out
            q = q + (-0.0 if row_enabled[b, row] & (row_count[b, row] > 0) else -_INF)
            if q > own:
                own = q
    else:
        for row in range(row_begin[s], row_begin[s + 1]):
            q, usable, _ = _row_value(cfg_f, cfg_i, q_num, row_count, row_enabled, b, row)
            if usable:
                if q > own:
                    own = q
                if confident_run:
                    n = row_count[b, row]
                    rsum = row_reward[b, row]
                    rbar = rsum / max(n, 1.0) if n > 0 else 0.0
                    cont = q_num[b, row] - rsum
                    if n + conc > 0:
                        second = (
                            n * rbar * rbar + 2 * rbar * cont + q_sec[b, row] + conc * v0 * v0
                        ) / (n + conc)
                        var = max(second - q * q, 0.0) / (n + conc + 1)
                    else:  # untried, valued by untried_value: unbounded above
                        var = _INF
                    up = q + z * np.sqrt(var)
                    if up > upper:
                        upper = up
    mconc = cfg_f[F_MCONC]
    n_m = m_row_count[b, s]
    ok = use_mentor[b] and n_m > 0
    m = (m_num[b, s] + mconc * v0) / (n_m + mconc)
    override = cfg_i[I_OVERRIDE]
    if override >= 0 and not state_tries[b, s] < override:
        ok = False
    if ok and confident_run:
        second = (m_sec[b, s] + mconc * v0 * v0) / (n_m + mconc)
        mvar = max(second - m * m, 0.0) / (n_m + mconc + 1)
        if not (m - z * np.sqrt(mvar)) > upper:
            ok = False
    # ---- (issue 11) LearnerConfig.mentor_fade: shrink m towards own by own experience
    fade = cfg_f[F_FADE]
    if fade > 0 and np.isfinite(own):
        n_own = state_tries[b, s]
        m = (fade * m + n_own * own) / (fade + n_own)
    if not ok:
        m = -_INF
    best = own if own >= m else m
    has_value = np.isfinite(best) and not terminal[s]
    return best, has_value, ok and m > own


# ==================================================================== propagation and sweeping
@njit(inline="always")
def _propagate_options(
    cfg_f,
    cfg_i,
    use_conf,
    row_state,
    row_enabled,
    q_num,
    q_sec,
    row_count,
    edge_row,
    edge_disc,
    edge_count,
    succ_head,
    succ_next,
    heap,
    hkey,
    hpos,
    hsize,
    prio,
    b,
    x,
    d,
    v_old,
    sampled,
    w_opt,
):
    """``V(x) += d``: every row with an edge to ``x`` gets ``Σγ^k d`` (a sampling run: its
    sampled weight ``(n + α) w_e Σγ^k / c_e``); queue its state."""
    thr = cfg_f[F_THRESHOLD]
    conc = cfg_f[F_CONC]
    any_conf = cfg_i[I_ANY_CONF] != 0 and use_conf[b]
    e = succ_head[b, x]
    while e >= 0:
        row = edge_row[b, e]
        g = edge_disc[b, e]
        if sampled:
            g = ((row_count[b, row] + conc) * w_opt[b, e]) * (g / edge_count[b, e])
        gd = g * d
        q_num[b, row] += gd
        if any_conf:
            c = max(edge_count[b, e], 1.0)
            q_sec[b, row] += g * g / c * ((v_old + d) ** 2 - v_old**2)
        p = abs(gd) / max(row_count[b, row] + conc, 1e-300)
        # queued if p > thr, the row is enabled and p raises its state's priority: one test
        # (p above the larger of the two bounds) instead of three branches that go either way
        s = row_state[row]
        if p > max(thr if row_enabled[b, row] else _INF, prio[b, s]):
            _raise(heap, hkey, hpos, hsize, prio, b, s, p)
        e = succ_next[b, e]


@njit(inline="always")
def _propagate_mentor(
    cfg_f,
    cfg_i,
    use_conf,
    m_num,
    m_sec,
    m_row_count,
    m_edge_row,
    m_edge_count,
    m_edge_reward,
    m_succ_head,
    m_succ_next,
    heap,
    hkey,
    hpos,
    hsize,
    prio,
    b,
    x,
    d,
    v_old,
    sampled,
    w_m,
):
    """The same for the mentor term of every state the mentor left towards ``x`` (a sampling
    run: weight ``(n + α_m) w_e`` in place of the count)."""
    thr = cfg_f[F_THRESHOLD]
    gamma = cfg_f[F_GAMMA]
    mconc = cfg_f[F_MCONC]
    any_conf = cfg_i[I_ANY_CONF] != 0 and use_conf[b]
    gd = gamma * d
    e = m_succ_head[b, x]
    while e >= 0:
        src = m_edge_row[b, e]
        c = m_edge_count[b, e]
        if sampled:
            c = (m_row_count[b, src] + mconc) * w_m[b, e]
        cd = c * gd
        m_num[b, src] += cd
        if any_conf:
            u_old = m_edge_reward[b, e] + gamma * v_old
            m_sec[b, src] += c * ((u_old + gd) ** 2 - u_old**2)
        p = abs(cd) / max(m_row_count[b, src] + mconc, 1e-300)
        if p > max(thr, prio[b, src]):  # (p > thr, and it raises the priority; one test)
            _raise(heap, hkey, hpos, hsize, prio, b, src, p)
        e = m_succ_next[b, e]


# ============================================================================ the tick loop
# error_model="numpy": a division by zero gives inf/nan instead of raising.
# _nrt=False: no reference counting in the loop. The inlined helpers take whole arrays, and Numba
# would otherwise incref and decref every one of them at every call (atomic operations on
# counters shared by the threads, ≈ 30 of them per backup and per predecessor push). The loop
# allocates nothing, and with the runtime off it cannot: Numba refuses to compile it if it did.
# nogil=True: the engine calls it from several threads at once, one run each.
@njit(cache=True, error_model="numpy", _nrt=False, nogil=True)  # type: ignore[call-overload]  # (not in the stubs)
def _run(
    b,
    t_end,
    t_reached,
    keys,
    cfg_f,
    cfg_i,
    # the world and the options (shared, read only)
    dyn_succ,
    dyn_cdf,
    dyn_rew,
    terminal,
    start_cdf,
    termination,
    policy,
    policy_cdf,
    # the row table (shared, read only)
    row_begin,
    row_state,
    row_option,
    row_first_action,
    primitive_rows,
    row_enabled,
    use_mentor,
    use_conf,
    # the value cache
    values,
    q_num,
    q_sec,
    m_num,
    m_sec,
    m_edge_reward,
    # the option model and its linked lists
    edge_row,
    edge_succ,
    edge_count,
    edge_disc,
    num_edges,
    row_count,
    row_reward,
    state_tries,
    row_head,
    row_next,
    succ_head,
    succ_next,
    # the mentor model and its linked lists (read only)
    m_edge_row,
    m_edge_succ,
    m_edge_count,
    m_row_count,
    m_row_head,
    m_row_next,
    m_succ_head,
    m_succ_next,
    # the sweeper
    pending,
    heap,
    hkey,
    hpos,
    hsize,
    prio,
    # the run state
    position,
    option_start,
    row_of,
    duration,
    disc_return,
    discount,
    epsilon,
    found_goal,
    goals,
    window_goals,
    episodes,
    episode_start,
    window_episode_steps,
    window_episodes,
    backups_done,
    decisions,
    first_goal_step,
    visits,
    # posterior sampling (PosteriorSample; use_sampling from the row table)
    use_sampling,
    w_opt,
    wu_opt,
    w_m,
    wu_m,
    resamples,
    # scratch
    round_states,
    round_best,
    round_old,
    round_delta,
    q_buf,
    usable_buf,
    enabled_buf,
    score_buf,
):
    """Advance run ``b`` from tick ``t_reached[b]`` to ``t_end``, in place: act, learn, plan,
    choose — :meth:`TorchEngine.tick <himit_torch.learner.engines.TorchEngine.tick>` for one run.
    (Sweep and choice are written out here rather than called: a call with this many arrays
    costs more than a whole tick.)

    The run stops early, at the start of a tick, when its edge list is full (``num_edges[b]``
    equals the capacity): the caller grows the lists and calls again. ``t_reached[b]`` says
    where it stopped. Runs touch only their own row of every per-run array, so any number of
    them can run at once on separate threads."""
    S = terminal.shape[0] - 1
    M = q_num.shape[1] - 1
    K = dyn_cdf.shape[2]
    capacity = edge_row.shape[1]
    gamma = cfg_f[F_GAMMA]
    threshold = cfg_f[F_THRESHOLD]
    backups = cfg_i[I_BACKUPS]
    round_size = cfg_i[I_ROUND]
    plan_every = cfg_i[I_PLAN_EVERY]
    stochastic = cfg_i[I_STOCHASTIC] != 0
    match = cfg_i[I_MATCH] != 0 and cfg_i[I_ANY_MENTOR] != 0
    mentor_run = cfg_i[I_ANY_MENTOR] != 0 and use_mentor[b]
    sampling_run = use_sampling[b]
    resample_every = cfg_i[I_RESAMPLE_EVERY]
    _heapify(heap, hkey, hpos, hsize, prio, b, S + 1)
    key = np.uint64(keys[b])
    t = t_reached[b]
    while t < t_end:
        if num_edges[b] >= capacity:
            break
        # ---- act: one primitive step of the run's option ----------------------------------
        u0 = _uniform(key, t, 0)
        u1 = _uniform(key, t, 1)
        row = row_of[b]
        option = row_option[row]
        pos = position[b]
        flat = option * S + pos
        if stochastic:
            action = 0
            while action < policy_cdf.shape[1] - 1 and policy_cdf[flat, action] < u1:
                action += 1
            stop_u = _uniform(key, t, 2)
        else:
            action = policy[flat]
            stop_u = u1
        slot = 0
        for k in range(K):
            if dyn_cdf[pos, action, k] <= u0:
                slot += 1
        if slot > K - 1:
            slot = K - 1
        nxt = dyn_succ[pos, action, slot]
        disc_return[b] += discount[b] * dyn_rew[pos, action, slot]
        discount[b] *= gamma
        duration[b] += 1
        t += 1
        at_goal = terminal[nxt]
        ended = (
            at_goal or termination[option * S + nxt] > stop_u or duration[b] >= cfg_i[I_MAX_STEPS]
        )
        position[b] = nxt
        visits[b, nxt] += 1
        if at_goal:
            goals[b] += 1
            window_goals[b] += 1
            if not found_goal[b]:
                first_goal_step[b] = t
            found_goal[b] = True
            episodes[b] += 1
            window_episode_steps[b] += t - episode_start[b]
            window_episodes[b] += 1
            episode_start[b] = t
        # ---- ε schedules other than "decision" (LearnerConfig.eps_schedule; TorchEngine._eps_tick)
        eps_schedule = cfg_i[I_EPS_SCHEDULE]
        if eps_schedule == 1:
            if found_goal[b]:
                epsilon[b] = max(epsilon[b] * cfg_f[F_EPS_DECAY], cfg_f[F_EPS_MIN])
        elif at_goal and eps_schedule == 2:
            if goals[b] >= cfg_i[I_EPS_GOALS]:
                epsilon[b] = cfg_f[F_EPS_MIN]
        elif at_goal and eps_schedule == 3:
            epsilon[b] = max(epsilon[b] * cfg_f[F_EPS_DECAY], cfg_f[F_EPS_MIN])
        # ---- learn: count the option's outcome (DirichletSMDPModel.update) -----------------
        if ended:
            start = option_start[b]
            ret = disc_return[b]
            g = discount[b]
            e = row_head[b, row]
            while e >= 0 and edge_succ[b, e] != nxt:
                e = row_next[b, e]
            if e < 0:
                e = num_edges[b]
                num_edges[b] += 1
                edge_row[b, e] = row
                edge_succ[b, e] = nxt
                edge_count[b, e] = 0.0
                edge_disc[b, e] = 0.0
                row_next[b, e] = row_head[b, row]
                row_head[b, row] = e
                succ_next[b, e] = succ_head[b, nxt]
                succ_head[b, nxt] = e
            c_old = edge_count[b, e]
            g_old = edge_disc[b, e]
            n_old = row_count[b, row]
            edge_count[b, e] = c_old + 1
            edge_disc[b, e] = g_old + g
            row_count[b, row] += 1
            row_reward[b, row] += ret
            state_tries[b, start] += 1
            if sampling_run:
                # ... a sampling run moves its sample to the updated posterior and rebuilds the
                # row from it (PosteriorSample.absorb, ValueCache.apply_sample_rows)
                u = _uniform(_skey(key, 0, 4), decisions[b], 0)
                total = n_old + cfg_f[F_CONC]
                keep = _fexp(_flog(u) / total) if total > 0 else 0.0
                f = row_head[b, row]
                while f >= 0:
                    w_opt[b, f] = w_opt[b, f] * keep
                    f = row_next[b, f]
                wu_opt[b, row] = wu_opt[b, row] * keep
                w_opt[b, e] = w_opt[b, e] + (1.0 - keep)
                _sampled_row_q(
                    cfg_f,
                    b,
                    row,
                    values,
                    q_num,
                    edge_succ,
                    edge_count,
                    edge_disc,
                    row_count,
                    row_reward,
                    row_head,
                    row_next,
                    w_opt,
                    wu_opt,
                )
            else:
                # ... and fold it into the Q cache (ValueCache.add_outcome)
                v_end = values[b, nxt]
                q_num[b, row] += ret + g * v_end
                if use_conf[b]:
                    c_new = c_old + 1
                    g_new = g_old + g
                    old_term = g_old * g_old / max(c_old, 1.0) if c_old > 0 else 0.0
                    q_sec[b, row] += (g_new * g_new / c_new - old_term) * v_end * v_end
            _push(heap, hkey, hpos, hsize, prio, b, start, _INF)  # the start state goes first
            pending[b] += 1
            decisions[b] += 1
            if sampling_run and (
                (resample_every == 0 and at_goal)
                or (resample_every > 0 and decisions[b] % resample_every == 0)
            ):
                # a fresh draw at the episode start / every N decisions (Learner.resample)
                _resample(
                    b,
                    key,
                    cfg_f,
                    cfg_i,
                    row_begin,
                    terminal,
                    use_mentor,
                    use_conf,
                    row_enabled,
                    values,
                    q_num,
                    q_sec,
                    m_num,
                    m_sec,
                    m_edge_reward,
                    edge_succ,
                    edge_count,
                    edge_disc,
                    row_count,
                    row_reward,
                    state_tries,
                    row_head,
                    row_next,
                    m_edge_succ,
                    m_edge_count,
                    m_row_count,
                    m_row_head,
                    m_row_next,
                    w_opt,
                    wu_opt,
                    w_m,
                    wu_m,
                    resamples,
                    heap,
                    hkey,
                    hpos,
                    hsize,
                    prio,
                )
        # ---- plan: prioritized sweeping (Sweeper.sweep + ValueCache.backup_and_propagate) --
        if pending[b] > 0 and t % plan_every == 0:
            budget = pending[b] * backups
            pending[b] = 0
            done = 0
            while done < budget:
                n = min(round_size, budget - done)
                k = 0
                while k < n and hsize[b] > 0 and hkey[b, 0] > threshold:
                    round_states[b, k] = _pop(heap, hkey, hpos, hsize, prio, b)
                    k += 1
                if k == 0:
                    break
                for i in range(k):  # the round's states are backed up together...
                    s = round_states[b, i]
                    best, has_value, _ = _state_backup(
                        cfg_f,
                        cfg_i,
                        row_begin,
                        terminal,
                        use_mentor,
                        use_conf,
                        q_num,
                        q_sec,
                        row_count,
                        row_reward,
                        row_enabled,
                        state_tries,
                        m_num,
                        m_sec,
                        m_row_count,
                        b,
                        s,
                    )
                    round_old[b, i] = values[b, s]
                    round_delta[b, i] = best - values[b, s] if has_value else 0.0
                    round_best[b, i] = best if has_value else values[b, s]
                for i in range(k):
                    values[b, round_states[b, i]] = round_best[b, i]
                backups_done[b] += k
                for i in range(k):  # ...then their changes propagate
                    d = round_delta[b, i]
                    if d != 0:
                        _propagate_options(
                            cfg_f,
                            cfg_i,
                            use_conf,
                            row_state,
                            row_enabled,
                            q_num,
                            q_sec,
                            row_count,
                            edge_row,
                            edge_disc,
                            edge_count,
                            succ_head,
                            succ_next,
                            heap,
                            hkey,
                            hpos,
                            hsize,
                            prio,
                            b,
                            round_states[b, i],
                            d,
                            round_old[b, i],
                            sampling_run,
                            w_opt,
                        )
                if mentor_run:
                    for i in range(k):
                        d = round_delta[b, i]
                        if d != 0:
                            _propagate_mentor(
                                cfg_f,
                                cfg_i,
                                use_conf,
                                m_num,
                                m_sec,
                                m_row_count,
                                m_edge_row,
                                m_edge_count,
                                m_edge_reward,
                                m_succ_head,
                                m_succ_next,
                                heap,
                                hkey,
                                hpos,
                                hsize,
                                prio,
                                b,
                                round_states[b, i],
                                d,
                                round_old[b, i],
                                sampling_run,
                                w_m,
                            )
                done += round_size
        if not ended:
            continue
        # ---- choose: ε-greedy over the run's own rows (choice.choose_rows) -------------------
        if found_goal[b] and cfg_i[I_EPS_SCHEDULE] == 0:
            epsilon[b] = max(epsilon[b] * cfg_f[F_EPS_DECAY], cfg_f[F_EPS_MIN])
        duration[b] = 0
        disc_return[b] = 0.0
        discount[b] = 1.0
        here = nxt
        if at_goal:
            if cfg_i[I_START] >= 0:
                here = cfg_i[I_START]
            else:
                u5 = _uniform(key, t - 1, 5)
                here = 0
                while here < S - 1 and start_cdf[here] <= u5:
                    here += 1
        position[b] = here
        option_start[b] = here
        first = row_begin[here]  # the rows of ``here``: first, first + 1, ..., first + n_rows - 1
        n_rows = row_begin[here + 1] - first
        for j in range(n_rows):
            q, usable, enabled = _row_value(
                cfg_f, cfg_i, q_num, row_count, row_enabled, b, first + j
            )
            q_buf[b, j] = q if usable else -_INF
            usable_buf[b, j] = usable
            enabled_buf[b, j] = enabled
        if match:
            # Where the mentor term wins, own options whose first action best reproduces the
            # mentor's move come first (choice._match_mentor).
            _, _, won = _state_backup(
                cfg_f,
                cfg_i,
                row_begin,
                terminal,
                use_mentor,
                use_conf,
                q_num,
                q_sec,
                row_count,
                row_reward,
                row_enabled,
                state_tries,
                m_num,
                m_sec,
                m_row_count,
                b,
                here,
            )
            if won:
                n_m = max(m_row_count[b, here], 1.0)
                for a in range(primitive_rows.shape[1]):
                    prow = primitive_rows[here, a]
                    total = 0.0
                    n_p = max(row_count[b, prow], 1.0)
                    e = row_head[b, prow]
                    while e >= 0:
                        f = m_row_head[b, here]
                        while f >= 0:
                            if m_edge_succ[b, f] == edge_succ[b, e]:
                                total += (edge_count[b, e] / n_p) * (m_edge_count[b, f] / n_m)
                            f = m_row_next[b, f]
                        e = row_next[b, e]
                    score_buf[b, a] = total
                A_p = primitive_rows.shape[1]
                best_score = 0.0
                for j in range(n_rows):
                    a = min(row_first_action[first + j], A_p - 1)
                    sc = score_buf[b, a] if usable_buf[b, j] else 0.0
                    if sc > best_score:
                        best_score = sc
                if best_score > 0:
                    for j in range(n_rows):
                        a = min(row_first_action[first + j], A_p - 1)
                        sc = score_buf[b, a] if usable_buf[b, j] else 0.0
                        if sc >= best_score - _TIE:
                            q_buf[b, j] += 1e6
        top = -_INF
        for j in range(n_rows):
            if q_buf[b, j] > top:
                top = q_buf[b, j]
        any_greedy = False
        for j in range(n_rows):
            if usable_buf[b, j] and q_buf[b, j] >= top - _TIE:
                any_greedy = True
                break
        explore = _uniform(key, t - 1, 3) < epsilon[b]
        count = 0
        for j in range(n_rows):
            if explore or not any_greedy:
                cand = enabled_buf[b, j]
            else:
                cand = usable_buf[b, j] and q_buf[b, j] >= top - _TIE
            usable_buf[b, j] = cand  # from here on: the candidate mask
            if cand:
                count += 1
        pick = min(np.int64(_uniform(key, t - 1, 4) * count), count - 1)
        if cfg_i[I_TIE_FIRST] != 0 and not explore:
            pick = 0
        chosen = first if n_rows > 0 else M  # (M: no row, as the torch engine's padding)
        seen = 0
        for j in range(n_rows):
            if usable_buf[b, j]:
                if seen == pick:
                    chosen = first + j
                    break
                seen += 1
        row_of[b] = chosen
    t_reached[b] = t


@njit(cache=True)
def link_edges(edge_row, edge_succ, num_edges, row_head, row_next, succ_head, succ_next):
    """Linked lists over each run's edges (by row and by successor), from the edge lists."""
    row_head[:] = -1
    succ_head[:] = -1
    row_next[:] = -1
    succ_next[:] = -1
    for b in range(edge_row.shape[0]):
        for e in range(num_edges[b]):
            r = edge_row[b, e]
            s = edge_succ[b, e]
            row_next[b, e] = row_head[b, r]
            row_head[b, r] = e
            succ_next[b, e] = succ_head[b, s]
            succ_head[b, s] = e


# Serial: once a window it costs microseconds, and a parallel loop costs seconds of compiling.
@njit(cache=True, error_model="numpy")
def mentor_wins(
    cfg_f,
    cfg_i,
    row_begin,
    terminal,
    use_mentor,
    use_conf,
    q_num,
    q_sec,
    row_count,
    row_reward,
    row_enabled,
    state_tries,
    m_num,
    m_sec,
    m_row_count,
    out,
):
    """``out[b]``: how many of run ``b``'s mentor-observed states the mentor term wins eq. 2 in
    (:meth:`Learner.mentor_win_share`), by the kernel's own backup."""
    B = out.shape[0]
    S = terminal.shape[0] - 1
    for b in range(B):
        won_states = 0
        if use_mentor[b]:
            for s in range(S):
                if m_row_count[b, s] > 0:
                    _, _, won = _state_backup(
                        cfg_f,
                        cfg_i,
                        row_begin,
                        terminal,
                        use_mentor,
                        use_conf,
                        q_num,
                        q_sec,
                        row_count,
                        row_reward,
                        row_enabled,
                        state_tries,
                        m_num,
                        m_sec,
                        m_row_count,
                        b,
                        s,
                    )
                    if won:
                        won_states += 1
        out[b] = won_states
