"""The tick loop, one run at a time: act → learn → plan → choose, each phase one function
(compiled on its own or inlined: :mod:`.jit`); :meth:`TorchEngine.tick
<himit_torch.learner.engines.TorchEngine.tick>` for one run."""

from __future__ import annotations

import numpy as np
from numba import njit

from himit_torch.learner.engines.kernel.backup import (
    backup_state,
    chosen_mentor,
    propagate_mentor,
    propagate_options,
    row_value,
    run_mentor_wins,
    state_backup,
)
from himit_torch.learner.engines.kernel.heap import heapify, pop, push
from himit_torch.learner.engines.kernel.jit import entry, ix, phase
from himit_torch.learner.engines.kernel.sampling import (
    fexp,
    flog,
    resample,
    sample_key,
    sampled_row_q,
)
from himit_torch.learner.engines.kernel.streams import uniform
from himit_torch.learner.engines.settings import (
    EPS_DECISION,
    EPS_GOALS,
    EPS_PAPER,
    EPS_STEP,
    MATCH,
    TIE_FIRST,
)

_INF = np.inf
_TIE = 1e-12


@njit(inline="always")
def act(st, world, rows, run, key, b, t):
    """One primitive step of run ``b``'s option at tick ``t`` (the torch engine's act phase):
    ``(row, nxt, at_goal, ended)``, the row executed, where it went, and whether the option
    ended there. Counts the step in the run state."""
    S = world.terminal.shape[0] - 1
    K = world.dyn_cdf.shape[2]
    u0 = uniform(key, t, 0)
    u1 = uniform(key, t, 1)
    row = run.row_of[b]
    option = rows.row_option[ix(row)]
    pos = run.position[b]
    flat = option * S + pos
    if st.stochastic:
        policy_cdf = world.policy_cdf
        action = 0
        while action < policy_cdf.shape[1] - 1 and policy_cdf[ix(flat), ix(action)] < u1:
            action += 1
        stop_u = uniform(key, t, 2)
    else:
        action = world.policy[ix(flat)]
        stop_u = u1
    slot = 0
    for k in range(K):
        if world.dyn_cdf[ix(pos), ix(action), ix(k)] <= u0:
            slot += 1
    if slot > K - 1:
        slot = K - 1
    nxt = world.dyn_succ[ix(pos), ix(action), ix(slot)]
    run.disc_return[b] += run.discount[b] * world.dyn_rew[ix(pos), ix(action), ix(slot)]
    run.discount[b] *= st.gamma
    run.duration[b] += 1
    at_goal = world.terminal[ix(nxt)]
    ended = (
        at_goal
        or world.termination[ix(option * S + nxt)] > stop_u
        or run.duration[b] >= st.max_option_steps
    )
    run.position[b] = nxt
    run.visits[b, ix(nxt)] += 1
    if at_goal:
        t_after = t + 1
        run.goals[b] += 1
        run.window_goals[b] += 1
        if not run.found_goal[b]:
            run.first_goal_step[b] = t_after
        run.found_goal[b] = True
        run.episodes[b] += 1
        run.window_episode_steps[b] += t_after - run.episode_start[b]
        run.window_episodes[b] += 1
        run.episode_start[b] = t_after
    return row, nxt, at_goal, ended


@njit(inline="always")
def decay_epsilon_per_step(st, run, b, at_goal):
    """The ε schedules other than "decision", after each step (``TorchEngine._eps_tick``)."""
    schedule = st.eps_schedule
    epsilon = run.epsilon
    if schedule == EPS_STEP:
        if run.found_goal[b]:
            epsilon[b] = max(epsilon[b] * st.eps_decay, st.eps_min)
    elif at_goal and schedule == EPS_GOALS:
        if run.goals[b] >= st.eps_goals:
            epsilon[b] = st.eps_min
    elif at_goal and schedule == EPS_PAPER:
        epsilon[b] = max(epsilon[b] * st.eps_decay, st.eps_min)


