"""Eq. 2 at a state (SPEC.md), and the propagation of a state's new value to the cached Q of
its predecessors: :class:`himit_torch.learner.values.ValueCache` for one run."""

from __future__ import annotations

import numpy as np
from numba import njit

from himit_torch.learner.engines.kernel.heap import raise_to
from himit_torch.learner.engines.kernel.jit import entry, ix, phase
from himit_torch.learner.engines.settings import UNTRIED_PRIOR, UNTRIED_SKIP

_INF = np.inf


@njit(inline="always")
def row_q(st, cache, model, b, row):
    """Q of one cached row: ``(numerator + concentration · v0) / (n + concentration)``
    (``ValueCache.row_q``)."""
    conc = st.concentration
    return (cache.q_num[b, ix(row)] + conc * st.initial_value) / (
        model.row_count[b, ix(row)] + conc
    )


@njit(inline="always")
def row_value(st, rows, cache, model, b, row):
    """``(Q, usable, enabled)`` of one cached row (``ValueCache.own_values``)."""
    n = model.row_count[b, ix(row)]
    q = row_q(st, cache, model, b, row)
    enabled = rows.row_enabled[b, ix(row)]
    mode = st.untried_mode
    if mode == UNTRIED_PRIOR:
        usable = enabled
    elif mode == UNTRIED_SKIP:
        usable = enabled and n > 0
    else:
        if not n > 0:
            q = st.untried_value
        usable = enabled
    return q, usable, enabled


@njit(inline="always")
def mentor_feasible(st, rows, model, mentor, b, s, m_row):
    """Whether the mentor term at ``s`` (mentor row ``m_row``: ``s`` with one mentor) passes
    feasibility testing (``backups.feasible_mentor``): False once every enabled row there was
    tried at least ``mentor_feasibility`` times and none of its outcomes ended in a state the
    mentor was seen moving to from ``s``."""
    need = st.mentor_feasibility
    any_enabled = False
    for row in range(rows.row_begin[ix(s)], rows.row_begin[ix(s + 1)]):
        if not rows.row_enabled[b, ix(row)]:
            continue
        any_enabled = True
        if model.row_count[b, ix(row)] < need:
            return True  # not yet tested
        e = model.row_head[b, ix(row)]
        while e >= 0:
            if model.edge_count[b, ix(e)] > 0:
                f = mentor.row_head[b, ix(m_row)]
                while f >= 0:
                    if mentor.edge_succ[b, ix(f)] == model.edge_succ[b, ix(e)]:
                        return True  # an own option reached the mentor's successor
                    f = mentor.row_next[b, ix(f)]
            e = model.row_next[b, ix(e)]
    return not any_enabled


@njit(inline="always")
def chosen_mentor(st, rows, model, mentor, cache, b, s):
    """``(mentor row, term, count)`` of the mentor term that enters eq. 2 at ``s``
    (``ValueCache._chosen_mentor``, ``backups.best_mentor``): among the mentors seen at ``s``
    (and not shown infeasible there), the one with the largest posterior-mean term, the first
    of equal ones; row −1 where there is none. One mentor: row ``s``."""
    S = mentor.succ_head.shape[1] - 1
    mentors = (mentor.row_count.shape[1] - 1) // S
    mconc = st.mentor_concentration
    v0 = st.initial_value
    chosen, best, n_best = -1, 0.0, 0.0
    for k in range(mentors):
        r = k * S + s
        n_m = mentor.row_count[b, ix(r)]
        if not n_m > 0:
            continue
        if st.mentor_feasibility > 0 and not mentor_feasible(st, rows, model, mentor, b, s, r):
            continue
        m = (cache.m_num[b, ix(r)] + mconc * v0) / (n_m + mconc)
        if chosen < 0 or m > best:
            chosen, best, n_best = r, m, n_m
    return chosen, best, n_best


