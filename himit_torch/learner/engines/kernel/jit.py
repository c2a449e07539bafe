"""The one set of compile flags the tick loop and its phases are compiled with."""

from __future__ import annotations

import numpy as np
from numba import njit

from himit_torch.learner.engines.kernel import stamp

# Every kernel's disk cache is stamped with a hash over all the kernels' sources, not just its own
# file (:mod:`.stamp`): registered here, before any kernel module decorates a function with
# ``entry`` or ``phase``.
stamp.register()

# error_model="numpy": a division by zero gives inf/nan instead of raising.
# _nrt=False: no reference counting. The functions take whole arrays, and Numba would otherwise
# incref and decref every one of them at every call (atomic operations on counters shared by the
# threads). The loop allocates nothing, and with the runtime off it cannot: Numba refuses to
# compile it if it did.
# nogil=True: the engine calls the loop from several threads at once, one run each.
# no_cpython_wrapper, no_cfunc_wrapper: called only from the kernels; a wrapper for calls from
# Python would unbox every argument tuple, which costs compile time and nothing else.
#
# Which phases are compiled on their own, and which are inlined into their caller's Numba IR
# (``inline="always"``), is a measured trade (benchmarks/bench_kernel_inprocess.py: the tick
# loop against the pre-redesign kernel in one process on the same arrays; the compile times by
# Numba's compile events). A call to a phase compiled on its own passes every field of every
# array of its tuples (~8 words an array, hundreds a call) and reloads them in the callee, and
# LLVM does not inline it: with ``act`` (every tick) and ``plan`` (every decision) on their own
# the loop ran at 0.90x the pre-redesign kernel; inlined, at 0.98-1.0x. Inlining costs compile
# time instead (Numba's inliner deep-copies the callee's IR once per call site), so what is not
# on the hot path is compiled once on its own: ``count_outcome``, ``start_option``,
# ``_match_mentor``, ``resample``, and eq. 2 for the callers outside the loop
# (:func:`.backup.backup_state`). Neither kernel called from Python needs a C callback
# (``no_cfunc_wrapper``): ~2 s less of a cold compile.
_FLAGS = dict(cache=True, error_model="numpy", _nrt=False, nogil=True)
# a kernel called from Python (the tick loop, link_edges, mentor_wins)
entry = njit(**_FLAGS, no_cfunc_wrapper=True)  # type: ignore[call-overload]  # (not in the stubs)
# a phase compiled on its own, called from the loop only
phase = njit(**_FLAGS, no_cpython_wrapper=True, no_cfunc_wrapper=True)  # type: ignore[call-overload]

# ``array[b, ix(i)]``: an index made unsigned where the hot path reads and writes. Numba wraps a
# negative signed index (``i < 0`` → ``i + len``): two instructions more for each access, and each
# array's length kept live for it. In a loop this large the lengths do not fit the registers, so
# the compiled loop reloaded them from the stack at every access. An unsigned index has no
# wraparound, and every index on the hot path is ≥ 0 (a −1 "none" is tested before it indexes).
# One imitator ran 1.2x as fast with the heap, eq. 2 and the propagation indexed so
# (benchmarks/bench_vs_limit.py); the state it reaches is bit-identical
# (benchmarks/state_fingerprint.py). Under ``NUMBA_BOUNDSCHECK=1`` an index that went negative
# raises ``IndexError`` at an ``ix`` site (unsigned indices are checked too), where a signed one
# would have wrapped around unnoticed.
ix = np.uint64
