"""BCO's refit compiled: the cloned actions of some runs from their own option model and their
mentor model, in one pass over each run's edges (:meth:`ClonedPolicy.refit
<himit_torch.learner.cloned_policy.ClonedPolicy.refit>` on the CPU).

It computes what :func:`~himit_torch.mentor.cloning.inverse_model`,
:func:`~himit_torch.mentor.cloning.relabel` and :func:`~himit_torch.mentor.cloning.clone_policy`
compute, to the bit: every sum adds the same numbers in the same order, from ``0.0`` —
``n(s, a)`` over ``s'`` ascending, an ``(s, s')``'s total over ``a`` ascending, a state's votes
in the mentor's edge order — and every ratio and tie test is the same operation. Only the
relabelled pairs are needed, so only the own edges out of the mentor's sources are read: a
state's few own transitions are sorted by ``(s', a)`` in place of the functions' sort of all
of them. Run by run in torch, the three functions took ≈ 8 ms for one run of 4.8k edges on
exp2's 40×40 world (201 refits a run in the benchmark's factorial);
``benchmarks/bench_bco_refit.py`` times both side by side and ``tests/learner/test_bco.py``
checks they agree.
"""

from __future__ import annotations

import numpy as np
import torch
from numba import njit

from himit_torch.mentor.cloning import TIE

__all__ = ["refit_actions"]


def refit_actions(
    runs: torch.Tensor,
    model_edges: tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor],
    mentor_edges: tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor],
    row_state: torch.Tensor,
    row_action: torch.Tensor,
    num_states: int,
    num_actions: int,
    likelihood: bool,
) -> torch.Tensor:
    """``[R, S]`` the cloned action of each run of ``runs`` at each state (``−1``: none).

    Args:
        runs: ``[R]`` int64, the runs (rows of the edge lists).
        model_edges: the own option model's ``edge_row``, ``edge_successor``, ``edge_count``
            ``[B, E]`` and ``num_edges [B]`` (CPU tensors).
        mentor_edges: the mentor model's, the same four (a mentor row ``r`` models state
            ``r mod S``).
        row_state, row_action: ``[M + 1]`` the state of each row and its primitive action
            (``−1``: not a primitive option's row).
        num_states, num_actions: ``S`` and ``A``.
        likelihood: the ``"likelihood"`` inverse model (``n(s, a, s') / n(s, a)``), else
            ``"counts"`` (``n(s, a, s')``).
    """
    arrays = [t.numpy() for t in (*model_edges, *mentor_edges, row_state, row_action)]
    out = np.empty((runs.numel(), num_states), np.int64)
    # (numba's stub of a dispatcher's __call__ takes fewer arguments than a kernel)
    _refit(  # type: ignore[call-arg]
        runs.numpy(), *arrays, num_states, num_actions, likelihood, TIE, out
    )
    return torch.from_numpy(out)


@njit(cache=True, nogil=True)
def _refit(
    runs,
    edge_row,
    edge_succ,
    edge_count,
    num_edges,
    m_row,
    m_succ,
    m_count,
    m_num_edges,
    row_state,
    row_action,
    S,
    A,
    likelihood,
    tie,
    out,
):
    needed = np.zeros(S + 1, np.bool_)
    # each needed state's own transitions: entries start[s] … fill[s] − 1
    start = np.zeros(S + 2, np.int64)
    votes = np.zeros((S, A), np.float64)
    n_sa = np.zeros(A, np.float64)
    for r in range(runs.size):
        b = runs[r]
        E, Em = num_edges[b], m_num_edges[b]
        out[r, :] = -1
        needed[:] = False
        for f in range(Em):
            needed[m_row[b, f] % S] = True
        # the own primitive transitions (count > 0) out of the needed states, bucketed by state
        start[:] = 0
        for e in range(E):
            row = edge_row[b, e]
            s = row_state[row]
            if row_action[row] >= 0 and needed[s] and edge_count[b, e] > 0:
                start[s + 1] += 1
        for s in range(S + 1):
            start[s + 1] += start[s]
        fill = start[:-1].copy()
        k_succ = np.empty(start[S + 1], np.int64)
        k_act = np.empty(start[S + 1], np.int64)
        k_count = np.empty(start[S + 1], np.float64)
        for e in range(E):
            row = edge_row[b, e]
            s = row_state[row]
            if row_action[row] >= 0 and needed[s] and edge_count[b, e] > 0:
                i = fill[s]
                k_succ[i], k_act[i], k_count[i] = edge_succ[b, e], row_action[row], edge_count[b, e]
                fill[s] = i + 1
        k_label = np.empty(start[S + 1], np.int64)  # the label of each entry's (s, s')
        for s in range(S):
            lo, hi = start[s], start[s + 1]
            if lo == hi:
                continue
            _sort_by_successor_action(k_succ, k_act, k_count, lo, hi)
            hi = _merge_repeats(k_succ, k_act, k_count, lo, hi)
            _label_pairs(k_succ, k_act, k_count, k_label, lo, hi, n_sa, likelihood, tie)
            fill[s] = hi  # the end of the merged entries
        # the mentor's votes, in its edge order
        for f in range(Em):
            s = m_row[b, f] % S
            label = _find_label(k_succ, k_act, k_label, start[s], fill[s], m_succ[b, f])
            if label >= 0:
                votes[s, label] += m_count[b, f]
        for f in range(Em):
            s = m_row[b, f] % S
            if not needed[s]:
                continue
            needed[s] = False  # (each state once)
            top = votes[s, 0]
            for a in range(1, A):
                if votes[s, a] > top:
                    top = votes[s, a]
            if top > 0:
                for a in range(A):
                    if votes[s, a] >= top - tie:
                        out[r, s] = a
                        break
            votes[s, :] = 0.0