@njit(inline="always")
def state_backup(st, world, rows, cache, model, mentor, b, s):
    """Eq. 2 at ``s`` for run ``b`` (``ValueCache.state_backup``): ``(best, has_value, won)``,
    ``won`` when the mentor term is the maximum."""
    conc = st.concentration
    v0 = st.initial_value
    z = st.confidence_z
    row_count = model.row_count
    confident_run = rows.use_conf[b]
    own = -_INF
    upper = -_INF
    if st.untried_mode == UNTRIED_SKIP and not confident_run:
        # The common case (untried rows left out, no confidence test), without a branch per
        # row: whether each of a state's rows has been tried goes either way.
        for row in range(rows.row_begin[ix(s)], rows.row_begin[ix(s + 1)]):
            q = row_q(st, cache, model, b, row)
            # + (−0.0) leaves every q as it is (−0.0 included); + (−∞) leaves it out
            q = q + (-0.0 if rows.row_enabled[b, ix(row)] & (row_count[b, ix(row)] > 0) else -_INF)
            if q > own:
                own = q
    else:
        for row in range(rows.row_begin[ix(s)], rows.row_begin[ix(s + 1)]):
            q, usable, _ = row_value(st, rows, cache, model, b, row)
            if usable:
                if q > own:
                    own = q
                if confident_run:
                    n = row_count[b, ix(row)]
                    rsum = model.row_reward[b, ix(row)]
                    rbar = rsum / max(n, 1.0) if n > 0 else 0.0
                    cont = cache.q_num[b, ix(row)] - rsum
                    if n + conc > 0:
                        second = (
                            n * rbar * rbar
                            + 2 * rbar * cont
                            + cache.q_sec[b, ix(row)]
                            + conc * v0 * v0
                        ) / (n + conc)
                        var = max(second - q * q, 0.0) / (n + conc + 1)
                    else:  # untried, valued by untried_value: unbounded above
                        var = _INF
                    up = q + z * np.sqrt(var)
                    if up > upper:
                        upper = up
    mconc = st.mentor_concentration
    ok = False
    m, n_m, m_row = 0.0, 0.0, -1
    if rows.use_mentor[b]:
        m_row, m, n_m = chosen_mentor(st, rows, model, mentor, cache, b, s)
        ok = m_row >= 0
    override = st.mentor_override_after
    if override >= 0 and not model.state_tries[b, ix(s)] < override:
        ok = False
    if ok and confident_run:
        second = (cache.m_sec[b, ix(m_row)] + mconc * v0 * v0) / (n_m + mconc)
        mvar = max(second - m * m, 0.0) / (n_m + mconc + 1)
        if not (m - z * np.sqrt(mvar)) > upper:
            ok = False
    # LearnerConfig.mentor_fade: shrink m towards own by own experience
    fade = st.mentor_fade
    if fade > 0 and np.isfinite(own):
        n_own = model.state_tries[b, ix(s)]
        m = (fade * m + n_own * own) / (fade + n_own)
    if not ok:
        m = -_INF
    best = own if own >= m else m
    has_value = np.isfinite(best) and not world.terminal[ix(s)]
    return best, has_value, ok and m > own


@phase
def backup_state(st, world, rows, cache, model, mentor, b, s):
    """:func:`state_backup` compiled once on its own, for the callers off the tick's hot path
    (:func:`mentor_wins`, the "match" rule, ``resample``), which would otherwise each compile
    an inlined copy (:mod:`.jit`)."""
    return state_backup(st, world, rows, cache, model, mentor, b, s)