@phase
def count_outcome(st, rows, cache, model, sweep, run, sample, key, b, row, nxt):
    """Learn: count the ended option's outcome (``DirichletSMDPModel.update``) and fold it into
    the Q cache (``ValueCache.add_outcome``; a sampling run: ``PosteriorSample.absorb`` and
    ``ValueCache.apply_sample_rows``); queue its start state first."""
    start = run.option_start[b]
    ret = run.disc_return[b]
    g = run.discount[b]
    edge_succ, edge_count, edge_disc = model.edge_succ, model.edge_count, model.edge_disc
    row_head, row_next = model.row_head, model.row_next
    e = row_head[b, ix(row)]
    while e >= 0 and edge_succ[b, ix(e)] != nxt:
        e = row_next[b, ix(e)]
    if e < 0:  # a new edge, linked at the heads of its row's and its successor's lists
        e = model.num_edges[b]
        model.num_edges[b] += 1
        model.edge_row[b, ix(e)] = row
        edge_succ[b, ix(e)] = nxt
        edge_count[b, ix(e)] = 0.0
        edge_disc[b, ix(e)] = 0.0
        row_next[b, ix(e)] = row_head[b, ix(row)]
        row_head[b, ix(row)] = e
        model.succ_next[b, ix(e)] = model.succ_head[b, ix(nxt)]
        model.succ_head[b, ix(nxt)] = e
    c_old = edge_count[b, ix(e)]
    g_old = edge_disc[b, ix(e)]
    n_old = model.row_count[b, ix(row)]
    edge_count[b, ix(e)] = c_old + 1
    edge_disc[b, ix(e)] = g_old + g
    model.row_count[b, ix(row)] += 1
    model.row_reward[b, ix(row)] += ret
    model.state_tries[b, ix(start)] += 1
    if rows.use_sampling[b]:
        # the sample moves to the updated posterior; the row is rebuilt from it
        w_opt = sample.w_opt
        u = uniform(sample_key(key, 0, 4), run.decisions[b], 0)
        total = n_old + st.concentration
        keep = fexp(flog(u) / total) if total > 0 else 0.0
        f = row_head[b, ix(row)]
        while f >= 0:
            w_opt[b, ix(f)] = w_opt[b, ix(f)] * keep
            f = row_next[b, ix(f)]
        sample.wu_opt[b, ix(row)] = sample.wu_opt[b, ix(row)] * keep
        w_opt[b, ix(e)] = w_opt[b, ix(e)] + (1.0 - keep)
        sampled_row_q(st, cache, model, sample, b, row)
    else:
        v_end = cache.values[b, ix(nxt)]
        cache.q_num[b, ix(row)] += ret + g * v_end
        if rows.use_conf[b]:
            c_new = c_old + 1
            g_new = g_old + g
            old_term = g_old * g_old / max(c_old, 1.0) if c_old > 0 else 0.0
            cache.q_sec[b, ix(row)] += (g_new * g_new / c_new - old_term) * v_end * v_end
    push(sweep, b, start, _INF)  # the start state goes first
    sweep.pending[b] += 1
    run.decisions[b] += 1


@njit(inline="always")
def resample_due(st, rows, run, b, at_goal):
    """A sampling run draws afresh at each episode's start (``resample_every`` 0) or every
    ``resample_every`` decisions (``BatchState.resample``)."""
    every = st.resample_every
    return rows.use_sampling[b] and (
        (every == 0 and at_goal) or (every > 0 and run.decisions[b] % every == 0)
    )


