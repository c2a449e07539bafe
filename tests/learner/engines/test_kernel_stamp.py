"""Every kernel's disk cache is stamped with a hash over all the kernels' sources
(:mod:`himit_torch.learner.engines.kernel.stamp`): an edit to any kernel file, or to the engine's
settings, makes every cached kernel stale, not only those defined in the edited file.

The end-to-end check works on a copy of the package in a temporary folder (never on the working
tree's sources), with a fresh ``NUMBA_CACHE_DIR``, and a small kernel added to the copy's kernel
package in place of ``run_ticks`` (which takes tens of seconds to compile): like ``run_ticks``, it
is cached with the kernels' flags (``jit.entry``) and reads a constant of another file."""

from __future__ import annotations

import ast
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from himit_torch.learner.engines import numba_available

pytestmark = pytest.mark.skipif(not numba_available(), reason="numba is not installed")

# A kernel of the copy's kernel package that returns a constant of the engine's settings (frozen
# into its machine code by Numba, as run_ticks freezes them).
PROBE = """
from himit_torch.learner.engines.kernel.jit import entry
from himit_torch.learner.engines.settings import UNTRIED_SKIP


@entry
def probe():
    return UNTRIED_SKIP
"""

RUN_PROBE = """
import json
from himit_torch.learner.engines.kernel import probe as module
value = module.probe()
stats = module.probe.stats
print(json.dumps({
    "file": module.__file__,
    "value": int(value),
    "hits": sum(stats.cache_hits.values()),
    "misses": sum(stats.cache_misses.values()),
}))
"""


def _package_copy(root: Path) -> Path:
    """A copy of the installed ``himit_torch`` package under ``root`` (without caches), with the
    probe kernel added: the copy's kernel folder."""
    import himit_torch

    source = Path(himit_torch.__file__).resolve().parent
    shutil.copytree(source, root / "himit_torch", ignore=shutil.ignore_patterns("__pycache__"))
    kernel = root / "himit_torch" / "learner" / "engines" / "kernel"
    (kernel / "probe.py").write_text(PROBE)
    return kernel


