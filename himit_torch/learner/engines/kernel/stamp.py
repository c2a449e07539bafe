"""One freshness stamp for every cached kernel: a hash over all the sources the kernels are made of.

Numba checks a function's disk cache against the function's own source file only (its
locator's ``get_source_stamp``: the file's content hash in Numba 0.68, its mtime and size in older
releases).
:func:`.tick.run_ticks` is made of more than :mod:`.tick`: Numba inlines or links in functions
from :mod:`.backup`, :mod:`.heap`, :mod:`.sampling` and :mod:`.streams`, and freezes the module
globals it reads (the codes of :mod:`himit_torch.learner.engines.settings`, the constants of
:mod:`himit_torch.learner.posterior_sampling`) into the machine code. With Numba's stamp, an edit to
one of those files alone left the cached ``run_ticks`` looking fresh, and the old code ran.

Here every kernel function's cache is stamped with :func:`kernel_stamp` instead: the SHA-256 of
:func:`stamped_sources` (every module of this package, the engine's settings, posterior sampling's
constants) and of the settings' values that come from elsewhere (the codes and field order that
:mod:`himit_torch.learner.config` decides). Any change to any of them makes every kernel's cache
stale at once; nothing else changes (same cache folder, same file names, same index keys).

How (Numba's cache locators, ``numba.core.caching``): a function's cache asks each class of
``CompileResultCacheImpl._locator_classes`` in turn for a locator (``from_function``), which says
where the cache lives and what stamp it must carry. :func:`register` puts in front of Numba's
own list a copy of each of its file-backed locators (``NUMBA_CACHE_DIR``, the ``__pycache__``
beside the source, the user-wide folder, in Numba's order) that answers only for the functions
defined in this package and stamps them with :func:`kernel_stamp`; every other function's cache
is found as before. Those are Numba internals, not a documented interface:
``tests/learner/engines/test_kernel_stamp.py`` checks that the kernels' caches do carry this stamp
and that an edit to one kernel file recompiles a function of another, and fails if a Numba
release changes how locators are chosen. (The environment variable
``NUMBA_CACHE_LOCATOR_CLASSES`` replaces the whole list: with it set, the kernels fall back to
Numba's own per-file stamp.)
"""

from __future__ import annotations

import hashlib
import os
from functools import cache
from pathlib import Path
from typing import Any

from numba.core import caching

__all__ = ["KERNEL_DIR", "kernel_stamp", "register", "stamped_sources"]

#: This package's folder: the functions defined in it are the ones stamped.
KERNEL_DIR = Path(__file__).resolve().parent


def stamped_sources() -> tuple[Path, ...]:
    """The files whose content the kernels' machine code depends on: every module of this package,
    the engine's settings (:mod:`himit_torch.learner.engines.settings`, whose codes the kernels
    compare against) and :mod:`himit_torch.learner.posterior_sampling` (whose constants
    :mod:`.sampling` reads)."""
    engines = KERNEL_DIR.parent
    return (
        *sorted(KERNEL_DIR.glob("*.py")),
        engines / "settings.py",
        engines.parent / "posterior_sampling.py",
    )


def _settings_values() -> str:
    """The settings' values decided outside the stamped files: its upper-case constants (codes
    computed from :mod:`himit_torch.learner.config`'s choices) and the order of
    ``KernelSettings``' fields (generated from the config schema; the kernels read them by
    position)."""
    from himit_torch.learner.engines import settings

    constants = sorted((k, repr(v)) for k, v in vars(settings).items() if k.isupper())
    return repr((constants, settings.KernelSettings._fields))


@cache
def _stamp(files: tuple[tuple[str, int, int], ...]) -> str:
    # (keyed by each file's mtime and size, as Numba's own stamp is, so that an edit while the
    # process runs is seen; the files are read once otherwise)
    h = hashlib.sha256()
    for path, _, _ in files:
        h.update(os.path.basename(path).encode() + b"\0")
        h.update(Path(path).read_bytes())
        h.update(b"\0")
    h.update(_settings_values().encode())
    return h.hexdigest()


def kernel_stamp() -> str:
    """The stamp every kernel's cache carries: a hex SHA-256 over :func:`stamped_sources` and the
    settings' values. It changes with any edit to any of those files."""
    files = []
    for path in stamped_sources():
        st = path.stat()
        files.append((str(path), st.st_mtime_ns, st.st_size))
    return _stamp(tuple(files))


def _is_kernel_file(py_file: str) -> bool:
    try:
        return Path(py_file).resolve().parent == KERNEL_DIR
    except OSError:
        return False


class _KernelStamped:
    """Mixed in front of a Numba file-backed locator: answers for this package's functions only,
    and stamps their caches with :func:`kernel_stamp` instead of their own file's hash."""

    @classmethod
    def from_function(cls, py_func: Any, py_file: str) -> Any:
        if not _is_kernel_file(py_file):
            return None
        return super().from_function(py_func, py_file)  # type: ignore[misc]

    def get_source_stamp(self) -> str:
        return kernel_stamp()


#: Numba's locators for functions in source files, in the order Numba tries them.
NUMBA_FILE_LOCATORS = (
    caching.UserProvidedCacheLocator,  # NUMBA_CACHE_DIR
    caching.InTreeCacheLocator,  # __pycache__ beside the source
    caching.UserWideCacheLocator,  # the user's cache folder
)
#: Ours: the same, stamped with :func:`kernel_stamp`.
KERNEL_LOCATORS = tuple(
    type(f"Kernel{base.__name__}", (_KernelStamped, base), {"__module__": __name__})
    for base in NUMBA_FILE_LOCATORS
)


def register() -> None:
    """Put ``KERNEL_LOCATORS`` in front of the locators Numba tries for a compiled function's
    cache (once; before any kernel is decorated: :mod:`.jit` calls it on import)."""
    impl = caching.CompileResultCacheImpl
    current: list[Any] = list(impl._locator_classes)
    if current[: len(KERNEL_LOCATORS)] != list(KERNEL_LOCATORS):
        impl._locator_classes = [*KERNEL_LOCATORS, *current]  # type: ignore[list-item]