@njit(inline="always")
def plan(st, world, rows, cache, model, mentor, sweep, sample, scratch, b):
    """Prioritized sweeping of run ``b``'s pending budget (``Sweeper.sweep`` with
    ``ValueCache.backup_and_propagate``): rounds of up to ``round_size`` states above the
    threshold, backed up together (eq. 2), then their changes propagated to predecessors.
    Returns the number of states backed up."""
    sampled = rows.use_sampling[b]
    mentor_run = st.any_mentor and rows.use_mentor[b]
    round_size = st.round_size
    threshold = st.priority_threshold
    values = cache.values
    round_states, round_best = scratch.round_states, scratch.round_best
    round_old, round_delta = scratch.round_old, scratch.round_delta
    budget = sweep.pending[b] * st.backups
    sweep.pending[b] = 0
    done = 0
    backed_up = 0
    while done < budget:
        n = min(round_size, budget - done)
        k = 0
        while k < n and sweep.hsize[b] > 0 and sweep.hkey[b, 0] > threshold:
            round_states[b, ix(k)] = pop(sweep, b)
            k += 1
        if k == 0:
            break
        for i in range(k):  # the round's states are backed up together...
            s = round_states[b, ix(i)]
            best, has_value, _ = state_backup(st, world, rows, cache, model, mentor, b, s)
            round_old[b, ix(i)] = values[b, ix(s)]
            round_delta[b, ix(i)] = best - values[b, ix(s)] if has_value else 0.0
            round_best[b, ix(i)] = best if has_value else values[b, ix(s)]
        for i in range(k):
            values[b, ix(round_states[b, ix(i)])] = round_best[b, ix(i)]
        backed_up += k
        for i in range(k):  # ...then their changes propagate
            d = round_delta[b, ix(i)]
            if d != 0:
                propagate_options(
                    st, rows, cache, model, sweep, sample, b, round_states[b, ix(i)], d,
                    round_old[b, ix(i)], sampled,
                )  # fmt: skip
        if mentor_run:
            for i in range(k):
                d = round_delta[b, ix(i)]
                if d != 0:
                    propagate_mentor(
                        st, rows, cache, mentor, sweep, sample, b, round_states[b, ix(i)], d,
                        round_old[b, ix(i)], sampled,
                    )  # fmt: skip
        done += round_size
    return backed_up


@njit(inline="always")
def _mentor_move_scores(st, rows, cache, model, mentor, scratch, b, here):
    """``scratch.score_buf[b, a]``: how well primitive ``a``'s learned one-step model reproduces
    the mentor's observed move at ``here`` (``choice.mentor_move_scores``; several mentors: the
    move of the one whose term eq. 2 takes)."""
    primitive_rows = rows.primitive_rows
    score_buf = scratch.score_buf
    m_row, _, _ = chosen_mentor(st, rows, model, mentor, cache, b, here)
    m_row = max(m_row, here)  # (none seen: mentor 0's empty row, as the torch path reads it)
    n_m = max(mentor.row_count[b, m_row], 1.0)
    for a in range(primitive_rows.shape[1]):
        prow = primitive_rows[here, a]
        total = 0.0
        n_p = max(model.row_count[b, prow], 1.0)
        e = model.row_head[b, prow]
        while e >= 0:
            f = mentor.row_head[b, m_row]
            while f >= 0:
                if mentor.edge_succ[b, f] == model.edge_succ[b, e]:
                    total += (model.edge_count[b, e] / n_p) * (mentor.edge_count[b, f] / n_m)
                f = mentor.row_next[b, f]
            e = model.row_next[b, e]
        score_buf[b, a] = total


@phase
def _match_mentor(st, world, rows, cache, model, mentor, scratch, b, here):
    """The "match" rule (``choice._match_mentor``): where the mentor term wins eq. 2 at
    ``here``, own options whose first action best reproduces the mentor's move come first
    (their Q in ``scratch.q_buf`` raised by 10⁶)."""
    _, _, won = backup_state(st, world, rows, cache, model, mentor, b, here)
    if not won:
        return
    _mentor_move_scores(st, rows, cache, model, mentor, scratch, b, here)
    score_buf, usable_buf, q_buf = scratch.score_buf, scratch.usable_buf, scratch.q_buf
    first = rows.row_begin[here]
    n_rows = rows.row_begin[here + 1] - first
    A_p = rows.primitive_rows.shape[1]
    best_score = 0.0
    for j in range(n_rows):
        a = min(rows.row_first_action[first + j], A_p - 1)
        sc = score_buf[b, a] if usable_buf[b, j] else 0.0
        if sc > best_score:
            best_score = sc
    if best_score > 0:
        for j in range(n_rows):
            a = min(rows.row_first_action[first + j], A_p - 1)
            sc = score_buf[b, a] if usable_buf[b, j] else 0.0
            if sc >= best_score - _TIE:
                q_buf[b, j] += 1e6