def _run_probe(root: Path, cache: Path) -> dict:
    env = {
        **os.environ,
        "PYTHONPATH": str(root),
        "NUMBA_CACHE_DIR": str(cache),
    }
    env.pop("NUMBA_CACHE_LOCATOR_CLASSES", None)
    out = subprocess.run(
        [sys.executable, "-c", RUN_PROBE],
        cwd=root,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 0, out.stderr
    result = json.loads(out.stdout.strip().splitlines()[-1])
    assert Path(result["file"]).resolve().is_relative_to(root.resolve())  # the copy, not the tree
    return result


# (it compiles a kernel in a copy of the package, ≈ 10 s: CI's)
@pytest.mark.slow
def test_an_edit_to_another_kernel_file_recompiles_a_cached_kernel(tmp_path):
    root, cache = tmp_path / "tree", tmp_path / "numba-cache"
    kernel = _package_copy(root)
    settings = kernel.parent / "settings.py"

    first = _run_probe(root, cache)
    assert (first["value"], first["hits"], first["misses"]) == (1, 0, 1)  # compiled, cached
    again = _run_probe(root, cache)
    assert (again["value"], again["hits"], again["misses"]) == (1, 1, 0)  # loaded from the cache

    # A constant changed in settings.py alone (the probe's own file unchanged): Numba's per-file
    # stamp would load the old machine code and return 1.
    text = settings.read_text()
    old = "UNTRIED_PRIOR, UNTRIED_SKIP, UNTRIED_VALUE = 0, 1, 2"
    assert old in text
    settings.write_text(text.replace(old, "UNTRIED_PRIOR, UNTRIED_SKIP, UNTRIED_VALUE = 0, 5, 2"))
    edited = _run_probe(root, cache)
    assert (edited["value"], edited["hits"], edited["misses"]) == (5, 0, 1)

    # Any edit to any kernel file (here a comment in heap.py, which the probe does not use)
    # makes every kernel's cache stale.
    heap = kernel / "heap.py"
    heap.write_text(heap.read_text() + "\n# edited\n")
    touched = _run_probe(root, cache)
    assert (touched["value"], touched["hits"], touched["misses"]) == (5, 0, 1)


def test_every_kernel_cache_carries_the_kernel_stamp():
    """Pins what :mod:`.stamp` assumes of Numba's internals (``numba.core.caching``): the cache of
    a ``cache=True`` function is found by the first of ``CompileResultCacheImpl._locator_classes``
    that answers, and is checked against that locator's ``get_source_stamp()``. If a Numba release
    changes this, this test fails instead of the kernels silently running stale code."""
    from numba.core import caching

    from himit_torch.learner.engines.kernel import backup, sampling, stamp, tick
    from himit_torch.learner.engines.numba_engine import KERNELS

    assert list(caching.CompileResultCacheImpl._locator_classes[:3]) == list(stamp.KERNEL_LOCATORS)
    # Numba still tries its file-backed locators in the order ours mirror
    numba_order = [c for c in caching.CacheImpl._locator_classes if c in stamp.NUMBA_FILE_LOCATORS]
    assert numba_order == list(stamp.NUMBA_FILE_LOCATORS)

    cached = [
        d
        for module in (tick, backup, sampling)
        for d in vars(module).values()
        if hasattr(d, "py_func")
        and d.py_func.__module__ == module.__name__
        and not isinstance(d._cache, caching.NullCache)  # cache=True (inlined helpers: not)
    ]
    assert set(KERNELS) <= set(cached)
    assert {d.py_func.__name__ for d in cached} >= {"run_ticks", "resample", "backup_state"}
    expected = stamp.kernel_stamp()
    for dispatcher in cached:
        cache = dispatcher._cache
        assert isinstance(cache, caching.FunctionCache), dispatcher
        locator = cache._impl.locator
        assert isinstance(locator, stamp.KERNEL_LOCATORS), (dispatcher, type(locator))
        assert locator.get_source_stamp() == expected
        # ... and that stamp is what the cache's index is checked against
        assert cache._cache_file._source_stamp == expected


def test_functions_outside_the_kernels_keep_numbas_own_locators(tmp_path):
    from numba.core import caching

    from himit_torch.learner.engines.kernel import stamp

    source = tmp_path / "elsewhere.py"
    namespace: dict = {}
    exec(compile("def f():\n    return 1\n", str(source), "exec"), namespace)
    source.write_text("def f():\n    return 1\n")
    locator = caching.FunctionCache(namespace["f"])._impl.locator
    assert not isinstance(locator, stamp.KERNEL_LOCATORS)
    assert isinstance(locator, stamp.NUMBA_FILE_LOCATORS)


def _runtime_imports(tree: ast.Module) -> list[ast.Import | ast.ImportFrom]:
    """The module's imports, less those under ``if TYPE_CHECKING:``."""
    skipped = {
        id(n)
        for block in ast.walk(tree)
        if isinstance(block, ast.If) and ast.unparse(block.test).endswith("TYPE_CHECKING")
        for n in ast.walk(block)
    }
    return [
        n
        for n in ast.walk(tree)
        if isinstance(n, (ast.Import, ast.ImportFrom)) and id(n) not in skipped
    ]


def test_the_stamp_covers_every_project_module_the_kernels_import():
    """A kernel file (or the settings) that imports another ``himit_torch`` module may read
    something of it at compile time: that module must be stamped too (or, for the config, the
    values the settings take from it)."""
    from himit_torch.learner.engines.kernel import stamp

    stamped = {p.resolve() for p in stamp.stamped_sources()}
    package = stamp.KERNEL_DIR.parents[2]  # himit_torch/
    value_stamped = {"himit_torch.learner.config"}  # through the settings' values
    for path in stamped:
        if path.name == "posterior_sampling.py":
            continue  # the kernels read its literal constants only, not the torch code it imports
        for node in _runtime_imports(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                modules = [node.module or ""]
            else:
                modules = [a.name for a in node.names]
            for module in modules:
                if not module.startswith("himit_torch.") or module in value_stamped:
                    continue
                target = package.joinpath(*module.split(".")[1:])
                if target.is_dir():  # ``from package import module``
                    names = [a.name for a in node.names]
                    files = [target / f"{n}.py" for n in names if (target / f"{n}.py").exists()]
                else:
                    files = [target.with_suffix(".py")]
                assert files, f"{path.name}: from {module} import ... (a package's __init__)"
                for file in files:
                    assert file.resolve() in stamped, f"{path.name} imports {module}: {file}"
