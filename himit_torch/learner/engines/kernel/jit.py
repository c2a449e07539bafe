"""The one set of compile flags every kernel function of the tick loop is compiled with."""

from __future__ import annotations

from numba import njit

# error_model="numpy": a division by zero gives inf/nan instead of raising.
# _nrt=False: no reference counting. The functions take whole arrays, and Numba would otherwise
# incref and decref every one of them at every call (atomic operations on counters shared by the
# threads). The loop allocates nothing, and with the runtime off it cannot: Numba refuses to
# compile it if it did.
# nogil=True: the engine calls the loop from several threads at once, one run each.
# A phase compiled on its own (rather than inlined into the loop's Numba IR) keeps the loop's
# type inference small; LLVM still inlines it where that pays.
phase = njit(cache=True, error_model="numpy", _nrt=False, nogil=True)  # type: ignore[call-overload]  # (not in the stubs)
