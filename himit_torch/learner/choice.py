"""Choosing the next option: ε-greedy over a run's own rows (the batched tensor-op path)."""

from __future__ import annotations

import torch

from himit_torch.learner.values import TIE, ValueCache, _take

__all__ = ["choose_rows", "greedy_rows", "trial_candidates", "mentor_move_scores"]


def choose_rows(
    cache: ValueCache,
    runs: torch.Tensor,
    states: torch.Tensor,
    u: torch.Tensor,
    epsilon: torch.Tensor,
    mentor_choice: str = "greedy",
    tie_break: str = "random",
    cloned: torch.Tensor | None = None,
) -> torch.Tensor:
    """ε-greedy choice of a row at ``states [R]`` for ``runs [R]``; ``u [R, 2]`` uniforms (ε,
    pick), ``epsilon [R]``.

    Greedy: the best usable rows (within ``TIE``), one of them uniformly (or the first, with
    ``tie_break="first"``); if none is usable yet (nothing tried here), any enabled row.
    Exploring: any enabled row, uniformly. ``mentor_choice="match"``: where the mentor term wins
    eq. 2, own options whose first action best reproduces the mentor's move come first.
    ``LearnerConfig.mentor_trial``: where the mentor term wins and some enabled own option is
    untried, the greedy choice tries one (:func:`trial_candidates`); exploring is unchanged.
    ``cloned [R]``: the BCO runs' cloned actions at ``states`` (:func:`greedy_rows`).
    """
    rows, greedy, enabled = greedy_rows(cache, runs, states, mentor_choice, cloned)
    explore = u[:, 0] < epsilon
    candidates = torch.where(explore[:, None], enabled, greedy)
    count = candidates.sum(1)
    pick = (u[:, 1] * count).long().clamp(max=count - 1)  # k-th candidate
    if tie_break == "first":
        pick = torch.where(explore, pick, torch.zeros_like(pick))
    slot = ((candidates.cumsum(1) == (pick + 1)[:, None]) & candidates).long().argmax(1)
    return rows.gather(1, slot[:, None])[:, 0]


