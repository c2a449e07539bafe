"""The sweep's indexed max-heap over one run's priorities (a :class:`.arrays.SweepArrays`):
the torch queue (:class:`himit_torch.learner.prioritized_sweeping.BlockPriorityQueue`) as a heap."""

from __future__ import annotations

import numpy as np
from numba import njit

from himit_torch.learner.engines.kernel.jit import ix


@njit(inline="always")
def _before(k1, s1, k2, s2):
    """Pop order: priority descending, then state ascending (the torch queue's order).

    A strict total order over the queued states (each state is queued at most once), so the pop
    sequence does not depend on how the heap is laid out. Bitwise ``|``/``&``, not ``or``/``and``:
    one condition without short-circuit branches, which the compiler can turn into a select
    where the heap picks a child (a coin flip for the branch predictor)."""
    return (k1 > k2) | ((k1 == k2) & (s1 < s2))


@njit(inline="always")
def _sift_up(sw, b, i):
    heap, hkey, hpos = sw.heap, sw.hkey, sw.hpos
    s = heap[b, ix(i)]
    k = hkey[b, ix(i)]
    while i > 0:
        parent = (i - 1) >> 1
        p = heap[b, ix(parent)]
        kp = hkey[b, ix(parent)]
        if not _before(k, s, kp, p):
            break
        heap[b, ix(i)] = p
        hkey[b, ix(i)] = kp
        hpos[b, ix(p)] = i
        i = parent
    heap[b, ix(i)] = s
    hkey[b, ix(i)] = k
    hpos[b, ix(s)] = i


@njit(inline="always")
def _sift_down(sw, b, i):
    heap, hkey, hpos = sw.heap, sw.hkey, sw.hpos
    n = sw.hsize[b]
    s = heap[b, ix(i)]
    k = hkey[b, ix(i)]
    while True:
        child = 2 * i + 1
        if child >= n:
            break
        if child + 1 < n:
            # the child that comes first, by arithmetic on the index rather than a branch
            # (which child wins is a coin flip for the branch predictor)
            child += np.int64(
                _before(
                    hkey[b, ix(child + 1)],
                    heap[b, ix(child + 1)],
                    hkey[b, ix(child)],
                    heap[b, ix(child)],
                )
            )
        c = heap[b, ix(child)]
        kc = hkey[b, ix(child)]
        if not _before(kc, c, k, s):
            break
        heap[b, ix(i)] = c
        hkey[b, ix(i)] = kc
        hpos[b, ix(c)] = i
        i = child
    heap[b, ix(i)] = s
    hkey[b, ix(i)] = k
    hpos[b, ix(s)] = i


@njit(inline="always")
def push(sw, b, s, p):
    """Raise the priority of ``s`` to at least ``p`` (a scatter-max, as the torch queue)."""
    if p > sw.prio[b, ix(s)]:
        raise_to(sw, b, s, p)


@njit(inline="always")
def raise_to(sw, b, s, p):
    """Set the priority of ``s`` to ``p``, which is above its priority now."""
    sw.prio[b, ix(s)] = p
    i = sw.hpos[b, ix(s)]
    n = sw.hsize[b]
    new = i < 0  # (not queued: a new slot at the end; without a branch)
    i = n if new else i
    sw.hsize[b] = n + np.int64(new)
    sw.heap[b, ix(i)] = s
    sw.hkey[b, ix(i)] = p
    _sift_up(sw, b, i)


@njit(inline="always")
def pop(sw, b):
    """The first state in pop order, removed (its priority set to 0)."""
    heap, hkey, hpos = sw.heap, sw.hkey, sw.hpos
    s = heap[b, 0]
    sw.hsize[b] -= 1
    n = sw.hsize[b]
    hpos[b, ix(s)] = -1
    sw.prio[b, ix(s)] = 0.0
    if n > 0:
        last = heap[b, ix(n)]
        heap[b, 0] = last
        hkey[b, 0] = hkey[b, ix(n)]
        hpos[b, ix(last)] = 0
        _sift_down(sw, b, 0)
    return s


@njit(inline="always")
def heapify(sw, b, num):
    """Build run ``b``'s heap from its priorities (states ``0 … num − 1``)."""
    heap, hkey, hpos, prio = sw.heap, sw.hkey, sw.hpos, sw.prio
    n = 0
    for s in range(num):
        hpos[b, ix(s)] = -1
        if prio[b, ix(s)] > 0.0:
            heap[b, ix(n)] = s
            hkey[b, ix(n)] = prio[b, ix(s)]
            hpos[b, ix(s)] = n
            n += 1
    sw.hsize[b] = n
    for i in range((n >> 1) - 1, -1, -1):
        _sift_down(sw, b, i)
