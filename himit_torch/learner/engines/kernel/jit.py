"""The one set of compile flags the tick loop and its phases are compiled with."""

from __future__ import annotations

from numba import njit

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
# (``inline="always"``), is a measured trade. Numba's inliner deep-copies the callee's IR once per
# block (time ~ blocks x variables), so inlining a large phase costs seconds of a cold start;
# a call to a phase compiled on its own passes every field of every array of its tuples (~8
# words an array, hundreds a call), which costs throughput where it is called each tick and LLVM
# does not inline it. Hence: tiny helpers inlined; ``choose`` (every decision) inlined; ``plan``,
# ``count_outcome``, ``act``, ``start_option``, ``_match_mentor`` and ``resample`` on their own.
_FLAGS = dict(cache=True, error_model="numpy", _nrt=False, nogil=True)
# the tick loop, called from Python
entry = njit(**_FLAGS)  # type: ignore[call-overload]  # (not in the stubs)
# a phase compiled on its own, called from the loop only
phase = njit(**_FLAGS, no_cpython_wrapper=True, no_cfunc_wrapper=True)  # type: ignore[call-overload]