def greedy_rows(
    cache: ValueCache,
    runs: torch.Tensor,
    states: torch.Tensor,
    mentor_choice: str = "greedy",
    cloned: torch.Tensor | None = None,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """The greedy candidates of :func:`choose_rows` at ``states [R]`` for ``runs [R]``:
    ``(rows [R, J], greedy [R, J], enabled [R, J])`` — the state's rows, those the greedy choice
    picks among (the best usable rows within ``TIE``; every enabled row where none is
    usable yet), and the rows the run may use at all.

    ``cloned [R]`` (the ``bco`` runs, :class:`~himit_torch.learner.cloned_policy.ClonedPolicy`):
    where it holds an action ``a ≥ 0`` whose primitive is available at the state, the greedy
    choice is that primitive's row alone, whatever the values say (``−1``: the greedy rule
    above).

    With ``LearnerConfig.mentor_trial`` (read from ``cache.config``), where the mentor term wins
    eq. 2 and some enabled own option has never been tried, the greedy candidates are the
    untried options most likely to reproduce the mentor's move (:func:`trial_candidates`)."""
    rows, q, usable, enabled, _, _ = cache.own_values(runs, states)
    q = torch.where(usable, q, torch.full_like(q, float("-inf")))
    trial = cache.config.mentor_trial and cache.any_mentor
    won = score = None
    if (mentor_choice == "match" or trial) and cache.any_mentor:
        _, _, won_ = cache.state_backup(runs[:, None], states[:, None])
        won = won_[:, 0]
        if bool(won.any()):
            A = cache.rows.primitive_rows.shape[1]
            first = cache.rows.row_first_action.index_select(0, rows.view(-1)).view_as(rows)
            score = mentor_move_scores(cache, runs, states).gather(1, first.clamp(max=A - 1))
    if mentor_choice == "match" and won is not None and score is not None:
        q = _match_mentor(won, score, q, usable)
    greedy = usable & (q >= q.amax(1, keepdim=True) - TIE)
    greedy = torch.where(greedy.any(1, keepdim=True), greedy, enabled)
    if trial and won is not None and score is not None:
        tried = _take(cache.model.row_count, cache._row_flat(runs[:, None], rows)) > 0
        use, candidates = trial_candidates(won, enabled & ~tried, score)
        greedy = torch.where(use[:, None], candidates, greedy)
    if cloned is not None:
        clone_row = cache.rows.primitive_rows[states, cloned.clamp(min=0)]
        use = (cloned >= 0) & (clone_row < cache.rows.num_rows)
        greedy = torch.where(use[:, None], rows == clone_row[:, None], greedy)
    return rows, greedy, enabled


def mentor_move_scores(cache: ValueCache, runs: torch.Tensor, states: torch.Tensor) -> torch.Tensor:
    """``[R, A]`` how well each primitive action's learned one-step model reproduces the mentor's
    observed move at ``states``: ``Σ_s' p̂(s'|s, a) p_m(s'|s)`` (maximum-likelihood means; with
    several mentors, of the mentor whose term eq. 2 takes there)."""
    prim = cache.rows.primitive_rows.index_select(0, states)  # [R, A]
    p_succ, p_w = _successor_probs(cache.model, runs[:, None], prim)  # [R, A, K]
    m_rows = cache.mentor_rows(runs, states)  # the mentor whose term eq. 2 takes
    m_succ, m_w = _successor_probs(cache.mentor, runs, m_rows)  # [R, Km]
    same = p_succ[..., :, None] == m_succ[:, None, None, :]  # [R, A, K, Km]
    return (same * p_w[..., None] * m_w[:, None, None, :]).sum((-1, -2))


def trial_candidates(
    won: torch.Tensor, untried: torch.Tensor, score: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """Trial of untried own options where the mentor leads (``LearnerConfig.mentor_trial``; the
    option-level analogue of Price & Boutilier's k-step repair, JAIR 2003).

    Where the mentor term wins eq. 2 (``won``) and some enabled option has never been tried
    there (``untried``), the greedy choice is among the untried options whose first action best
    reproduces the mentor's move (``score``, :func:`mentor_move_scores` of each option's first
    action: the learner's one-step model of that action, no model of the option needed); all
    untried options where no score is above 0. Elsewhere the greedy rule stands.

    Args:
        won: ``[R]`` bool; untried: ``[R, J]`` bool; score: ``[R, J]`` ≥ 0.
    Returns ``(use [R], candidates [R, J])``: where the trial applies, and its candidates.

    >>> import torch
    >>> use, cand = trial_candidates(
    ...     torch.tensor([True, True, False]),
    ...     torch.tensor([[True, True, False], [False, False, False], [True, False, False]]),
    ...     torch.tensor([[0.2, 0.5, 0.9], [0.0, 0.0, 0.0], [0.3, 0.0, 0.0]]),
    ... )
    >>> use.tolist(), cand.tolist()
    ([True, False, False], [[False, True, False], [False, False, False], [False, False, False]])
    """
    use = won & untried.any(1)
    score = torch.where(untried, score, torch.full_like(score, -1.0))
    best = score.amax(1, keepdim=True)
    candidates = untried & (score >= best - TIE)
    return use, candidates & use[:, None]


def _match_mentor(won, score, q, usable):
    """Rank own options first by how well their first action reproduces the mentor's move, then
    by ``Q``, where the mentor term wins (returned as a score with the shape of ``q``)."""
    score = torch.where(usable, score, torch.zeros_like(score))
    best = score.amax(1, keepdim=True)
    use = won[:, None] & (best > 0)
    # Matching options outrank the rest; among them, Q decides.
    lifted = torch.where(score >= best - TIE, q + 1e6, q)
    return torch.where(use, lifted, q)


def _successor_probs(model, runs, rows):
    """Posterior-mean successor probabilities ``(successors [..., K], probs [..., K])`` of
    ``rows`` (shape ``[...]``, ``runs`` broadcast) in a count model (maximum likelihood)."""
    forward = model.index().forward
    runs = runs.expand_as(rows)
    e = forward[runs, rows]
    ok = e >= 0
    ec = e.clamp(min=0)
    r = runs[..., None]
    counts = torch.where(
        ok,
        _take(model.edge_count, r * model.capacity + ec),
        torch.zeros((), dtype=torch.float64, device=e.device),
    )
    n = _take(model.row_count, runs * model.row_count.shape[1] + rows)
    succ = torch.where(
        ok, _take(model.edge_successor, r * model.capacity + ec), torch.full_like(e, -1)
    )
    return succ, counts / n.clamp(min=1)[..., None]