@njit(cache=True, nogil=True)
def _sort_by_successor_action(k_succ, k_act, k_count, lo, hi):
    """Insertion sort of entries ``lo … hi − 1`` by ``(s', a)``, stable (a state has a few)."""
    for i in range(lo + 1, hi):
        s2, a, n = k_succ[i], k_act[i], k_count[i]
        j = i - 1
        while j >= lo and (k_succ[j] > s2 or (k_succ[j] == s2 and k_act[j] > a)):
            k_succ[j + 1], k_act[j + 1], k_count[j + 1] = k_succ[j], k_act[j], k_count[j]
            j -= 1
        k_succ[j + 1], k_act[j + 1], k_count[j + 1] = s2, a, n


@njit(cache=True, nogil=True)
def _merge_repeats(k_succ, k_act, k_count, lo, hi):
    """Sum entries of one ``(s', a)`` into the first (from ``0.0``, in their order); returns the
    new end. (An option model lists an edge once, so this merges nothing there.)"""
    end = lo
    i = lo
    while i < hi:
        total = 0.0 + k_count[i]
        j = i + 1
        while j < hi and k_succ[j] == k_succ[i] and k_act[j] == k_act[i]:
            total += k_count[j]
            j += 1
        k_succ[end], k_act[end], k_count[end] = k_succ[i], k_act[i], total
        end += 1
        i = j
    return end


@njit(cache=True, nogil=True)
def _label_pairs(k_succ, k_act, k_count, k_label, lo, hi, n_sa, likelihood, tie):
    """One state's entries ``lo … hi − 1`` (sorted by ``(s', a)``): each ``(s, s')``'s label,
    ``argmax_a p(a | s, s')``, ties within ``tie`` to the lowest action."""
    if likelihood:
        n_sa[:] = 0.0
        for i in range(lo, hi):  # per action, over s' ascending
            n_sa[k_act[i]] += k_count[i]
    i = lo
    while i < hi:
        j = i
        total = 0.0
        while j < hi and k_succ[j] == k_succ[i]:  # over a ascending
            total += k_count[j] / n_sa[k_act[j]] if likelihood else k_count[j]
            j += 1
        best = -1.0
        for m in range(i, j):
            w = k_count[m] / n_sa[k_act[m]] if likelihood else k_count[m]
            p = w / total
            if p > best:
                best = p
        label = -1
        for m in range(i, j):
            w = k_count[m] / n_sa[k_act[m]] if likelihood else k_count[m]
            if w / total >= best - tie:
                label = k_act[m]  # (the lowest: a ascending)
                break
        for m in range(i, j):
            k_label[m] = label
        i = j


@njit(cache=True, nogil=True)
def _find_label(k_succ, k_act, k_label, lo, hi, successor):
    """The label of ``(s, successor)`` among a state's entries ``lo … hi − 1``; ``−1``: none."""
    for i in range(lo, hi):
        if k_succ[i] == successor:
            return k_label[i]
    return -1
