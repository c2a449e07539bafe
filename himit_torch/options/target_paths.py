"""The deterministic policy that heads for one target cell inside a region of the grid, compiled:
what the doorway and corner options of :mod:`himit_torch.options.builders` are made of.

Every cell of the region gets the move that starts a cheapest path to the target inside the
region (entering a cell costs ``cost[cell]``): Dijkstra backwards from the target (grid moves
are symmetric), then in each cell the move with the lowest ``cost[next] + distance[next]``,
ties to the move that closes the larger of the row/column gaps to the target, then to the lower
action. This was Python over dicts and a heap of tuples, ≈ 90 µs a target: 3 s of the paper's
six worlds (≈ 5,000 targets on 120×120 alone). The distances are exact sums of the same costs
in any order a search finds them (each is final when popped, and a tie never relaxes), so the
compiled search gives the same policy (``tests/options/test_target_paths.py`` checks it against
the Python search it replaced).
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["target_actions"]


def target_actions(
    successors: np.ndarray,
    vertical: np.ndarray,
    size: int,
    allowed: np.ndarray,
    cost: np.ndarray,
    target: int,
    region: np.ndarray,
    scratch: np.ndarray,
) -> np.ndarray:
    """The action of each cell of ``region`` towards ``target`` (``-1``: no path inside it).

    Args:
        successors: ``[S, A]`` int64, the cell each move leads to (itself into a wall).
        vertical: ``[A]`` bool, whether the move changes the row (it then closes the row gap).
        size: the grid's side (cell ``s`` is row ``s // size``, column ``s % size``).
        allowed: ``[S]`` bool, the cells a path may use (the region and the target).
        cost: ``[S]`` float64, the cost of entering each allowed cell.
        target: the target cell.
        region: ``[n]`` int64, the cells to give an action, in the order returned.
        scratch: ``[S]`` float64, all ``inf``; left so.
    """
    return _target_actions(successors, vertical, size, allowed, cost, target, region, scratch)


@njit(cache=True, nogil=True)
def _target_actions(successors, vertical, size, allowed, cost, target, region, scratch):
    distance = scratch
    reached = np.empty(distance.size, np.int64)  # the cells given a distance (to reset)
    n_reached = 1
    reached[0] = target
    distance[target] = 0.0
    # a binary heap of (distance, cell), popped in Python's tuple order; a cell is pushed at most
    # once per move into it
    heap_d = np.empty(np.count_nonzero(allowed) * successors.shape[1] + 1, np.float64)
    heap_s = np.empty(heap_d.size, np.int64)
    heap_d[0], heap_s[0] = 0.0, target
    n_heap = 1
    while n_heap:
        d, u = heap_d[0], heap_s[0]
        n_heap -= 1
        _sift_down(heap_d, heap_s, n_heap, heap_d[n_heap], heap_s[n_heap])
        if d > distance[u]:
            continue
        nd = d + cost[u]
        for a in range(successors.shape[1]):
            v = successors[u, a]
            if v == u or not allowed[v] or v == target:
                continue
            if nd < distance[v]:
                if distance[v] == np.inf:
                    reached[n_reached] = v
                    n_reached += 1
                distance[v] = nd
                _push(heap_d, heap_s, n_heap, nd, v)
                n_heap += 1

    target_row, target_col = target // size, target % size
    actions = np.full(region.size, -1, np.int64)
    for i in range(region.size):
        s = region[i]
        row, col = s // size, s % size
        best_key, best_gap = np.inf, 0
        for a in range(successors.shape[1]):
            v = successors[s, a]
            if v == s or distance[v] == np.inf:
                continue
            gap = abs(target_row - row) if vertical[a] else abs(target_col - col)
            key = cost[v] + distance[v]
            # (key, -gap, a) < the best so far, as Python compares the tuples
            if actions[i] < 0 or key < best_key or (key == best_key and -gap < -best_gap):
                actions[i], best_key, best_gap = a, key, gap
    for i in range(n_reached):
        distance[reached[i]] = np.inf
    return actions


@njit(inline="always")
def _less(d1, s1, d2, s2):
    return d1 < d2 or (d1 == d2 and s1 < s2)


@njit(inline="always")
def _push(heap_d, heap_s, n, d, s):
    """Add ``(d, s)`` to the heap of ``n`` entries."""
    i = n
    while i > 0:
        parent = (i - 1) // 2
        if not _less(d, s, heap_d[parent], heap_s[parent]):
            break
        heap_d[i], heap_s[i] = heap_d[parent], heap_s[parent]
        i = parent
    heap_d[i], heap_s[i] = d, s


@njit(inline="always")
def _sift_down(heap_d, heap_s, n, d, s):
    """Put ``(d, s)`` (the former last entry) in the heap of ``n`` entries whose root was just
    taken."""
    if n == 0:
        return
    i = 0
    while True:
        child = 2 * i + 1
        if child >= n:
            break
        if child + 1 < n and _less(
            heap_d[child + 1], heap_s[child + 1], heap_d[child], heap_s[child]
        ):
            child += 1
        if not _less(heap_d[child], heap_s[child], d, s):
            break
        heap_d[i], heap_s[i] = heap_d[child], heap_s[child]
        i = child
    heap_d[i], heap_s[i] = d, s