@njit(inline="always")
def propagate_options(st, rows, cache, model, sweep, sample, b, x, d, v_old, sampled):
    """``V(x) += d``: every row with an edge to ``x`` gets ``Σγ^k d`` (a sampling run: its
    sampled weight ``(n + α) w_e Σγ^k / c_e``); queue its state
    (``ValueCache.backup_and_propagate``, the options' half)."""
    thr = st.priority_threshold
    conc = st.concentration
    any_conf = st.any_confidence and rows.use_conf[b]
    row_count = model.row_count
    prio = sweep.prio
    e = model.succ_head[b, ix(x)]
    while e >= 0:
        row = model.edge_row[b, ix(e)]
        g = model.edge_disc[b, ix(e)]
        if sampled:
            g = ((row_count[b, ix(row)] + conc) * sample.w_opt[b, ix(e)]) * (
                g / model.edge_count[b, ix(e)]
            )
        gd = g * d
        cache.q_num[b, ix(row)] += gd
        if any_conf:
            c = max(model.edge_count[b, ix(e)], 1.0)
            cache.q_sec[b, ix(row)] += g * g / c * ((v_old + d) ** 2 - v_old**2)
        p = abs(gd) / max(row_count[b, ix(row)] + conc, 1e-300)
        # queued if p > thr, the row is enabled and p raises its state's priority: one test
        # (p above the larger of the two bounds) instead of three branches that go either way
        s = rows.row_state[ix(row)]
        if p > max(thr if rows.row_enabled[b, ix(row)] else _INF, prio[b, ix(s)]):
            raise_to(sweep, b, s, p)
        e = model.succ_next[b, ix(e)]


@njit(inline="always")
def propagate_mentor(st, rows, cache, mentor, sweep, sample, b, x, d, v_old, sampled):
    """The same for the mentor term of every state the mentor left towards ``x`` (a sampling
    run: weight ``(n + α_m) w_e`` in place of the count), each edge's change discounted by its
    ``E[γ^k]`` (``m_edge_disc``: γ for one-step moves)."""
    thr = st.priority_threshold
    mconc = st.mentor_concentration
    any_conf = st.any_confidence and rows.use_conf[b]
    prio = sweep.prio
    S = mentor.succ_head.shape[1] - 1
    e = mentor.succ_head[b, ix(x)]
    while e >= 0:
        disc = cache.m_edge_disc[b, ix(e)]
        gd = disc * d
        src = mentor.edge_row[b, ix(e)]
        c = mentor.edge_count[b, ix(e)]
        if sampled:
            c = (mentor.row_count[b, ix(src)] + mconc) * sample.w_m[b, ix(e)]
        cd = c * gd
        cache.m_num[b, ix(src)] += cd
        if any_conf:
            u_old = cache.m_edge_reward[b, ix(e)] + disc * v_old
            cache.m_sec[b, ix(src)] += c * ((u_old + gd) ** 2 - u_old**2)
        p = abs(cd) / max(mentor.row_count[b, ix(src)] + mconc, 1e-300)
        s = src if src < S else src % S  # the state of mentor row src (several mentors)
        if p > max(thr, prio[b, ix(s)]):  # (p > thr, and it raises the priority; one test)
            raise_to(sweep, b, s, p)
        e = mentor.succ_next[b, ix(e)]


@phase
def run_mentor_wins(st, world, rows, cache, model, mentor, b):
    """``(won, seen)`` for run ``b``: how many of its mentor-observed states the mentor term
    wins eq. 2 in, by the kernel's own backup, and how many states some mentor was seen leaving
    (the tick loop closes each window with it; :meth:`learner.views.mentor_win_share <himit_torch.LearnerViews.mentor_win_share>` divides the
    two)."""
    S = world.terminal.shape[0] - 1
    mentors = (mentor.row_count.shape[1] - 1) // S
    won_states = 0
    seen_states = 0
    for s in range(S):
        seen = False
        for k in range(mentors):
            seen = seen or mentor.row_count[b, k * S + s] > 0
        if seen:
            seen_states += 1
            if rows.use_mentor[b]:
                _, _, won = backup_state(st, world, rows, cache, model, mentor, b, s)
                if won:
                    won_states += 1
    return won_states, seen_states


# Serial: it costs microseconds, and a parallel loop costs seconds of compiling.
@entry
def mentor_wins(st, world, rows, cache, model, mentor, out, seen_out):
    """:func:`run_mentor_wins` of every run, into ``out[b]`` (won) and ``seen_out[b]`` (seen)."""
    for b in range(out.shape[0]):
        out[b], seen_out[b] = run_mentor_wins(st, world, rows, cache, model, mentor, b)