@phase
def _trial_mentor(st, world, rows, cache, model, mentor, scratch, b, here):
    """``LearnerConfig.mentor_trial`` (``choice.trial_candidates``): where the mentor term wins
    eq. 2 at ``here`` and some enabled row there is untried, the untried rows whose first
    action best reproduces the mentor's move are the only greedy candidates (their Q in
    ``scratch.q_buf`` set to 2·10⁶, above every other, and usable)."""
    first = rows.row_begin[here]
    n_rows = rows.row_begin[here + 1] - first
    enabled_buf = scratch.enabled_buf
    any_untried = False
    for j in range(n_rows):
        if enabled_buf[b, j] and not model.row_count[b, first + j] > 0:
            any_untried = True
            break
    if not any_untried:
        return
    _, _, won = backup_state(st, world, rows, cache, model, mentor, b, here)
    if not won:
        return
    _mentor_move_scores(st, rows, cache, model, mentor, scratch, b, here)
    score_buf, usable_buf, q_buf = scratch.score_buf, scratch.usable_buf, scratch.q_buf
    A_p = rows.primitive_rows.shape[1]
    best_score = -1.0
    for j in range(n_rows):
        if enabled_buf[b, j] and not model.row_count[b, first + j] > 0:
            sc = score_buf[b, min(rows.row_first_action[first + j], A_p - 1)]
            if sc > best_score:
                best_score = sc
    for j in range(n_rows):
        if enabled_buf[b, j] and not model.row_count[b, first + j] > 0:
            sc = score_buf[b, min(rows.row_first_action[first + j], A_p - 1)]
            if sc >= best_score - _TIE:
                q_buf[b, j] = 2e6
                usable_buf[b, j] = True


@njit(inline="always")
def choose(st, world, rows, cache, model, mentor, run, clone, scratch, key, b, t, here):
    """ε-greedy over the own rows of ``here`` (``choice.choose_rows``) with the draws of tick
    ``t``: the run's next row, in ``run.row_of[b]``. A ``bco`` run's greedy choice is its cloned
    action's primitive row where it has one (``choice.greedy_rows``)."""
    M = cache.q_num.shape[1] - 1
    q_buf, usable_buf, enabled_buf = scratch.q_buf, scratch.usable_buf, scratch.enabled_buf
    # the rows of ``here``: first, first + 1, ..., first + n_rows - 1
    first = rows.row_begin[ix(here)]
    n_rows = rows.row_begin[ix(here + 1)] - first
    for j in range(n_rows):
        q, usable, enabled = row_value(st, rows, cache, model, b, first + j)
        q_buf[b, ix(j)] = q if usable else -_INF
        usable_buf[b, ix(j)] = usable
        enabled_buf[b, ix(j)] = enabled
    if st.mentor_choice == MATCH and st.any_mentor:
        _match_mentor(st, world, rows, cache, model, mentor, scratch, b, here)
    if st.mentor_trial and st.any_mentor and rows.use_mentor[b]:
        _trial_mentor(st, world, rows, cache, model, mentor, scratch, b, here)
    top = -_INF
    for j in range(n_rows):
        if q_buf[b, ix(j)] > top:
            top = q_buf[b, ix(j)]
    any_greedy = False
    for j in range(n_rows):
        if usable_buf[b, ix(j)] and q_buf[b, ix(j)] >= top - _TIE:
            any_greedy = True
            break
    clone_row = M  # (M: no cloned action here)
    cloned = clone.action[b, ix(here)]
    if cloned >= 0:
        clone_row = rows.primitive_rows[ix(here), ix(cloned)]
    explore = uniform(key, t, 3) < run.epsilon[b]
    count = 0
    for j in range(n_rows):
        if explore:
            cand = enabled_buf[b, ix(j)]
        elif clone_row < M:
            cand = first + j == clone_row
        elif not any_greedy:
            cand = enabled_buf[b, ix(j)]
        else:
            cand = usable_buf[b, ix(j)] and q_buf[b, ix(j)] >= top - _TIE
        usable_buf[b, ix(j)] = cand  # from here on: the candidate mask
        if cand:
            count += 1
    pick = min(np.int64(uniform(key, t, 4) * count), count - 1)
    if st.tie_break == TIE_FIRST and not explore:
        pick = 0
    chosen = first if n_rows > 0 else M  # (M: no row, as the torch engine's padding)
    seen = 0
    for j in range(n_rows):
        if usable_buf[b, ix(j)]:
            if seen == pick:
                chosen = first + j
                break
            seen += 1
    run.row_of[b] = chosen


