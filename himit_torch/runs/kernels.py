"""Compiling the compiled engine's kernels ahead of a run: in a parent process while the world
processes it starts set up, so that they load the kernels from Numba's disk cache instead of
each compiling them. (The engine needs none of this: each kernel's first call in a process
holds the cache's lock, so processes that start together compile once anyway. This only moves
the compiling earlier.)

``python -m himit_torch.runs.kernels`` does it once for an environment (``make install`` runs it),
filling the cache the kernels use by default, so that the first run afterwards only loads them.
On the way it builds options and a mentor, and so compiles the set-up's own compiled functions
too (``himit_torch.options.target_paths``, ``himit_torch.exact.option_chains``).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager

from himit_torch.learner.config import LearnerConfig
from himit_torch.learner.engines.numba_engine import cache_lock
from himit_torch.learner.learner import Learner
from himit_torch.mentor.policy import mentor_policy, record_demonstrations
from himit_torch.options.builders import learner_options, mentor_options
from himit_torch.worlds.multirooms import MultiRooms

__all__ = ["prepare_kernels", "kernels_prepared_here"]

_prepared = False
_guard = threading.Lock()


def _prepare_locked() -> None:
    """Call every kernel once in this process, with the argument types every learner passes: a
    few hundred ticks of an imitator, a posterior-sampling imitator and a ``bco`` run (whose
    refit at the start compiles :mod:`~himit_torch.learner.cloned_refit`) on an 8×8 world, to a
    window's end."""
    global _prepared
    with _guard:
        if _prepared:
            return
        world = MultiRooms(8, 2)
        demonstrations = record_demonstrations(
            world, mentor_policy(world, mentor_options(world)), 1, seed=0
        )
        Learner(
            world,
            learner_options(world),
            ["imitation", "imitation_psrl", "bco"],
            [0, 0, 0],
            LearnerConfig(window=200),
            demonstrations=demonstrations,
            engine="numba",
        ).run(200)
        _prepared = True


def prepare_kernels() -> float:
    """Load the compiled kernels into this process — compiling them first if Numba's disk cache
    has none — and return the seconds it took (0 once they are loaded).

    One process compiles at a time per cache: another process that gets here, or to a kernel's
    first call, meanwhile waits for it, then loads what it cached."""
    if _prepared:
        return 0.0
    start = time.perf_counter()
    with cache_lock():
        _prepare_locked()
    return time.perf_counter() - start


@contextmanager
def kernels_prepared_here() -> Iterator[None]:
    """Take the kernel cache's lock now, and at the end of the block load (or compile) the
    kernels in this process before letting it go. Processes started inside the block wait at
    their first kernel call until then, and load the kernels from the cache instead of compiling
    them too (``run_experiments`` starts its world processes this way)."""
    with cache_lock():
        yield
        _prepare_locked()


if __name__ == "__main__":
    import numba

    where = numba.config.CACHE_DIR or "beside the kernels' sources"  # type: ignore[attr-defined]
    print(
        f"himit_torch: compiled kernels ready in {prepare_kernels():.1f} s (Numba cache: {where})"
    )
