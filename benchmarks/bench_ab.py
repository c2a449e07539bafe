"""Interleaved A/B of ``himit bench`` between two checkouts: compile time and steady throughput.

Each measurement is a fresh process of ``python -m himit_torch.cli bench --engine numba`` with
``PYTHONPATH`` set to one checkout and its own Numba cache. Cold = a process with an empty
cache, warm = the same with a filled one (their difference: the kernels' compile); then two
steady cases. Medians of ``REPEATS`` (default 3), the checkouts interleaved so that a change in
the machine's load hits both alike:

    REPEATS=3 python benchmarks/bench_ab.py NEW_CHECKOUT BASE_CHECKOUT

(``STEADY_ONLY=1``: the steady cases only.)

(e.g. ``git worktree add /tmp/base <commit>`` for the base).
"""

import os
import re
import statistics
import subprocess
import sys
import tempfile
import time

TREES = {"base": sys.argv[2], "new": sys.argv[1]}
REPEATS = int(os.environ.get("REPEATS", 3))
STEADY_ONLY = bool(os.environ.get("STEADY_ONLY"))  # the steady cases only, no cold/warm processes
SMALL = ["--size", "24", "--rooms", "6", "--batch", "2", "--agent", "mix"]
SMALL += ["--steps", "6000", "--warmup", "1"]
CASES = [
    ("80c B=1", ["--size", "80", "--rooms", "10", "--corner-options", "--batch", "1"]
     + ["--agent", "imitation", "--steps", "200000"]),
    ("40 B=16 mix", ["--size", "40", "--rooms", "10", "--batch", "16", "--agent", "mix"]
     + ["--steps", "100000"]),
]  # fmt: skip


def bench(tree: str, args: list[str], cache: str) -> float:
    """Steps per second reported by one ``himit bench`` process."""
    env = {**os.environ, "PYTHONPATH": tree, "NUMBA_CACHE_DIR": cache}
    out = subprocess.run(
        [sys.executable, "-m", "himit_torch.cli", "bench", "--engine", "numba", *args],
        cwd=tree,
        env=env,
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    return float(re.search(r"([\d,]+) steps/s", out).group(1).replace(",", ""))


def timed(tree: str, args: list[str], cache: str) -> float:
    start = time.perf_counter()
    bench(tree, args, cache)
    return time.perf_counter() - start


res: dict[tuple[str, str], list[float]] = {}
caches = {k: tempfile.mkdtemp() for k in TREES}
for k, tree in TREES.items():  # fill each tree's cache
    bench(tree, SMALL, caches[k])
for _ in range(0 if STEADY_ONLY else REPEATS):
    for k, tree in TREES.items():
        cold = timed(tree, SMALL, tempfile.mkdtemp())
        warm = timed(tree, SMALL, caches[k])
        for name, value in (("cold", cold), ("warm", warm), ("compile", cold - warm)):
            res.setdefault((f"{name} process s" if name != "compile" else "compile s", k), [])
            res[(f"{name} process s" if name != "compile" else "compile s", k)].append(value)
        print("cold/warm", k, f"{cold:.2f}", f"{warm:.2f}", flush=True)
for _ in range(REPEATS):
    for name, args in CASES:
        for k, tree in TREES.items():
            res.setdefault((name, k), []).append(bench(tree, args, caches[k]))
            print(name, k, res[(name, k)][-1], flush=True)
print("\n| case | base (median) | new (median) | new/base | base runs | new runs |")
print("|---|---|---|---|---|---|")
for name in ([] if STEADY_ONLY else ["cold process s", "warm process s", "compile s"]) + [
    c[0] for c in CASES
]:
    b, n = res[(name, "base")], res[(name, "new")]
    fmt = (lambda x: f"{x:,.0f}") if b[0] > 100 else (lambda x: f"{x:.2f}")
    ratio = statistics.median(n) / statistics.median(b)
    print(
        f"| {name} | {fmt(statistics.median(b))} | {fmt(statistics.median(n))} | {ratio:.3f} "
        f"| {', '.join(map(fmt, b))} | {', '.join(map(fmt, n))} |"
    )