@phase
def start_option(st, world, run, key, b, t, nxt, at_goal):
    """Where the next option starts: ``nxt``, or a start state after a goal (drawn with the
    uniforms of tick ``t``, ``WorldTables.start_states``); the option's counters reset."""
    if run.found_goal[b] and st.eps_schedule == EPS_DECISION:
        run.epsilon[b] = max(run.epsilon[b] * st.eps_decay, st.eps_min)
    run.duration[b] = 0
    run.disc_return[b] = 0.0
    run.discount[b] = 1.0
    here = nxt
    if at_goal:
        if st.start_state >= 0:
            here = st.start_state
        else:
            start_cdf = world.start_cdf
            S = world.terminal.shape[0] - 1
            u5 = uniform(key, t, 5)
            here = 0
            while here < S - 1 and start_cdf[here] <= u5:
                here += 1
    run.position[b] = here
    run.option_start[b] = here
    return here


@phase
def close_window(st, world, rows, cache, model, mentor, run, windows, b):
    """Record run ``b``'s window that ends now into ``windows`` (``RunMetrics.record``'s
    counts, ``WINDOW_COUNTS``, and ε) and reset its window counters."""
    i = windows.closed[b]
    won, seen = run_mentor_wins(st, world, rows, cache, model, mentor, b)
    counts = windows.counts
    counts[b, i, 0] = run.window_goals[b]
    counts[b, i, 1] = run.episodes[b]
    counts[b, i, 2] = run.window_episode_steps[b]
    counts[b, i, 3] = run.window_episodes[b]
    counts[b, i, 4] = run.backups_done[b]
    counts[b, i, 5] = run.decisions[b]
    counts[b, i, 6] = won
    counts[b, i, 7] = seen
    windows.epsilon[b, i] = run.epsilon[b]
    windows.closed[b] = i + 1
    run.window_goals[b] = 0
    run.window_episode_steps[b] = 0
    run.window_episodes[b] = 0


@entry  # (the flags: .jit)
def run_ticks(
    t_end,
    t_reached,
    st,
    world,
    rows,
    cache,
    model,
    mentor,
    sweep,
    run,
    sample,
    clone,
    windows,
    scratch,
):
    """Advance the run from tick ``t_reached[0]`` to ``t_end``, in place: act, learn, plan,
    choose — :meth:`TorchEngine.tick <himit_torch.learner.engines.TorchEngine.tick>` for one run
    — closing each window (:func:`close_window`) at its last tick, as ``Learner.run`` does
    between the torch engine's calls.

    Every per-run array holds this one run's row (``B = 1``): a one-run batch's arrays, or one
    run's rows of a batch's (``x[b : b + 1]``, the compiled engine's ``_run_all``),
    so any number of runs can advance at once on separate threads. The run stops early, at the
    start of a tick, when its edge list is full (``num_edges[0]`` equals the capacity): the
    caller grows the lists and calls again. ``t_reached[0]`` says where it stopped."""
    # One run per call, row 0 of every per-run array (a one-run batch's, or a run's rows of a
    # batch: NumbaEngine): a constant, so every per-run index is an offset LLVM computes once.
    b = 0
    capacity = model.edge_row.shape[1]
    heapify(sweep, b, world.terminal.shape[0])
    key = np.uint64(run.keys[b])
    t = t_reached[b]
    while t < t_end:
        if model.num_edges[b] >= capacity:
            break
        row, nxt, at_goal, ended = act(st, world, rows, run, key, b, t)
        t += 1
        decay_epsilon_per_step(st, run, b, at_goal)
        if ended:
            count_outcome(st, rows, cache, model, sweep, run, sample, key, b, row, nxt)
            if resample_due(st, rows, run, b, at_goal):
                resample(st, world, rows, cache, model, mentor, sweep, sample, key, b)
        if sweep.pending[b] > 0 and t % st.plan_every == 0:
            run.backups_done[b] += plan(
                st, world, rows, cache, model, mentor, sweep, sample, scratch, b
            )
        if ended:
            here = start_option(st, world, run, key, b, t - 1, nxt, at_goal)
            choose(st, world, rows, cache, model, mentor, run, clone, scratch, key, b, t - 1, here)
        if t % st.window == 0:
            close_window(st, world, rows, cache, model, mentor, run, windows, b)
    t_reached[b] = t


@entry
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
