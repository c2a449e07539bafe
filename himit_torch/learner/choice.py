"""Choosing the next option: ε-greedy over a run's own rows (the batched tensor-op path)."""

from __future__ import annotations

import torch

from himit_torch.learner.values import TIE, ValueCache, _take

__all__ = ["choose_rows", "greedy_rows"]


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
    above)."""
    rows, q, usable, enabled, _, _ = cache.own_values(runs, states)
    q = torch.where(usable, q, torch.full_like(q, float("-inf")))
    if mentor_choice == "match" and cache.any_mentor:
        q = _match_mentor(cache, runs, states, rows, q, usable)
    greedy = usable & (q >= q.amax(1, keepdim=True) - TIE)
    greedy = torch.where(greedy.any(1, keepdim=True), greedy, enabled)
    if cloned is not None:
        clone_row = cache.rows.primitive_rows[states, cloned.clamp(min=0)]
        use = (cloned >= 0) & (clone_row < cache.rows.num_rows)
        greedy = torch.where(use[:, None], rows == clone_row[:, None], greedy)
    return rows, greedy, enabled


def mentor_move_scores(cache: ValueCache, runs: torch.Tensor, states: torch.Tensor) -> torch.Tensor:
    """``[R, A]`` how well each primitive action's learned one-step model reproduces the mentor's
    observed move at ``states``: ``Σ_s' p̂(s'|s, a) p_m(s'|s)`` (maximum-likelihood means)."""
    prim = cache.rows.primitive_rows.index_select(0, states)  # [R, A]
    p_succ, p_w = _successor_probs(cache.model, runs[:, None], prim)  # [R, A, K]
    m_succ, m_w = _successor_probs(cache.mentor, runs, states)  # [R, Km]
    same = p_succ[..., :, None] == m_succ[:, None, None, :]  # [R, A, K, Km]
    return (same * p_w[..., None] * m_w[:, None, None, :]).sum((-1, -2))


def _match_mentor(cache, runs, states, rows, q, usable):
    """Rank own options first by how well their first action reproduces the mentor's move, then
    by ``Q``, where the mentor term wins (returned as a score with the shape of ``q``)."""
    _, _, won = cache.state_backup(runs[:, None], states[:, None])
    won = won[:, 0]
    if not bool(won.any()):
        return q
    score_a = mentor_move_scores(cache, runs, states)
    A = score_a.shape[1]
    first = cache.rows.row_first_action.index_select(0, rows.view(-1)).view_as(rows)
    score = score_a.gather(1, first.clamp(max=A - 1))  # [R, J]
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
