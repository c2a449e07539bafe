"""The compiled engine's kernels (Numba): the algorithm of
:class:`~himit_torch.learner.engines.TorchEngine`, one run at a time.

* :mod:`.arrays` — the named tuples that group the arrays by owner (world, rows, cache, models,
  sweeper, run state, sample, scratch); every kernel function takes these, never loose arrays.
* :mod:`.streams` — the counter-based uniforms (:func:`himit_torch.rng.uniforms`).
* :mod:`.heap` — the sweep's indexed max-heap.
* :mod:`.backup` — eq. 2 at a state, and the propagation of a state's change to its
  predecessors.
* :mod:`.sampling` — posterior sampling (:mod:`himit_torch.learner.posterior_sampling`).
* :mod:`.tick` — act, learn, plan, choose, and the tick loop :func:`.tick.run_ticks`.
* :mod:`.jit` — the flags every cached kernel is compiled with; :mod:`.stamp` — their disk cache's
  freshness stamp, one hash over all these sources (an edit to any of them recompiles them all).

Every array is allocated by the caller (:mod:`himit_torch.learner.engines.numba_engine`) and
worked on in place. Helpers take whole arrays and indices (never slices), so the hot loop makes
no allocations and no reference-counting calls. The arithmetic follows the torch engine operation
for operation (same formulas, same order of additions into each cache entry, the same uniforms),
so that both engines take the same decisions and their values agree to rounding.
"""
