"""One option's absorbing chain, as the exact option models solve it: which states it may continue
in, and its one-step kernel split into what continues and what stops (compiled).

For an option started in its initiation states ``I`` (``start``), the continuing states ``C`` are
those reached in one or more steps of its policy on which it may go on (``1 − β > 0``, not
terminal). Each one-step kernel entry ``K[s, s']`` of the policy from ``s ∈ I ∪ C`` becomes
``go_on = K (1 − β(s'))`` and ``ends = K β(s')`` (β forced to 1 at terminal states), and lands in
one of four parts of :func:`himit_torch.exact.option_models.option_models`' solve:

* ``hit``:  from a start, stopping at once            (``s ∈ I``, ``ends > 0``)
* ``T_CC``: from a continuing state, going on          (``s ∈ C``, ``go_on > 0``)
* ``E_C``:  from a continuing state, stopping in an exit (``s ∈ C``, ``ends > 0``)
* ``T_JC``: from a start, going on                     (``s ∈ I``, ``go_on > 0``)

This was a dozen NumPy calls per option (a breadth-first search over frontiers, the kernel's
entries, ``np.unique`` twice), each costing more than its work on the paper's options of ~70
cells: ≈ 0.9 ms an option, most of the exact models' time on 120×120's 2,644 options. Compiled,
the same values come out in the same order (every sum the models take later is over them in that
order, so the models are the same to the bit; ``tests/exact/test_option_chains.py`` checks every
part against the obvious NumPy computation).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

__all__ = ["OptionChain", "option_chain"]


class OptionChain(NamedTuple):
    """One option's chain (see the module docstring). Rows index ``start`` (``hit_row``,
    ``j_state``) or ``continuing`` (``cc_row``, ``exit_row``); ``cc_col``/``jc_col`` index
    ``continuing``; ``exit_col`` indexes ``exits``; ``jc_row`` indexes ``j_state``. Each part's
    entries are in the order of the kernel's: by row of ``I ∪ C``, then action, then the world's
    successor order."""

    continuing: np.ndarray  # [nC] int64 states C, sorted
    hit_row: np.ndarray  # index into start
    hit_state: np.ndarray  # the state it stops in
    hit_value: np.ndarray  # K β
    cc_row: np.ndarray
    cc_col: np.ndarray
    cc_value: np.ndarray  # K (1 − β)
    exits: np.ndarray  # [nE] int64 states a continuing state may stop in, sorted
    exit_row: np.ndarray
    exit_col: np.ndarray
    exit_value: np.ndarray  # K β
    j_state: np.ndarray  # [nJ] indices into start of the starts that may go on, sorted
    jc_row: np.ndarray
    jc_col: np.ndarray
    jc_value: np.ndarray  # K (1 − β)


def option_chain(
    indptr: np.ndarray,
    indices: np.ndarray,
    data: np.ndarray,
    terminal: np.ndarray,
    beta: np.ndarray,
    actions: np.ndarray,
    weights: np.ndarray,
    start: np.ndarray,
    scratch: np.ndarray,
) -> OptionChain:
    """The chain of one option started in ``start``.

    Args:
        indptr, indices, data: the world's transitions as CSR over rows ``a · S + s`` (int64,
            int64, float64; zeros eliminated).
        terminal: ``[S]`` bool, the world's terminal states.
        beta: ``[S]`` float64 termination probabilities.
        actions, weights: ``[S, k]`` int64 and float64: in ``s`` the option takes
            ``actions[s, j]`` with probability ``weights[s, j]`` (entries with weight ≤ 0 are
            skipped). A deterministic policy is ``k = 1`` with weights 1 (``p · 1.0`` is ``p``
            exactly); a stochastic one, every action with its probability.
        start: ``[nI]`` int64 initiation states.
        scratch: ``[S]`` int64, all ``-1``; left so.
    """
    return OptionChain(
        *_chain(indptr, indices, data, terminal, beta, actions, weights, start, scratch)
    )


@njit(cache=True, nogil=True)
def _chain(indptr, indices, data, terminal, beta, actions, weights, start, scratch):
    S, width = terminal.size, actions.shape[1]
    n_start = start.size

    # The continuing states C: reached from a start by steps it may go on after. ``scratch``
    # marks them found (≥ 0) while searching, then holds their index in C. The search expands
    # every state of I then of C once, so it also counts the kernel's entries from I ∪ C.
    found = np.empty(S, np.int64)
    n_found = expanded = total = 0
    while expanded < n_start + n_found:  # the starts, then what was found
        s = start[expanded] if expanded < n_start else found[expanded - n_start]
        expanded += 1
        for j in range(width):
            if not weights[s, j] > 0:
                continue
            row = actions[s, j] * S + s
            total += indptr[row + 1] - indptr[row]
            for k in range(indptr[row], indptr[row + 1]):
                nxt = indices[k]
                stop = 1.0 if terminal[nxt] else beta[nxt]
                if data[k] * weights[s, j] > 0 and 1.0 - stop > 0 and scratch[nxt] < 0:
                    scratch[nxt] = 0
                    found[n_found] = nxt
                    n_found += 1
    continuing = np.sort(found[:n_found])
    n_cont = continuing.size
    for i in range(n_cont):
        scratch[continuing[i]] = i

    # The kernel's entries from I then C, each into its parts (each part holds at most all).
    rows = np.empty((4, total), np.int64)  # hit, T_CC, E_C, T_JC
    cols = np.empty((4, total), np.int64)
    values = np.empty((4, total), np.float64)
    filled = np.zeros(4, np.int64)
    for i in range(n_start + n_cont):
        s = start[i] if i < n_start else continuing[i - n_start]
        for j in range(width):
            if not weights[s, j] > 0:
                continue
            row = actions[s, j] * S + s
            for k in range(indptr[row], indptr[row + 1]):
                nxt = indices[k]
                prob = data[k] * weights[s, j]
                stop = 1.0 if terminal[nxt] else beta[nxt]
                go_on, ends = prob * (1.0 - stop), prob * stop
                if i < n_start:
                    _put(rows, cols, values, filled, 0, i, nxt, ends)  # hit
                    _put(rows, cols, values, filled, 3, i, scratch[nxt], go_on)  # T_JC
                else:
                    _put(rows, cols, values, filled, 1, i - n_start, scratch[nxt], go_on)  # T_CC
                    _put(rows, cols, values, filled, 2, i - n_start, nxt, ends)  # E_C
    for i in range(n_cont):
        scratch[continuing[i]] = -1

    n_hit, n_cc, n_exit, n_jc = filled
    exits, exit_col = _unique(cols[2, :n_exit], scratch)
    j_state, jc_row = _unique(rows[3, :n_jc], scratch)
    return (
        continuing,
        rows[0, :n_hit].copy(),
        cols[0, :n_hit].copy(),
        values[0, :n_hit].copy(),
        rows[1, :n_cc].copy(),
        cols[1, :n_cc].copy(),
        values[1, :n_cc].copy(),
        exits,
        rows[2, :n_exit].copy(),
        exit_col,
        values[2, :n_exit].copy(),
        j_state,
        jc_row,
        cols[3, :n_jc].copy(),
        values[3, :n_jc].copy(),
    )


@njit(inline="always")
def _unique(values, scratch):
    """``np.unique(values, return_inverse=True)`` for values in ``0 … S−1`` (``scratch`` [S],
    all ``-1``, left so)."""
    ordered = np.sort(values)
    n = 0
    for i in range(ordered.size):
        if i == 0 or ordered[i] != ordered[i - 1]:
            ordered[n] = ordered[i]
            n += 1
    distinct = ordered[:n].copy()
    for i in range(n):
        scratch[distinct[i]] = i
    inverse = np.empty(values.size, np.int64)
    for i in range(values.size):
        inverse[i] = scratch[values[i]]
    for i in range(n):
        scratch[distinct[i]] = -1
    return distinct, inverse


@njit(inline="always")
def _put(rows, cols, values, filled, part, row, col, value):
    """Append ``(row, col, value)`` to ``part`` if ``value > 0``."""
    if value > 0:
        n = filled[part]
        rows[part, n], cols[part, n], values[part, n] = row, col, value
        filled[part] = n + 1
